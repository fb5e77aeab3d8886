//! The `spreadsheet-export` binary, run as a user runs it: headers, values
//! (checked against the driver's own steps), exit codes, files left behind,
//! and the XLSX read back.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use calamine::{open_workbook, Data, Reader, Xlsx};
use driver::profile::austin::AustinProfile;
use driver::profile::leib::LeibProfile;
use driver::profile::scurve::{p2_period_ticks, Arithmetic, SCurve, ScurveConfig, P2_PULSE_TICKS};
use driver::profile::trapezoid::Trapezoid;
use driver::profile::Step;

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");
const HEADER: &str = "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s,period_ticks";
const MOTOR_HEADER: &str = "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s,\
                            period_ticks,accel_steps_per_s2,torque_required_nm,torque_available_nm,margin";

fn export(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stdout(output: &Output) -> String {
    String::from_utf8(output.stdout.clone()).expect("UTF-8 output")
}

fn stderr(output: &Output) -> String {
    String::from_utf8(output.stderr.clone()).expect("UTF-8 stderr")
}

/// Parsed CSV rows (without the header).
fn records(text: &str) -> Vec<csv::StringRecord> {
    csv::Reader::from_reader(text.as_bytes())
        .records()
        .collect::<Result<_, _>>()
        .expect("valid CSV")
}

fn number(record: &csv::StringRecord, column: usize) -> f64 {
    record[column].parse().expect("a number")
}

fn files_in(directory: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(directory)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .collect();
    files.sort();
    files
}

/// Asserts a failure with exit code 2 and one `spreadsheet-export: ` line.
fn assert_bad_input(output: &Output, reason: &str) {
    let message = stderr(output);
    assert_eq!(output.status.code(), Some(2), "{message}");
    assert!(message.starts_with("spreadsheet-export: "), "{message:?}");
    assert_eq!(message.lines().count(), 1, "{message:?}");
    assert!(message.contains(reason), "{message:?} lacks {reason:?}");
    assert!(output.stdout.is_empty());
}

fn scurve_steps(arithmetic: Arithmetic, speed: u32, steps: u32) -> Vec<Step> {
    let config = ScurveConfig {
        arithmetic,
        ..ScurveConfig::default()
    };
    SCurve::new(config, speed, steps).unwrap().collect()
}

/// The period of a step of this delay: the delay itself, except in
/// `p2-exact`, where the reference cog adds its pulse and overhead.
fn delay_period(delay_ticks: u32) -> u64 {
    u64::from(delay_ticks)
}

fn p2_period(delay_ticks: u32) -> u64 {
    p2_period_ticks(delay_ticks, P2_PULSE_TICKS)
}

/// Every row equals the driver's step, and time is the running sum of the
/// periods.
fn assert_matches_driver(text: &str, steps: &[Step], clkfreq: f64, sign: f64) {
    assert_matches_driver_with(text, steps, clkfreq, sign, delay_period);
}

fn assert_matches_driver_with(
    text: &str,
    steps: &[Step],
    clkfreq: f64,
    sign: f64,
    period: fn(u32) -> u64,
) {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(HEADER));
    let rows = records(text);
    assert_eq!(rows.len(), steps.len());
    let mut ticks = 0u64;
    let mut previous_time = -1.0;
    for (row, step) in rows.iter().zip(steps) {
        assert_eq!(number(row, 0) as u32, step.index);
        assert_eq!(&row[1], step.phase.as_str());
        match step.angle_deg() {
            Some(angle) => assert_eq!(number(row, 2), angle),
            None => assert_eq!(&row[2], ""),
        }
        assert_eq!(number(row, 3), sign * step.velocity_steps_per_s);
        assert_eq!(row[4].parse::<u32>().unwrap(), step.delay_ticks);
        let time = number(row, 5);
        assert_eq!(time, ticks as f64 / clkfreq);
        assert!(time > previous_time, "time_s must increase");
        previous_time = time;
        assert_eq!(row[6].parse::<u64>().unwrap(), period(step.delay_ticks));
        ticks += period(step.delay_ticks);
    }
}

