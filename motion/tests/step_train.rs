//! `AxisCore::step_train` (slew steps, and the ramp steps the profile
//! computed ahead), `slew_train` and `commit_train` against the core
//! itself: a train's steps are the core's own, edge for edge, and handing a
//! train back leaves the core exactly where running its events one by one
//! does.

use cogstep_motion::axis::Direction;
use cogstep_motion::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs, StepTrain};
use cogstep_motion::profile::scurve::{Arithmetic, ScurveConfig};
use proptest::prelude::*;

const CLKFREQ: u32 = 50_000_000;

fn config(p2exact: bool, sd: bool) -> AxisCoreConfig {
    config_with_math(p2exact, sd, 0)
}

/// [`config`] with a math time: ramp steps shorter than it are counted.
fn config_with_math(p2exact: bool, sd: bool, math_ticks: u64) -> AxisCoreConfig {
    let outputs = if sd {
        Outputs::StepDir { step: 0, dir: 1 }
    } else {
        Outputs::CwCcw { cw: 0, ccw: 1 }
    };
    AxisCoreConfig {
        scurve: ScurveConfig {
            clkfreq: CLKFREQ,
            arithmetic: if p2exact {
                Arithmetic::P2Exact
            } else {
                Arithmetic::Smooth
            },
            ..ScurveConfig::default()
        },
        outputs,
        pulse_ticks: 250,
        dir_setup_ticks: 250,
        jog_timeout_ticks: 7_500_000,
        math_ticks,
        limit_estop: false,
        input_latency_ticks: 0,
    }
}

/// Everything a caller can see of a core.
fn observe(core: &AxisCore) -> String {
    format!(
        "pos {} togo {} mode {:?} last {:?} next {:?} plain {:?} ledger {:?} info {:?} dropped {} overruns {}",
        core.position(),
        core.steps_to_go(),
        core.mode(),
        core.last_step(),
        core.next_event(),
        core.next_plain_step(),
        core.ledger(),
        core.move_info(),
        core.dropped_steps(),
        core.math_overruns()
    )
}

#[derive(Clone, Debug)]
enum Input {
    Move { speed: u32, steps: i32 },
    Jog { speed: u32, forward: bool },
    StopPin(bool),
}

