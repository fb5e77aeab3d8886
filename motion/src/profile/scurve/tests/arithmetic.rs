//! Both arithmetics step by step: the delays, Smooth's accuracy and
//! symmetry, the angles, any valid move well formed, P2Exact's division and
//! Smooth's cosine bound.

use super::*;
use crate::profile::scurve::cosines::{smooth_cosines, COSINE_BLOCK};
use crate::profile::scurve::p2exact::{div_u32, p2_ramp_angles, P2_DEG128_TO_BINARY};
use crate::profile::scurve::ramp::Ramp;
use crate::profile::scurve::smooth::smooth_angle;

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

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// The 32-bit division P2Exact's delays take is QDIV's quotient.
    #[test]
    fn div_u32_is_qdiv(
        dividend in prop_oneof![any::<u32>(), Just(u32::MAX), 1u32..1_000],
        divisor in prop_oneof![1u32..=u32::MAX, 1u32..100, Just(u32::MAX)],
    ) {
        prop_assert_eq!(div_u32(dividend, divisor), cordic_core::qdiv(u64::from(dividend), divisor).0);
        // Next to exact multiples, where a rounded-up quotient would show.
        let multiple = dividend - dividend % divisor;
        for near in [multiple, multiple.saturating_sub(1), multiple.saturating_add(1)] {
            prop_assert_eq!(div_u32(near, divisor), near / divisor);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// A P2Exact cosine is the same whichever block computes it: a block
    /// of 64 (a host's fill), of 8 (a microcontroller's, `P2_FILL_KEYS`) or
    /// the key alone, each the reference's own QROTATE of that key.
    #[test]
    fn p2exact_cosines_do_not_depend_on_the_block(
        accel_steps in prop_oneof![1u32..200, 200u32..5_000_000],
        offset_deg in 1u32..=89,
        speed in 2u32..=200_000,
        key_seed in any::<u32>(),
    ) {
        let config = ScurveConfig { offset_deg, arithmetic: Arithmetic::P2Exact, ..ScurveConfig::default() };
        let ramp = Ramp::new(&config, speed, accel_steps);
        let key = key_seed % (2 * accel_steps + 1);
        let (halfsp, angle) = p2_rotation(&config, ramp, key);
        let wanted = (angle, cordic_core::qrotate(halfsp, 0, angle).0);
        for span in [COSINE_BLOCK as u32, 8, 1] {
            let first = key - key % span;
            let len = (key + 1 - first) as usize;
            let (mut angles, mut cosines) = ([0; COSINE_BLOCK], [0; COSINE_BLOCK]);
            let radius = p2_ramp_angles(&config, ramp, first, &mut angles[..len]);
            cordic_core::cos_batch(radius, &angles[..len], &mut cosines[..len]);
            prop_assert_eq!((angles[len - 1], cosines[len - 1]), wanted, "span {}", span);
        }
    }

    /// Smooth's cosines from the second-order recurrence are within 0.51 LSB
    /// (of 2^30) of the cosine of the exact ramp angle, at every key of
    /// every block (the bound proved at `smooth_cosines`).
    #[test]
    fn smooth_cosines_stay_within_their_bound(
        accel_steps in prop_oneof![1u32..200, 200u32..5_000_000],
        offset_deg in 1u32..=89,
        block in 0u32..1_000,
    ) {
        let config = ScurveConfig { offset_deg, ..ScurveConfig::default() };
        let ramp = Ramp::new(&config, 50_000, accel_steps);
        let blocks = accel_steps.div_ceil(COSINE_BLOCK as u32);
        let first = (block % blocks) * COSINE_BLOCK as u32;
        let len = (accel_steps - first).min(COSINE_BLOCK as u32) as usize;
        let (mut angles, mut cosines) = ([0; COSINE_BLOCK], [0; COSINE_BLOCK]);
        smooth_cosines(&config, ramp, first, &mut angles[..len], &mut cosines[..len]);
        for (k, &cosine) in (first..).zip(&cosines[..len]) {
            let degrees = f64::from(offset_deg)
                + f64::from(k) * f64::from(180 - offset_deg) / f64::from(accel_steps);
            let exact = degrees.to_radians().cos() * f64::from(1u32 << 30);
            prop_assert!((f64::from(cosine) - exact).abs() <= 0.51, "key {} of {}: {} vs {}", k, accel_steps, cosine, exact);
            prop_assert_eq!(angles[(k - first) as usize], smooth_angle(offset_deg, accel_steps, k));
        }
    }
}

/// The reference's rotation of a cosine key (its `stom`, `deg128` and
/// `halfsp`), written out apart from the crate's: (radius, binary angle).
fn p2_rotation(config: &ScurveConfig, ramp: Ramp, key: u32) -> (i32, u32) {
    let offset = config.offset_deg;
    let stom = 2 * u64::from(ramp.accel_steps);
    let deg128 = (u64::from(key) * u64::from(360 - 2 * offset) * 128 / stom) as u32 + offset * 128;
    (
        (ramp.speed / 2) as i32,
        deg128.wrapping_mul(P2_DEG128_TO_BINARY),
    )
}
