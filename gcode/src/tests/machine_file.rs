//! The machine file: the shipped files parse; each bad file is the right
//! typed error, naming its key.

use crate::machine::{HomeEnd, Key, MachineError, MachineSpec};

const XYZ_CNC: &str = include_str!("../../../spreadsheet-export/machines/xyz-cnc.toml");
const PLOTTER: &str = include_str!("../../../spreadsheet-export/machines/plotter.toml");

const GOOD: &str = "\
[axes.x]
steps_per_mm = 80.0
max_speed_mm_s = 200.0
max_accel_mm_s2 = 2000.0
[planner]
junction_deviation_mm = 0.01
arc_tolerance_mm = 0.002
";

fn error(text: &str) -> MachineError {
    MachineSpec::from_toml_str(text).expect_err("a bad machine file")
}

#[test]
fn the_shipped_cnc_parses_in_file_order() {
    let spec = MachineSpec::from_toml_str(XYZ_CNC).unwrap();
    assert_eq!(spec.letters(), ['x', 'y', 'z']);
    assert_eq!(spec.axes()[0].steps_per_mm, 80.0);
    assert_eq!(spec.axes()[2].steps_per_mm, 400.0);
    assert_eq!(spec.axes()[2].home, Some(HomeEnd::Max));
    assert_eq!(spec.axes()[2].home_position_mm(), Some(0.0));
    assert_eq!(spec.homable_axes(), 0b111);
    assert_eq!(spec.planner().queue_len, 32);
    let machine = spec.planner_machine::<3>();
    assert_eq!(machine.max_speed_steps_per_s, [16_000.0, 16_000.0, 8_000.0]);
    assert_eq!(
        machine.max_accel_steps_per_s2,
        [160_000.0, 160_000.0, 200_000.0]
    );
    // δ in steps at the smallest steps/mm: 0.01 mm × 80.
    assert!((machine.junction_deviation_steps - 0.8).abs() < 1e-12);
}

#[test]
fn the_shipped_plotter_parses() {
    let spec = MachineSpec::from_toml_str(PLOTTER).unwrap();
    assert_eq!(spec.letters(), ['x', 'y']);
    assert_eq!(spec.homable_axes(), 0);
    assert_eq!(spec.planner().queue_len, 32, "the default");
    assert!(spec.try_planner_machine::<1>().is_none());
    let padded = spec.planner_machine::<4>();
    assert_eq!(padded.max_speed_steps_per_s[3], 24_000.0);
}

#[test]
fn axes_keep_the_file_order() {
    let text = GOOD.replace("[axes.x]", "[axes.z]\nsteps_per_mm = 400\nmax_speed_mm_s = 10\nmax_accel_mm_s2 = 100\n[axes.a]\nsteps_per_mm = 10\nmax_speed_mm_s = 10\nmax_accel_mm_s2 = 100\n[axes.x]");
    let spec = MachineSpec::from_toml_str(&text).unwrap();
    assert_eq!(spec.letters(), ['z', 'a', 'x']);
    assert_eq!(spec.axis_index('X'), Some(2));
    assert_eq!(spec.axes()[0].steps_per_mm, 400.0, "an integer is a number");
}

#[test]
fn missing_keys_are_named() {
    assert_eq!(
        error(&GOOD.replace("steps_per_mm = 80.0\n", "")),
        MachineError::Missing(Key::Axis('x', "steps_per_mm"))
    );
    assert_eq!(
        error(&GOOD.replace("arc_tolerance_mm = 0.002\n", "")),
        MachineError::Missing(Key::Planner("arc_tolerance_mm"))
    );
    assert_eq!(
        error("[axes.x]\nsteps_per_mm = 1\nmax_speed_mm_s = 1\nmax_accel_mm_s2 = 1\n"),
        MachineError::Missing(Key::Table("planner"))
    );
    assert_eq!(
        error("[planner]\njunction_deviation_mm = 0.01\narc_tolerance_mm = 0.002\n"),
        MachineError::Missing(Key::Table("axes"))
    );
    assert_eq!(
        error(&GOOD.replace("max_accel_mm_s2 = 2000.0\n", "")).to_string(),
        "axes.x.max_accel_mm_s2 is missing"
    );
}

#[test]
fn non_positive_values_are_named() {
    assert_eq!(
        error(&GOOD.replace("max_speed_mm_s = 200.0", "max_speed_mm_s = 0")),
        MachineError::NotPositive {
            key: Key::Axis('x', "max_speed_mm_s"),
            value: 0.0
        }
    );
    assert_eq!(
        error(&GOOD.replace("steps_per_mm = 80.0", "steps_per_mm = -80.0")).to_string(),
        "axes.x.steps_per_mm must be above 0 and finite (it is -80)"
    );
    assert!(matches!(
        error(&GOOD.replace("max_accel_mm_s2 = 2000.0", "max_accel_mm_s2 = inf")),
        MachineError::NotPositive {
            key: Key::Axis('x', "max_accel_mm_s2"),
            ..
        }
    ));
    assert!(matches!(
        error(&GOOD.replace("arc_tolerance_mm = 0.002", "arc_tolerance_mm = 0.0")),
        MachineError::NotPositive {
            key: Key::Planner("arc_tolerance_mm"),
            ..
        }
    ));
    assert!(matches!(
        error(&GOOD.replace(
            "junction_deviation_mm = 0.01",
            "junction_deviation_mm = -0.01"
        )),
        MachineError::Negative {
            key: Key::Planner("junction_deviation_mm"),
            ..
        }
    ));
    // 0 is a valid junction deviation: stop at every corner.
    MachineSpec::from_toml_str(
        &GOOD.replace("junction_deviation_mm = 0.01", "junction_deviation_mm = 0"),
    )
    .unwrap();
}

