//! Random command sequences against the hub: whatever users do, the count
//! stays exact, nothing panics or deadlocks, and virtual time is repeatable.

use cogstep_test_support::edges::position_from_edges;
use cogstep_test_support::hub::{start_axis, tracing_hub, Wiring};
use cogstep_test_support::ledger::accounted;
use cogstep_test_support::props::{cases, Tally};
use driver::{Axis, AxisError, Direction, Edge, Hub, HubConfig, Mode, StepLedger};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// Carries out one operation on the hub.
fn apply(hub: &Hub, axes: &[Axis; 2], op: &Op) -> Result<(), AxisError> {
    match *op {
        Op::Move { axis, speed, steps } => axes[axis].move_steps(speed, steps),
        Op::StopPin { axis, high } => axes[axis].set_stop_pin(high),
        Op::EmergencyStop { axis } => axes[axis].emergency_stop(),
        Op::Jog {
            axis,
            speed,
            reverse,
        } => {
            let direction = if reverse {
                Direction::Reverse
            } else {
                Direction::Forward
            };
            axes[axis].jog(speed, direction)
        }
        Op::JogRelease { axis } => axes[axis].jog_release(),
        Op::SetPosition { axis, position } => axes[axis].set_position(position),
        Op::Advance { ticks } => {
            hub.advance(ticks);
            Ok(())
        }
    }
}

/// Runs the actions on a fresh hub with one cc and one sd axis; returns the
/// trace and the final positions.
fn run(actions: &[Op]) -> (Vec<Edge>, [i64; 2]) {
    let hub = tracing_hub(HubConfig::default());
    let axes = [
        start_axis(&hub, 0, Wiring::Cc),
        start_axis(&hub, 1, Wiring::Sd),
    ];
    for action in actions {
        let result = apply(&hub, &axes, action);
        // Refusals are the model's business (check_model); here any is fine.
        let _ = result;
    }
    for axis in &axes {
        if axis.steps_to_go() > 100_000 {
            axis.emergency_stop().unwrap();
        }
    }
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    hub.run_until_idle();
    (hub.trace(), [axes[0].position(), axes[1].position()])
}

/// Position from the pins alone: cw minus ccw pulses for cc; step pulses
/// signed by the direction pin's level at each rising edge for sd.
fn positions_from_edges(trace: &[Edge]) -> [i64; 2] {
    [
        position_from_edges(Wiring::Cc.outputs(0), trace),
        position_from_edges(Wiring::Sd.outputs(1), trace),
    ]
}

// ---------------------------------------------------------------------------
// The model-based property: a small reference model of what each command
// must do to position, steps to go, the ledger and the mode, checked after
// every operation.

#[derive(Clone, Debug)]
enum Op {
    Move {
        axis: usize,
        speed: u32,
        steps: i32,
    },
    StopPin {
        axis: usize,
        high: bool,
    },
    EmergencyStop {
        axis: usize,
    },
    Jog {
        axis: usize,
        speed: u32,
        reverse: bool,
    },
    JogRelease {
        axis: usize,
    },
    SetPosition {
        axis: usize,
        position: i64,
    },
    Advance {
        ticks: u64,
    },
}

