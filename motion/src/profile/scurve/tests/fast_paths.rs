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

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// A P2Exact stop decelerates on ramp runs, and its steps are the
    /// general path's: no step faster than the one before (the stop's
    /// rule, where it binds, a step of the general path), whenever the
    /// stop comes (accelerating, at speed, decelerating already) and
    /// whatever follows it (a merge lifting the rule, a second stop).
    #[test]
    fn p2exact_stops_run_ahead_and_change_nothing(
        speed in 20u32..100_000,
        steps in 50u32..8_000,
        clkfreq in prop_oneof![Just(200_000_000u32), 100_000u32..=u32::MAX],
        offset_deg in prop_oneof![Just(40u32), 1u32..=89],
        accel_div in prop_oneof![Just(10u32), 1u32..40],
        stop_at in 0u32..8_000,
        then in prop::option::of((1u32..400, prop_oneof![
            (1u32..3_000).prop_map(Replan::Merge),
            Just(Replan::Stop),
        ])),
    ) {
        let cfg = ScurveConfig { clkfreq, arithmetic: Arithmetic::P2Exact, offset_deg, accel_div };
        prop_assume!(speed <= clkfreq);
        let mut fast = SCurve::new(cfg, speed, steps).unwrap();
        let mut general = fast.clone();
        let mut made = 0u32;
        let (mut after_stop, mut on_runs) = (0u32, 0u32);
        let mut stopped = false;
        loop {
            if made == stop_at {
                fast.stop();
                general.stop();
                stopped = true;
            }
            if let Some((later, request)) = then {
                if stopped && made == stop_at + later {
                    apply(&mut fast, request);
                    apply(&mut general, request);
                }
            }
            let on_run = fast.ramp_span().is_some();
            let a = fast.next();
            let b = general.next_general();
            prop_assert_eq!(a, b);
            prop_assert_eq!(fast.velocity().to_bits(), general.velocity().to_bits());
            prop_assert_eq!(fast.remaining_steps(), general.remaining_steps());
            let Some(step) = a else { break };
            if stopped && then.is_none() {
                after_stop += 1;
                on_runs += u32::from(on_run);
                prop_assert!(step.phase == Phase::Decel, "{:?} after a stop", step);
            }
            made += 1;
        }
        // Not vacuous: a stop's deceleration is mostly runs (each phase's
        // first step and the rule's are the general path's).
        if after_stop >= 100 {
            prop_assert!(
                on_runs * 10 >= after_stop * 8,
                "{} of {} steps after the stop on runs", on_runs, after_stop
            );
        }
    }
}

/// Where a P2Exact stop's rule binds after a run was armed (the property
/// test above found these: the step after the stop's first is one unit
/// of velocity faster than it), the run ends before that step and the
/// general path holds it: the steps are the general path's, and the held
/// step keeps the delay of the one before.
#[test]
fn p2exact_stop_rule_holds_a_step_a_run_would_speed_up() {
    let cases = [
        // (offset°, accel_div, clkfreq, speed, steps, stop at)
        (37, 34, 200_000_000, 3_522, 3_829, 924),
        (40, 27, 200_000_000, 2_089, 7_841, 1_543),
        (63, 37, 2_092_432_974, 2_744, 2_982, 1_326),
    ];
    for (offset_deg, accel_div, clkfreq, speed, steps, stop_at) in cases {
        let arithmetic = Arithmetic::P2Exact;
        let cfg = ScurveConfig {
            clkfreq,
            arithmetic,
            offset_deg,
            accel_div,
        };
        let mut fast = SCurve::new(cfg, speed, steps).unwrap();
        let mut general = fast.clone();
        let mut made = 0;
        let mut held = 0;
        let mut previous: Option<Step> = None;
        loop {
            if made == stop_at {
                fast.stop();
                general.stop();
            }
            let (a, b) = (fast.next(), general.next_general());
            assert_eq!(a, b, "{cfg:?} {speed} steps/s, step {made}");
            let Some(step) = a else { break };
            if let Some(before) = previous.filter(|_| made > stop_at) {
                assert!(step.velocity_steps_per_s <= before.velocity_steps_per_s);
                held += u32::from(step.delay_ticks == before.delay_ticks);
            }
            previous = Some(step);
            made += 1;
        }
        assert!(held > 0, "{cfg:?}: the rule never held a step");
    }
}

/// A helper core as the owner sees it: one request out at a time, its
/// answer ready `latency` steps after it was posted. Its two rooms (the
/// request's and the answer's) are reused from one request to the next,
/// as a board's slot reuses them: each copy into them leaves the dead
/// entries of the one before.
#[derive(Default)]
struct Helper {
    from: Option<SCurve>,
    ahead: Option<SCurve>,
    /// A request is out.
    out: bool,
    armed: bool,
    ready_at: u32,
    key: Option<u32>,
}

