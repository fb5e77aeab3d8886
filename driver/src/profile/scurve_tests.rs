//! Tests of the S-curve: planning, both arithmetic modes, re-planning.

extern crate std;
use std::vec::Vec;

use super::*;
use proptest::prelude::*;

fn config(arithmetic: Arithmetic) -> ScurveConfig {
    ScurveConfig {
        arithmetic,
        ..ScurveConfig::default()
    }
}

fn steps_of(arithmetic: Arithmetic, speed: u32, steps: u32) -> Vec<Step> {
    SCurve::new(config(arithmetic), speed, steps)
        .expect("valid move")
        .collect()
}

/// The largest change of velocity between two neighbouring positions of the
/// ramp a move of this speed uses: the most a single step may change it.
fn ramp_velocity_step(arithmetic: Arithmetic, speed: u32) -> f64 {
    let steps = steps_of(arithmetic, speed, speed.saturating_mul(4) / 10 + 100);
    steps
        .windows(2)
        .map(|w| (w[1].velocity_steps_per_s - w[0].velocity_steps_per_s).abs())
        .fold(0.0, f64::max)
}

/// The reference cog, written out plainly from the design text: the model
/// P2Exact is checked against.
fn reference_delays(
    speed: u32,
    accel_steps: u32,
    slew_steps: u32,
    offset: u32,
    clkfreq: u32,
) -> Vec<u32> {
    let stom = 2 * accel_steps;
    let halfsp = (speed / 2) as i32;
    let delay_at = |stepn: u32| -> u32 {
        let deg128 = if stom == 0 {
            180 * 128
        } else {
            stepn as u64 * (360 - 2 * offset as u64) * 128 / stom as u64 + offset as u64 * 128
        };
        let angle = (deg128 as u32).wrapping_mul(93_206);
        let x = cordic_core::qrotate(halfsp, 0, angle).0;
        let v = (halfsp as i64 - x as i64).max(1) as u32;
        (clkfreq / v).min(95_000_000)
    };
    let mut delays = Vec::new();
    let mut last = delay_at(accel_steps.saturating_sub(1));
    for stepn in 0..accel_steps {
        last = delay_at(stepn);
        delays.push(last);
    }
    for _ in 0..slew_steps {
        delays.push(last);
    }
    for stepn in accel_steps..2 * accel_steps {
        delays.push(delay_at(stepn));
    }
    delays
}

#[test]
fn plans_the_design_example() {
    let p = plan(&ScurveConfig::default(), 20_000, 20_000).unwrap();
    assert_eq!(p.accel_steps, 2_002);
    assert_eq!(p.slew_steps, 15_996);
    assert_eq!(p.speed, 20_000);
    assert!(!p.short_move);
}

#[test]
fn design_example_delays() {
    // First delay at 40°: 200e6 / (20,000·(1 − cos 40°)/2) = 85,486.3 ticks.
    let smooth = steps_of(Arithmetic::Smooth, 20_000, 20_000);
    assert_eq!(smooth[0].delay_ticks, 85_486);
    assert_eq!(
        smooth[0].angle_deg().map(|a| (a * 1000.0).round()),
        Some(40_000.0)
    );
    assert_eq!(smooth[5_000].delay_ticks, 10_000);
    // The reference: halfsp = 10,000, X = round(10,000·cos 40.0004°) = 7,660,
    // v = 2,340, delay = 200e6 / 2,340 = 85,470.
    let exact = steps_of(Arithmetic::P2Exact, 20_000, 20_000);
    assert_eq!(exact[0].delay_ticks, 85_470);
    assert_eq!(exact[5_000].delay_ticks, 10_000);
    assert_eq!(exact[5_000].phase, Phase::Slew);
}

#[test]
fn fixes_the_reference_short_move_flaws() {
    let cfg = ScurveConfig::default();
    // Odd short move (ss == 1): the reference keeps 20,000 steps/s.
    let odd = plan(&cfg, 20_000, 101).unwrap();
    assert_eq!((odd.accel_steps, odd.slew_steps, odd.speed), (50, 1, 480));
    let even = plan(&cfg, 20_000, 100).unwrap();
    assert_eq!(
        (even.accel_steps, even.slew_steps, even.speed),
        (50, 0, 480)
    );
    // Moves of 1–4 steps: the reference gives speed 10·(asteps − 2) ≤ 0.
    for steps in 1..=5 {
        let p = plan(&cfg, 20_000, steps).unwrap();
        assert_eq!(p.speed, 10, "{steps} steps");
        assert!(p.short_move);
    }
    // A slow move is never sped up by the rule.
    assert_eq!(plan(&cfg, 3, 2).unwrap().speed, 3);
}

