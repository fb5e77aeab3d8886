//! Inputs that reach the firmware while its axis moves (merges, speed
//! changes, reversals, the stop pin, emergency stops, status reads), at
//! random CTs: the pins still get exactly the core's edges. Status reads
//! and commands come in the middle of slew trains and of steps left for
//! their rising edges, which the firmware hands back to its core first.
//! The board runs either the general step interrupt alone or, as the
//! LM3S6965 board does, the fast path first ([`FastTrain`]), which takes
//! the train of an axis alone at speed.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use cogstep_firmware::{core_config, FastEvent, FastTrain, Firmware, Hardware, Output, Variant};
use critical_section::CriticalSection;
use driver::axis::{AxisContract, Direction};
use driver::axis_core::{AxisCore, CoreCommand, Edge};
use proptest::prelude::*;

const CLKFREQ: u32 = 50_000_000;

struct FakeState {
    now: AtomicU64,
    drives: Mutex<Vec<(u64, Output, bool)>>,
    /// The board's fast path, when it has one.
    fast: Option<Mutex<FastTrain>>,
    /// Steps the fast path made.
    fast_steps: AtomicU64,
}

fn board(fast: bool) -> FakeBoard {
    FakeBoard(Box::leak(Box::new(FakeState {
        now: AtomicU64::new(0),
        drives: Mutex::new(Vec::new()),
        fast: fast.then(|| Mutex::new(FastTrain::new())),
        fast_steps: AtomicU64::new(0),
    })))
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
    /// Every edge the runner drives names its own CT: here, where the clock
    /// jumps to each wake-up, the CT it is driven at (a board that encodes
    /// edges with their CTs, the Pico's PIO build, relies on it).
    fn drive_pin(&self, axis: usize, output: Output, level: bool, ct: u64) {
        assert_eq!(
            ct,
            self.now_ticks(),
            "an edge driven with another CT than its own"
        );
        self.set_pin(axis, output, level);
    }
    fn with_fast_train<R>(
        &self,
        _cs: CriticalSection<'_>,
        use_it: impl FnOnce(&mut FastTrain) -> R,
    ) -> R {
        match &self.0.fast {
            Some(fast) => use_it(&mut fast.lock().unwrap()),
            None => use_it(&mut FastTrain::new()),
        }
    }
}

/// The board's step interrupt at CT now (a wake-up it asked for): the
/// fast path first, as the LM3S6965 board runs it, when it has one.
fn step_interrupt(firmware: &Firmware<FakeBoard>, board: FakeBoard) -> Option<u64> {
    let Some(fast) = &board.0.fast else {
        return firmware.step_interrupt().0;
    };
    let mut fast = fast.lock().unwrap();
    // A lent train's timer fires at its edge (the CT whose low 32 bits
    // the train keeps), and nothing else runs the interrupt meanwhile (a
    // command takes the train back first).
    let now = board.now_ticks();
    if fast.is_lent() && now as u32 != fast.armed_ct() {
        return Some(now + u64::from(fast.armed_ct().wrapping_sub(now as u32)));
    }
    let served = now;
    let event = fast.on_timer(|pin, level| {
        let output = if pin % 2 == 0 {
            Output::First
        } else {
            Output::Second
        };
        board.set_pin(pin as usize / 2, output, level)
    });
    match event {
        FastEvent::Rise { interval } | FastEvent::Fall { interval } => {
            if matches!(event, FastEvent::Rise { .. }) {
                board.0.fast_steps.fetch_add(1, Ordering::SeqCst);
            }
            Some(served + u64::from(interval))
        }
        FastEvent::Slow => {
            firmware
                .step_interrupt_lending(board.now_ticks(), &mut fast)
                .0
        }
    }
}

