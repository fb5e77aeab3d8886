//! The hub in `P2Exact` against the reference cog (`Step_driver2_sd.spin2`):
//! edge times, mode at the end of a move, and STM as the command word.

use cogstep_test_support::edges::rising;
use cogstep_test_support::hub::tracing_hub;
use driver::profile::scurve::{Arithmetic, SCurve, ScurveConfig};
use driver::{Hub, HubConfig, Mode};

const STOP: u8 = 0;
const STEP: u8 = 1;
const DIR: u8 = 2;

fn p2_hub() -> Hub {
    tracing_hub(HubConfig {
        arithmetic: Arithmetic::P2Exact,
        ..HubConfig::default()
    })
}

/// The reference cog's step loop, as its PASM runs it: after the rising
/// edge `getct cv`; `addct1 cv, delayh` (the pulse, 1,000 ticks); `drvl`
/// at CT1; `addct2 cv, delay`; `waitct2`; `tjnz` back to `_dostep1`;
/// `drvh`; `getct cv`. The wait ends 2 clocks into `waitct2`, the taken
/// `tjnz` costs 4 and `drvh` 2 before `getct` samples CT again, so each
/// rising edge comes `delay + delayh + 8` after the one before.
fn reference_rising_edges(first: u64, delays: &[u32]) -> Vec<u64> {
    const DELAYH: u64 = 1_000;
    const WAITCT2_WAKE: u64 = 2;
    const TJNZ_TAKEN: u64 = 4;
    const DRVH: u64 = 2;
    let mut cv = first;
    let mut edges = vec![first];
    for delay in &delays[..delays.len() - 1] {
        cv += DELAYH; // addct1 cv, delayh
        cv += u64::from(*delay); // addct2 cv, delay; waitct2 waits for it
        cv += WAITCT2_WAKE + TJNZ_TAKEN + DRVH; // ... to the next getct cv
        edges.push(cv);
    }
    edges
}

#[test]
fn p2exact_edges_follow_the_reference_cogs_running_target() {
    let mut compared_moves = 0;
    let mut compared_steps = 0;
    for (speed, steps) in [
        (20_000u32, 4_000u32),
        (45_000, 9_000),
        (1_009, 204),
        (25, 8),
        (3_000, 1_001),
        (600, 61),
    ] {
        let hub = p2_hub();
        let x = hub.start_sd(STOP, STEP, DIR).unwrap();
        hub.set_input(STOP, true).unwrap();
        let start = hub.now();
        x.move_steps(speed, i32::try_from(steps).unwrap()).unwrap();
        hub.run_until_idle();
        let config = ScurveConfig {
            arithmetic: Arithmetic::P2Exact,
            ..ScurveConfig::default()
        };
        let delays: Vec<u32> = SCurve::new(config, speed, steps)
            .unwrap()
            .map(|s| s.delay_ticks)
            .collect();
        let edges = rising(&hub.trace(), STEP);
        assert_eq!(
            edges,
            reference_rising_edges(start, &delays),
            "{steps} at {speed}"
        );
        compared_moves += 1;
        compared_steps += edges.len();
    }
    assert_eq!((compared_moves, compared_steps), (6, 14_274));
}

#[test]
fn the_real_board_runs_slower_than_asked_and_smooth_does_not() {
    for (asked, reference_rate) in [(20_000u32, 18_169u64), (45_000, 36_684)] {
        for arithmetic in [Arithmetic::P2Exact, Arithmetic::Smooth] {
            let hub = Hub::new(HubConfig {
                arithmetic,
                trace_edges: true,
                ..HubConfig::default()
            })
            .unwrap();
            let x = hub.start_sd(STOP, STEP, DIR).unwrap();
            hub.set_input(STOP, true).unwrap();
            x.move_steps(asked, 40_000).unwrap();
            hub.run_until_idle();
            let edges = rising(&hub.trace(), STEP);
            // The middle of the move is at speed: the mean of 1,000 periods.
            let span = edges[21_000] - edges[20_000];
            let rate = (200_000_000_000 + span / 2) / span;
            match arithmetic {
                Arithmetic::P2Exact => assert_eq!(rate, reference_rate),
                Arithmetic::Smooth => assert_eq!(rate, u64::from(asked)),
            }
        }
    }
}

#[test]
fn mode_and_stm_as_the_reference_shows_them() {
    let hub = p2_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    // STM is the command word: 0 as soon as the cog has the command.
    x.move_steps(10_000, -3_000).unwrap();
    assert_eq!(x.stm(), 0);
    assert_eq!(x.steps_to_go(), 3_000);
    assert_eq!(
        x.mode().reference_bits(),
        0b010011,
        "moving, accelerating, reverse"
    );
    // A merge: still STM 0, the steps join.
    hub.advance(20_000_000);
    x.move_steps(10_000, -500).unwrap();
    assert_eq!(x.stm(), 0);
    hub.run_until_idle();
    assert_eq!(x.position(), -3_500);
    // `and mode, #%0100000`: after a reverse move the direction bit clears.
    assert_eq!(x.mode().reference_bits(), 0b000000);
    // After a stop-pin stop only b5 is left.
    x.move_steps(10_000, 5_000).unwrap();
    hub.advance(40_000_000);
    hub.set_input(STOP, false).unwrap();
    hub.run_until_idle();
    assert_eq!(x.mode().reference_bits(), 0b100000);
    assert!(x.mode().has(Mode::STOP_LATCHED));
}

#[test]
fn max_velocity_is_written_when_deceleration_starts() {
    let hub = p2_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    assert_eq!(x.max_velocity(), 0);
    x.move_steps(20_000, 20_000).unwrap();
    // Accelerating and at speed: not written yet.
    hub.advance(100_000_000);
    assert!(x.mode().has(Mode::SLEW));
    assert_eq!(x.max_velocity(), 0);
    hub.run_until_idle();
    // The last ramp step's velocity: halfsp − QROTATE(halfsp, angle) at 180°.
    let config = ScurveConfig {
        arithmetic: Arithmetic::P2Exact,
        ..ScurveConfig::default()
    };
    let steps: Vec<_> = SCurve::new(config, 20_000, 20_000).unwrap().collect();
    let last_before_decel = steps
        .iter()
        .take_while(|s| s.phase != driver::profile::Phase::Decel)
        .last()
        .unwrap();
    assert_eq!(
        x.max_velocity(),
        last_before_decel.velocity_steps_per_s as u32
    );
    assert!(x.max_velocity() > 19_000);
    // A second move keeps the first's value until it decelerates.
    x.move_steps(5_000, 5_000).unwrap();
    hub.advance(20_000_000);
    assert_eq!(
        x.max_velocity(),
        last_before_decel.velocity_steps_per_s as u32
    );
    hub.run_until_idle();
    assert!(x.max_velocity() <= 5_000);
}