#[test]
fn every_small_move_is_sane_in_both_modes() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        for speed in [1, 2, 9, 10, 11, 100, 5_000, 50_000, 1_000_000] {
            for steps in 1..=60 {
                let p = plan(&config(arithmetic), speed, steps).unwrap();
                let all = steps_of(arithmetic, speed, steps);
                assert_eq!(all.len(), steps as usize);
                let clkfreq = 200_000_000u64;
                for step in &all {
                    assert!(step.delay_ticks >= 1);
                    assert!(step.velocity_steps_per_s > 0.0);
                    assert!(step.velocity_steps_per_s <= f64::from(p.speed) + 1e-9);
                    // No faster than asked: at most one tick of rounding.
                    // (The reference's 95,000,000-tick cap, kept by P2Exact, is
                    // faster than asked below 2.1 steps/s at 200 MHz.)
                    let capped =
                        step.delay_ticks == P2_MAX_DELAY_TICKS && arithmetic == Arithmetic::P2Exact;
                    assert!(
                        capped || u64::from(step.delay_ticks) + 1 >= clkfreq / u64::from(speed),
                        "{arithmetic:?} speed {speed} steps {steps}: {step:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn p2_exact_matches_the_reference_cog() {
    for (speed, steps, offset) in [
        (20_000, 20_000, 40),
        (1_000, 137, 30),
        (777, 4_000, 45),
        (50_000, 100_001, 40),
        (3, 17, 40),
        (25, 9, 10),
    ] {
        let cfg = ScurveConfig {
            offset_deg: offset,
            arithmetic: Arithmetic::P2Exact,
            ..ScurveConfig::default()
        };
        let p = plan(&cfg, speed, steps).unwrap();
        let delays: Vec<u32> = SCurve::new(cfg, speed, steps)
            .unwrap()
            .map(|s| s.delay_ticks)
            .collect();
        let model = reference_delays(p.speed, p.accel_steps, p.slew_steps, offset, cfg.clkfreq);
        assert_eq!(
            delays, model,
            "speed {speed}, steps {steps}, offset {offset}"
        );
    }
}

#[test]
fn smooth_edges_stay_within_a_few_ticks_of_the_ideal_curve() {
    let speed = 30_000u32;
    let steps = steps_of(Arithmetic::Smooth, speed, 50_000);
    let clkfreq = 200e6;
    let mut ideal_time = 0.0f64;
    let mut actual: u64 = 0;
    let mut worst = 0.0f64;
    for step in &steps {
        ideal_time += clkfreq / step.velocity_steps_per_s;
        actual += u64::from(step.delay_ticks);
        worst = worst.max((ideal_time - actual as f64).abs());
    }
    // Keeping the ramp's delays monotonic holds a few ticks back near the
    // top of the ramp; the carry gives them back, and nothing is lost.
    assert!(worst <= 4.0, "drift {worst} ticks");
    assert!(
        (ideal_time - actual as f64).abs() <= 1.0,
        "end drift {}",
        ideal_time - actual as f64
    );
    // The reference truncates: 200e6 / 30,000 = 6,666.67 becomes 6,666 at
    // slew (30,003 steps/s); smooth alternates 6,666 and 6,667 to average it.
    let exact = steps_of(Arithmetic::P2Exact, speed, 50_000);
    assert_eq!(exact[25_000].delay_ticks, 6_666);
    let slew: u64 = steps[20_000..20_003]
        .iter()
        .map(|s| u64::from(s.delay_ticks))
        .sum();
    assert_eq!(slew, 20_000);
}

#[test]
fn smooth_is_symmetric_and_reaches_the_requested_speed() {
    let steps = steps_of(Arithmetic::Smooth, 12_345, 10_000);
    let n = steps.len();
    for k in 0..n / 2 {
        assert_eq!(
            steps[k].velocity_steps_per_s,
            steps[n - 1 - k].velocity_steps_per_s,
            "step {k}"
        );
        assert!(steps[k].delay_ticks.abs_diff(steps[n - 1 - k].delay_ticks) <= 2);
    }
    assert_eq!(steps[n / 2].velocity_steps_per_s, 12_345.0);
    // The reference's slew reuses the last ramp delay: slightly slower than asked.
    let exact = steps_of(Arithmetic::P2Exact, 12_345, 10_000);
    assert!(exact[n / 2].velocity_steps_per_s < 12_345.0);
    // and its deceleration is one angle step early: the last step runs at the
    // velocity of the second, not the first.
    assert_ne!(exact[0].delay_ticks, exact[n - 1].delay_ticks);
    assert_eq!(exact[1].delay_ticks, exact[n - 1].delay_ticks);
}

#[test]
fn angles_run_from_offset_to_mirror() {
    let steps = steps_of(Arithmetic::Smooth, 10_000, 5_000);
    let first = steps[0].angle_deg().unwrap();
    let last = steps[steps.len() - 1].angle_deg().unwrap();
    assert!((first - 40.0).abs() < 1e-6);
    assert!((last - 320.0).abs() < 1e-6, "{last}");
    assert_eq!(steps[2_500].angle_deg(), Some(180.0));
    // The reference's 93,206 factor overshoots: 180° comes out as 180.005°.
    // The reference's 93,206 factor (2^32/46,080 truncated) is off from the start.
    let exact = steps_of(Arithmetic::P2Exact, 10_000, 5_000);
    let start = exact[0].angle_deg().unwrap();
    assert!((start - 39.999_68).abs() < 1e-5, "{start}");
}

#[test]
fn merge_adds_to_the_slew_without_slowing() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        let mut curve = SCurve::new(config(arithmetic), 10_000, 3_000).unwrap();
        let mut seen: Vec<Step> = curve.by_ref().take(1_500).collect();
        assert_eq!(seen[1_499].phase, Phase::Slew);
        curve.merge(1_000).unwrap();
        seen.extend(curve.by_ref());
        assert_eq!(seen.len(), 4_000);
        // Phases run accel → slew → decel once: no dip between the moves.
        let changes = seen.windows(2).filter(|w| w[0].phase != w[1].phase).count();
        assert_eq!(changes, 2, "{arithmetic:?}");
        assert_eq!(
            seen.iter().filter(|s| s.phase == Phase::Slew).count(),
            4_000 - 2 * 1_002
        );
    }
}

#[test]
fn merge_while_decelerating_climbs_back_from_the_current_velocity() {
    let mut curve = SCurve::new(config(Arithmetic::Smooth), 10_000, 3_000).unwrap();
    let mut seen: Vec<Step> = curve.by_ref().take(2_500).collect();
    assert_eq!(seen[2_499].phase, Phase::Decel);
    curve.merge(3_000).unwrap();
    seen.extend(curve.by_ref());
    assert_eq!(seen.len(), 6_000);
    assert_eq!(seen[2_500].phase, Phase::Accel);
    assert!(seen[2_500].velocity_steps_per_s > seen[2_499].velocity_steps_per_s);
    let bound = ramp_velocity_step(Arithmetic::Smooth, 10_000) + 1e-6;
    for w in seen.windows(2) {
        assert!((w[1].velocity_steps_per_s - w[0].velocity_steps_per_s).abs() <= bound);
    }
    assert_eq!(seen[4_000].velocity_steps_per_s, 10_000.0);
}

#[test]
fn stop_decelerates_at_once_from_every_phase_and_the_count_stays_exact() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        for stop_at in [1, 10, 500, 1_001, 1_500, 3_500, 3_990, 3_999] {
            let total = 4_000;
            let mut curve = SCurve::new(config(arithmetic), 10_000, total).unwrap();
            let before: Vec<Step> = curve.by_ref().take(stop_at).collect();
            let dropped = curve.stop();
            let after: Vec<Step> = curve.by_ref().collect();
            assert_eq!(
                before.len() + after.len() + dropped as usize,
                total as usize
            );
            // Decelerating from the next step on: velocity never rises again
            // (P2Exact's deceleration angles sit one step higher than its
            // acceleration's, as the reference's do: one ramp step of slack).
            let slack = match arithmetic {
                Arithmetic::Smooth => 1e-9,
                Arithmetic::P2Exact => ramp_velocity_step(arithmetic, 10_000),
            };
            let mut previous = before[before.len() - 1].velocity_steps_per_s;
            for step in &after {
                assert_eq!(step.phase, Phase::Decel, "{arithmetic:?} stop at {stop_at}");
                assert!(
                    step.velocity_steps_per_s <= previous + slack,
                    "{arithmetic:?} stop at {stop_at}"
                );
                previous = step.velocity_steps_per_s;
            }
            // A later move of the dropped steps completes the target.
            if dropped > 0 {
                let rest = SCurve::new(config(arithmetic), 10_000, dropped)
                    .unwrap()
                    .count();
                assert_eq!(before.len() + after.len() + rest, total as usize);
            }
        }
    }
}

