//! The Raspberry Pi Pico's PIO build, edge by edge (link 2 of the PIO
//! proof, `firmware/boards/rp-pico/README.md`): the firmware built with
//! its `pio` feature runs under the rp2040py emulator
//! (`firmware/run-pico-sim --pio`), whose PIO0 is a model that applies the
//! step program's closed form to every word the firmware writes to a TX
//! FIFO, at the simulated time it writes it (`firmware/pico-sim/pio_model.py`).
//! Commands arrive over UART0 mid-move; the axis cores are replayed on
//! the host from the CT each command acted at, and every edge of the VCD
//! is compared with theirs: every edge at the CT the core scheduled, to
//! the 8 ns cycle, with the one offset between the microsecond timer and
//! the state machines' first cycle (under a microsecond, the same for
//! every edge); every pulse 625 cycles (5 µs) exactly; no FIFO run dry,
//! no word written to a full FIFO, no edge refused. A test fails on the
//! first edge that is not, naming it.
//!
//! Ignored (it needs Debian's Rust toolchain and the emulator's virtual
//! environment): `.ci/run` runs it with `cargo test -p cogstep-tests
//! --test firmware_pico_pio -- --ignored`. The emulator runs some 25
//! times slower than the chip, so the moves are short.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use cogstep_test_support::pico::{
    pin_names, pio_counts, position_of, read_vcd, start_pico_sim, wait_idle, wait_position, Action,
    Replay,
};
use cogstep_test_support::script::DeviceScript;
use cogstep_test_support::serial::RawPort;
use driver::profile::scurve::Arithmetic;
use driver::CoreCommand::{EmergencyStop, Jog, Move};

/// The longest any wait here may take before it fails.
const PATIENCE: Duration = Duration::from_secs(120);
/// The PIO build's CT: the 125 MHz system clock.
const CLKFREQ: u32 = 125_000_000;
/// ns per CT tick.
const NS_PER_CT: i64 = 8;
/// 5 µs: the core's pulse and direction set-up, and the program's pulse.
const PULSE_CT: u64 = 625;
/// The offset between the timer's microseconds and the state machines'
/// first cycle is below a microsecond (`src/pio.rs`).
const OFFSET_LIMIT_NS: i64 = 1_000;

/// What the check saw: the offset of every edge from its CT, the steps
/// checked, and the pulse widths (ns).
struct Checked {
    offset_ns: i64,
    steps: usize,
    pulses: (i64, i64),
}

