//! G28 on a hub: each axis with a home switch in the machine file homes
//! onto a simulated switch with [`driver::gcode::home_config`], takes its
//! home position, and the program goes on from there.
#![cfg(feature = "std")]

use cogstep_test_support::hub::{start_axis, Wiring};
use cogstep_test_support::ledger::assert_accounted;
use driver::gcode::{home_config, GcodePath, GcodePathError, LineOutcome, MachineSpec};
use driver::{Axis, Hub, HubConfig};

/// x homes at its low end (0 mm), y at its high end (0 mm, it works
/// below), z has no switch.
const MACHINE: &str =
    "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 150.0\nmax_accel_mm_s2 = 3000.0\n\
soft_min_mm = 0.0\nsoft_max_mm = 100.0\nhome = \"min\"\nhome_speed_mm_s = 20.0\n\
[axes.y]\nsteps_per_mm = 50.0\nmax_speed_mm_s = 150.0\nmax_accel_mm_s2 = 2000.0\n\
soft_min_mm = -60.0\nsoft_max_mm = 0.0\nhome = \"max\"\n\
[axes.z]\nsteps_per_mm = 400.0\nmax_speed_mm_s = 20.0\nmax_accel_mm_s2 = 500.0\n\
[planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n";

/// Three axes, stop pins high; x's switch pressed 7 mm below where it
/// starts, y's 3 mm above (the machine starts somewhere in its range).
fn machine() -> (Hub, Vec<Axis>, GcodePath) {
    let spec = MachineSpec::from_toml_str(MACHINE).unwrap();
    let hub = Hub::new(HubConfig::default()).unwrap();
    let axes: Vec<Axis> = (0..3).map(|i| start_axis(&hub, i, Wiring::Sd)).collect();
    hub.attach_switch(40, &axes[0], i64::MIN..=-560, true)
        .unwrap();
    hub.attach_switch(41, &axes[1], 150..=i64::MAX, true)
        .unwrap();
    let homing = spec
        .axes()
        .iter()
        .zip(40u8..)
        .map(|(axis, pin)| home_config(axis, pin))
        .collect();
    let refs: Vec<&Axis> = axes.iter().collect();
    let path = GcodePath::new(&hub, &refs, &spec)
        .unwrap()
        .with_homing(homing);
    (hub, axes, path)
}

#[test]
fn g28_homes_each_axis_with_a_switch_and_the_program_goes_on_from_home() {
    let (_hub, axes, mut path) = machine();
    let program = "G21 G90\nG1 X2 F600\nG28\nG1 X10 Y-10 F3000\nM2\n";
    path.run_program(program).unwrap();
    path.finish().unwrap();
    // After G28 x is at 0 mm and y at 0 mm, wherever they were: the
    // line to (10, −10) ends at 800 and −500 steps.
    assert_eq!(axes[0].position(), 800);
    assert_eq!(axes[1].position(), -500);
    assert_eq!(axes[2].position(), 0);
    for axis in &axes {
        assert_accounted(axis);
    }
}

#[test]
fn the_home_position_is_the_switch_point_in_machine_steps() {
    let spec = MachineSpec::from_toml_str(MACHINE).unwrap();
    let x = home_config(&spec.axes()[0], 40).unwrap();
    assert_eq!(x.direction, driver::Direction::Reverse);
    assert_eq!((x.seek_speed, x.latch_speed), (1_600, 160));
    assert_eq!(x.backoff_steps, 80);
    assert_eq!(x.max_travel, 110 * 80);
    assert_eq!(x.set_position, 0);
    let y = home_config(&spec.axes()[1], 41).unwrap();
    assert_eq!(y.direction, driver::Direction::Forward);
    // No home speed given: a tenth of the top speed.
    assert_eq!(y.seek_speed, 15 * 50);
    assert_eq!(home_config(&spec.axes()[2], 42), None);
}

#[test]
fn g28_of_an_axis_without_a_switch_is_refused_and_moves_nothing() {
    let (_hub, axes, mut path) = machine();
    let error = path.run_line(1, "G28 Z0").unwrap_err();
    assert!(
        matches!(error, GcodePathError::Gcode(ref e) if e.kind == driver::gcode::GcodeErrorKind::NoHomeSwitch('z') && e.column == 5),
        "{error:?}"
    );
    assert_eq!(path.run_line(2, "G1 X1 F600"), Ok(LineOutcome::Queued));
    path.finish().unwrap();
    assert_eq!(axes[0].position(), 80);
    assert_eq!(axes[2].position(), 0);
}
