//! Re-planning a move in progress: merge, stop, emergency stop and speed
//! change.

use super::*;

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
            // and no delay is shorter than the one before it.
            let mut previous = before[before.len() - 1];
            for step in &after {
                assert_eq!(step.phase, Phase::Decel, "{arithmetic:?} stop at {stop_at}");
                assert!(
                    step.velocity_steps_per_s <= previous.velocity_steps_per_s
                        && step.delay_ticks >= previous.delay_ticks,
                    "{arithmetic:?} stop at {stop_at}: {previous:?} then {step:?}"
                );
                previous = *step;
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

/// The plain bisection `switch_ramp` used before the block-aware search:
/// every probe one [`SCurve::delay_at`] (in Smooth, up to 64 cosines each).
fn last_position_not_faster_by_bisection(
    curve: &SCurve,
    ramp: super::super::ramp::Ramp,
    current: u64,
) -> u32 {
    if curve.delay_at(ramp, 0, Phase::Accel) < current {
        return 0;
    }
    let (mut low, mut high) = (0u32, ramp.accel_steps);
    while low < high {
        let mid = low + (high - low).div_ceil(2);
        if curve.delay_at(ramp, mid, Phase::Accel) >= current {
            low = mid;
        } else {
            high = mid - 1;
        }
    }
    low
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The block-aware search finds exactly the position the plain
    /// bisection finds, for delays on, between and beyond a ramp's own.
    #[test]
    fn the_block_aware_ramp_search_is_the_plain_bisection(
        arithmetic in prop::sample::select(vec![Arithmetic::Smooth, Arithmetic::P2Exact]),
        speed in 10u32..60_000,
        probes in prop::collection::vec((0u32..70_000, -2i64..=2), 1..12),
    ) {
        let config = config(arithmetic);
        let curve = SCurve::new(config, speed, 1_000_000).unwrap();
        let accel_steps = speed / config.accel_div + 2;
        let ramp = super::super::ramp::Ramp::new(&config, speed, accel_steps);
        for (position, nudge) in probes {
            let position = position % (accel_steps + 2);
            let current = curve
                .delay_at(ramp, position, Phase::Accel)
                .saturating_add_signed(nudge);
            prop_assert_eq!(
                curve.last_position_not_faster(ramp, current),
                last_position_not_faster_by_bisection(&curve, ramp, current),
                "speed {}, position {}, nudge {}", speed, position, nudge
            );
        }
        for current in [0, 1, u64::MAX] {
            prop_assert_eq!(
                curve.last_position_not_faster(ramp, current),
                last_position_not_faster_by_bisection(&curve, ramp, current)
            );
        }
    }
}
