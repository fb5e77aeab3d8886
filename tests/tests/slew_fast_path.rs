//! The slew fast path is invisible: an axis that makes its plain slew steps
//! in closed form ([`AxisCore::run_slew`], what a cog does when nothing
//! traces its edges) ends every run in exactly the state, with exactly the
//! edge counts and levels, that making each step on its own gives; and a
//! hub without a trace (fast path) shows what a hub with one (every edge
//! made one by one) shows, after every operation.

use cogstep_test_support::hub::{start_axis, Wiring};
use driver::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs};
use driver::profile::scurve::Arithmetic;
use driver::{Axis, Direction, Hub, HubConfig};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    Move {
        speed: u32,
        steps: i32,
    },
    StopPin {
        high: bool,
    },
    EmergencyStop,
    Jog {
        speed: u32,
        reverse: bool,
    },
    JogRelease,
    SetPosition {
        position: i64,
    },
    /// Run to CT + ticks; the fast path's batches are cut at `batch` steps.
    Advance {
        ticks: u64,
        batch: u32,
    },
}

fn op() -> impl Strategy<Value = Op> {
    let speed = prop_oneof![4 => 500u32..40_000, 1 => 40_000u32..120_000];
    let steps = prop_oneof![3 => -20_000i32..20_000, 1 => -300i32..300];
    let ticks = prop_oneof![
        2 => 0u64..2_000_000,
        2 => 2_000_000u64..200_000_000,
        1 => 200_000_000u64..2_000_000_000,
    ];
    prop_oneof![
        6 => (speed.clone(), steps).prop_map(|(speed, steps)| Op::Move { speed, steps }),
        2 => any::<bool>().prop_map(|high| Op::StopPin { high }),
        1 => Just(Op::EmergencyStop),
        2 => (speed, any::<bool>()).prop_map(|(speed, reverse)| Op::Jog { speed, reverse }),
        1 => Just(Op::JogRelease),
        1 => (-1_000i64..1_000).prop_map(|position| Op::SetPosition { position }),
        8 => (ticks, prop_oneof![Just(1u32), 2u32..64, Just(u32::MAX)])
            .prop_map(|(ticks, batch)| Op::Advance { ticks, batch }),
    ]
}

/// What the edges did to each output pin: rising edges and the level after.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct PinCount {
    rising: u64,
    high: bool,
}

struct Run {
    core: AxisCore,
    ct: u64,
    pins: [PinCount; 64],
}

impl Run {
    fn new(arithmetic: Arithmetic, outputs: Outputs) -> Self {
        let mut config = AxisCoreConfig::new(outputs);
        config.scurve.arithmetic = arithmetic;
        Run {
            core: AxisCore::new(config, 0),
            ct: 0,
            pins: [PinCount::default(); 64],
        }
    }

    fn edge(&mut self, edge: Edge) {
        let pin = &mut self.pins[usize::from(edge.pin)];
        pin.rising += u64::from(edge.level);
        pin.high = edge.level;
    }

    /// Every event up to `limit`, as a cog runs them: one by one, or with
    /// the slew steps in batches of at most `batch`. Returns the batches made.
    fn advance(&mut self, limit: u64, batch: Option<u32>) -> u64 {
        let mut batches = 0;
        while let Some(t) = self.core.next_event().filter(|t| *t <= limit) {
            self.ct = self.ct.max(t);
            if let Some(run) = batch.and_then(|max| self.core.run_slew(self.ct, limit, max)) {
                let pin = &mut self.pins[usize::from(run.pin)];
                pin.rising += u64::from(run.steps);
                pin.high = false;
                batches += 1;
                continue;
            }
            let mut edges = Vec::new();
            self.core.run_event(self.ct, &mut |edge| edges.push(edge));
            for edge in edges {
                self.edge(edge);
            }
        }
        self.ct = self.ct.max(limit);
        batches
    }