impl Helper {
    /// Steps `curve` once as a board with a second core would: before the
    /// step, takes the helper's run if its prediction came true (else
    /// drops it); after it, posts the armed run's end. Returns the step
    /// and whether a run was taken.
    fn step(&mut self, curve: &mut SCurve, made: u32, latency: u32) -> (Option<Step>, bool) {
        let mut adopted = false;
        if self.out && self.ready_at <= made {
            let used_up = curve.run.len > 0 && curve.run.next == curve.run.len;
            if used_up || curve.run_end_index() != self.key {
                if used_up && self.armed {
                    let (from, ahead) = (self.from.as_ref(), self.ahead.as_ref());
                    adopted = curve.adopt_run_ahead(from.unwrap(), ahead.unwrap());
                }
                self.out = false;
            }
        }
        let step = curve.next();
        if !self.out && curve.run_ahead_from(&mut self.from) {
            let from = self.from.as_ref().unwrap();
            self.armed = SCurve::arm_run_ahead_from(from, &mut self.ahead);
            self.out = true;
            self.ready_at = made + 1 + latency;
            self.key = curve.run_end_index();
        }
        (step, adopted)
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Ramp runs computed ahead by another core (the Pico's core 1) and
    /// taken when their prediction came true change nothing: the steps are
    /// the ones the curve computes alone, across re-planning at any step
    /// and a helper that answers at once or late (after the run it was
    /// for, whose answer is then dropped).
    #[test]
    fn runs_computed_ahead_change_nothing(
        speed in 1u32..100_000,
        steps in 1u32..6_000,
        exact in any::<bool>(),
        latency in prop_oneof![Just(0u32), 0u32..80],
        replans in prop::collection::vec((0u32..8_000, replan()), 0..6),
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let mut helped = SCurve::new(config(arithmetic), speed, steps).unwrap();
        let mut alone = helped.clone();
        let mut helper = Helper::default();
        let mut made = 0u32;
        loop {
            for &(at, request) in &replans {
                if at == made {
                    apply(&mut helped, request);
                    apply(&mut alone, request);
                }
            }
            let (a, _) = helper.step(&mut helped, made, latency);
            let b = alone.next();
            prop_assert_eq!(a, b);
            prop_assert_eq!(helped.velocity().to_bits(), alone.velocity().to_bits());
            prop_assert_eq!(helped.remaining_steps(), alone.remaining_steps());
            if a.is_none() {
                break;
            }
            made += 1;
        }
    }
}

/// With nothing re-planned and a helper that answers at once, every run
/// after the first comes from the helper; a re-plan between a prediction
/// and its use makes the curve refuse the run (and compute its own).
#[test]
fn runs_computed_ahead_are_taken_when_right_and_refused_after_a_replan() {
    for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
        let mut curve = SCurve::new(config(arithmetic), 20_000, 10_000).unwrap();
        let mut helper = Helper::default();
        let mut made = 0;
        let mut adopted = 0;
        loop {
            let (step, taken) = helper.step(&mut curve, made, 0);
            adopted += u32::from(taken);
            if step.is_none() {
                break;
            }
            made += 1;
        }
        // 2,002 ramp steps each side, runs of up to RUN_STEPS.
        let runs = 2 * 2_002 / super::super::runs::RUN_STEPS as u32;
        assert!(
            adopted + 8 >= runs,
            "{arithmetic:?}: {adopted} of about {runs} runs taken"
        );

        // A prediction, then a merge: refused; the curve's own run is the same.
        let mut curve = SCurve::new(config(arithmetic), 20_000, 10_000).unwrap();
        let mut alone = curve.clone();
        while curve.run.len == 0 {
            assert_eq!(curve.next(), alone.next());
        }
        let mut from = Some(curve.clone());
        assert!(curve.run_ahead_from(&mut from));
        let from = from.unwrap();
        let mut ahead = from.clone();
        assert!(ahead.arm_run_ahead());
        curve.merge(100).unwrap();
        alone.merge(100).unwrap();
        // Up to where a run is used up again: the state is not `from`.
        loop {
            assert_eq!(curve.next(), alone.next());
            if curve.run.len > 0 && curve.run.next == curve.run.len {
                break;
            }
        }
        assert_ne!(curve, from);
        assert!(!curve.adopt_run_ahead(&from, &ahead));
        for _ in 0..200 {
            assert_eq!(curve.next(), alone.next());
        }
    }
}

/// The hand-written copies and comparisons (a board's core 1 hands curves
/// back and forth): a copy is equal, and a word changed anywhere in a
/// run's or a block's arrays makes two curves differ.
#[test]
fn curves_copy_whole_and_compare_every_word() {
    let mut curve = SCurve::new(config(Arithmetic::Smooth), 20_000, 10_000).unwrap();
    for _ in 0..100 {
        curve.next();
    }
    assert!(curve.run.len > 0 && curve.cosines.len > 0);
    let copy = curve.clone();
    assert_eq!(copy, curve);
    let mut into = SCurve::new(config(Arithmetic::P2Exact), 5, 7).unwrap();
    into.clone_from(&curve);
    assert_eq!(into, curve);
    for i in 0..super::super::runs::RUN_STEPS {
        let mut changed = curve.clone();
        changed.run.delay_ticks[i] ^= 1 << (i % 32);
        assert_ne!(changed, curve, "run entry {i}");
    }
    for i in 0..super::super::cosines::COSINE_BLOCK {
        let mut changed = curve.clone();
        changed.cosines.cosines[i] ^= 1 << (i % 32);
        assert_ne!(changed, curve, "cosine {i}");
        let mut changed = curve.clone();
        changed.cosines.angles[i] = changed.cosines.angles[i].wrapping_add(1);
        assert_ne!(changed, curve, "angle {i}");
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
