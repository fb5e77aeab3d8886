//! The short paths (slew steps, ramp runs, batched cosines, `fold`) give
//! exactly what the general path gives.

use super::*;

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

    /// The fast paths (the slew's and the ramp runs computed ahead) are an
    /// optimisation only: stepping through `next` gives exactly what the
    /// general path alone gives, across re-planning at any step, on long
    /// and short ramps.
    #[test]
    fn the_fast_paths_change_nothing(
        speed in 1u32..100_000,
        steps in 1u32..6_000,
        clkfreq in prop_oneof![Just(200_000_000u32), 100_000u32..=u32::MAX],
        exact in any::<bool>(),
        offset_deg in prop_oneof![Just(40u32), 1u32..=89],
        accel_div in prop_oneof![Just(10u32), 1u32..40],
        replans in prop::collection::vec((0u32..8_000, replan()), 0..6),
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let cfg = ScurveConfig { clkfreq, arithmetic, offset_deg, accel_div };
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

#[test]
fn fold_gives_the_steps_next_gives() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        for (speed, steps) in [(50_000, 10_004), (50_000, 1_000_000), (7, 9), (20_000, 101)] {
            let curve = SCurve::new(config(arithmetic), speed, steps).unwrap();
            // A `for` loop calls `next` (collect would go through fold).
            let mut by_next = Vec::new();
            for step in curve.clone() {
                by_next.push(step);
            }
            let mut by_fold = Vec::new();
            curve.fold((), |(), step| by_fold.push(step));
            assert_eq!(by_next, by_fold);
        }
    }
}