    fn apply(&mut self, op: &Op, batch: bool) -> u64 {
        let ct = self.ct;
        let _ = match *op {
            Op::Move { speed, steps } => self.core.command(ct, CoreCommand::Move { speed, steps }),
            Op::StopPin { high } => {
                self.core.set_stop_pin(ct, high);
                Ok(driver::axis_core::Taken::Done)
            }
            Op::EmergencyStop => self.core.command(ct, CoreCommand::EmergencyStop),
            Op::Jog { speed, reverse } => self.core.command(
                ct,
                CoreCommand::Jog {
                    speed,
                    direction: if reverse {
                        Direction::Reverse
                    } else {
                        Direction::Forward
                    },
                },
            ),
            Op::JogRelease => self.core.command(ct, CoreCommand::JogRelease),
            Op::SetPosition { position } => {
                self.core.command(ct, CoreCommand::SetPosition(position))
            }
            Op::Advance { ticks, batch: max } => {
                return self.advance(ct.saturating_add(ticks), batch.then_some(max));
            }
        };
        0
    }
}

/// Runs `ops` step by step and with the fast path; the two must agree on
/// the whole core state (positions, CTs, carries, ledger, mode, the last
/// step), the CT and every pin's count and level after every operation.
/// Returns the batches the fast path made.
fn differential(
    arithmetic: Arithmetic,
    outputs: Outputs,
    ops: &[Op],
) -> Result<u64, TestCaseError> {
    let mut plain = Run::new(arithmetic, outputs);
    let mut fast = Run::new(arithmetic, outputs);
    plain.core.set_stop_pin(0, true);
    fast.core.set_stop_pin(0, true);
    let mut batches = 0;
    for (i, op) in ops.iter().enumerate() {
        plain.apply(op, false);
        batches += fast.apply(op, true);
        prop_assert_eq!(
            format!("{:?}", plain.core),
            format!("{:?}", fast.core),
            "core state after op {} {:?}",
            i,
            op
        );
        prop_assert_eq!(plain.ct, fast.ct);
        prop_assert_eq!(plain.pins, fast.pins, "pins after op {} {:?}", i, op);
    }
    plain.apply(
        &Op::Advance {
            ticks: u64::MAX,
            batch: 0,
        },
        false,
    );
    batches += fast.apply(
        &Op::Advance {
            ticks: u64::MAX,
            batch: u32::MAX,
        },
        true,
    );
    prop_assert_eq!(format!("{:?}", plain.core), format!("{:?}", fast.core));
    prop_assert_eq!(plain.pins, fast.pins);
    Ok(batches)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn closed_form_slew_steps_are_the_steps_one_by_one(
        ops in prop::collection::vec(op(), 1..24),
        p2exact in any::<bool>(),
        sd in any::<bool>(),
    ) {
        let arithmetic = if p2exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let outputs = if sd {
            Outputs::StepDir { step: 1, dir: 2 }
        } else {
            Outputs::CwCcw { cw: 1, ccw: 2 }
        };
        differential(arithmetic, outputs, &ops)?;
    }
}

/// The property above is not vacuous: a plain long move takes the fast path.
#[test]
fn a_long_move_is_made_in_batches() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        let ops = [
            Op::Move {
                speed: 30_000,
                steps: -100_000,
            },
            Op::Advance {
                ticks: 100_000_000,
                batch: 100,
            },
        ];
        let batches =
            differential(arithmetic, Outputs::StepDir { step: 1, dir: 2 }, &ops).expect("the same");
        // About 11,000 slew steps in the first 0.5 s, 100 a batch, then the rest at once.
        assert!(batches > 50, "{arithmetic:?}: {batches} batches");
    }
}

// ---------------------------------------------------------------------------
// The hub: trace on (every edge one by one) against trace off (fast path).

#[derive(Clone, Debug)]
enum HubOp {
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
    Advance {
        ticks: u64,
    },
}