fn input() -> impl Strategy<Value = Input> {
    prop_oneof![
        4 => (500u32..40_000, -20_000i32..20_000)
            .prop_filter("a move has steps", |(_, steps)| *steps != 0)
            .prop_map(|(speed, steps)| Input::Move { speed, steps }),
        1 => (500u32..20_000, any::<bool>()).prop_map(|(speed, forward)| Input::Jog { speed, forward }),
        1 => any::<bool>().prop_map(Input::StopPin),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Inputs at random CTs; between them, wherever the core offers a
    /// train (slew or ramp steps), a random number of its steps is made
    /// through it on one copy of the core and through `run_event` on
    /// another. The edges agree, the copies look the same after the
    /// hand-back (math overruns, the deceleration's max velocity and the
    /// last step's velocity included), and they run on to the same edges
    /// and the same end.
    #[test]
    fn a_train_is_the_cores_own_steps(
        p2exact in any::<bool>(),
        sd in any::<bool>(),
        math_ticks in prop_oneof![Just(0u64), 500u64..5_000],
        inputs in proptest::collection::vec((input(), 0u64..20_000_000, 0u32..3_000), 1..6),
    ) {
        let mut by_train = AxisCore::new(config_with_math(p2exact, sd, math_ticks), 0);
        by_train.set_stop_pin(0, true);
        let mut by_events = by_train.clone();
        let (mut train_edges, mut event_edges) = (Vec::<Edge>::new(), Vec::<Edge>::new());
        let mut now = 0u64;

        for (input, gap, take) in inputs {
            let until = now + gap;
            // Run both up to `until`, through trains where offered.
            loop {
                let next = by_events.next_event().filter(|&t| t <= until);
                prop_assert_eq!(by_train.next_event().filter(|&t| t <= until), next);
                let Some(t) = next else { break };
                if let Some(mut train) = by_train.step_train().filter(|_| take > 0) {

                    while train.has_step() && train.made() < take && train.rise_ct <= until {
                        train_edges.push(Edge { ct: train.rise_ct, pin: train.pin, level: true });
                        train_edges.push(Edge {
                            ct: train.rise_ct + u64::from(train.pulse_ticks),
                            pin: train.pin,
                            level: false,
                        });
                        let rise = train.rise_ct;
                        train.make_step();
                        by_events.run_event(rise, &mut |edge| event_edges.push(edge));
                    }
                    by_train.commit_train(&train);
                    prop_assert_eq!(observe(&by_train), observe(&by_events));
                    if train.made() > 0 {
                        continue;
                    }
                }
                by_train.run_event(t, &mut |edge| train_edges.push(edge));
                by_events.run_event(t, &mut |edge| event_edges.push(edge));
            }
            now = until;
            match input {
                Input::Move { speed, steps } => {
                    let command = CoreCommand::Move { speed, steps };
                    prop_assert_eq!(by_train.command(now, command), by_events.command(now, command));
                }
                Input::Jog { speed, forward } => {
                    let direction = if forward { Direction::Forward } else { Direction::Reverse };
                    let command = CoreCommand::Jog { speed, direction };
                    prop_assert_eq!(by_train.command(now, command), by_events.command(now, command));
                }
                Input::StopPin(high) => {
                    by_train.set_stop_pin(now, high);
                    by_events.set_stop_pin(now, high);
                }
            }
            prop_assert_eq!(observe(&by_train), observe(&by_events));
        }
        by_train.set_stop_pin(now, true);
        by_events.set_stop_pin(now, true);
        by_train.run_until(u64::MAX, &mut |edge| train_edges.push(edge));
        by_events.run_until(u64::MAX, &mut |edge| event_edges.push(edge));
        prop_assert_eq!(&train_edges, &event_edges);
        prop_assert_eq!(observe(&by_train), observe(&by_events));

    }
}

/// A core with its stop pin high that has just taken a move.
fn moving(p2exact: bool, speed: u32, steps: i32) -> AxisCore {
    let mut core = AxisCore::new(config(p2exact, true), 0);
    core.set_stop_pin(0, true);
    core.command(0, CoreCommand::Move { speed, steps }).unwrap();
    core
}

/// What a copy of `core` looks like once it takes `train` back.
fn committed(core: &AxisCore, train: &StepTrain) -> String {
    let mut core = core.clone();
    core.commit_train(train);
    observe(&core)
}

/// Runs the core's events one by one until `done` says so.
fn run_until_offered(core: &mut AxisCore, done: impl Fn(&AxisCore) -> bool) {
    while !done(core) {
        let t = core.next_event().expect("the move goes on");
        core.run_event(t, &mut |_| {});
    }
}

/// A long move at speed spends nearly all its steps in one train.
#[test]
fn a_long_move_slews_in_a_train() {
    let mut core = moving(false, 20_000, 20_000);
    run_until_offered(&mut core, |core| core.slew_train().is_some());
    let mut train = core.slew_train().unwrap();
    while train.has_step() {
        train.make_step();
    }
    // 15,996 slew steps; the first arms the fast path.
    assert_eq!(train.made(), 15_995);
    core.commit_train(&train);
    core.run_until(u64::MAX, &mut |_| {});
    assert_eq!(core.position(), 20_000);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// `make_steps(k)` leaves a train exactly where k calls of
    /// `make_step` do, and the steps made with the train's own delay and
    /// carry land on the same CTs: what a timer interrupt that makes the
    /// steps itself (the firmware's fast path) hands back.
    #[test]
    fn make_steps_is_k_make_step(
        p2exact in any::<bool>(),
        speed in 500u32..90_000,
        first in 0u32..2_000,
        second in 0u32..20_000,
    ) {
        let mut core = moving(p2exact, speed, 100_000);
        run_until_offered(&mut core, |core| core.slew_train().is_some());
        let mut one_by_one = core.slew_train().unwrap();
        let mut at_once = one_by_one;
        // The delays as a caller computes them from delay_q32 and carry.
        let (mut rise, mut carry) = (at_once.rise_ct, at_once.carry());
        for (k, part) in [first, second].into_iter().enumerate() {
            let part = part.min(one_by_one.steps_left);
            for _ in 0..part {
                let total = at_once.delay_q32() + u64::from(carry);
                carry = total as u32;
                rise += (total >> 32) + u64::from(at_once.period_extra());
                one_by_one.make_step();
                prop_assert_eq!(rise, one_by_one.rise_ct, "part {}", k);
            }
            at_once.make_steps(part);
            prop_assert_eq!(at_once, one_by_one);
        }
        prop_assert_eq!(committed(&core, &at_once), committed(&core, &one_by_one));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// `make_steps_into` (a run of steps at once, the rising CTs into a
    /// slice) leaves a train exactly where `make_step` one at a time
    /// does, each made while `has_step` holds and its CT is at most the
    /// run's last, and its CTs are the ones those steps rise at: on slew
    /// and ramp trains, a move's or a jog's (whose deadline stops it), in
    /// runs of random lengths up to random CTs.
    #[test]
    fn make_steps_into_is_make_step_one_at_a_time(
        p2exact in any::<bool>(),
        jog in any::<bool>(),
        speed in 500u32..90_000,
        skip in 0u32..3_000,
        runs in proptest::collection::vec((0usize..40, 0u64..2_000_000), 1..12),
    ) {
        let mut core = AxisCore::new(config(p2exact, true), 0);
        core.set_stop_pin(0, true);
        let command = if jog {
            CoreCommand::Jog { speed, direction: Direction::Forward }
        } else {
            CoreCommand::Move { speed, steps: 100_000 }
        };
        core.command(0, command).unwrap();
        // A jog (no heartbeat: it stops 150 ms after its command) from
        // within `skip`·2,000 ticks of its deadline, so that runs reach it.
        run_until_offered(&mut core, |core| {
            core.step_train().is_some_and(|train| match jog {
                true => train.limit_ct - train.rise_ct <= u64::from(skip) * 2_000,
                false => core.position() >= i64::from(skip),
            })
        });
        let mut at_once = core.step_train().unwrap();
        let mut one_by_one = at_once;
        for (len, ahead) in runs {
            let last = at_once.rise_ct + ahead;
            let mut rises = vec![0; len];
            let made = at_once.make_steps_into(last, &mut rises);
            let mut expected = Vec::new();
            while expected.len() < len && one_by_one.has_step() && one_by_one.rise_ct <= last {
                expected.push(one_by_one.rise_ct);
                one_by_one.make_step();
            }
            prop_assert_eq!(&rises[..made], &expected[..]);
            prop_assert_eq!(at_once, one_by_one);
        }
        prop_assert_eq!(committed(&core, &at_once), committed(&core, &one_by_one));
    }
}

/// A move's ramps, up and down, go nearly all in trains of the steps the
/// profile computed ahead: only the step that computes the next run is
/// the core's own.
#[test]
fn a_moves_ramps_go_in_trains() {
    for p2exact in [false, true] {
        let mut core = moving(p2exact, 20_000, 20_000);
        let (mut ramp_in_trains, mut slew_in_trains, mut by_events) = (0u32, 0u32, 0u32);
        while let Some(t) = core.next_event() {
            if let Some(mut train) = core.step_train() {
                while train.has_step() {
                    train.make_step();
                }
                if train.is_ramp() {
                    ramp_in_trains += train.made();
                } else {
                    slew_in_trains += train.made();
                }
                core.commit_train(&train);
                continue;
            }
            let before = core.position();
            core.run_event(t, &mut |_| {});
            by_events += u32::try_from(core.position() - before).unwrap();
        }
        assert_eq!(core.position(), 20_000);
        assert_eq!(ramp_in_trains + slew_in_trains + by_events, 20_000);
        // 2,002 ramp steps up and as many down.
        assert!(
            ramp_in_trains > 3_800,
            "{p2exact}: {ramp_in_trains} ramp steps in trains"
        );
        assert!(
            by_events < 100,
            "{p2exact}: {by_events} steps by the core's own events"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// On a ramp train, `make_steps(k)` then the hand-back leave the core
    /// where k of its own events do, and the train's rising edges are
    /// those events' CTs.
    #[test]
    fn make_steps_on_a_ramp_is_k_of_the_cores_events(
        p2exact in any::<bool>(),
        speed in 500u32..90_000,
        skip in 1u32..50,
        part in 0u32..9,
    ) {
        let mut core = moving(p2exact, speed, 100_000);
        run_until_offered(&mut core, |core| core.position() >= i64::from(skip));
        run_until_offered(&mut core, |core| core.step_train().is_some_and(|train| train.is_ramp()));
        let mut train = core.step_train().unwrap();
        let part = part.min(train.steps_left);
        let mut by_events = core.clone();
        let mut rises = Vec::new();
        for _ in 0..part {
            let t = by_events.next_event().unwrap();
            by_events.run_event(t, &mut |edge| if edge.level { rises.push(edge.ct) });
        }
        let mut one_by_one = train;
        let mut train_rises = Vec::new();
        for _ in 0..part {
            train_rises.push(one_by_one.rise_ct);
            one_by_one.make_step();
        }
        prop_assert_eq!(&train_rises, &rises);
        train.make_steps(part);
        prop_assert_eq!(train, one_by_one);
        prop_assert_eq!(committed(&core, &train), observe(&by_events));
    }
}

/// `ramp_run_lasts` (whether a run computed ahead could come before the
/// armed one is used up): wherever a ramp run is armed, it lasts exactly
/// the delays its steps left then take, one by one, as the core makes
/// them (and not a tick more); with none armed, it lasts 0 ticks.
#[test]
fn a_ramp_run_lasts_the_delays_of_its_steps_left() {
    for p2exact in [false, true] {
        let mut core = moving(p2exact, 20_000, 3_000);
        // (steps made so far, run end, the core) wherever a run is armed.
        let mut asked = Vec::new();
        let mut delays = Vec::new();
        let mut made = 0u32;
        while let Some(t) = core.next_event() {
            match core.run_end_index() {
                Some(end) => asked.push((made, end, core.clone())),
                None => assert!(
                    core.ramp_run_lasts(0) && !core.ramp_run_lasts(1),
                    "no run armed"
                ),
            }
            let before = core.position();
            core.run_event(t, &mut |_| {});
            if core.position() != before {
                made += 1;
                delays.push(u64::from(core.last_step().delay_ticks));
            }
        }
        assert_eq!(core.position(), 3_000);
        assert!(
            asked.len() > 1_000,
            "{} steps with a run armed",
            asked.len()
        );
        // The run's entries left: the delays the core computes after its
        // steps `made + 1` to `end` (each the wait before the step after
        // it), which the steps then take.
        for (made, end, armed) in &asked {
            let expected: u64 = delays[*made as usize..*end as usize].iter().sum();
            assert!(
                armed.ramp_run_lasts(expected) && !armed.ramp_run_lasts(expected + 1),
                "p2exact {p2exact}: {made} made, run to {end}, {expected} ticks"
            );
        }
    }
}
