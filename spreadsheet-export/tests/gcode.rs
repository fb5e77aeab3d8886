//! `spreadsheet-export gcode`: the binary on small programs in a temporary
//! directory (header, last row, summary, exact stop, errors, `--check`,
//! outputs left behind or not), and properties of the library's run over
//! random programs.

use std::path::PathBuf;
use std::process::{Command, Output};

use calamine::{open_workbook, Data, Reader, Xlsx};
use cogstep_gcode::Interpreter;
use proptest::prelude::*;
use spreadsheet_export::cli::Format;
use spreadsheet_export::gcode::job::{Row, Sink};
use spreadsheet_export::gcode::{self, GcodeRequest};
use spreadsheet_export::ExportError;

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");
const MACHINES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/machines");
const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/examples");

fn machine(name: &str) -> String {
    format!("{MACHINES}/{name}.toml")
}

fn export(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// A program in a fresh temporary directory.
fn program(text: &str) -> (tempfile::TempDir, PathBuf) {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("part.gcode");
    std::fs::write(&path, text).unwrap();
    (directory, path)
}

/// `key=value` from the summary line.
fn summary_value(stderr: &str, key: &str) -> String {
    let line = stderr
        .lines()
        .find(|line| line.contains("total_time_s="))
        .unwrap_or_else(|| panic!("no summary in {stderr}"));
    line.split_whitespace()
        .find_map(|field| field.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("no {key} in {line}"))
        .to_string()
}

fn summary_number(stderr: &str, key: &str) -> f64 {
    summary_value(stderr, key).parse().unwrap()
}

const SQUARE: &str = "G21 G90\nG1 X20 F3000\nG1 Y20\nG1 X0\nG1 Y0\nG0 X12.3 Y-4.56\nM2\n";

#[test]
fn the_table_has_the_header_and_ends_on_the_program_end() {
    let (_directory, path) = program(SQUARE);
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = String::from_utf8(output.stdout.clone()).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("time_s,line,x_steps,y_steps,x_mm,y_mm,feed_mm_s")
    );
    let last: Vec<&str> = text.lines().last().unwrap().split(',').collect();
    // 12.3 mm and −4.56 mm at 80 steps/mm, rounded: 984 and −365 (−364.8).
    assert_eq!(&last[1..6], ["6", "984", "-365", "12.3", "-4.5625"]);
    // Times rise, every row moves some axis by one step at most.
    let mut previous: Option<(f64, i64, i64)> = None;
    for line in text.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        let (t, x, y) = (
            fields[0].parse::<f64>().unwrap(),
            fields[2].parse::<i64>().unwrap(),
            fields[3].parse::<i64>().unwrap(),
        );
        if let Some((t0, x0, y0)) = previous {
            assert!(t > t0, "{line}");
            assert!((x - x0).abs() <= 1 && (y - y0).abs() <= 1, "{line}");
            assert!((x, y) != (x0, y0), "{line}");
        }
        previous = Some((t, x, y));
    }
    let message = stderr(&output);
    assert!(
        message.starts_with("spreadsheet-export: total_time_s="),
        "{message}"
    );
    // Within junction deviation (0.02 mm) and one step (1/80 mm).
    let deviation = summary_number(&message, "max_deviation_mm");
    assert!(deviation <= 0.02 + 1.0 / 80.0, "{message}");
    let accel = summary_value(&message, "peak_accel_mm_s2");
    for (axis, value) in accel.split(',').map(|f| f.split_once(':').unwrap()) {
        let value: f64 = value.parse().unwrap();
        assert!(
            value <= 3000.0 * 1.01 && value > 2000.0,
            "{axis}: {message}"
        );
    }
}

#[test]
fn exact_stop_is_slower_and_ends_in_the_same_place() {
    let run = |extra: &[&str]| {
        let text =
            std::fs::read_to_string(format!("{EXAMPLES}/arcs-short-segments.gcode")).unwrap();
        let (directory, path) = program(&text);
        let out = directory.path().join("t.csv");
        let mut args = vec![
            "gcode",
            path.to_str().unwrap(),
            "--machine",
            &machine("xyz-cnc"),
            "-o",
            out.to_str().unwrap(),
        ]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
        args.extend(extra.iter().map(|s| s.to_string()));
        let output = Command::new(BIN).args(&args).output().unwrap();
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
        let table = std::fs::read_to_string(&out).unwrap();
        let last = table.lines().last().unwrap().to_string();
        (summary_number(&stderr(&output), "total_time_s"), last)
    };
    let (blend, blend_end) = run(&[]);
    let (stop, stop_end) = run(&["--exact-stop"]);
    assert!(stop > 2.0 * blend, "{stop} {blend}");
    assert_eq!(
        blend_end.split(',').skip(1).collect::<Vec<_>>()[..4],
        stop_end.split(',').skip(1).collect::<Vec<_>>()[..4]
    );
}