#[test]
fn stop_while_accelerating_beats_the_reference() {
    // The reference finishes its 1,002-step ramp first (2,004 steps to stop);
    // cogstep turns round at once and retraces the 100 steps it climbed.
    let mut curve = SCurve::new(config(Arithmetic::Smooth), 10_000, 10_000).unwrap();
    let before = curve.by_ref().take(100).count();
    curve.stop();
    assert_eq!(curve.count() + before, 199);
}

#[test]
fn emergency_stop_ends_the_move() {
    let mut curve = SCurve::new(config(Arithmetic::Smooth), 10_000, 10_000).unwrap();
    curve.by_ref().take(10).count();
    assert_eq!(curve.estop(), 9_990);
    assert_eq!(curve.next(), None);
}

#[test]
fn speed_changes_keep_acceleration_bounded_and_count_exact() {
    for (from, to) in [(5_000u32, 20_000u32), (20_000, 5_000), (20_000, 100)] {
        let mut curve = SCurve::new(config(Arithmetic::Smooth), from, 40_000).unwrap();
        let mut seen: Vec<Step> = curve.by_ref().take(20_000).collect();
        curve.change_speed(to).unwrap();
        seen.extend(curve.by_ref());
        assert_eq!(seen.len(), 40_000);
        // A ramp starts and ends at v(offset) = 0.117·speed, not at 0: slowing
        // below the old ramp's floor drops from that floor, as a stop would.
        let floor = f64::from(from) * 0.117;
        let bound = ramp_velocity_step(Arithmetic::Smooth, from)
            .max(ramp_velocity_step(Arithmetic::Smooth, to))
            .max(if to < from { floor } else { 0.0 })
            + 1e-6;
        for (i, w) in seen.windows(2).enumerate() {
            let change = (w[1].velocity_steps_per_s - w[0].velocity_steps_per_s).abs();
            assert!(change <= bound, "{from}→{to} step {i}: {change} > {bound}");
        }
        assert!(
            seen.iter().any(|s| s.velocity_steps_per_s == f64::from(to)),
            "{from}→{to}"
        );
    }
}