/// Every edge of the run against the replay: the same edges in the same
/// order on each pin, each at `epoch + CT × 8 ns + offset` with one
/// offset for all (in `0..OFFSET_LIMIT_NS`), each step pulse 5 µs exactly.
/// Fails on the first edge that is not, naming it (axis, pin, edge index,
/// expected and seen).
fn check_edges(replay: &Replay, vcd: &Path, epoch_ns: i64) -> Checked {
    let changes = read_vcd(vcd);
    let mut offset_ns = None;
    let mut steps = 0;
    let mut pulses = (i64::MAX, i64::MIN);
    // The offset comes from the earliest edge of the run.
    let mut first = (i64::MAX, 0);
    for (index, expected) in replay.edges.iter().enumerate() {
        for (pin, name) in pin_names(index).iter().enumerate() {
            let wanted = expected.iter().find(|edge| usize::from(edge.pin) == pin);
            if let (Some(edge), Some(&(at_ns, _))) =
                (wanted, changes.get(name).and_then(|seen| seen.first()))
            {
                let due_ns = epoch_ns + i64::try_from(edge.ct).unwrap() * NS_PER_CT;
                if due_ns < first.0 {
                    first = (due_ns, at_ns - due_ns);
                }
            }
        }
    }
    if first.0 != i64::MAX {
        offset_ns = Some(first.1);
    }
    let offset_ns = offset_ns.unwrap_or(0);
    assert!(
        (0..OFFSET_LIMIT_NS).contains(&offset_ns),
        "the first edge is {offset_ns} ns after its CT: the state machines' start is off the timer by more than a microsecond"
    );
    for (index, expected) in replay.edges.iter().enumerate() {
        for (pin, name) in pin_names(index).iter().enumerate() {
            let wanted: Vec<_> = expected
                .iter()
                .filter(|edge| usize::from(edge.pin) == pin)
                .collect();
            let seen = changes.get(name).cloned().unwrap_or_default();
            for (number, edge) in wanted.iter().enumerate() {
                let kind = if edge.level { "rising" } else { "falling" };
                let due_ns = epoch_ns + i64::try_from(edge.ct).unwrap() * NS_PER_CT + offset_ns;
                let Some(&(at_ns, level)) = seen.get(number) else {
                    panic!(
                        "{name} (axis {index}): {kind} edge {number} (CT {}, due at {due_ns} ns) never came ({} edges seen)",
                        edge.ct,
                        seen.len()
                    );
                };
                assert_eq!(
                    level, edge.level,
                    "{name} (axis {index}): edge {number} at {at_ns} ns is {} where the core has a {kind} edge at CT {} ({due_ns} ns)",
                    if level { "rising" } else { "falling" },
                    edge.ct
                );
                assert_eq!(
                    at_ns,
                    due_ns,
                    "{name} (axis {index}): {kind} edge {number} at {at_ns} ns, the core scheduled CT {} ({due_ns} ns): {} ns off",
                    edge.ct,
                    at_ns - due_ns
                );
                let pulse_pin = pin == 0 || index % 2 == 1;
                if edge.level && pulse_pin {
                    steps += 1;
                } else if !edge.level && pulse_pin && number > 0 {
                    let width = at_ns - seen[number - 1].0;
                    assert_eq!(
                        width,
                        PULSE_CT as i64 * NS_PER_CT,
                        "{name} (axis {index}): step pulse {} (rising at {} ns) is {width} ns wide",
                        number / 2,
                        seen[number - 1].0
                    );
                    pulses = (pulses.0.min(width), pulses.1.max(width));
                }
            }
            assert_eq!(
                seen.len(),
                wanted.len(),
                "{name} (axis {index}): {} edges where the core made {}; the first extra at {:?}",
                seen.len(),
                wanted.len(),
                seen.get(wanted.len())
            );
        }
    }
    Checked {
        offset_ns,
        steps,
        pulses,
    }
}

/// A run: the emulator, its port, and the replay of what the lines did.
struct Run {
    pico: DeviceScript,
    raw: RawPort,
    replay: Replay,
    vcd: PathBuf,
    axes: usize,
}

impl Run {
    fn start(axes: usize, arithmetic: Arithmetic, name: &str) -> Run {
        let vcd = std::env::temp_dir().join(format!(
            "cogstep-pico-pio-{name}-{}.vcd",
            std::process::id()
        ));
        let pico = start_pico_sim(axes, arithmetic, true, Some(&vcd));
        let mut raw = RawPort::open_when_answering(pico.path(), PATIENCE);
        assert_eq!(
            raw.command("I"),
            [
                format!(
                    "[cogstep {} proto:1 axes:{axes} clkfreq:{CLKFREQ}]",
                    env!("CARGO_PKG_VERSION")
                ),
                "ok".to_string()
            ]
        );
        Run {
            pico,
            raw,
            replay: Replay::new(axes, CLKFREQ, arithmetic),
            vcd,
            axes,
        }
    }

    /// Sends `line`, expects `ok`, and replays `actions` at the CT it
    /// acted at (the firmware's COGSTEP_COMMAND_CT, low 32 bits of the
    /// cycle count: these runs are far shorter than its 34 s wrap).
    fn act(&mut self, line: &str, actions: &[Action]) {
        assert_eq!(self.raw.command(line), ["ok"], "{line}");
        let ct = u64::try_from(self.pico.number("ct")).expect("a CT");
        for &action in actions {
            self.replay.apply(ct, action);
        }
    }