fn op() -> impl Strategy<Value = Op> {
    let axis = 0usize..2;
    let steps = prop_oneof![
        6 => -3_000i32..3_000,
        1 => prop_oneof![
            Just(i32::MIN),
            Just(i32::MAX),
            Just(-i32::MAX),
            Just(1),
            Just(-1),
            Just(0),
            -5i32..5,
        ],
    ];
    let speed = prop_oneof![
        6 => 500u32..60_000,
        1 => prop_oneof![Just(0u32), Just(1), Just(u32::MAX), 1u32..100, 150_000u32..250_000],
    ];
    let position = prop_oneof![
        3 => -10_000i64..10_000,
        1 => prop_oneof![Just(i64::MAX), Just(i64::MIN), Just(i64::MAX - 2), Just(i64::MIN + 2)],
    ];
    prop_oneof![
        5 => (axis.clone(), speed.clone(), steps).prop_map(|(axis, speed, steps)| Op::Move { axis, speed, steps }),
        2 => (axis.clone(), any::<bool>()).prop_map(|(axis, high)| Op::StopPin { axis, high }),
        1 => axis.clone().prop_map(|axis| Op::EmergencyStop { axis }),
        2 => (axis.clone(), speed, any::<bool>())
            .prop_map(|(axis, speed, reverse)| Op::Jog { axis, speed, reverse }),
        1 => axis.clone().prop_map(|axis| Op::JogRelease { axis }),
        1 => (axis, position).prop_map(|(axis, position)| Op::SetPosition { axis, position }),
        4 => (0u64..40_000_000).prop_map(|ticks| Op::Advance { ticks }),
    ]
}

/// Any operation but setting the position (which moves it without edges).
fn op_keeping_position() -> impl Strategy<Value = Op> {
    op().prop_filter("no set_position", |op| {
        !matches!(op, Op::SetPosition { .. })
    })
}

