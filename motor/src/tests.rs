//! The rotor model against physics: natural frequency and damping, resonance,
//! the dead band friction leaves, loss of synchronism, symmetry.

use core::f64::consts::PI;

use proptest::prelude::*;

use super::*;
use cogstep_motion::profile::Profile;
use cogstep_ramps::trapezoid::Trapezoid;

const CLKFREQ: u32 = 200_000_000;

fn motor(
    step_deg: f64,
    phases: u8,
    inertia: f64,
    damping: f64,
    load: f64,
    hold: f64,
) -> MotorParams {
    MotorParams::new(step_deg, phases, inertia, damping, load, hold).unwrap()
}

/// A 2-phase 1.8° motor with damping ratio `zeta` and no friction.
fn ringing_motor(zeta: f64) -> MotorParams {
    let (inertia, hold): (f64, f64) = (1e-4, 0.5);
    let stiffness = 50.0 * hold;
    let damping = zeta * 2.0 * (stiffness * inertia).sqrt();
    motor(1.8, 2, inertia, damping, 0.0, hold)
}

/// The error (steps) every `dt` seconds for `duration` seconds.
fn record<C: PullOutCurve>(rotor: &mut Rotor<C>, dt: f64, duration: f64) -> Vec<(f64, f64)> {
    let start = rotor.time_s();
    let mut samples = vec![(0.0, rotor.error_steps())];
    let mut t = 0.0;
    while t < duration {
        t += dt;
        rotor.run_until(start + t);
        samples.push((t, rotor.error_steps()));
    }
    samples
}

/// Times of the downward zero crossings (linear between samples) once the
/// swing is below `amplitude` steps, and the peaks between them.
fn crossings(samples: &[(f64, f64)], amplitude: f64) -> (Vec<f64>, Vec<f64>) {
    let mut times = Vec::new();
    let mut peaks = Vec::new();
    let mut peak = 0.0f64;
    for pair in samples.windows(2) {
        let ((t0, e0), (t1, e1)) = (pair[0], pair[1]);
        peak = peak.max(e1.abs());
        if e0 > 0.0 && e1 <= 0.0 {
            if peak < amplitude {
                times.push(t0 + (t1 - t0) * e0 / (e0 - e1));
                peaks.push(peak);
            }
            peak = 0.0;
        }
    }
    (times, peaks)
}

/// Frequency (Hz) and damping ratio measured from a single step's ringing.
fn ring(params: MotorParams) -> (f64, f64) {
    let mut rotor = Rotor::new(params, ConstantTorque(params.holding_torque_nm));
    rotor.step(true);
    let f_n = params.natural_frequency_hz();
    let samples = record(&mut rotor, 1.0 / (f_n * 400.0), 60.0 / f_n);
    // Small swings only: a full step is a 90° electrical swing, where the
    // pendulum's period is 18 % longer than the small-oscillation one.
    let (times, peaks) = crossings(&samples, 0.1);
    assert!(times.len() >= 6, "{} crossings", times.len());
    let periods = (times.len() - 1) as f64;
    let frequency = periods / (times[times.len() - 1] - times[0]);
    // Peak ratio over one period: the logarithmic decrement.
    let decrement = (peaks[1] / peaks[peaks.len() - 1]).ln() / (peaks.len() - 2) as f64;
    let zeta = decrement / (4.0 * PI * PI + decrement * decrement).sqrt();
    (frequency, zeta)
}

