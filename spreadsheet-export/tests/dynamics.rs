//! `--dynamics` and `compare`, run as a user runs them: the lecture's three
//! motors on the lecture's move, the rotor columns against the driver's
//! model, exit codes, the compare table and its fastest settings re-checked.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use calamine::{open_workbook, Data, Reader, Xlsx};
use driver::motor::Rotor;
use driver::profile::trapezoid::Trapezoid;
use spreadsheet_export::motor::Motor;

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");
const DYNAMICS_HEADER: &str = "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s,\
    period_ticks,accel_steps_per_s2,torque_required_nm,torque_available_nm,margin,\
    rotor_angle_deg,rotor_lag_steps,synchronous";
const COMPARE_HEADER: &str =
    "profile,total_time_s,peak_torque_nm,min_margin,max_rotor_lag_steps,synchronous";
/// The lecture's move: 0 → 4,000 steps/s (20 rev/s) in 0.2 s.
const LECTURE_MOVE: [&str; 8] = [
    "--profile",
    "trapezoid",
    "--steps",
    "2000",
    "--speed",
    "4000",
    "--accel",
    "20000",
];

fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8(output.stderr.clone()).expect("UTF-8 stderr")
}

fn stdout(output: &Output) -> String {
    String::from_utf8(output.stdout.clone()).expect("UTF-8 stdout")
}

fn motor(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("motors")
        .join(name)
}

fn records(text: &str) -> Vec<csv::StringRecord> {
    csv::Reader::from_reader(text.as_bytes())
        .records()
        .collect::<Result<_, _>>()
        .expect("valid CSV")
}

fn number(record: &csv::StringRecord, column: usize) -> f64 {
    record[column].parse().expect("a number")
}