#[test]
fn unknown_keys_and_axes_are_named() {
    assert_eq!(
        error(&GOOD.replace("max_speed_mm_s", "max_sped_mm_s")),
        MachineError::UnknownKey("axes.x.max_sped_mm_s".into())
    );
    assert_eq!(
        error(&format!("{GOOD}queue_length = 8\n")),
        MachineError::UnknownKey("planner.queue_length".into())
    );
    assert_eq!(
        error(&format!("motor = 1\n{GOOD}")),
        MachineError::UnknownKey("motor".into())
    );
    assert_eq!(
        error(&GOOD.replace("[axes.x]", "[axes.q]")),
        MachineError::UnknownAxis("q".into())
    );
    assert_eq!(
        error(&GOOD.replace("[axes.x]", "[axes.X]")),
        MachineError::UnknownAxis("X".into())
    );
}

#[test]
fn wrong_types_are_named() {
    assert_eq!(
        error(&GOOD.replace("steps_per_mm = 80.0", "steps_per_mm = \"80\"")),
        MachineError::WrongType {
            key: Key::Axis('x', "steps_per_mm"),
            expected: "a number"
        }
    );
    assert_eq!(
        error(&GOOD.replace(
            "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 200.0\nmax_accel_mm_s2 = 2000.0\n",
            "axes = 3\n"
        )),
        MachineError::WrongType {
            key: Key::Table("axes"),
            expected: "a table"
        }
    );
    assert_eq!(
        error(&format!("{GOOD}queue_len = 0\n")),
        MachineError::QueueLen
    );
    assert_eq!(
        error(&format!("{GOOD}queue_len = 2.5\n")),
        MachineError::QueueLen
    );
    assert_eq!(
        MachineSpec::from_toml_str(&format!("{GOOD}queue_len = 8\n"))
            .unwrap()
            .planner()
            .queue_len,
        8
    );
}

#[test]
fn soft_limits_and_homes_are_checked() {
    let with = |extra: &str| {
        GOOD.replace(
            "max_accel_mm_s2 = 2000.0\n",
            &format!("max_accel_mm_s2 = 2000.0\n{extra}\n"),
        )
    };
    assert_eq!(
        error(&with("soft_min_mm = 10\nsoft_max_mm = 10")),
        MachineError::SoftLimits {
            axis: 'x',
            min: 10.0,
            max: 10.0
        }
    );
    assert_eq!(
        error(&with("soft_min_mm = 10\nsoft_max_mm = -5")).to_string(),
        "axes.x.soft_min_mm (10) must be below axes.x.soft_max_mm (-5)"
    );
    assert!(matches!(
        error(&with("soft_max_mm = nan")),
        MachineError::NotFinite {
            key: Key::Axis('x', "soft_max_mm"),
            ..
        }
    ));
    assert_eq!(error(&with("home = \"left\"")), MachineError::Home('x'));
    assert_eq!(error(&with("home = 1")), MachineError::Home('x'));
    assert_eq!(
        error(&with("home_speed_mm_s = 5")),
        MachineError::HomeSpeedWithoutHome('x')
    );
    assert!(matches!(
        error(&with("home = \"min\"\nhome_speed_mm_s = -5")),
        MachineError::NotPositive {
            key: Key::Axis('x', "home_speed_mm_s"),
            ..
        }
    ));
    let spec =
        MachineSpec::from_toml_str(&with("soft_min_mm = -5\nsoft_max_mm = 100\nhome = \"max\""))
            .unwrap();
    assert_eq!(spec.axes()[0].home_position_mm(), Some(100.0));
}

#[test]
fn axis_counts_are_checked() {
    let axis = |letter: char| {
        format!("[axes.{letter}]\nsteps_per_mm = 10\nmax_speed_mm_s = 10\nmax_accel_mm_s2 = 10\n")
    };
    let planner = "[planner]\njunction_deviation_mm = 0.01\narc_tolerance_mm = 0.002\n";
    let nine: String = crate::AXIS_LETTERS
        .iter()
        .map(|&letter| axis(letter))
        .collect();
    assert_eq!(
        error(&format!("{nine}{planner}")),
        MachineError::AxisCount(9)
    );
    let eight: String = crate::AXIS_LETTERS[..8]
        .iter()
        .map(|&letter| axis(letter))
        .collect();
    let spec = MachineSpec::from_toml_str(&format!("{eight}{planner}")).unwrap();
    assert_eq!(spec.letters().len(), 8);
    assert_eq!(
        error(&format!("[axes]\n{planner}")),
        MachineError::AxisCount(0)
    );
}

#[test]
fn toml_syntax_errors_name_the_line() {
    let MachineError::Toml { line, .. } =
        error(&GOOD.replace("max_speed_mm_s = 200.0", "max_speed_mm_s = = 200.0"))
    else {
        panic!("a TOML error");
    };
    assert_eq!(line, 3);
}