/// What the model knows of one axis.
#[derive(Clone, Copy, Debug, Default)]
struct Model {
    stop_pin_high: bool,
    /// Position minus the signed count of its step edges (set_position moves it).
    edge_offset: i64,
    /// Signed step edges counted so far.
    edge_position: i64,
    /// `edge_position` when the position was last set (the ledger's base).
    edges_at_base: i64,
    /// Rising edges on the axis's output pins, counted from the trace.
    rising_edges: u64,
    dropped_total: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Seen {
    position: i64,
    steps_to_go: u64,
    mode: u32,
    ledger: StepLedger,
}

fn seen(axis: &Axis) -> Seen {
    Seen {
        position: axis.position(),
        steps_to_go: axis.steps_to_go(),
        mode: axis.mode().bits(),
        ledger: axis.ledger(),
    }
}

/// Runs `ops` on one cc and one sd axis, checking the model after each.
/// Returns how many operations were checked.
fn check_model(ops: &[Op]) -> Result<usize, TestCaseError> {
    let hub = tracing_hub(HubConfig::default());
    let axes = [
        hub.start_cc(0, 1, 2).expect("cc"),
        hub.start_sd(3, 4, 5).expect("sd"),
    ];
    let mut models = [Model::default(); 2];
    for (i, pin) in [0u8, 3].into_iter().enumerate() {
        hub.set_input(pin, true).unwrap();
        models[i].stop_pin_high = true;
    }
    let mut dir_high = false;
    for op in ops {
        let index = match *op {
            Op::Move { axis, .. }
            | Op::StopPin { axis, .. }
            | Op::EmergencyStop { axis }
            | Op::Jog { axis, .. }
            | Op::JogRelease { axis }
            | Op::SetPosition { axis, .. } => Some(axis),
            Op::Advance { .. } => None,
        };
        let before: Vec<Seen> = axes.iter().map(seen).collect();
        if let Op::StopPin { axis, high } = *op {
            models[axis].stop_pin_high = high;
        }
        let result = apply(&hub, &axes, op);
        // The edges since the last check, counted from the pins alone.
        for edge in hub.take_trace() {
            count_edge(&mut models, &mut dir_high, edge);
        }
        let after: Vec<Seen> = axes.iter().map(seen).collect();
        // What the command must have done to its own axis.
        if let Some(axis) = index {
            let (b, a) = (before[axis], after[axis]);
            let mode_before = Mode(b.mode);
            match (op, &result) {
                (_, Err(error)) => {
                    // A refusal changes nothing.
                    prop_assert_eq!(a, b, "{:?} refused with {} changed the axis", op, error);
                }
                (Op::Move { steps, .. }, Ok(())) => {
                    prop_assert_eq!(a.ledger.accepted, b.ledger.accepted + i64::from(*steps));
                    prop_assert!(!mode_before.has(Mode::HOLD) || !models[axis].stop_pin_high);
                    if !models[axis].stop_pin_high {
                        prop_assert!(Mode(a.mode).has(Mode::HOLD));
                    }
                }
                (Op::SetPosition { position, .. }, Ok(())) => {
                    prop_assert_eq!(a.position, *position);
                    prop_assert_eq!(a.ledger.base, *position);
                    models[axis].edge_offset = position.wrapping_sub(models[axis].edge_position);
                    // The ledger starts again from here.
                    models[axis].edges_at_base = models[axis].edge_position;
                }
                (Op::EmergencyStop { .. }, Ok(())) => {
                    prop_assert_eq!(a.steps_to_go, 0);
                    prop_assert!(Mode(a.mode).has(Mode::ESTOP));
                    prop_assert!(!Mode(a.mode).has(Mode::MOVING | Mode::HOLD));
                }
                _ => {}
            }
            // The refusals the model can predict from what it saw before.
            let error = result.err();
            match *op {
                Op::Move {
                    steps: i32::MIN, ..
                } => {
                    prop_assert_eq!(error, Some(AxisError::StepsOutOfRange))
                }
                Op::Move { speed, steps, .. } if speed == 0 || steps == 0 => {
                    prop_assert!(matches!(error, Some(AxisError::Plan(_))))
                }
                Op::Move { speed, .. }
                    if speed < 150_000 && mode_before.has(Mode::JOG | Mode::MOVING) =>
                {
                    prop_assert_eq!(error, Some(AxisError::Jogging))
                }
                Op::Move { speed, .. }
                    if speed < 150_000 && speed > 0 && mode_before.has(Mode::HOLD) =>
                {
                    prop_assert_eq!(error, Some(AxisError::Busy))
                }
                Op::Jog { speed, .. }
                    if speed > 0 && speed < 150_000 && !models[axis].stop_pin_high =>
                {
                    prop_assert_eq!(error, Some(AxisError::StopPinLow))
                }
                Op::SetPosition { .. } => {
                    // Nothing left to make (a move's last period may still run).
                    let idle = b.steps_to_go == 0;
                    prop_assert_eq!(error.is_none(), idle, "{:?}", error);
                }
                Op::StopPin { .. } | Op::EmergencyStop { .. } | Op::JogRelease { .. } => {
                    prop_assert_eq!(error, None)
                }
                _ => {}
            }
        }
        // What holds on every axis after every operation.
        for (axis, (model, now)) in models.iter_mut().zip(&after).enumerate() {
            let mode = Mode(now.mode);
            prop_assert_eq!(
                now.position,
                model.edge_offset.wrapping_add(model.edge_position),
                "axis {}",
                axis
            );
            prop_assert!(now.ledger.dropped_total >= model.dropped_total);
            model.dropped_total = now.ledger.dropped_total;
            if mode.has(Mode::HOLD) {
                prop_assert!(now.steps_to_go > 0);
            }
            if now.steps_to_go == 0 && !mode.has(Mode::MOVING) {
                let ledger = now.ledger;
                prop_assert_eq!(
                    i128::from(now.position),
                    accounted(&ledger),
                    "axis {} idle: {:?}",
                    axis,
                    ledger
                );
                prop_assert!(!mode.has(Mode::JOG) && !mode.has(Mode::HOLD), "{:?}", mode);
            }
        }
    }
    // The end: huge moves are cut short (and counted), the rest runs out.
    for (i, axis) in axes.iter().enumerate() {
        if axis.steps_to_go() > 100_000 {
            axis.emergency_stop().unwrap();
        }
        hub.set_input([0u8, 3][i], true).unwrap();
    }
    hub.run_until_idle();
    // The last edges, counted as after every operation.
    for edge in hub.take_trace() {
        count_edge(&mut models, &mut dir_high, edge);
    }
    for (axis, (handle, model)) in axes.iter().zip(&models).enumerate() {
        let ledger = handle.ledger();
        prop_assert_eq!(handle.steps_to_go(), 0);
        prop_assert_eq!(i128::from(handle.position()), accounted(&ledger));
        // The position is the one the pins made.
        prop_assert_eq!(
            handle.position(),
            model.edge_offset.wrapping_add(model.edge_position),
            "axis {} at the end",
            axis
        );
        // The edges since the last set position are the steps the ledger
        // says were made: taken, less dropped, plus jogged.
        let made =
            i128::from(ledger.accepted) - i128::from(ledger.dropped) + i128::from(ledger.jogged);
        prop_assert_eq!(
            i128::from(model.edge_position - model.edges_at_base),
            made,
            "axis {}: signed step edges since the last set position against the ledger {:?}",
            axis,
            ledger
        );
        // Every rising edge the trace holds is one the pin counters saw.
        let counted: u64 = step_pins(axis)
            .iter()
            .map(|pin| hub.rising_edges(*pin))
            .sum();
        prop_assert_eq!(model.rising_edges, counted, "axis {}", axis);
    }
    Ok(ops.len())
}

/// The output pins of axis 0 (cc: cw 1, ccw 2) and axis 1 (sd: step 4).
fn step_pins(axis: usize) -> &'static [u8] {
    if axis == 0 {
        &[1, 2]
    } else {
        &[4]
    }
}