/// Runs the step interrupt at every wake-up up to `until`, then sets
/// the clock there.
fn run(firmware: &Firmware<FakeBoard>, board: FakeBoard, until: u64) {
    let mut guard = 0u64;
    loop {
        guard += 1;
        assert!(
            guard < 2_000_000,
            "hung at {}",
            board.0.now.load(Ordering::SeqCst)
        );
        match step_interrupt(firmware, board) {
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
        fast in any::<bool>(),
        cc in any::<bool>(),
        p2exact in any::<bool>(),
        inputs in proptest::collection::vec((input(), 0u64..5_000_000), 1..12),
    ) {
        let variant = if cc { Variant::Cc } else { Variant::Sd };
        let mut config = core_config(CLKFREQ, variant);
        if p2exact {
            config.scurve.arithmetic = driver::profile::scurve::Arithmetic::P2Exact;
        }
        let board = board(fast);
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

/// A long move alone at speed: the fast path makes its slew steps, the
/// pins get the core's edges, and the edge counts read while the train is
/// lent (without taking it back) and at the end are the pins' own.
#[test]
fn the_fast_path_makes_the_slew_steps() {
    for p2exact in [false, true] {
        let mut config = core_config(CLKFREQ, Variant::Sd);
        if p2exact {
            config.scurve.arithmetic = driver::profile::scurve::Arithmetic::P2Exact;
        }
        let board = board(true);
        let firmware = Firmware::new(board, 1, |_| config).unwrap();
        let axis = &firmware.axes()[0];
        axis.move_steps(20_000, 20_000).unwrap();
        let mut core = AxisCore::new(config, 0);
        core.set_stop_pin(0, true);
        core.command(
            u64::from(config.dir_setup_ticks),
            CoreCommand::Move {
                speed: 20_000,
                steps: 20_000,
            },
        )
        .unwrap();
        let mut expected = Vec::new();
        core.run_until(u64::MAX, &mut |edge| {
            expected.push((edge.ct, edge.pin, edge.level))
        });

        // Half way, the counts read while the train is out are the pins'.
        run(&firmware, board, 25_000_000);
        assert!(board.0.fast.as_ref().unwrap().lock().unwrap().is_lent());
        let counts = axis.edge_counts();
        let driven = board.0.drives.lock().unwrap().clone();
        let rising = driven
            .iter()
            .filter(|d| d.1 == Output::First && d.2)
            .count() as u64;
        let falling = driven
            .iter()
            .filter(|d| d.1 == Output::First && !d.2)
            .count() as u64;
        assert_eq!((counts.rising[0], counts.falling[0]), (rising, falling));
        assert!(board.0.fast.as_ref().unwrap().lock().unwrap().is_lent());

        run(&firmware, board, u64::MAX);
        let status = axis.status().unwrap();
        assert_eq!(status.position, 20_000);
        let driven: Vec<(u64, u8, bool)> = board
            .0
            .drives
            .lock()
            .unwrap()
            .iter()
            .map(|&(ct, output, level)| (ct, output.index() as u8, level))
            .collect();
        let first_difference = driven.iter().zip(&expected).position(|(a, b)| a != b);
        assert_eq!(
            first_difference,
            None,
            "{:?}",
            first_difference.map(|i| (driven[i], expected[i]))
        );
        assert_eq!(driven.len(), expected.len());
        assert_eq!(axis.edge_counts().rising[0], 20_000);
        let fast_steps = board.0.fast_steps.load(Ordering::SeqCst);
        assert!(fast_steps > 13_000, "{fast_steps} steps on the fast path");
    }
}

/// A P2Exact jog re-jogged at another speed: the slew train the core
/// offers near the jog's deadline has no step before its give-back; the
/// step interrupt once took it out and gave it back for ever at one CT
/// (found by the property test above). Now the core makes that step and
/// the axis runs on.
#[test]
fn a_train_with_no_step_before_its_give_back_does_not_stall_the_interrupt() {
    for fast in [false, true] {
        let mut config = core_config(CLKFREQ, Variant::Sd);
        config.scurve.arithmetic = driver::profile::scurve::Arithmetic::P2Exact;
        let board = board(fast);
        let firmware = Firmware::new(board, 1, |_| config).unwrap();
        let axis = &firmware.axes()[0];
        axis.jog(15_854, Direction::Forward).unwrap();
        let mut at = 4_160_638;
        run(&firmware, board, at);
        axis.status().unwrap();
        at += 2_832_285;
        run(&firmware, board, at);
        assert!(axis.move_steps(1_000, -1).is_err());
        at += 812_397;
        run(&firmware, board, at);
        axis.jog(4_200, Direction::Forward).unwrap();
        run(&firmware, board, u64::MAX);
        let status = axis.status().unwrap();
        assert_eq!(status.steps_to_go, 0);
        assert_eq!(axis.edge_counts().rising[0], status.position as u64);
    }
}