#[test]
fn the_first_error_stops_the_run_and_leaves_no_file() {
    let (directory, path) = program("G1 X10 F600\nG1 Y5\nG1 X2 S1000\nG1 Y0\n");
    let out = directory.path().join("t.csv");
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(
        message.contains("line 3, column 7: unsupported word S1000"),
        "{message}"
    );
    let left: Vec<_> = std::fs::read_dir(directory.path()).unwrap().collect();
    assert_eq!(left.len(), 1, "only the program is left: {left:?}");
    // On stdout: the rows of the lines before the error, none after.
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
    ]);
    assert_eq!(output.status.code(), Some(2));
    let text = String::from_utf8(output.stdout).unwrap();
    let last: Vec<&str> = text.lines().last().unwrap().split(',').collect();
    assert_eq!(&last[1..4], ["2", "800", "400"]);
}

#[test]
fn check_lists_every_error() {
    let (_directory, path) = program("G1 X10 F600\nM3 S100\nG1 Y5\nG2 X1 Y1\nG1 Q3\nG1 X0\n");
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
        "--check",
    ]);
    assert_eq!(output.status.code(), Some(2));
    let message = stderr(&output);
    let errors: Vec<&str> = message
        .lines()
        .filter(|line| line.contains(", column "))
        .collect();
    assert_eq!(errors.len(), 3, "{message}");
    assert!(errors[0].contains("line 2, column "), "{message}");
    assert!(errors[1].contains("line 4,"), "{message}");
    assert!(errors[2].contains("line 5, column 4"), "{message}");
    assert!(
        message.lines().last().unwrap().contains("3 error(s)"),
        "{message}"
    );
    assert!(output.stdout.is_empty());
    let (_directory, good) = program(SQUARE);
    let output = export(&[
        "gcode",
        good.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
        "--check",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!(output.stdout.is_empty());
}

#[test]
fn xlsx_vcd_and_plot_are_written_together() {
    let (directory, path) = program(SQUARE);
    let table = directory.path().join("t.xlsx");
    let vcd = directory.path().join("t.vcd");
    let plot = directory.path().join("t.png");
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
        "-o",
        table.to_str().unwrap(),
        "--vcd",
        vcd.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let mut workbook: Xlsx<_> = open_workbook(&table).unwrap();
    let sheet = workbook.worksheet_range("path").unwrap();
    let header: Vec<String> = sheet
        .rows()
        .next()
        .unwrap()
        .iter()
        .map(|c| c.to_string())
        .collect();
    assert_eq!(
        header,
        [
            "time_s",
            "line",
            "x_steps",
            "y_steps",
            "x_mm",
            "y_mm",
            "feed_mm_s"
        ]
    );
    let last = sheet.rows().next_back().unwrap();
    assert_eq!(last[2], Data::Float(984.0));
    assert_eq!(last[3], Data::Float(-365.0));
    let rows = summary_number(&stderr(&output), "rows");
    assert_eq!(sheet.rows().count() as f64, rows + 1.0);
    // Every step edge is a rising edge of its axis's step pin.
    let edges = summary_number(&stderr(&output), "edges");
    let mut parser = vcd::Parser::new(std::io::BufReader::new(std::fs::File::open(&vcd).unwrap()));
    let header = parser.parse_header().unwrap();
    let step_ids: Vec<_> = ["x_step", "y_step"]
        .iter()
        .map(|name| header.find_var(&["cogstep", name]).unwrap().code)
        .collect();
    let mut rises = 0u64;
    for command in parser {
        if let vcd::Command::ChangeScalar(id, vcd::Value::V1) = command.unwrap() {
            if step_ids.contains(&id) {
                rises += 1;
            }
        }
    }
    assert_eq!(rises as f64, edges);
    assert_eq!(&std::fs::read(&plot).unwrap()[1..4], b"PNG");
}

#[test]
fn clashing_outputs_and_a_missing_machine_leave_nothing() {
    let (directory, path) = program(SQUARE);
    let same = directory.path().join("same.csv");
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        &machine("plotter"),
        "-o",
        same.to_str().unwrap(),
        "--vcd",
        same.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains("name the same file"),
        "{}",
        stderr(&output)
    );
    let output = export(&[
        "gcode",
        path.to_str().unwrap(),
        "--machine",
        "/no/such/machine.toml",
        "-o",
        same.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).contains("machine file"),
        "{}",
        stderr(&output)
    );
    assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
}