/// Counts one edge of the trace into the models: cw minus ccw pulses for
/// the cc axis, step pulses signed by the direction pin for the sd axis.
fn count_edge(models: &mut [Model; 2], dir_high: &mut bool, edge: Edge) {
    match (edge.pin, edge.level) {
        (1, true) => {
            models[0].edge_position += 1;
            models[0].rising_edges += 1;
        }
        (2, true) => {
            models[0].edge_position -= 1;
            models[0].rising_edges += 1;
        }
        (5, level) => *dir_high = level,
        (4, true) => {
            models[1].edge_position += if *dir_high { -1 } else { 1 };
            models[1].rising_edges += 1;
        }
        _ => {}
    }
}

/// Runs the model over `default_cases` random sequences (more with
/// `COGSTEP_MODEL_CASES`: the `--ignored` run uses 20,000) of up to
/// `longest` operations and says how many sequences and operations it
/// checked.
fn run_model(default_cases: u32, longest: usize) {
    let tally = Tally::default();
    let config = ProptestConfig {
        cases: cases(default_cases),
        ..ProptestConfig::default()
    };
    proptest!(config, |(ops in prop::collection::vec(op(), 1..longest))| {
        tally.add(check_model(&ops)?);
    });
    tally.report("model");
}

#[test]
fn every_accepted_command_is_carried_out_and_every_step_accounted() {
    run_model(2_000, 40);
}

#[test]
#[ignore = "the long run: cargo test --release -p cogstep-tests --test hub_props -- --ignored"]
fn every_accepted_command_is_carried_out_long_run() {
    run_model(20_000, 60);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn position_is_the_signed_count_of_step_edges(actions in prop::collection::vec(op_keeping_position(), 1..24)) {
        let (trace, positions) = run(&actions);
        prop_assert_eq!(positions_from_edges(&trace), positions);
        // Pulses never overlap on one pin: rising, falling, rising...
        for pin in [1u8, 2, 4] {
            let mut high = false;
            for edge in trace.iter().filter(|e| e.pin == pin) {
                prop_assert_ne!(edge.level, high);
                high = edge.level;
            }
            prop_assert!(!high);
        }
    }

    #[test]
    fn virtual_time_is_repeatable(actions in prop::collection::vec(op(), 1..16)) {
        let first = run(&actions);
        let second = run(&actions);
        prop_assert_eq!(first, second);
    }
}