/// The lecture's move with `--dynamics` on a motor file.
fn lecture(motor_file: &Path, extra: &[&str]) -> Output {
    let mut args = LECTURE_MOVE.to_vec();
    args.extend(["--motor", motor_file.to_str().unwrap(), "--dynamics"]);
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn the_lectures_type_100_loses_synchronism_and_types_200_and_300_keep_it() {
    // Type 100: exit 4 ahead of the static check's 3; stderr names the step;
    // the column turns false there and stays false.
    let output = lecture(&motor("type-100.toml"), &[]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(4), "{message}");
    assert!(message.contains("BELOW the safety factor"), "{message}");
    let lost: u32 = message
        .split("LOST SYNCHRONISM at step ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|step| step.parse().ok())
        .unwrap_or_else(|| panic!("no step in {message}"));
    let text = stdout(&output);
    assert_eq!(text.lines().next(), Some(DYNAMICS_HEADER));
    let rows = records(&text);
    assert_eq!(rows.len(), 2_000);
    for row in &rows {
        let step = number(row, 0) as u32;
        let expected = if step < lost { "true" } else { "false" };
        assert_eq!(&row[13], expected, "step {step}");
        if step < lost {
            assert!(number(row, 12).abs() <= 2.0, "step {step}: {}", &row[12]);
        }
    }
    // Lost for good: far behind at the end.
    assert!(number(&rows[1_999], 12) > 100.0);

    // Types 200 and 300: synchronous all the way, within a fraction of a
    // step at the end; the static margins are the lecture's 1.2 and ~1.6.
    for (file, margin) in [("type-200.toml", "1.217"), ("type-300.toml", "1.585")] {
        let output = lecture(&motor(file), &[]);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(0), "{file}: {message}");
        assert!(
            message.contains(&format!("smallest margin {margin}")),
            "{message}"
        );
        assert!(message.contains("rotor dynamics: synchronous"), "{message}");
        let rows = records(&stdout(&output));
        assert!(rows.iter().all(|row| &row[13] == "true"), "{file}");
        let largest = rows
            .iter()
            .map(|row| number(row, 12).abs())
            .fold(0.0, f64::max);
        assert!(largest < 1.0, "{file}: largest lag {largest}");
        let last = rows.last().unwrap();
        assert!(number(last, 12).abs() < 0.5, "{file}: {}", &last[12]);
        // 2,000 steps of 1.8°: 3,600° of rotor, give or take the lag.
        assert!(
            (number(last, 11) - 3_600.0).abs() < 0.5 * 1.8,
            "{}",
            &last[11]
        );
    }
}

#[test]
fn rotor_columns_are_the_drivers_model_and_reverse_mirrors_them() {
    let path = motor("type-200.toml");
    let motor = Motor::load(&path).unwrap();
    let mut rotor = Rotor::new(motor.rotor_params().unwrap(), motor.pull_out_curve());
    let forward = records(&stdout(&lecture(&path, &[])));
    let steps = Trapezoid::new(200_000_000, 4_000.0, 20_000.0, 2_000).unwrap();
    for (row, step) in forward.iter().zip(steps) {
        rotor.step(true);
        rotor.run_for(f64::from(step.delay_ticks) / 200e6);
        let sample = rotor.sample();
        assert_eq!(number(row, 11), sample.angle_deg);
        assert_eq!(number(row, 12), sample.error_steps);
    }
    let mut args = LECTURE_MOVE.to_vec();
    args[3] = "-2000";
    args.extend(["--motor", path.to_str().unwrap(), "--dynamics"]);
    let reverse = records(&stdout(&run(&args)));
    for (f, r) in forward.iter().zip(&reverse) {
        assert_eq!(number(r, 11), -number(f, 11));
        assert_eq!(number(r, 12), number(f, 12), "lag counts along the move");
        assert_eq!(&r[13], &f[13]);
    }
}

#[test]
fn dynamics_needs_a_motor_with_damping_and_refuses_cleanly() {
    let output = run(&["--steps", "10", "--speed", "100", "--dynamics"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("--motor"), "{}", stderr(&output));

    let directory = tempfile::tempdir().unwrap();
    let undamped = directory.path().join("undamped.toml");
    std::fs::write(
        &undamped,
        "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
         load_torque_nm = 0\ntorque_curve = [[0, 0.5], [1000, 0.4]]\n",
    )
    .unwrap();
    let out = directory.path().join("move.csv");
    let output = run(&[
        "--steps",
        "10",
        "--speed",
        "100",
        "--motor",
        undamped.to_str().unwrap(),
        "--dynamics",
        "-o",
        out.to_str().unwrap(),
    ]);
    let message = stderr(&output);
    assert_eq!(output.status.code(), Some(2), "{message}");
    assert!(message.contains("damping_nm_s_per_rad"), "{message}");
    assert_eq!(message.lines().count(), 1);
    assert!(!out.exists());

    let bad_phases = directory.path().join("phases.toml");
    std::fs::write(
        &bad_phases,
        "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
         load_torque_nm = 0\ntorque_curve = [[0, 0.5], [1000, 0.4]]\nphases = 1\n\
         damping_nm_s_per_rad = 1e-4\n",
    )
    .unwrap();
    let output = run(&[
        "--steps",
        "10",
        "--speed",
        "100",
        "--motor",
        bad_phases.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("phases must be 2 to 10"));

    // An inertia typed a thousand million times too small: refused, not a
    // run of billions of substeps.
    let stiff = directory.path().join("stiff.toml");
    std::fs::write(
        &stiff,
        "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-15\nload_inertia_kgm2 = 0\n\
         load_torque_nm = 0\ntorque_curve = [[0, 0.5], [1000, 0.4]]\n\
         damping_nm_s_per_rad = 1e-4\n",
    )
    .unwrap();
    let output = run(&[
        "--steps",
        "10",
        "--speed",
        "100",
        "--motor",
        stiff.to_str().unwrap(),
        "--dynamics",
    ]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(
        stderr(&output).contains("natural frequency"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn a_lost_move_still_writes_its_files_and_the_workbook_and_plot_carry_the_rotor() {
    let directory = tempfile::tempdir().unwrap();
    let xlsx = directory.path().join("move.xlsx");
    let svg = directory.path().join("move.svg");
    let output = lecture(
        &motor("type-100.toml"),
        &[
            "-o",
            xlsx.to_str().unwrap(),
            "--plot",
            svg.to_str().unwrap(),
        ],
    );
    assert_eq!(output.status.code(), Some(4), "{}", stderr(&output));
    let mut workbook: Xlsx<_> = open_workbook(&xlsx).unwrap();
    let steps = workbook.worksheet_range("steps").unwrap();
    let header: Vec<String> = steps
        .rows()
        .next()
        .unwrap()
        .iter()
        .map(|cell| cell.to_string())
        .collect();
    assert_eq!(header.join(","), DYNAMICS_HEADER);
    assert_eq!(steps.rows().nth(1).unwrap()[13], Data::Bool(true));
    assert_eq!(steps.rows().next_back().unwrap()[13], Data::Bool(false));
    let summary = workbook.worksheet_range("summary").unwrap();
    let value = |quantity: &str| {
        summary
            .rows()
            .find(|row| row[0] == quantity)
            .unwrap_or_else(|| panic!("no {quantity}"))[1]
            .to_string()
    };
    assert_eq!(value("synchronism"), "LOST");
    assert!(value("synchronism lost at step").parse::<f64>().is_ok());
    assert_eq!(value("synchronism lost beyond"), "2");
    let chart_data = workbook.worksheet_range("chart_data").unwrap();
    let chart_header: Vec<String> = chart_data
        .rows()
        .next()
        .unwrap()
        .iter()
        .map(|cell| cell.to_string())
        .collect();
    assert_eq!(
        chart_header[4..],
        ["rotor_velocity_steps_per_s", "rotor_lag_steps"]
    );
    let archive = std::fs::read(&xlsx).unwrap();
    assert!(String::from_utf8_lossy(&archive).contains("xl/charts/chart3.xml"));
    let svg_text = std::fs::read_to_string(&svg).unwrap();
    assert!(svg_text.contains("rotor lag (steps)"));
    assert!(svg_text.contains("rotor"));
}

/// The compare table as (header, rows).
fn compare(args: &[&str]) -> (Output, String, Vec<csv::StringRecord>) {
    let mut full = vec!["compare"];
    full.extend_from_slice(args);
    let output = run(&full);
    let text = stdout(&output);
    let header = text.lines().next().unwrap_or_default().to_string();
    let rows = records(&text);
    (output, header, rows)
}

#[test]
fn compare_gives_one_line_per_profile_on_the_same_move() {
    let path = motor("type-200.toml");
    let (output, header, rows) = compare(&[
        "--motor",
        path.to_str().unwrap(),
        "--steps",
        "2000",
        "--speed",
        "4000",
        "--accel",
        "20000",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(header, COMPARE_HEADER);
    let names: Vec<&str> = rows.iter().map(|row| &row[0]).collect();
    assert_eq!(names, ["p2", "p2-exact", "austin", "leib", "trapezoid"]);
    // The trapezoid's line is the export's table summed up.
    let trapezoid = &rows[4];
    let table = records(&stdout(&lecture(&path, &[])));
    let total: f64 = table.iter().map(|row| number(row, 6)).sum::<f64>() / 200e6;
    assert!((number(trapezoid, 1) - total).abs() < 1e-6);
    let peak = table
        .iter()
        .map(|row| number(row, 8).abs())
        .fold(0.0, f64::max);
    assert!((number(trapezoid, 2) - peak).abs() < 1e-4);
    let margin = table
        .iter()
        .map(|row| number(row, 10))
        .fold(f64::INFINITY, f64::min);
    assert!((number(trapezoid, 3) - margin).abs() < 1e-4);
    let lag = table
        .iter()
        .map(|row| number(row, 12).abs())
        .fold(0.0, f64::max);
    assert!((number(trapezoid, 4) - lag).abs() < 1e-4);
    assert_eq!(&trapezoid[5], "true");
    for row in &rows {
        assert!(["true", "false"].contains(&&row[5]));
        assert!(number(row, 1) > 0.0);
    }

    // Without --accel the ramps take the S-curve's; the S-curves' lines
    // do not change.
    let (output, _, without) = compare(&[
        "--motor",
        path.to_str().unwrap(),
        "--steps",
        "2000",
        "--speed",
        "4000",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(without[0], rows[0]);
    assert_eq!(without[1], rows[1]);
    assert_ne!(without[4], rows[4]);
}

#[test]
fn compare_fastest_settings_keep_synchronism_when_run_on_the_derated_motor() {
    let directory = tempfile::tempdir().unwrap();
    let path = motor("type-300.toml");
    let (output, header, rows) = compare(&[
        "--motor",
        path.to_str().unwrap(),
        "--steps",
        "400",
        "--speed",
        "4000",
        "--accel",
        "20000",
        "--fastest",
    ]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(
        header,
        format!("{COMPARE_HEADER},fastest_time_s,fastest_speed,fastest_accel")
    );
    // The same motor with every torque divided by its safety factor.
    let motor = Motor::load(&path).unwrap();
    let factor = motor.safety_factor;
    let curve: Vec<String> = motor
        .torque_curve
        .iter()
        .map(|(speed, torque)| format!("[{speed}, {}]", torque / factor))
        .collect();
    let derated = directory.path().join("derated.toml");
    std::fs::write(
        &derated,
        format!(
            "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 3.5e-5\nload_inertia_kgm2 = 6e-5\n\
             load_torque_nm = 0.3\ndamping_nm_s_per_rad = 1e-4\nholding_torque_nm = {}\n\
             torque_curve = [{}]\n",
            motor.holding_torque_nm / factor,
            curve.join(", ")
        ),
    )
    .unwrap();
    for row in &rows {
        let profile = &row[0];
        assert!(!row[6].is_empty(), "{profile}: a setting was found");
        let (time, speed, accel) = (number(row, 6), &row[7], &row[8]);
        assert!(speed.parse::<u32>().is_ok(), "{profile}: whole steps/s");
        let mut args = vec![
            "--profile",
            profile,
            "--steps",
            "400",
            "--speed",
            speed,
            "--motor",
            derated.to_str().unwrap(),
            "--dynamics",
        ];
        if profile.starts_with("p2") {
            assert_eq!(
                accel, "",
                "{profile}: the S-curve has no acceleration setting"
            );
        } else {
            args.extend(["--accel", accel]);
        }
        let output = run(&args);
        assert_ne!(
            output.status.code(),
            Some(4),
            "{profile}: {}",
            stderr(&output)
        );
        let table = records(&stdout(&output));
        let total: f64 = table.iter().map(|row| number(row, 6)).sum::<f64>() / 200e6;
        assert!((total - time).abs() < 1e-6, "{profile}: {total} vs {time}");
    }
}

#[test]
fn compare_refuses_bad_input_with_exit_code_2() {
    let path = motor("type-200.toml");
    let cases: [(&[&str], &str); 4] = [
        (&["--steps", "2000", "--speed", "4000"], "--motor"),
        (
            &[
                "--motor",
                path.to_str().unwrap(),
                "--steps",
                "0",
                "--speed",
                "4000",
            ],
            "must not be 0",
        ),
        (
            &[
                "--motor",
                path.to_str().unwrap(),
                "--steps",
                "2000",
                "--speed",
                "20000",
            ],
            "beyond the torque curve",
        ),
        (
            &[
                "--motor",
                "no-such.toml",
                "--steps",
                "2000",
                "--speed",
                "4000",
            ],
            "motor file",
        ),
    ];
    for (args, reason) in cases {
        let (output, _, _) = compare(args);
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {message}");
        assert!(message.contains(reason), "{message} lacks {reason}");
        assert_eq!(message.lines().count(), 1, "{message}");
        assert!(output.stdout.is_empty());
    }
}