#[test]
fn bad_input_is_refused() {
    let cfg = ScurveConfig::default();
    assert_eq!(plan(&cfg, 0, 10), Err(PlanError::ZeroSpeed));
    assert_eq!(plan(&cfg, 10, 0), Err(PlanError::ZeroSteps));
    assert_eq!(
        plan(&cfg, 300_000_000, 10),
        Err(PlanError::SpeedTooHigh {
            speed: 300_000_000,
            clkfreq: 200_000_000
        })
    );
    assert_eq!(
        plan(
            &ScurveConfig {
                offset_deg: 0,
                ..cfg
            },
            10,
            10
        ),
        Err(PlanError::BadOffset(0))
    );
    assert_eq!(
        plan(
            &ScurveConfig {
                offset_deg: 90,
                ..cfg
            },
            10,
            10
        ),
        Err(PlanError::BadOffset(90))
    );
    assert_eq!(
        plan(
            &ScurveConfig {
                accel_div: 0,
                ..cfg
            },
            10,
            10
        ),
        Err(PlanError::BadAccelDiv)
    );
    assert_eq!(
        plan(&ScurveConfig { clkfreq: 0, ..cfg }, 10, 10),
        Err(PlanError::ZeroClock)
    );
    let mut curve = SCurve::new(cfg, 10, 10).unwrap();
    assert_eq!(curve.merge(u32::MAX), Err(ReplanError::TooManySteps));
    assert_eq!(curve.remaining_steps(), 10);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn any_valid_move_is_well_formed(
        speed in 1u32..400_000,
        steps in 1u32..30_000,
        offset in 1u32..=89,
        clkfreq in prop_oneof![Just(200_000_000u32), 1_000_000u32..=u32::MAX],
        exact in any::<bool>(),
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let cfg = ScurveConfig { clkfreq, offset_deg: offset, accel_div: 10, arithmetic };
        prop_assume!(speed <= clkfreq);
        let p = plan(&cfg, speed, steps).unwrap();
        let all: Vec<Step> = SCurve::new(cfg, speed, steps).unwrap().collect();
        prop_assert_eq!(all.len(), steps as usize);
        for (i, step) in all.iter().enumerate() {
            prop_assert_eq!(step.index as usize, i);
            prop_assert!(step.delay_ticks >= 1);
            prop_assert!(step.velocity_steps_per_s <= f64::from(p.speed) + 1e-9);
        }
        for w in all.windows(2) {
            if w[0].phase == Phase::Accel && w[1].phase == Phase::Accel {
                prop_assert!(w[1].delay_ticks <= w[0].delay_ticks);
            }
            if w[0].phase == Phase::Decel && w[1].phase == Phase::Decel {
                prop_assert!(w[1].delay_ticks >= w[0].delay_ticks);
            }
        }
        let accel = all.iter().filter(|s| s.phase == Phase::Accel).count();
        let decel = all.iter().filter(|s| s.phase == Phase::Decel).count();
        prop_assert_eq!(accel, decel);
        if !exact {
            let n = all.len();
            for k in 0..n / 2 {
                prop_assert_eq!(all[k].velocity_steps_per_s, all[n - 1 - k].velocity_steps_per_s);
            }
        }
    }
}

