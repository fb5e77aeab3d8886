//! Inputs that reach the firmware while its axis moves (merges, speed
//! changes, reversals, the stop pin, emergency stops, status reads), at
//! random CTs: the pins still get exactly the core's edges. Status reads
//! and commands come in the middle of slew trains and of steps left for
//! their rising edges, which the firmware hands back to its core first.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use cogstep_firmware::{core_config, Firmware, Hardware, Output, Variant};
use driver::axis::{AxisContract, Direction};
use driver::axis_core::{AxisCore, CoreCommand, Edge};
use proptest::prelude::*;

const CLKFREQ: u32 = 50_000_000;

struct FakeState {
    now: AtomicU64,
    drives: Mutex<Vec<(u64, Output, bool)>>,
}

/// A board whose clock jumps to each wake-up the step interrupt asks for.
#[derive(Clone, Copy)]
struct FakeBoard(&'static FakeState);

impl Hardware for FakeBoard {
    fn now_ticks(&self) -> u64 {
        self.0.now.load(Ordering::SeqCst)
    }
    fn request_step_interrupt(&self) {}
    fn set_pin(&self, _axis: usize, output: Output, level: bool) {
        let now = self.now_ticks();
        self.0.drives.lock().unwrap().push((now, output, level));
    }
}

/// Runs the step interrupt at every wake-up up to `until`, then sets
/// the clock there.
fn run(firmware: &Firmware<FakeBoard>, board: FakeBoard, until: u64) {
    loop {
        match firmware.step_interrupt().0 {
            Some(t) if t <= until => board.0.now.store(t, Ordering::SeqCst),
            _ => break,
        }
    }
    let now = board.0.now.load(Ordering::SeqCst);
    board.0.now.store(until.max(now), Ordering::SeqCst);
}

#[derive(Clone, Copy, Debug)]
enum Input {
    Move { speed: u32, steps: i32 },
    Jog { speed: u32, forward: bool },
    StopPin(bool),
    EmergencyStop,
    Status,
}

fn input() -> impl Strategy<Value = Input> {
    prop_oneof![
        5 => (1_000u32..30_000, -6_000i32..6_000)
            .prop_filter("a move has steps", |(_, steps)| *steps != 0)
            .prop_map(|(speed, steps)| Input::Move { speed, steps }),
        1 => (1_000u32..20_000, any::<bool>()).prop_map(|(speed, forward)| Input::Jog { speed, forward }),
        1 => any::<bool>().prop_map(Input::StopPin),
        1 => Just(Input::EmergencyStop),
        3 => Just(Input::Status),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn inputs_mid_move_keep_the_pins_on_the_cores_edges(
        cc in any::<bool>(),
        p2exact in any::<bool>(),
        inputs in proptest::collection::vec((input(), 0u64..5_000_000), 1..12),
    ) {
        let variant = if cc { Variant::Cc } else { Variant::Sd };
        let mut config = core_config(CLKFREQ, variant);
        if p2exact {
            config.scurve.arithmetic = driver::profile::scurve::Arithmetic::P2Exact;
        }
        let board = FakeBoard(Box::leak(Box::new(FakeState {
            now: AtomicU64::new(0),
            drives: Mutex::new(Vec::new()),
        })));
        let firmware = Firmware::new(board, 1, |_| config).unwrap();
        let axis = &firmware.axes()[0];

        // The core alone, given each input the set-up time after the
        // firmware got it (its core runs that far ahead of the clock).
        let lookahead = u64::from(config.dir_setup_ticks);
        let mut core = AxisCore::new(config, 0);
        core.set_stop_pin(0, true);
        let mut expected: Vec<Edge> = Vec::new();

        let mut at = 0u64;
        for (input, gap) in inputs {
            at += gap;
            run(&firmware, board, at);
            let core_at = at + lookahead;
            core.run_until(core_at, &mut |edge| expected.push(edge));
            let direction = |forward: bool| if forward { Direction::Forward } else { Direction::Reverse };
            match input {
                Input::Move { speed, steps } => {
                    let theirs = core.command(core_at, CoreCommand::Move { speed, steps }).map(|_| ());
                    prop_assert_eq!(axis.move_steps(speed, steps), theirs);
                }
                Input::Jog { speed, forward } => {
                    let command = CoreCommand::Jog { speed, direction: direction(forward) };
                    let theirs = core.command(core_at, command).map(|_| ());
                    prop_assert_eq!(axis.jog(speed, direction(forward)), theirs);
                }
                Input::StopPin(high) => {
                    core.set_stop_pin(core_at, high);
                    axis.set_stop_pin(high).unwrap();
                }
                Input::EmergencyStop => {
                    core.command(core_at, CoreCommand::EmergencyStop).unwrap();
                    axis.emergency_stop().unwrap();
                }
                Input::Status => {
                    let status = axis.status().unwrap();
                    prop_assert_eq!(status.position, core.position());
                    prop_assert_eq!(status.steps_to_go, core.steps_to_go());
                    prop_assert_eq!(status.mode, core.mode());
                    prop_assert_eq!(status.velocity_steps_per_s, core.last_step().velocity);
                }
            }
        }
        core.set_stop_pin(at + lookahead, true);
        axis.set_stop_pin(true).unwrap();
        core.run_until(u64::MAX, &mut |edge| expected.push(edge));
        run(&firmware, board, u64::MAX);
        let status = axis.status().unwrap();
        prop_assert_eq!(status.position, core.position());
        let expected: Vec<(u64, Output, bool)> = expected
            .into_iter()
            .map(|edge| (edge.ct, if edge.pin == 0 { Output::First } else { Output::Second }, edge.level))
            .collect();
        let driven = board.0.drives.lock().unwrap().clone();
        prop_assert_eq!(driven, expected);
    }
}