    /// Waits for every axis to stop, checks every edge and the PIO
    /// model's counts, and returns what the check saw.
    fn finish(mut self) -> Checked {
        wait_idle(&mut self.raw, self.axes, PATIENCE);
        // The last edges reach the pins up to the lead (4 ms) later.
        let until = self.pico.number("now") + 10_000_000;
        while self.pico.number("now") < until {
            std::thread::sleep(Duration::from_millis(20));
        }
        // The harness counts positions from the model's edges (for
        // `switch ... when axisN`): the same as the firmware's.
        let lines = self.raw.status(self.axes);
        for (index, line) in lines.iter().enumerate() {
            let counted = self.pico.number(&format!("position axis{}", index + 1));
            assert_eq!(counted, position_of(line), "axis {index}: {line}");
        }
        let pio = pio_counts(&mut self.pico);
        let epoch_ns = self.pico.number("epoch");
        drop(self.raw);
        drop(self.pico);
        self.replay.finish();
        let checked = check_edges(&self.replay, &self.vcd, epoch_ns);
        for count in ["late", "overflows", "problems", "refused", "made_late"] {
            assert_eq!(
                pio.get(count).map(String::as_str),
                Some("0"),
                "the PIO model counted {count}: {pio:?}"
            );
        }
        eprintln!(
            "{} steps, every edge at its CT + {} ns, pulses {}..{} ns; PIO model: {pio:?}",
            checked.steps, checked.offset_ns, checked.pulses.0, checked.pulses.1
        );
        let _ = std::fs::remove_file(&self.vcd);
        checked
    }
}

/// Four axes at `speed` steps/s with commands arriving mid-move: a move
/// on each axis (a jog on the fourth), then a merge (a new target) on
/// axis 1, a stop and a resume on axis 2 (its stop pin low, then high),
/// a jog heartbeat on axis 4, and an emergency stop of everything.
fn four_axes_with_commands_mid_move(
    speed: u32,
    steps: i32,
    arithmetic: Arithmetic,
    name: &str,
) -> Checked {
    let axes = 4;
    let mut run = Run::start(axes, arithmetic, name);
    let forward = driver::Direction::Forward;
    run.act(
        &format!("M 0 {speed} {steps}"),
        &[Action::Command(0, Move { speed, steps })],
    );
    run.act(
        &format!("M 1 {speed} {}", -steps),
        &[Action::Command(
            1,
            Move {
                speed,
                steps: -steps,
            },
        )],
    );
    run.act(
        &format!("M 2 {speed} {steps}"),
        &[Action::Command(2, Move { speed, steps })],
    );
    run.act(
        &format!("J 3 {speed} +"),
        &[Action::Command(
            3,
            Jog {
                speed,
                direction: forward,
            },
        )],
    );
    wait_position(&mut run.raw, axes, 0, i64::from(steps / 4), PATIENCE);
    let merged = steps / 2;
    run.act(
        &format!("M 0 {speed} {merged}"),
        &[Action::Command(
            0,
            Move {
                speed,
                steps: merged,
            },
        )],
    );
    run.act("S 1", &[Action::StopPin(1, false)]);
    run.act(
        &format!("J 3 {speed} +"),
        &[Action::Command(
            3,
            Jog {
                speed,
                direction: forward,
            },
        )],
    );
    wait_position(&mut run.raw, axes, 2, i64::from(steps / 2), PATIENCE);
    run.act("R 1", &[Action::StopPin(1, true)]);
    wait_position(&mut run.raw, axes, 2, i64::from(steps * 3 / 4), PATIENCE);
    run.act(
        "E",
        &[
            Action::Command(0, EmergencyStop),
            Action::Command(1, EmergencyStop),
            Action::Command(2, EmergencyStop),
            Action::Command(3, EmergencyStop),
        ],
    );
    run.finish()
}

/// Four axes at 3,000 steps/s each, ramping most of the way (1,200-step
/// moves): the commands land while every axis is still on its ramp's
/// slow part, where each step's words are few and long.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_every_edge_at_its_ct_with_commands_mid_move() {
    let checked = four_axes_with_commands_mid_move(3_000, 1_200, Arithmetic::Smooth, "four");
    assert!(checked.steps > 2_000, "{} steps", checked.steps);
}