#[test]
fn a_single_step_rings_at_the_natural_frequency_with_the_damping_given() {
    for zeta in [0.02, 0.05, 0.1] {
        let params = ringing_motor(zeta);
        assert!((params.damping_ratio() - zeta).abs() < 1e-12);
        let (frequency, measured_zeta) = ring(params);
        let expected = params.natural_frequency_hz() * (1.0 - zeta * zeta).sqrt();
        assert!(
            (frequency / expected - 1.0).abs() < 0.02,
            "ζ {zeta}: {frequency} Hz, expected {expected} Hz"
        );
        assert!(
            (measured_zeta / zeta - 1.0).abs() < 0.05,
            "ζ {zeta}: measured {measured_zeta}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any motor: 2- or 5-phase, inertia and torque over two decades.
    #[test]
    fn natural_frequency_holds_for_any_motor(
        five_phase in any::<bool>(),
        inertia in 1e-6f64..1e-3,
        hold in 0.05f64..5.0,
        zeta in 0.01f64..0.1,
    ) {
        let (step, phases) = if five_phase { (0.72, 5) } else { (1.8, 2) };
        let stiffness = motor(step, phases, 1.0, 0.0, 0.0, 1.0).electrical_factor() * hold;
        let damping = zeta * 2.0 * (stiffness * inertia).sqrt();
        let params = motor(step, phases, inertia, damping, 0.0, hold);
        let (frequency, _) = ring(params);
        let expected = params.natural_frequency_hz() * (1.0 - zeta * zeta).sqrt();
        prop_assert!((frequency / expected - 1.0).abs() < 0.02, "{} vs {}", frequency, expected);
    }

    /// Gentle moves on the lecture's load (a strong motor, ramps well within
    /// its torque): synchronism holds, the rotor never falls a step behind
    /// between edges, and it comes to rest within the friction's dead band.
    #[test]
    fn gentle_moves_keep_synchronism_and_end_in_the_dead_band(
        steps in 1u32..600,
        speed in 50f64..1_500.0,
        accel in 1_000f64..8_000.0,
    ) {
        let hold = 0.75;
        let mut rotor = lecture_rotor(hold);
        for step in Trapezoid::new(CLKFREQ, speed, accel, steps).unwrap() {
            rotor.step(true);
            rotor.run_for(f64::from(step.delay_ticks) / f64::from(CLKFREQ));
            prop_assert!(rotor.error_steps().abs() < 1.0, "{}", rotor.error_steps());
        }
        rotor.settle();
        prop_assert_eq!(rotor.lost_at_step(), None);
        let dead_band_steps = (0.3f64 / hold).asin() / (PI / 2.0);
        prop_assert!(rotor.error_steps().abs() <= dead_band_steps + 1e-3, "{}", rotor.error_steps());
    }

    /// Mirror a move and the rotor mirrors.
    #[test]
    fn reverse_moves_mirror_forward_ones(steps in 1u32..400, speed in 100f64..3_000.0) {
        let params = motor(1.8, 2, 8.5e-5, 0.005, 0.1, 0.5);
        let mut forward = Rotor::new(params, ConstantTorque(0.5));
        let mut reverse = Rotor::new(params, ConstantTorque(0.5));
        for step in Trapezoid::new(CLKFREQ, speed, 20_000.0, steps).unwrap() {
            let dt = f64::from(step.delay_ticks) / f64::from(CLKFREQ);
            forward.step(true);
            forward.run_for(dt);
            reverse.step(false);
            reverse.run_for(dt);
            prop_assert_eq!(forward.error_steps(), -reverse.error_steps());
        }
        prop_assert_eq!(forward.lost_at_step(), reverse.lost_at_step());
    }
}

/// Steps at a constant rate from rest; the largest |error| in the second
/// half of the run, steps.
fn swing_at_rate(params: MotorParams, rate: f64, seconds: f64) -> (f64, bool) {
    let mut rotor = Rotor::new(params, ConstantTorque(params.holding_torque_nm));
    let steps = (rate * seconds) as u32;
    let mut largest = 0.0f64;
    for index in 0..steps {
        rotor.step(true);
        // Sample within the interval too: the swing peaks between edges.
        for _ in 0..8 {
            rotor.run_for(1.0 / rate / 8.0);
            if index >= steps / 2 {
                largest = largest.max(rotor.error_steps().abs());
            }
        }
    }
    (largest, rotor.lost_at_step().is_none())
}

#[test]
fn stepping_near_the_natural_frequency_resonates() {
    // Damped enough to stay synchronous everywhere: the swing at f_n is
    // well above the swing below and above it.
    let params = ringing_motor(0.1);
    let f_n = params.natural_frequency_hz();
    let (at_resonance, synchronous) = swing_at_rate(params, f_n, 2.0);
    assert!(synchronous);
    for away in [0.6, 2.0, 3.0] {
        let (swing, synchronous) = swing_at_rate(params, f_n * away, 2.0);
        assert!(synchronous, "{away}·f_n keeps synchronism");
        assert!(
            at_resonance > 1.5 * swing,
            "at f_n the swing is {at_resonance} steps, at {away}·f_n {swing}"
        );
    }
    // Lightly damped, resonance loses the rotor; away from it, it keeps.
    let light = ringing_motor(0.02);
    assert!(!swing_at_rate(light, f_n, 2.0).1, "lost at f_n");
    for away in [2.0, 3.0] {
        assert!(
            swing_at_rate(light, f_n * away, 2.0).1,
            "kept at {away}·f_n"
        );
    }
}

/// The lecture's load on a motor with `hold` N·m at every rate (and little
/// damping: 1e-4 N·m·s/rad drags 0.013 N·m at 4,000 steps/s).
fn lecture_rotor(hold: f64) -> Rotor<ConstantTorque> {
    Rotor::new(motor(1.8, 2, 8.5e-5, 1e-4, 0.3, hold), ConstantTorque(hold))
}

fn run_trapezoid<C: PullOutCurve>(rotor: &mut Rotor<C>, speed: f64, accel: f64, steps: u32) {
    for step in Trapezoid::new(CLKFREQ, speed, accel, steps).unwrap() {
        rotor.step(true);
        rotor.run_for(f64::from(step.delay_ticks) / f64::from(CLKFREQ));
    }
}

#[test]
fn a_synchronous_move_ends_within_the_friction_dead_band() {
    let hold = 0.6;
    let mut rotor = lecture_rotor(hold);
    run_trapezoid(&mut rotor, 4_000.0, 20_000.0, 2_000);
    rotor.settle();
    assert_eq!(rotor.lost_at_step(), None);
    assert_eq!(rotor.command_steps(), 2_000);
    // Friction holds the rotor where sin(N·error) ≤ T_load / T_h.
    let dead_band_steps = (0.3f64 / hold).asin() / (PI / 2.0);
    let error = rotor.error_steps();
    assert!(
        error.abs() <= dead_band_steps + 1e-3,
        "{error} > {dead_band_steps}"
    );
    assert!(error.abs() < 0.5);
    assert_eq!(rotor.sample().velocity_steps_per_s, 0.0, "at rest");

    // Without friction (nor the load's inertia, which on this light damping
    // would ring up at the first steps) the damping brings it home.
    let params = motor(1.8, 2, 2.5e-5, 0.002, 0.0, hold);
    let mut free = Rotor::new(params, ConstantTorque(hold));
    run_trapezoid(&mut free, 4_000.0, 20_000.0, 2_000);
    free.settle();
    assert_eq!(free.lost_at_step(), None);
    assert!(free.error_steps().abs() < 0.01, "{}", free.error_steps());
}

#[test]
fn a_load_beyond_the_torque_loses_synchronism_for_good() {
    // 0.3 N·m of friction against 0.25 N·m: the first steps pile up.
    let mut rotor = lecture_rotor(0.25);
    run_trapezoid(&mut rotor, 4_000.0, 20_000.0, 2_000);
    let lost = rotor.lost_at_step().expect("lost");
    assert!(lost < 10, "lost at step {lost}");
    rotor.settle();
    assert!(rotor.error_steps() > 100.0, "{}", rotor.error_steps());
    assert!(!rotor.sample().synchronous);
    // Re-homing accepts where the rotor is.
    rotor.rehome();
    assert!(rotor.sample().synchronous);
    assert!(rotor.error_steps().abs() <= 0.5);
}

#[test]
fn an_edge_that_puts_the_field_half_a_cycle_ahead_is_a_loss() {
    // Two steps at once on a 2-phase motor: exactly half a cycle, not lost;
    // a third is beyond it.
    let mut rotor = lecture_rotor(0.5);
    rotor.step(true);
    rotor.step(true);
    assert_eq!(rotor.lost_at_step(), None);
    rotor.step(true);
    assert_eq!(rotor.lost_at_step(), Some(2));
}

#[test]
fn the_five_phase_motor_has_fifty_pole_pairs_and_a_five_step_limit() {
    let params = motor(0.72, 5, 1e-4, 0.0, 0.0, 1.0);
    assert!((params.electrical_factor() - 50.0).abs() < 1e-9);
    assert_eq!(params.sync_limit_steps(), 5.0);
    let two = motor(1.8, 2, 1e-4, 0.0, 0.0, 1.0);
    assert!((two.electrical_factor() - 50.0).abs() < 1e-9);
    assert_eq!(two.sync_limit_steps(), 2.0);
}

#[test]
fn bad_figures_are_refused() {
    assert_eq!(
        MotorParams::new(0.0, 2, 1e-4, 0.0, 0.0, 1.0),
        Err(MotorError::BadStepAngle(0.0))
    );
    assert_eq!(
        MotorParams::new(1.8, 1, 1e-4, 0.0, 0.0, 1.0),
        Err(MotorError::BadPhases(1))
    );
    assert!(matches!(
        MotorParams::new(1.8, 2, f64::NAN, 0.0, 0.0, 1.0),
        Err(MotorError::BadInertia(_))
    ));
    assert!(matches!(
        MotorParams::new(1.8, 2, 1e-4, -1.0, 0.0, 1.0),
        Err(MotorError::BadDamping(_))
    ));
    assert!(matches!(
        MotorParams::new(1.8, 2, 1e-4, 0.0, f64::INFINITY, 1.0),
        Err(MotorError::BadLoadTorque(_))
    ));
    assert!(matches!(
        MotorParams::new(1.8, 2, 1e-4, 0.0, 0.0, 0.0),
        Err(MotorError::BadHoldingTorque(_))
    ));
    // A rotor that would ring at megahertz is a typo, not a motor.
    assert!(matches!(
        MotorParams::new(1.8, 2, 1e-15, 0.0, 0.0, 1.0),
        Err(MotorError::TooStiff(_))
    ));
    // Time that does not move forward changes nothing.
    let mut rotor = lecture_rotor(0.5);
    rotor.step(true);
    let before = rotor.sample();
    for duration in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        rotor.run_for(duration);
    }
    assert_eq!(rotor.sample(), before);
}

#[test]
fn the_curve_interpolates_holds_and_extrapolates_down_to_zero() {
    let points = [(0.0, 0.6), (4_000.0, 0.4), (8_000.0, 0.2)];
    let curve = TorquePoints::new(&points);
    assert_eq!(curve.pull_out_nm(0.0), 0.6);
    assert!((curve.pull_out_nm(2_000.0) - 0.5).abs() < 1e-12);
    assert!((curve.pull_out_nm(-6_000.0) - 0.3).abs() < 1e-12);
    assert!((curve.pull_out_nm(10_000.0) - 0.1).abs() < 1e-12);
    assert_eq!(curve.pull_out_nm(20_000.0), 0.0);
    assert!((curve.derated(2.0).pull_out_nm(4_000.0) - 0.2).abs() < 1e-12);
    let late = [(1_000.0, 0.5)];
    assert_eq!(TorquePoints::new(&late).pull_out_nm(0.0), 0.5);
    assert_eq!(TorquePoints::new(&late).pull_out_nm(9e9), 0.5);
}

#[test]
fn the_step_rate_follows_the_edges_and_falls_when_they_stop() {
    let mut rotor = lecture_rotor(0.5);
    assert_eq!(rotor.step_rate(), 0.0);
    rotor.step(true);
    rotor.run_for(1e-3);
    assert_eq!(rotor.step_rate(), 0.0, "one edge: no rate yet");
    rotor.step(true);
    rotor.run_for(0.5e-3);
    assert!((rotor.step_rate() - 1_000.0).abs() < 1e-6);
    rotor.run_for(1.5e-3);
    assert!((rotor.step_rate() - 500.0).abs() < 1e-6);
}

#[test]
fn a_profile_drives_it_through_the_trait() {
    // Any Profile works: what the export and the demo do.
    let mut profile = Trapezoid::new(CLKFREQ, 2_000.0, 10_000.0, 100).unwrap();
    assert_eq!(profile.remaining_steps(), 100);
    let mut rotor = lecture_rotor(0.6);
    for step in profile.by_ref() {
        rotor.step(true);
        rotor.run_for(f64::from(step.delay_ticks) / f64::from(CLKFREQ));
    }
    assert_eq!(rotor.steps_seen(), 100);
    assert!(rotor.sample().synchronous);
}