#[test]
fn the_old_invocation_still_works() {
    let output = export(&["--steps", "100", "--speed", "2000"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!(String::from_utf8(output.stdout)
        .unwrap()
        .starts_with("step,phase,"));
}

/// A sink that keeps the rows' checks and the last row.
#[derive(Default)]
struct Collect {
    rows: u64,
    last: Option<Row>,
    worst_jump: i64,
}

impl Sink for Collect {
    fn row(&mut self, row: &Row) -> Result<(), ExportError> {
        if let Some(last) = &self.last {
            for (a, b) in row.positions.iter().zip(&last.positions) {
                self.worst_jump = self.worst_jump.max((a - b).abs());
            }
            assert!(row.ct > last.ct);
        }
        self.rows += 1;
        self.last = Some(*row);
        Ok(())
    }
}

fn random_program() -> impl Strategy<Value = Vec<String>> {
    let word = prop_oneof![
        (0.0f64..60.0, 0.0f64..60.0, 5.0f64..80.0)
            .prop_map(|(x, y, f)| format!("G1 X{x:.3} Y{y:.3} F{:.0}", f * 60.0)),
        (0.0f64..60.0, 0.0f64..60.0).prop_map(|(x, y)| format!("G0 X{x:.3} Y{y:.3}")),
        (-8.0f64..8.0, -8.0f64..8.0, any::<bool>()).prop_map(|(i, j, cw)| {
            // A full circle from where the tool is.
            format!("G{} I{i:.3} J{j:.3} F1800", if cw { 2 } else { 3 })
        }),
        (-3.0f64..3.0, -3.0f64..3.0)
            .prop_map(|(x, y)| format!("G91\nG1 X{x:.3} Y{y:.3} F2400\nG90")),
        Just("G4 P0.01".to_string()),
        Just("G61".to_string()),
        Just("G64".to_string()),
    ];
    proptest::collection::vec(word, 1..12)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Every random program ends exactly on its programmed end in steps,
    /// moves one step at a time, and stays within junction deviation plus
    /// the arc tolerance plus one step of the programmed path.
    #[test]
    fn random_programs_end_on_their_end_and_stay_on_the_path(lines in random_program()) {
        let text = lines.join("\n") + "\n";
        let (directory, path) = program(&text);
        let machine_path = PathBuf::from(machine("plotter"));
        let spec = gcode::load_machine(&machine_path).unwrap();
        // The interpreter alone says where the program ends (a line it
        // refuses changes nothing; the run stops there).
        let mut interpreter = Interpreter::new(&spec);
        let mut end = [0i64; 8];
        let mut refused = false;
        for (index, line) in text.lines().enumerate() {
            if interpreter.interpret_line(index as u32 + 1, line, &mut |_| {}).is_err() {
                refused = true;
                break;
            }
            end = interpreter.position_steps();
        }
        let request = GcodeRequest {
            program: path.clone(),
            machine: machine_path,
            output: None,
            format: Format::Csv,
            vcd: None,
            plot: None,
            exact_stop: false,
            clkfreq: 200_000_000,
        };
        let mut sink = Collect::default();
        let result = gcode::run_program(&request, &spec, &mut sink);
        prop_assert_eq!(result.is_err(), refused);
        let ended = sink.last.map_or([0; 8], |row| row.positions);
        prop_assert_eq!(&ended[..2], &end[..2]);
        prop_assert!(sink.worst_jump <= 1);
        if let Ok(summary) = result {
            let bound = spec.planner().junction_deviation_mm + spec.planner().arc_tolerance_mm
                + 1.0 / 80.0;
            prop_assert!(summary.max_deviation_mm <= bound, "{}", summary.line());
            prop_assert_eq!(summary.rows, sink.rows);
        }
        drop(directory);
    }
}