#[test]
fn p2_csv_is_the_drivers_smooth_s_curve() {
    let output = export(&["--steps", "20000", "--speed", "20000"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = stdout(&output);
    let steps = scurve_steps(Arithmetic::Smooth, 20_000, 20_000);
    assert_matches_driver(&text, &steps, 200e6, 1.0);
    // The first row, as the design describes it.
    let first = &records(&text)[0];
    assert_eq!((&first[0], &first[1]), ("0", "accel"));
    let angle = number(first, 2);
    assert!((39.99..40.01).contains(&angle), "{angle}");
    let delay = number(first, 4);
    assert!((delay - 85_486.0).abs() <= 20.0, "{delay}");
    assert_eq!(number(first, 5), 0.0);
    assert!(stderr(&output).is_empty());
}

#[test]
fn p2_exact_csv_is_the_drivers_reference_arithmetic() {
    let output = export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "--profile",
        "p2-exact",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = stdout(&output);
    let steps = scurve_steps(Arithmetic::P2Exact, 20_000, 20_000);
    assert_matches_driver_with(&text, &steps, 200e6, 1.0, p2_period);
    let rows = records(&text);
    assert!((number(&rows[0], 4) - 85_470.0).abs() <= 20.0);
    // At speed the P2 steps every 10,000 + 1,000 + 8 ticks: a scope
    // reads 18,169 steps/s where 20,000 were asked.
    assert_eq!((&rows[10_000][4], &rows[10_000][6]), ("10000", "11008"));
}

#[test]
fn reverse_move_has_negative_velocity_and_the_same_timing() {
    let output = export(&["--steps", "-3000", "--speed", "5000"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let steps = scurve_steps(Arithmetic::Smooth, 5_000, 3_000);
    assert_matches_driver(&stdout(&output), &steps, 200e6, -1.0);
}

#[test]
fn other_clock_offset_and_divisor_reach_the_driver() {
    let output = export(&[
        "--steps",
        "777",
        "--speed",
        "3001",
        "--clkfreq",
        "80000000",
        "--offset",
        "25",
        "--accel-div",
        "7",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let config = ScurveConfig {
        clkfreq: 80_000_000,
        offset_deg: 25,
        accel_div: 7,
        arithmetic: Arithmetic::Smooth,
    };
    let steps: Vec<Step> = SCurve::new(config, 3_001, 777).unwrap().collect();
    assert_matches_driver(&stdout(&output), &steps, 80e6, 1.0);
}

#[test]
fn linear_ramp_profiles_are_the_drivers() {
    let (clkfreq, speed, accel, steps) = (200_000_000, 4_000.0, 20_000.0, 1_000);
    let cases: [(&str, Vec<Step>); 3] = [
        (
            "austin",
            AustinProfile::new(clkfreq, speed, accel, steps)
                .unwrap()
                .collect(),
        ),
        (
            "leib",
            LeibProfile::new(clkfreq, speed, accel, steps)
                .unwrap()
                .collect(),
        ),
        (
            "trapezoid",
            Trapezoid::new(clkfreq, speed, accel, steps)
                .unwrap()
                .collect(),
        ),
    ];
    for (profile, expected) in cases {
        let output = export(&[
            "--steps",
            "1000",
            "--speed",
            "4000",
            "--accel",
            "20000",
            "--profile",
            profile,
        ]);
        assert_eq!(
            output.status.code(),
            Some(0),
            "{profile}: {}",
            stderr(&output)
        );
        assert_matches_driver(&stdout(&output), &expected, 200e6, 1.0);
    }
}

/// The lecture: J_load = 6e-5 kg·m², 0.3 N·m friction, 0 → 20 rev/s in
/// 0.2 s with 1.8° steps (4,000 steps/s, 20,000 steps/s², 628.3 rad/s²):
/// a 2.5e-5 kg·m² motor needs 0.353 N·m, a 3.5e-5 one 0.359 N·m (the
/// lecture truncates 0.35969).
#[test]
fn lecture_example_on_the_exact_trapezoid() {
    let directory = tempfile::tempdir().unwrap();
    for (rotor, lecture_nm) in [(2.5e-5, 0.353), (3.5e-5, 0.359)] {
        let motor = motor_file(directory.path(), rotor, 1.0, 1.0);
        let output = export(&[
            "--steps",
            "1000",
            "--speed",
            "4000",
            "--accel",
            "20000",
            "--profile",
            "trapezoid",
            "--motor",
            motor.to_str().unwrap(),
        ]);
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
        let rows = records(&stdout(&output));
        // 400 steps accelerating (v²/2a), 200 at speed, 400 decelerating.
        let accelerating: Vec<_> = rows.iter().filter(|row| &row[1] == "accel").collect();
        assert_eq!(accelerating.len(), 400);
        // Each acceleration lies between two steps: both in the ramp.
        for row in &accelerating[..399] {
            let accel = number(row, 7);
            assert!((accel - 20_000.0).abs() < 20.0, "{accel}");
            let torque = number(row, 8);
            assert!((torque - lecture_nm).abs() < 1e-3, "{rotor}: {torque}");
        }
        let mean = accelerating[..399]
            .iter()
            .map(|row| number(row, 8))
            .sum::<f64>()
            / 399.0;
        let truncated = (mean * 1000.0).floor() / 1000.0;
        assert_eq!(truncated, lecture_nm, "{rotor}: mean {mean}");
    }
}

/// The README's motor example, with the motor file the crate ships.
#[test]
fn shipped_lecture_motor_file_gives_the_readme_result() {
    let motor = concat!(env!("CARGO_MANIFEST_DIR"), "/motors/lecture.toml");
    let output = export(&[
        "--steps",
        "1000",
        "--speed",
        "4000",
        "--accel",
        "20000",
        "--profile",
        "trapezoid",
        "--motor",
        motor,
    ]);
    assert_eq!(output.status.code(), Some(3), "{}", stderr(&output));
    assert_eq!(
        stderr(&output).trim_end(),
        "spreadsheet-export: motor check: smallest margin 1.472 at step 398 \
         (required 0.3534 N·m, available 0.5201 N·m); safety factor 1.5: \
         BELOW the safety factor: the motor may lose steps"
    );
}

#[test]
fn file_output_equals_stdout_output() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("move.csv");
    let to_file = export(&[
        "--steps",
        "500",
        "--speed",
        "4000",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert_eq!(to_file.status.code(), Some(0), "{}", stderr(&to_file));
    assert!(to_file.stdout.is_empty());
    let to_stdout = export(&["--steps", "500", "--speed", "4000"]);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), stdout(&to_stdout));
    assert_eq!(files_in(directory.path()), vec![path]);
}

#[test]
fn bad_input_is_one_line_and_exit_code_2() {
    let cases: &[(&[&str], &str)] = &[
        (&["--steps", "0", "--speed", "100"], "--steps must not be 0"),
        (
            &["--steps", "10", "--speed", "0"],
            "--speed must be a positive",
        ),
        (
            &["--steps", "10", "--speed", "-100"],
            "--speed must be a positive",
        ),
        (&["--steps", "10", "--speed", "300000000"], "too fast"),
        (&["--steps", "10", "--speed", "100.5"], "whole number"),
        (
            &["--steps", "10", "--speed", "100", "--profile", "s-curve"],
            "invalid value",
        ),
        (
            &["--steps", "10", "--speed", "100", "--profile", "austin"],
            "needs --accel",
        ),
        (
            &["--steps", "10", "--speed", "100", "--profile", "leib"],
            "needs --accel",
        ),
        (
            &["--steps", "10", "--speed", "100", "--profile", "trapezoid"],
            "needs --accel",
        ),
        (
            &["--steps", "10", "--speed", "100", "--offset", "90"],
            "offset",
        ),
        (
            &["--steps", "10", "--speed", "100", "--format", "xlsx"],
            "needs an output file",
        ),
        (
            &["--steps", "10", "--speed", "100", "--plot", "v.jpg"],
            ".png or .svg",
        ),
        (&["--steps", "10"], "--speed"),
        (
            &[
                "--steps",
                "10",
                "--speed",
                "100",
                "--motor",
                "no-such-motor.toml",
            ],
            "motor file",
        ),
    ];
    for (args, reason) in cases {
        assert_bad_input(&export(args), reason);
    }
}

#[test]
fn errors_leave_no_file_behind() {
    let directory = tempfile::tempdir().unwrap();
    let motor = directory.path().join("motor.toml");
    std::fs::write(&motor, "step_angle_deg = 1.8\nrotor_inertia_kgm2 = [").unwrap();
    let out = directory.path().join("move.csv");
    let xlsx = directory.path().join("move.xlsx");
    let plot = directory.path().join("move.png");
    let (motor, out, xlsx, plot) = (
        motor.to_str().unwrap(),
        out.to_str().unwrap(),
        xlsx.to_str().unwrap(),
        plot.to_str().unwrap(),
    );
    let cases: &[(&[&str], &str)] = &[
        // A malformed motor file.
        (
            &[
                "--steps", "100", "--speed", "1000", "--motor", motor, "-o", out, "--plot", plot,
            ],
            "motor file",
        ),
        // The speed the clock cannot time.
        (
            &[
                "--steps",
                "100",
                "--speed",
                "1000",
                "--clkfreq",
                "999",
                "-o",
                xlsx,
            ],
            "too fast",
        ),
        // More rows than an XLSX sheet holds.
        (
            &[
                "--steps", "1048576", "--speed", "1000", "-o", xlsx, "--plot", plot,
            ],
            "XLSX sheet",
        ),
    ];
    for (args, reason) in cases {
        assert_bad_input(&export(args), reason);
        assert_eq!(files_in(directory.path()), vec![PathBuf::from(motor)]);
    }
}

#[test]
fn unwritable_paths_are_exit_code_2() {
    let directory = tempfile::tempdir().unwrap();
    let missing = directory.path().join("no/such/dir/move.csv");
    let output = export(&[
        "--steps",
        "10",
        "--speed",
        "100",
        "-o",
        missing.to_str().unwrap(),
    ]);
    assert_bad_input(&output, "cannot write");
    // A directory where the file should go.
    let occupied = directory.path().join("taken.csv");
    std::fs::create_dir(&occupied).unwrap();
    let output = export(&[
        "--steps",
        "10",
        "--speed",
        "100",
        "-o",
        occupied.to_str().unwrap(),
    ]);
    assert_bad_input(&output, "cannot write");
    assert_eq!(files_in(directory.path()), vec![occupied.clone()]);
    assert_eq!(std::fs::read_dir(&occupied).unwrap().count(), 0);
}

/// The lecture's load with a motor whose pull-out torque is `torque_nm` up
/// to 30,000 steps/s.
fn motor_file(directory: &Path, rotor_inertia_kgm2: f64, torque_nm: f64, safety: f64) -> PathBuf {
    let path = directory.join("motor.toml");
    std::fs::write(
        &path,
        format!(
            "step_angle_deg = 1.8\n\
             rotor_inertia_kgm2 = {rotor_inertia_kgm2:e}\n\
             load_inertia_kgm2 = 6e-5\n\
             load_torque_nm = 0.3\n\
             safety_factor = {safety:?}\n\
             torque_curve = [[0, {torque_nm:?}], [30000, {torque_nm:?}]]\n"
        ),
    )
    .unwrap();
    path
}

#[test]
fn motor_columns_and_a_passing_check() {
    let directory = tempfile::tempdir().unwrap();
    let motor = motor_file(directory.path(), 2.5e-5, 2.0, 1.5);
    let output = export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "--motor",
        motor.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = stdout(&output);
    assert_eq!(text.lines().next(), Some(MOTOR_HEADER));
    let rows = records(&text);
    assert_eq!(rows.len(), 20_000);
    let step_angle_rad = 1.8_f64.to_radians();
    let mut smallest = f64::INFINITY;
    for row in &rows {
        let accel = number(row, 7);
        let required = number(row, 8);
        let expected = 8.5e-5 * accel * step_angle_rad + 0.3;
        assert!((required - expected).abs() < 1e-12, "{required} {expected}");
        assert_eq!(number(row, 9), 2.0);
        assert!((number(row, 10) - 2.0 / required.abs()).abs() < 1e-9);
        smallest = smallest.min(number(row, 10));
    }
    let message = stderr(&output);
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(
        message.contains(&format!("smallest margin {smallest:.3} at step")),
        "{message}"
    );
    assert!(message.contains(": ok"), "{message}");
}

#[test]
fn margin_below_the_safety_factor_is_exit_code_3_with_the_file_kept() {
    let directory = tempfile::tempdir().unwrap();
    let motor = motor_file(directory.path(), 3.5e-5, 0.5, 1.5);
    let out = directory.path().join("move.csv");
    let output = export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "--motor",
        motor.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(3), "{}", stderr(&output));
    let message = stderr(&output);
    assert!(message.starts_with("spreadsheet-export: motor check: smallest margin"));
    assert!(message.contains("BELOW the safety factor"), "{message}");
    // The step named is the one with the smallest margin in the table.
    let rows = records(&std::fs::read_to_string(&out).unwrap());
    assert_eq!(rows.len(), 20_000);
    let (step, margin) = rows
        .iter()
        .map(|row| (number(row, 0) as u32, number(row, 10)))
        .fold((0, f64::INFINITY), |best, item| {
            if item.1 < best.1 {
                item
            } else {
                best
            }
        });
    assert!(margin < 1.5);
    assert!(message.contains(&format!("at step {step} ")), "{message}");
}

#[test]
fn torque_curve_too_short_for_the_move_is_exit_code_2() {
    let directory = tempfile::tempdir().unwrap();
    let motor = directory.path().join("motor.toml");
    std::fs::write(
        &motor,
        "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 2.5e-5\nload_inertia_kgm2 = 0\n\
         load_torque_nm = 0\ntorque_curve = [[0, 0.5], [10000, 0.3]]\n",
    )
    .unwrap();
    let output = export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "--motor",
        motor.to_str().unwrap(),
    ]);
    assert_bad_input(&output, "beyond the torque curve");
}

fn cell_text(data: &Data) -> String {
    match data {
        Data::String(text) => text.clone(),
        other => other.to_string(),
    }
}

fn cell_number(data: &Data) -> f64 {
    match data {
        Data::Float(value) => *value,
        Data::Int(value) => *value as f64,
        other => panic!("not a number: {other:?}"),
    }
}

#[test]
fn xlsx_reads_back_with_table_summary_and_charts() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("move.xlsx");
    let motor = motor_file(directory.path(), 2.5e-5, 2.0, 1.0);
    let output = export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "-o",
        path.to_str().unwrap(),
        "--motor",
        motor.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let csv_text = stdout(&export(&[
        "--steps",
        "20000",
        "--speed",
        "20000",
        "--motor",
        motor.to_str().unwrap(),
    ]));
    let csv_rows = records(&csv_text);

    let mut workbook: Xlsx<_> = open_workbook(&path).unwrap();
    assert_eq!(
        workbook.sheet_names(),
        vec!["steps", "summary", "chart_data"]
    );

    let steps = workbook.worksheet_range("steps").unwrap();
    assert_eq!(steps.height(), 20_001);
    let header: Vec<String> = steps.rows().next().unwrap().iter().map(cell_text).collect();
    assert_eq!(header.join(","), MOTOR_HEADER);
    // Every cell equals the CSV's.
    for (sheet_row, csv_row) in steps.rows().skip(1).zip(&csv_rows) {
        assert_eq!(cell_text(&sheet_row[1]), &csv_row[1]);
        for column in [0, 2, 3, 4, 5, 6, 7, 8, 9, 10] {
            assert_eq!(cell_number(&sheet_row[column]), number(csv_row, column));
        }
    }

    let summary = workbook.worksheet_range("summary").unwrap();
    let value = |quantity: &str| -> Data {
        summary
            .rows()
            .find(|row| cell_text(&row[0]) == quantity)
            .unwrap_or_else(|| panic!("no {quantity}"))[1]
            .clone()
    };
    assert_eq!(cell_text(&value("profile")), "p2");
    assert_eq!(cell_number(&value("steps requested")), 20_000.0);
    assert_eq!(cell_number(&value("accel steps")), 2_002.0);
    assert_eq!(cell_number(&value("slew steps")), 15_996.0);
    assert_eq!(cell_number(&value("decel steps")), 2_002.0);
    assert_eq!(cell_number(&value("top speed")), 20_000.0);
    let last = csv_rows.last().unwrap();
    let total = number(last, 5) + number(last, 6) / 200e6;
    assert!((cell_number(&value("total time")) - total).abs() < 1e-12);
    let rate = cell_number(&value("average step rate (real)"));
    assert!((rate - 20_000.0 / total).abs() < 1e-6, "{rate}");
    let largest = csv_rows
        .iter()
        .map(|row| number(row, 7).abs())
        .fold(0.0, f64::max);
    assert_eq!(cell_number(&value("largest acceleration")), largest);
    let smallest = csv_rows
        .iter()
        .map(|row| number(row, 10))
        .fold(f64::INFINITY, f64::min);
    assert_eq!(cell_number(&value("smallest motor margin")), smallest);
    assert_eq!(cell_text(&value("motor check")), "ok");

    let chart_data = workbook.worksheet_range("chart_data").unwrap();
    // Thinned to at most 4,000 points, the extremes kept.
    assert!(
        (100..=4_001).contains(&chart_data.height()),
        "{}",
        chart_data.height()
    );
    let charted_largest = chart_data
        .rows()
        .skip(1)
        .map(|row| cell_number(&row[3]).abs())
        .fold(0.0, f64::max);
    assert_eq!(charted_largest, largest);

    // The charts are in the package.
    let archive = std::fs::read(&path).unwrap();
    let names = String::from_utf8_lossy(&archive);
    assert!(names.contains("xl/charts/chart1.xml"));
    assert!(names.contains("xl/charts/chart2.xml"));
}

#[test]
fn p2_exact_xlsx_states_the_real_average_rate() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("exact.xlsx");
    let output = export(&[
        "--steps",
        "200000",
        "--speed",
        "20000",
        "--profile",
        "p2-exact",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let steps = scurve_steps(Arithmetic::P2Exact, 20_000, 200_000);
    let ticks: u64 = steps.iter().map(|step| p2_period(step.delay_ticks)).sum();
    let mut workbook: Xlsx<_> = open_workbook(&path).unwrap();
    let summary = workbook.worksheet_range("summary").unwrap();
    let value = |quantity: &str| -> f64 {
        cell_number(
            &summary
                .rows()
                .find(|row| cell_text(&row[0]) == quantity)
                .unwrap_or_else(|| panic!("no {quantity}"))[1],
        )
    };
    assert_eq!(value("total time"), ticks as f64 / 200e6);
    let rate = value("average step rate (real)");
    assert_eq!(rate, 200_000.0 * 200e6 / ticks as f64);
    // Mostly at speed, where the board makes 18,169 steps/s of the 20,000.
    assert!((17_000.0..18_169.0).contains(&rate), "{rate}");
}

#[test]
fn plots_are_written_as_png_and_svg() {
    let directory = tempfile::tempdir().unwrap();
    let png = directory.path().join("move.png");
    let svg = directory.path().join("move.svg");
    for path in [&png, &svg] {
        let output = export(&[
            "--steps",
            "5000",
            "--speed",
            "8000",
            "--plot",
            path.to_str().unwrap(),
            "-o",
            directory.path().join("move.csv").to_str().unwrap(),
        ]);
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    }
    assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    let svg_text = std::fs::read_to_string(&svg).unwrap();
    assert!(svg_text.contains("velocity (steps/s)"));
    assert!(svg_text.contains("acceleration (steps/s²)"));
    assert_eq!(files_in(directory.path()).len(), 3);
}

#[test]
fn together_writes_one_position_column_per_axis_and_the_deviation() {
    let output = export(&["--together", "1200,-400,0", "--speed", "20000"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = stdout(&output);
    assert_eq!(
        text.lines().next(),
        Some(
            "time_s,ct_ticks,progress,axis0_position,axis1_position,axis2_position,deviation_steps"
        )
    );
    let rows = records(&text);
    // Positions only ever move one step at a time, toward the target, and
    // stay within a step of the line.
    let mut last = [0.0f64; 3];
    for row in &rows {
        for (axis, previous) in last.iter_mut().enumerate() {
            let position = number(row, 3 + axis);
            assert!((position - *previous).abs() <= 1.0);
            *previous = position;
        }
        let progress = number(row, 2);
        let deviation = number(row, 6);
        assert!(deviation <= 1.0);
        let expected = [1_200.0 * progress, -400.0 * progress, 0.0]
            .iter()
            .zip(&last)
            .map(|(line, position)| (position - line).abs())
            .fold(0.0, f64::max);
        assert!((deviation - expected).abs() < 1e-9);
    }
    assert_eq!(last, [1_200.0, -400.0, 0.0]);
    assert_eq!(number(&rows[rows.len() - 1], 2), 1.0);
    let summary = stderr(&output);
    assert!(
        summary.starts_with("spreadsheet-export: ")
            && summary.contains("largest deviation from the line 0."),
        "{summary}"
    );

    // To a file, in P2Exact: the lead's edge times are the reference move's.
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("group.csv");
    let output = export(&[
        "--together",
        "-300,900",
        "--speed",
        "18000",
        "--profile",
        "p2-exact",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let rows = records(&std::fs::read_to_string(&path).unwrap());
    let lead_ticks: Vec<u64> = rows
        .windows(2)
        .filter(|pair| pair[0][4] != pair[1][4])
        .map(|pair| pair[1][1].parse().unwrap())
        .collect();
    let reference: Vec<u64> = scurve_steps(Arithmetic::P2Exact, 18_000, 900)
        .iter()
        .scan(0u64, |ct, step| {
            let at = *ct;
            *ct += p2_period(step.delay_ticks);
            Some(at)
        })
        .collect();
    assert_eq!(lead_ticks, reference);

    for (args, reason) in [
        (
            vec!["--together", "1,2,3,4,5,6,7,8,9", "--speed", "9"],
            "1 to 8",
        ),
        (
            vec!["--together", "1,2", "--speed", "9", "--profile", "austin"],
            "p2-exact",
        ),
        (
            vec!["--together", "1,2", "--speed", "9", "-o", "x.xlsx"],
            "CSV",
        ),
        (vec!["--together", "1,2", "--speed", "0"], "--speed"),
    ] {
        assert_bad_input(&export(&args), reason);
    }
}