#[test]
fn merging_into_a_short_move_climbs_to_the_requested_speed() {
    let mut curve = SCurve::new(config(Arithmetic::Smooth), 40_000, 50).unwrap();
    assert_eq!(curve.plan().speed, 230);
    let mut seen: Vec<Step> = curve.by_ref().take(10).collect();
    curve.merge(20_000).unwrap();
    seen.extend(curve.by_ref());
    assert_eq!(seen.len(), 20_050);
    assert!(seen.iter().any(|s| s.velocity_steps_per_s == 40_000.0));
    // No step changes velocity by more than the new ramp's own start does
    // (from rest to v(40°) = 0.117·speed).
    for w in seen.windows(2) {
        assert!(w[1].velocity_steps_per_s - w[0].velocity_steps_per_s <= 40_000.0 * 0.117);
    }
}

/// A re-planning request at some step of a move.
#[derive(Clone, Copy, Debug)]
enum Replan {
    Merge(u32),
    Stop,
    Estop,
    Speed(u32),
}

fn apply(curve: &mut SCurve, replan: Replan) {
    match replan {
        Replan::Merge(steps) => {
            let _ = curve.merge(steps);
        }
        Replan::Stop => {
            curve.stop();
        }
        Replan::Estop => {
            curve.estop();
        }
        Replan::Speed(speed) => {
            let _ = curve.change_speed(speed);
        }
    }
}

fn replan() -> impl Strategy<Value = Replan> {
    prop_oneof![
        4 => (1u32..5_000).prop_map(Replan::Merge),
        2 => Just(Replan::Stop),
        1 => Just(Replan::Estop),
        3 => (1u32..80_000).prop_map(Replan::Speed),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The slew fast path is an optimisation only: stepping through
    /// `next` gives exactly what the general path alone gives, across
    /// re-planning at any step.
    #[test]
    fn the_slew_fast_path_changes_nothing(
        speed in 1u32..100_000,
        steps in 1u32..6_000,
        clkfreq in prop_oneof![Just(200_000_000u32), 100_000u32..=u32::MAX],
        exact in any::<bool>(),
        replans in prop::collection::vec((0u32..8_000, replan()), 0..6),
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let cfg = ScurveConfig { clkfreq, arithmetic, ..ScurveConfig::default() };
        prop_assume!(speed <= clkfreq);
        let mut fast = SCurve::new(cfg, speed, steps).unwrap();
        let mut general = fast.clone();
        let mut made = 0u32;
        loop {
            for &(at, request) in &replans {
                if at == made {
                    apply(&mut fast, request);
                    apply(&mut general, request);
                }
            }
            let a = fast.next();
            let b = general.next_general();
            prop_assert_eq!(a, b);
            prop_assert_eq!(fast.velocity().to_bits(), general.velocity().to_bits());
            prop_assert_eq!(fast.remaining_steps(), general.remaining_steps());
            if a.is_none() {
                break;
            }
            made += 1;
        }
    }
}

#[test]
fn batched_cosines_give_the_scalar_timing() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        for (speed, steps) in [(50_000, 1_000_000), (7, 9), (20_000, 101), (333, 5_000)] {
            let mut curve = SCurve::new(config(arithmetic), speed, steps).unwrap();
            let asteps = curve.ramp.accel_steps;
            // Up the ramp, then down it, as a move walks it.
            let walk = (0..=asteps)
                .map(|p| (p, Phase::Accel))
                .chain((0..asteps).rev().map(|p| (p, Phase::Decel)));
            for (position, phase) in walk {
                let scalar = curve.timing(curve.ramp, position, phase);
                assert_eq!(curve.timing_batched(position, phase), scalar);
            }
        }
    }
}
