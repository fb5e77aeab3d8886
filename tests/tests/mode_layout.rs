//! The mode long's layout, every flag (motion's own layout test stops at
//! JOG: LIMIT and HOMING are checked here), and the hub setting LIMIT and
//! HOMING in their bits when a limit trips and while an axis homes.

use cogstep_test_support::hub::{start_axis, Wiring};
use driver::{AxisState, ClockMode, Direction, HomeConfig, Hub, HubConfig, Mode};

/// Every named flag and its bit: the reference's six (bits 0–5), then
/// cogstep's own, above bit 7.
const LAYOUT: [(Mode, u32); 11] = [
    (Mode::MOVING, 0),
    (Mode::ACCEL, 1),
    (Mode::DECEL, 2),
    (Mode::SLEW, 3),
    (Mode::REVERSE, 4),
    (Mode::STOP_LATCHED, 5),
    (Mode::ESTOP, 8),
    (Mode::HOLD, 9),
    (Mode::JOG, 10),
    (Mode::LIMIT, 11),
    (Mode::HOMING, 12),
];

#[test]
fn every_mode_flag_sits_on_its_bit() {
    for (flag, bit) in LAYOUT {
        assert_eq!(flag.bits(), 1 << bit, "{flag:?}");
    }
    // The list is every flag there is: no flag unnamed, none twice.
    let all = LAYOUT
        .iter()
        .fold(0u32, |bits, (flag, _)| bits | flag.bits());
    assert_eq!(Mode::all().bits(), all);
    assert_eq!(all.count_ones() as usize, LAYOUT.len());
    // cogstep's flags stay out of the reference's six.
    let ours = Mode::LIMIT | Mode::HOMING | Mode::ESTOP | Mode::HOLD | Mode::JOG;
    assert_eq!(ours.reference_bits(), 0);
    assert_eq!(
        &(Mode::LIMIT | Mode::HOMING | Mode::MOVING).binary(),
        b"000001"
    );
    assert_eq!((Mode::LIMIT | Mode::HOMING).bits(), 0b1_1000_0000_0000);
}

#[test]
fn limit_and_homing_read_as_their_states() {
    assert_eq!(Mode::LIMIT.describe(), "stopped by a hard limit");
    assert_eq!(Mode::HOMING.describe(), "homing");
    assert_eq!((Mode::HOMING | Mode::MOVING).describe(), "homing");
    assert_eq!(
        AxisState::from_mode(Mode::HOMING | Mode::MOVING, true),
        AxisState::Run
    );
}

fn hub() -> Hub {
    Hub::new(HubConfig {
        clock: ClockMode::Virtual,
        ..HubConfig::default()
    })
    .expect("hub")
}

#[test]
fn a_tripped_limit_sets_bit_11_until_cleared() {
    let hub = hub();
    let x = start_axis(&hub, 0, Wiring::Sd);
    hub.attach_switch(10, &x, 2_000..=i64::MAX, true).unwrap();
    x.set_limit_pins(None, Some((10, true))).unwrap();
    assert_eq!(x.mode().bits() & (1 << 11), 0);
    x.move_steps(20_000, 5_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.limit_fault(), Some(Direction::Forward));
    assert_ne!(x.mode().bits() & (1 << 11), 0, "{:?}", x.mode());
    assert!(x.status().mode.has(Mode::LIMIT));
    // Back off the switch, then clear: the bit goes.
    x.move_steps(20_000, -1_000).unwrap();
    hub.run_until_idle();
    x.clear_limit_fault().unwrap();
    assert_eq!(x.mode().bits() & (1 << 11), 0, "{:?}", x.mode());
}

#[test]
fn homing_sets_bit_12_while_it_runs() {
    let hub = hub();
    let x = start_axis(&hub, 0, Wiring::Sd);
    hub.attach_switch(10, &x, i64::MIN..=-3_217, true).unwrap();
    x.home(HomeConfig {
        switch_pin: 10,
        ..HomeConfig::default()
    })
    .unwrap();
    hub.advance(2_000_000);
    assert!(x.is_homing());
    assert_ne!(x.mode().bits() & (1 << 12), 0, "{:?}", x.mode());
    hub.run_until_idle();
    assert!(x.home_outcome().expect("homed").is_ok());
    assert_eq!(x.mode().bits() & (1 << 12), 0, "{:?}", x.mode());
}