fn hub_op() -> impl Strategy<Value = HubOp> {
    let axis = 0usize..2;
    let speed = 500u32..60_000;
    prop_oneof![
        5 => (axis.clone(), speed.clone(), -30_000i32..30_000)
            .prop_map(|(axis, speed, steps)| HubOp::Move { axis, speed, steps }),
        1 => (axis.clone(), any::<bool>()).prop_map(|(axis, high)| HubOp::StopPin { axis, high }),
        1 => axis.clone().prop_map(|axis| HubOp::EmergencyStop { axis }),
        1 => (axis.clone(), speed, any::<bool>())
            .prop_map(|(axis, speed, reverse)| HubOp::Jog { axis, speed, reverse }),
        1 => axis.prop_map(|axis| HubOp::JogRelease { axis }),
        5 => (0u64..400_000_000).prop_map(|ticks| HubOp::Advance { ticks }),
    ]
}

fn hub_apply(hub: &Hub, axes: &[Axis; 2], op: &HubOp) {
    let _ = match *op {
        HubOp::Move { axis, speed, steps } => axes[axis].move_steps(speed, steps),
        HubOp::StopPin { axis, high } => axes[axis].set_stop_pin(high),
        HubOp::EmergencyStop { axis } => axes[axis].emergency_stop(),
        HubOp::Jog {
            axis,
            speed,
            reverse,
        } => axes[axis].jog(
            speed,
            if reverse {
                Direction::Reverse
            } else {
                Direction::Forward
            },
        ),
        HubOp::JogRelease { axis } => axes[axis].jog_release(),
        HubOp::Advance { ticks } => {
            hub.advance(ticks);
            Ok(())
        }
    };
}

/// Everything a user of the hub can read.
fn observed(hub: &Hub, axes: &[Axis; 2]) -> String {
    let pins: Vec<(u64, bool)> = (0..6)
        .map(|pin| (hub.rising_edges(pin), hub.output(pin)))
        .collect();
    let axes: Vec<String> = axes
        .iter()
        .map(|axis| {
            format!(
                "{:?} {:?} v{} d{} last{} start{} top{} max{} drop{} over{}",
                axis.status(),
                axis.ledger(),
                axis.velocity(),
                axis.delay_ticks(),
                axis.last_step_ct(),
                axis.move_start_ct(),
                axis.top_velocity(),
                axis.max_velocity(),
                axis.dropped_steps(),
                axis.math_overruns(),
            )
        })
        .collect();
    format!("ct {} pins {pins:?} axes {axes:?}", hub.now())
}

fn hub_run(trace_edges: bool, arithmetic: Arithmetic, ops: &[HubOp]) -> Vec<String> {
    let hub = Hub::new(HubConfig {
        trace_edges,
        arithmetic,
        ..HubConfig::default()
    })
    .expect("hub");
    let axes = [
        start_axis(&hub, 0, Wiring::Cc),
        start_axis(&hub, 1, Wiring::Sd),
    ];
    let mut seen = Vec::new();
    for op in ops {
        hub_apply(&hub, &axes, op);
        seen.push(observed(&hub, &axes));
    }
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    hub.run_until_idle();
    seen.push(observed(&hub, &axes));
    seen
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn a_hub_without_a_trace_shows_what_a_hub_with_one_shows(
        ops in prop::collection::vec(hub_op(), 1..16),
        p2exact in any::<bool>(),
    ) {
        let arithmetic = if p2exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let traced = hub_run(true, arithmetic, &ops);
        let fast = hub_run(false, arithmetic, &ops);
        for (i, (traced, fast)) in traced.iter().zip(&fast).enumerate() {
            prop_assert_eq!(traced, fast, "after op {}", i);
        }
    }
}

/// Mid-move, when `advance` returns, the pins show every edge made so far:
/// the rising edges on the step pin are the steps made, with and without
/// the trace (the fast path counts its batches the same way).
#[test]
fn edges_are_counted_when_an_advance_returns_mid_move() {
    for trace_edges in [false, true] {
        let hub = Hub::new(HubConfig {
            trace_edges,
            ..HubConfig::default()
        })
        .expect("hub");
        let axis = hub.start_sd(0, 1, 2).expect("sd");
        hub.set_input(0, true).unwrap();
        axis.move_steps(20_000, 50_000).unwrap();
        for _ in 0..20 {
            hub.advance(20_000_000);
            let position = axis.position();
            assert!(position > 0 && position < 50_000);
            assert_eq!(hub.rising_edges(1), position as u64, "trace {trace_edges}");
        }
    }
}