/// The same with the axis cores in P2Exact (`run-pico-sim --arithmetic
/// p2exact`), against host cores in P2Exact.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_in_p2exact_every_edge_at_its_ct_with_commands_mid_move() {
    let checked =
        four_axes_with_commands_mid_move(3_000, 1_200, Arithmetic::P2Exact, "four-p2exact");
    assert!(checked.steps > 2_000, "{} steps", checked.steps);
}

/// Four axes at 30,000 steps/s each with commands mid-move, 6,000-step
/// moves (a ramp up and down, the merge and the stop landing on the
/// ramps): both cores busy computing ramp runs, with room for where the
/// commands land, which follows the wall clock (P2Exact keeps every
/// edge to 42,500 and runs dry at 45,000: docs/performance.md, "The PIO
/// build at 50,000"). About 15 s.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_30000_every_edge_at_its_ct_with_commands_mid_move() {
    let checked = four_axes_with_commands_mid_move(30_000, 6_000, Arithmetic::Smooth, "four-30k");
    assert!(checked.steps > 15_000, "{} steps", checked.steps);
}

/// The same in P2Exact. About 20 s.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_30000_in_p2exact_every_edge_at_its_ct_with_commands_mid_move() {
    let checked =
        four_axes_with_commands_mid_move(30_000, 6_000, Arithmetic::P2Exact, "four-30k-p2exact");
    assert!(checked.steps > 15_000, "{} steps", checked.steps);
}

/// The promise: four axes at 50,000 steps/s with commands
/// mid-move, every edge at its CT. Its 12,000-step moves ramp for 5,002
/// steps up and down and run 2,000 at speed: three axes reach 50,000
/// steps/s (the one stopped and resumed mid-move 48,400), the four
/// ramping together up and down. It takes both cores at full stretch:
/// the steps a run at a time (`pio.rs`, `set_rises`), the division's
/// short way (motion's `ieee_div`) and core 1's guesses (`core1.rs`).
/// With no steps at speed between the ramps up and down, four axes
/// ramping together from rest keep time to about 44,000 each
/// (`pio_rates.py`; docs/performance.md, "The PIO build at 50,000").
/// About 32 s, some 38,600 steps.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_50000_every_edge_at_its_ct_with_commands_mid_move() {
    let checked = four_axes_with_commands_mid_move(50_000, 12_000, Arithmetic::Smooth, "four-50k");
    assert!(checked.steps > 30_000, "{} steps", checked.steps);
}

/// The scenario at the speed in `COGSTEP_PICO_PIO_SPEED` (steps/s) with
/// moves of `COGSTEP_PICO_PIO_STEPS` steps (default: a fifth of the
/// speed, a ramp up and down), `COGSTEP_PICO_PIO_ARITHMETIC=p2exact` for
/// P2Exact: to find by hand the highest speed at which the PIO build keeps
/// every edge at its CT with commands mid-move (docs/performance.md has
/// the figure).
#[test]
#[ignore = "by hand: COGSTEP_PICO_PIO_SPEED=N"]
fn four_axes_at_a_chosen_speed() {
    let number =
        |name: &str| -> Option<u32> { std::env::var(name).ok().and_then(|text| text.parse().ok()) };
    let speed = number("COGSTEP_PICO_PIO_SPEED").expect("COGSTEP_PICO_PIO_SPEED=steps/s");
    let steps = number("COGSTEP_PICO_PIO_STEPS").unwrap_or(speed / 5);
    let arithmetic = match std::env::var("COGSTEP_PICO_PIO_ARITHMETIC").as_deref() {
        Ok("p2exact") => Arithmetic::P2Exact,
        _ => Arithmetic::Smooth,
    };
    let steps = i32::try_from(steps).expect("COGSTEP_PICO_PIO_STEPS fits an i32");
    four_axes_with_commands_mid_move(speed, steps, arithmetic, "four-chosen");
}
