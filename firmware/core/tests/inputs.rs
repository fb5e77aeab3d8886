//! Switch inputs on a board whose cores run ahead of its pins, on the
//! host: a fake board runs the firmware's axes a lead ahead of its pins
//! (as the Pico does), records each axis's steps in a `StepHistory` as it
//! drives them, and tells the axes of a switch change when the pins reach
//! it. Homing and a limit trip then latch what an axis core told on time
//! latches.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use cogstep_firmware::{core_config, Firmware, Hardware, Output, StepHistory, Variant};
use driver::axis::{AxisContract, AxisError, Direction, HomeConfig, HomeReport, LimitTrip};
use driver::axis_core::{AxisCore, AxisCoreConfig, CoreCommand};
use driver::refusal::bad_setting;
use proptest::prelude::*;

/// The CT: a microsecond timer, as on the Pico.
const CLKFREQ: u32 = 1_000_000;
/// How far the cores run ahead of the pins, ticks.
const LEAD: u64 = 4_000;
/// How often the fake board looks at its switches, ticks.
const SAMPLE: u64 = 10;
const HOME_PIN: u8 = 14;
const LIMIT_PIN: u8 = 22;

struct FakeState {
    now: AtomicU64,
    history: Mutex<StepHistory<1024>>,
}

#[derive(Clone, Copy)]
struct FakeBoard(&'static FakeState);

impl Hardware for FakeBoard {
    fn now_ticks(&self) -> u64 {
        self.0.now.load(Ordering::SeqCst)
    }
    fn request_step_interrupt(&self) {}
    fn set_pin(&self, _axis: usize, output: Output, level: bool) {
        let now = self.now_ticks();
        self.0.history.lock().unwrap().record(now, output, level);
    }
    fn switch_pins(&self) -> u64 {
        (1 << HOME_PIN) | (1 << LIMIT_PIN)
    }
}

struct Rig {
    board: FakeBoard,
    firmware: Firmware<FakeBoard>,
    /// The pins' time.
    pins_ct: u64,
}

impl Rig {
    fn new() -> Rig {
        let board = FakeBoard(Box::leak(Box::new(FakeState {
            now: AtomicU64::new(LEAD),
            history: Mutex::new(StepHistory::new(Variant::Sd)),
        })));
        let firmware = Firmware::new(board, 1, |_| AxisCoreConfig {
            // As the Pico's: twice the lead.
            input_latency_ticks: 2 * LEAD,
            ..core_config(CLKFREQ, Variant::Sd)
        })
        .unwrap();
        Rig {
            board,
            firmware,
            pins_ct: 0,
        }
    }

    fn axis(&self) -> &dyn AxisContract {
        &self.firmware.axes()[0]
    }

    /// Runs every wake-up up to the pins' time plus the lead (the cores'
    /// frontier), as the Pico's main loop does.
    fn produce(&self) {
        let frontier = self.pins_ct + LEAD;
        // Anything may have changed: re-plan from the frontier.
        self.board.0.now.store(frontier, Ordering::SeqCst);
        let mut next = self.firmware.step_interrupt().0;
        while let Some(t) = next.filter(|&t| t <= frontier) {
            self.board.0.now.store(t, Ordering::SeqCst);
            next = self.firmware.step_interrupt().0;
        }
        self.board.0.now.store(frontier, Ordering::SeqCst);
    }

    /// Runs until the axis is idle and `done`, the switch on `pin`
    /// reading `pressed(physical)` as the pins' steps place the axis.
    fn run(&mut self, pin: u8, pressed: impl Fn(i64) -> bool, done: impl Fn(&Rig) -> bool) {
        let levels = |physical| u64::from(pressed(physical)) << pin;
        let mut told = levels(0);
        self.firmware.axes()[0].set_inputs(told, None);
        for _ in 0..1_000_000 {
            self.pins_ct += SAMPLE;
            self.produce();
            let then = self
                .board
                .0
                .history
                .lock()
                .unwrap()
                .physical_at(self.pins_ct);
            if levels(then) != told {
                told = levels(then);
                self.firmware.axes()[0].set_inputs(told, Some(then));
                self.produce();
            }
            let idle = self.axis().status().unwrap().steps_to_go == 0;
            let pins_done = self
                .board
                .0
                .history
                .lock()
                .unwrap()
                .physical_at(self.pins_ct)
                == self.firmware.axes()[0].physical_position();
            if idle && pins_done && done(self) {
                return;
            }
        }
        panic!("the axis never came to rest");
    }
}

fn home_config() -> HomeConfig {
    HomeConfig {
        switch_pin: HOME_PIN,
        active_level: false,
        direction: Direction::Reverse,
        seek_speed: 4_000,
        latch_speed: 400,
        backoff_steps: 100,
        max_travel: 10_000,
        set_position: 0,
    }
}

/// The same homing on an axis core told after every event (the hub's cog).
fn home_on_time(config: HomeConfig, pressed: impl Fn(i64) -> bool) -> (HomeReport, i64) {
    let mut core = AxisCore::new(core_config(CLKFREQ, Variant::Sd), 0);
    core.set_stop_pin(0, true);
    let levels = |physical| u64::from(!pressed(physical)) << config.switch_pin;
    core.set_inputs(0, levels(0));
    core.command(0, CoreCommand::Home(config)).unwrap();
    while let Some(t) = core.next_event() {
        core.run_event(t, &mut |_| {});
        core.set_inputs(t, levels(core.physical_position()));
    }
    let Some(Ok(report)) = core.home_outcome() else {
        panic!("homing on time ended with {:?}", core.home_outcome());
    };
    (report, core.position() - core.physical_position())
}

#[test]
fn homing_a_lead_ahead_latches_the_step_the_pins_reached_the_switch_on() {
    check_homing(home_config(), -1_234);
}

/// A backoff of one step ends before the pins have left the switch (its
/// release comes the lead later): the approach waits for it instead of
/// calling the switch stuck (proptest found this case).
#[test]
fn a_backoff_shorter_than_the_lead_waits_for_the_release() {
    let config = HomeConfig {
        seek_speed: 5_054,
        latch_speed: 300,
        backoff_steps: 1,
        ..home_config()
    };
    check_homing(config, -394);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// Any switch point and speeds: the same steps as an axis core told
    /// on time, and the same origin.
    #[test]
    fn homing_a_lead_ahead_agrees_with_homing_on_time(
        switch_at in 150i64..1_500,
        seek_speed in 2_000u32..10_000,
        latch_speed in 300u32..1_500,
        backoff_steps in 1u32..200,
    ) {
        let config = HomeConfig {
            seek_speed,
            latch_speed,
            backoff_steps,
            ..home_config()
        };
        check_homing(config, -switch_at);
    }
}

/// Homes the rig's axis (a lead ahead of its pins) onto an active-low
/// switch pressed at and below `switch_at`, and checks it against an
/// axis core told on time.
fn check_homing(config: HomeConfig, switch_at: i64) {
    let pressed = move |physical: i64| physical <= switch_at;
    let (expected, expected_origin) = home_on_time(config, pressed);
    let mut rig = Rig::new();
    // Open (high) before homing starts.
    rig.firmware.axes()[0].set_inputs(1 << HOME_PIN, None);
    rig.axis().home(config).unwrap();
    // Active low: the switch pulls its pin low when pressed.
    rig.run(
        HOME_PIN,
        |physical| !pressed(physical),
        |rig| !rig.axis().limit_status().unwrap().homing,
    );
    let status = rig.axis().limit_status().unwrap();
    let Some(Ok(report)) = status.home_outcome else {
        panic!("homing ended with {:?}", status.home_outcome);
    };
    assert_eq!(
        (report.seek_physical, report.latch_physical),
        (switch_at, switch_at)
    );
    assert_eq!(
        (report.seek_position, report.latch_position),
        (expected.seek_position, expected.latch_position)
    );
    let physical = rig.firmware.axes()[0].physical_position();
    let position = rig.axis().status().unwrap().position;
    assert_eq!(
        position - physical,
        expected_origin,
        "{report:?} vs {expected:?}"
    );
}

#[test]
fn a_limit_a_lead_ahead_trips_on_its_step() {
    let mut rig = Rig::new();
    rig.axis()
        .set_limit_pins(None, Some((LIMIT_PIN, true)))
        .unwrap();
    rig.axis().move_steps(8_000, 6_000).unwrap();
    rig.run(LIMIT_PIN, |physical| physical >= 2_500, |_| true);
    let trip = rig.axis().limit_status().unwrap().trip;
    let physical = rig.firmware.axes()[0].physical_position();
    let Some(LimitTrip {
        side,
        position,
        physical: at,
        stopping_steps,
    }) = trip
    else {
        panic!("no trip");
    };
    assert_eq!((side, position, at), (Direction::Forward, 2_500, 2_500));
    assert_eq!(at + stopping_steps as i64, physical);
    // A move further is refused until the fault is cleared.
    assert_eq!(
        rig.axis().move_steps(1_000, 10),
        Err(AxisError::IntoLimit(Direction::Forward))
    );
    rig.axis().clear_limit_fault().unwrap();
    assert_eq!(rig.axis().limit_status().unwrap().trip, None);
}

#[test]
fn switch_pins_the_board_does_not_read_are_refused_and_change_nothing() {
    let rig = Rig::new();
    let refused = Err(AxisError::BadSetting(bad_setting::PIN_NOT_A_SWITCH_INPUT));
    assert_eq!(rig.axis().set_limit_pins(Some((3, true)), None), refused);
    assert_eq!(
        rig.axis().home(HomeConfig {
            switch_pin: 13,
            ..home_config()
        }),
        refused
    );
    let status = rig.axis().limit_status().unwrap();
    assert_eq!((status.limit_pins, status.homing), ([None, None], false));
    // Past 63: the core's own refusal.
    assert_eq!(
        rig.axis().set_limit_pins(Some((64, true)), None),
        Err(AxisError::BadSetting(bad_setting::LIMIT_PIN_OUT_OF_RANGE))
    );
}

#[test]
fn the_stop_input_and_the_protocol_level_both_hold_the_axis() {
    let rig = Rig::new();
    let axis = &rig.firmware.axes()[0];
    axis.set_stop_input(false);
    assert!(!rig.axis().status().unwrap().stop_pin_high);
    // `R` alone does not release an axis whose stop input is low.
    rig.axis().set_stop_pin(true).unwrap();
    assert!(!rig.axis().status().unwrap().stop_pin_high);
    axis.set_stop_input(true);
    assert!(rig.axis().status().unwrap().stop_pin_high);
    rig.axis().set_stop_pin(false).unwrap();
    assert!(!rig.axis().status().unwrap().stop_pin_high);
}
