//! P2Exact against models of the reference cog: the design text's, and the
//! driver's Spin2 and PASM with their flaws; the step period on the board.

use super::*;

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

/// The reference driver (`Step_driver2_sd.spin2`), written out from its
/// Spin2 `move` and its PASM cog with the registers' own widths: the model
/// P2Exact is checked against, flaws included.
mod reference {
    extern crate std;
    use std::vec::Vec;

    use cordic_core::{qdiv, qmul, qrotate};

    /// `move(sp, st)`: (speed written to the hub, asteps), in Spin2's
    /// signed 32-bit arithmetic.
    pub fn plan(sp: i32, st: i32) -> (i32, i32) {
        let mut asteps = sp / 10 + 2;
        let t = (st / 2).abs();
        if asteps > t {
            asteps = t;
        }
        let ss = st.abs() - asteps * 2;
        let sp = if ss == 0 { 10 * (asteps - 2) } else { sp };
        (sp, asteps)
    }

    /// The cog's registers that matter for timing.
    pub struct Cog {
        pub steps: u32,
        pub xsteps: u32,
        pub stepn: u32,
        pub stom: u32,
        astps: u32,
        halfsp: u32,
        newmin: u32,
        newrange: u32,
        freq: u32,
        at_speed: bool,
        delay: u32,
    }

    impl Cog {
        /// The cog once it has taken the command (`_setup`).
        pub fn new(speed: i32, steps: i32, asteps: i32, offset: u32, freq: u32) -> Self {
            let steps = steps.unsigned_abs(); // abs steps wc
            let astps = asteps as u32;
            let (mut stom, mut xsteps) = (steps, 0);
            let t3 = astps << 1;
            if t3 < stom {
                xsteps = steps - t3;
                stom = t3;
            }
            Self {
                steps,
                xsteps,
                stepn: 0,
                stom,
                astps,
                halfsp: (speed as u32) >> 1, // shr: a logical shift
                newmin: offset << 7,
                newrange: 360 - 2 * offset,
                freq,
                at_speed: false,
                delay: 1,
            }
        }

        /// `_getdelay`, register by register. QDIV by 0 gives cordic-core's
        /// defined result; `fges`/`fles` compare signed.
        fn getdelay(&mut self) -> u32 {
            let t1 = qmul(self.stepn, self.newrange).0 << 7;
            let newvalue = qdiv(u64::from(t1), self.stom).0.wrapping_add(self.newmin);
            let angle = qmul(newvalue, 93_206).0;
            let x = qrotate(self.halfsp as i32, 0, angle).0 as u32;
            let t2 = (self.halfsp.wrapping_sub(x) as i32).max(1) as u32;
            let delay = qdiv(u64::from(self.freq), t2).0;
            (delay as i32).min(95_000_000) as u32
        }

        /// `_dostep` after the wait: `None` when no step is left, else the
        /// delay to the next step.
        fn dostep(&mut self) -> Option<u32> {
            if self.steps == 0 {
                return None;
            }
            if self.at_speed {
                self.xsteps = self.xsteps.wrapping_sub(1);
            } else {
                self.delay = self.getdelay();
            }
            self.steps = self.steps.wrapping_sub(1);
            if !self.at_speed {
                self.stepn += 1;
            }
            Some(self.delay)
        }

        /// Runs the move: the delay after each step, at most `limit` steps;
        /// the stop pin goes low after step `stop_after` (`_mainloop`).
        pub fn run(&mut self, limit: usize, stop_after: Option<usize>) -> Vec<u32> {
            let mut delays = Vec::new();
            while delays.len() < limit {
                let Some(delay) = self.dostep() else { break };
                delays.push(delay);
                if stop_after == Some(delays.len()) {
                    self.steps = self.steps.wrapping_sub(self.xsteps);
                    self.xsteps = 0;
                }
                if self.astps == self.stepn {
                    // _mlp2 (no second command pending) / _mlp3.
                    self.at_speed = self.xsteps != 0;
                }
            }
            delays
        }
    }

    /// The delays of a whole move `move(sp, st)` as the reference makes them.
    pub fn delays(sp: i32, st: i32, offset: u32, freq: u32) -> Vec<u32> {
        let (speed, asteps) = plan(sp, st);
        Cog::new(speed, st, asteps, offset, freq).run(usize::MAX, None)
    }
}

#[test]
fn the_reference_model_agrees_with_the_design_model() {
    for (speed, steps) in [(20_000, 20_000), (1_000, 137), (3, 17), (50_000, 100_001)] {
        let (sp, asteps) = reference::plan(speed, steps);
        let ss = steps - 2 * asteps;
        let design = reference_delays(sp as u32, asteps as u32, ss as u32, 40, 200_000_000);
        assert_eq!(reference::delays(speed, steps, 40, 200_000_000), design);
    }
}

#[test]
fn p2_exact_rounds_the_speed_down_as_the_reference_does() {
    // |st| = 2·(sp/10 + 2): never capped, but ss == 0 still lowers sp to
    // 10·(asteps − 2), a multiple of 10.
    for (speed, steps, lowered, first_delay) in [
        (1_009, 204, 1_000, Some(1_709_401)),
        (25, 8, 20, Some(95_000_000)),
        (20_003, 4_004, 20_000, None),
    ] {
        let exact = plan(&config(Arithmetic::P2Exact), speed, steps).unwrap();
        assert_eq!(
            (exact.speed, exact.slew_steps),
            (lowered, 0),
            "{steps} at {speed}"
        );
        assert!(exact.short_move);
        let delays: Vec<u32> = steps_of(Arithmetic::P2Exact, speed, steps)
            .iter()
            .map(|s| s.delay_ticks)
            .collect();
        let model = reference::delays(speed as i32, steps as i32, 40, 200_000_000);
        assert_eq!(delays, model, "{steps} at {speed}");
        if let Some(first) = first_delay {
            assert_eq!(delays[0], first);
        }
        // Smooth keeps the speed asked for.
        assert_eq!(
            plan(&config(Arithmetic::Smooth), speed, steps)
                .unwrap()
                .speed,
            speed
        );
    }
}

/// Whether the reference botches this move (see the module docs): its
/// plan differs from P2Exact's (odd short moves at full speed, 2- and
/// 4-step moves at −10 or 0) or it divides by zero (1 step).
fn reference_flawed(speed: u32, steps: u32) -> bool {
    let (sp, asteps) = reference::plan(speed as i32, steps as i32);
    let ours = plan(&config(Arithmetic::P2Exact), speed, steps).unwrap();
    asteps == 0 || i64::from(sp) != i64::from(ours.speed)
}

#[test]
fn p2_exact_matches_the_reference_cog_on_every_sane_move() {
    // Every move of 1..=240 steps at 60 speeds from 1 to 1,000,000 steps/s
    // (11,567 sane moves, 1,678,478 steps compared when written),
    // plus longer ones: where the reference is sane, P2Exact is it, tick
    // for tick; where it is flawed, the plans differ (tests below).
    let mut speeds: Vec<u32> = (1..=30).collect();
    speeds.extend([
        37, 49, 50, 99, 100, 101, 255, 999, 1_000, 1_009, 2_222, 4_999, 10_000, 12_345, 20_000,
        20_003, 30_000, 45_000, 50_000, 77_777, 100_000, 199_999, 250_000, 400_000, 500_000,
        654_321, 777_777, 900_000, 999_999, 1_000_000,
    ]);
    let (mut moves, mut steps_compared) = (0u64, 0u64);
    for &speed in &speeds {
        let natural = speed / 10 + 2;
        let long = if speed <= 100_000 {
            vec![2 * natural - 1, 2 * natural, 2 * natural + 1, 3 * natural]
        } else {
            Vec::new()
        };
        let lengths = (1..=240).chain(long);
        for steps in lengths {
            let model = reference::delays(speed as i32, steps as i32, 40, 200_000_000);
            let exact: Vec<u32> = steps_of(Arithmetic::P2Exact, speed, steps)
                .iter()
                .map(|s| s.delay_ticks)
                .collect();
            if reference_flawed(speed, steps) {
                // cogstep's fix: a positive speed, never above the reference's.
                let reference_speed = reference::plan(speed as i32, steps as i32).0;
                let ours = plan(&config(Arithmetic::P2Exact), speed, steps).unwrap();
                assert!(ours.speed >= 1, "{steps} at {speed}");
                assert!(
                    reference_speed <= 0 || i64::from(ours.speed) <= i64::from(reference_speed),
                    "{steps} at {speed}"
                );
                continue;
            }
            assert_eq!(exact, model, "{steps} steps at {speed}");
            moves += 1;
            steps_compared += u64::from(steps);
        }
    }
    assert!(
        moves > 10_000 && steps_compared > 1_000_000,
        "{moves} moves, {steps_compared} steps"
    );
}

#[test]
fn flaw_odd_short_moves_keep_full_speed_in_the_reference_only() {
    // 101 steps at 20,000: asteps capped to 50, ss = 1, so the reference
    // never lowers sp and climbs a 50-step ramp to 20,000 steps/s.
    assert_eq!(reference::plan(20_000, 101), (20_000, 50));
    let model = reference::delays(20_000, 101, 40, 200_000_000);
    assert_eq!(model.iter().min(), Some(&10_000));
    // cogstep lowers it as it would an even short move: 480 steps/s.
    for arithmetic in [Arithmetic::P2Exact, Arithmetic::Smooth] {
        let ours = steps_of(arithmetic, 20_000, 101);
        assert_eq!(plan(&config(arithmetic), 20_000, 101).unwrap().speed, 480);
        assert!(ours
            .iter()
            .all(|s| u64::from(s.delay_ticks) >= 200_000_000 / 480));
    }
    // 3 steps: asteps 1, ss 1: the reference runs the step at full speed.
    assert_eq!(reference::plan(20_000, 3), (20_000, 1));
    assert_eq!(
        plan(&config(Arithmetic::P2Exact), 20_000, 3).unwrap().speed,
        10
    );
}

#[test]
fn flaw_two_and_four_step_moves_get_speed_minus_ten_and_zero_in_the_reference_only() {
    // 2 steps: asteps 1, ss 0, sp = 10·(1 − 2) = −10; `shr` makes halfsp
    // 2^31 − 5 and the first delay 0 ticks (a target in the past).
    assert_eq!(reference::plan(20_000, 2), (-10, 1));
    assert_eq!(reference::delays(20_000, 2, 40, 200_000_000)[0], 0);
    // 4 steps: asteps 2, sp = 0, halfsp 0, v forced to 1: 95,000,000 ticks
    // (0.475 s) per step, whatever was asked.
    assert_eq!(reference::plan(20_000, 4), (0, 2));
    assert_eq!(
        reference::delays(20_000, 4, 40, 200_000_000),
        [95_000_000; 4]
    );
    // cogstep: 10 steps/s (accel_div), the slowest sane short-move speed.
    for steps in [2, 4] {
        for arithmetic in [Arithmetic::P2Exact, Arithmetic::Smooth] {
            assert_eq!(plan(&config(arithmetic), 20_000, steps).unwrap().speed, 10);
            let ours = steps_of(arithmetic, 20_000, steps);
            assert!(ours.iter().all(|s| s.delay_ticks >= 20_000_000), "{ours:?}");
            assert!(ours.iter().all(|s| s.delay_ticks < 95_000_000 * 2));
        }
    }
}

#[test]
fn flaw_one_step_move_divides_by_zero_in_the_reference_only() {
    // 1 step: asteps 0, so stom = 2·asteps = 0 and `_getdelay` runs
    // QDIV t1 / 0: the angle is garbage (here the defined all-ones quotient).
    let (speed, asteps) = reference::plan(20_000, 1);
    assert_eq!((speed, asteps), (20_000, 0));
    let mut cog = reference::Cog::new(speed, 1, asteps, 40, 200_000_000);
    assert_eq!((cog.stom, cog.xsteps), (0, 1));
    assert_eq!(cog.run(10, None).len(), 1);
    // cogstep: one step at 10 steps/s.
    for arithmetic in [Arithmetic::P2Exact, Arithmetic::Smooth] {
        let ours = steps_of(arithmetic, 20_000, 1);
        assert_eq!(ours.len(), 1);
        assert_eq!(plan(&config(arithmetic), 20_000, 1).unwrap().speed, 10);
        assert!(ours[0].delay_ticks >= 20_000_000);
    }
}

#[test]
fn flaw_a_stop_during_a_one_step_move_wraps_the_count_in_the_reference_only() {
    // The stop pin low after the step: `sub steps, xsteps` = 0 − 1.
    let (speed, asteps) = reference::plan(20_000, 1);
    let mut cog = reference::Cog::new(speed, 1, asteps, 40, 200_000_000);
    let made = cog.run(1_000, Some(1));
    assert_eq!(made.len(), 1_000, "the reference keeps stepping");
    assert!(cog.steps > 4_294_966_000, "{} steps to go", cog.steps);
    // cogstep: the stop drops nothing and the move ends.
    for arithmetic in [Arithmetic::P2Exact, Arithmetic::Smooth] {
        let mut curve = SCurve::new(config(arithmetic), 20_000, 1).unwrap();
        assert!(curve.next().is_some());
        assert_eq!(curve.stop(), 0);
        assert_eq!(curve.next(), None);
        assert_eq!(curve.remaining_steps(), 0);
    }
}

#[test]
fn the_reference_finishes_its_ramp_after_a_stop_and_cogstep_does_not() {
    // Stop pin low after 100 steps of a 10,000-step move at 10,000 steps/s:
    // the reference climbs its whole 1,002-step ramp first (2,004 steps).
    let (speed, asteps) = reference::plan(10_000, 10_000);
    let made = reference::Cog::new(speed, 10_000, asteps, 40, 200_000_000).run(20_000, Some(100));
    assert_eq!(made.len(), 2_004);
    let mut curve = SCurve::new(config(Arithmetic::P2Exact), 10_000, 10_000).unwrap();
    let before = curve.by_ref().take(100).count();
    curve.stop();
    assert_eq!(before + curve.count(), 199);
}

/// Steps of a move until `ticks` have passed on the P2's edge clock (each
/// step's period: delay + pulse + overhead), then a stop: every step made.
fn stop_at_time(arithmetic: Arithmetic, speed: u32, steps: u32, ticks: u64) -> (Vec<Step>, usize) {
    let mut curve = SCurve::new(config(arithmetic), speed, steps).unwrap();
    let mut made = Vec::new();
    let mut edge = 0u64;
    while edge <= ticks {
        let Some(step) = curve.next() else { break };
        edge += p2_period_ticks(step.delay_ticks, P2_PULSE_TICKS);
        made.push(step);
    }
    let stopped_after = made.len();
    curve.stop();
    made.extend(curve);
    (made, stopped_after)
}

#[test]
fn issue_11_item_12_a_stop_while_accelerating_never_speeds_up() {
    // `move(49, -18305)`, 85,530,942 ticks later the stop pin goes low. The
    // reference's integer velocity at 49 steps/s is a whole number of
    // 24ths of the speed: turning round mid-ramp onto the deceleration's
    // angles stepped up one unit (+4.2 %).
    let (made, stopped_after) = stop_at_time(Arithmetic::P2Exact, 49, 18_305, 85_530_942);
    assert!((1..=12).contains(&stopped_after), "{stopped_after}");
    for pair in made[stopped_after - 1..].windows(2) {
        assert!(pair[1].delay_ticks >= pair[0].delay_ticks, "{pair:?}");
        assert!(
            pair[1].velocity_steps_per_s <= pair[0].velocity_steps_per_s,
            "{pair:?}"
        );
    }
    // And at every stop point of that ramp and just past it.
    for stop_after in 1..=8 {
        let mut curve = SCurve::new(config(Arithmetic::P2Exact), 49, 18_305).unwrap();
        let mut made: Vec<Step> = curve.by_ref().take(stop_after).collect();
        curve.stop();
        made.extend(curve);
        for pair in made[stop_after - 1..].windows(2) {
            assert!(
                pair[1].delay_ticks >= pair[0].delay_ticks,
                "stop after {stop_after}: {pair:?}"
            );
        }
    }
}

#[test]
fn a_move_without_a_stop_keeps_the_reference_deceleration() {
    // The guard is for stops only: a plain P2Exact move still steps onto
    // the reference's 180° deceleration step, faster than its slew.
    let exact = steps_of(Arithmetic::P2Exact, 49, 100);
    let model = reference::delays(49, 100, 40, 200_000_000);
    assert_eq!(
        exact.iter().map(|s| s.delay_ticks).collect::<Vec<_>>(),
        model
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// After a stop at any step of any move, in either arithmetic, no step
    /// is faster than the step before it, and the count stays exact.
    #[test]
    fn no_step_after_a_stop_is_faster_than_the_one_before(
        speed in prop_oneof![1u32..200, 1u32..100_000],
        steps in 1u32..4_000,
        stop_fraction in 0.0f64..1.0,
        offset in 1u32..=89,
        exact in any::<bool>(),
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let cfg = ScurveConfig { offset_deg: offset, arithmetic, ..ScurveConfig::default() };
        let stop_after = ((f64::from(steps) * stop_fraction) as usize).max(1);
        let mut curve = SCurve::new(cfg, speed, steps).unwrap();
        let mut made: Vec<Step> = curve.by_ref().take(stop_after).collect();
        let dropped = curve.stop();
        made.extend(curve.by_ref());
        prop_assert_eq!(made.len() + dropped as usize, steps as usize);
        let from = made.len().min(stop_after) - 1;
        for pair in made[from..].windows(2) {
            prop_assert!(pair[1].delay_ticks >= pair[0].delay_ticks, "{:?}", pair);
            prop_assert!(pair[1].velocity_steps_per_s <= pair[0].velocity_steps_per_s, "{:?}", pair);
        }
    }

    /// P2Exact is the reference cog tick for tick on any sane move.
    #[test]
    fn p2_exact_is_the_reference_on_random_moves(
        // About half the moves are ones the reference plans wrong: left
        // out where they are drawn (a filter's rejects, not the run's, so
        // that a long run with `PROPTEST_CASES` set is not cut short).
        (speed, steps) in (1u32..2_000_000, 1u32..8_000)
            .prop_filter("a move the reference plans right", |&(speed, steps)| !reference_flawed(speed, steps)),
        offset in 1u32..=89,
    ) {
        let cfg = ScurveConfig { offset_deg: offset, arithmetic: Arithmetic::P2Exact, ..ScurveConfig::default() };
        let exact: Vec<u32> = SCurve::new(cfg, speed, steps).unwrap().map(|s| s.delay_ticks).collect();
        prop_assert_eq!(exact, reference::delays(speed as i32, steps as i32, offset, 200_000_000));
    }
}

/// The reference cog's edge times, from its PASM, clock by clock: the
/// instructions between the CT2 target and the next `getct cv`, and the
/// running target that `addct1 cv, delayh` / `addct2 cv, delay` move on.
fn reference_edge_times(delays: &[u32]) -> Vec<u64> {
    // waitct2 (2 once the event is flagged) + tjnz taken (4) + drvh (2).
    const WAKE_TO_GETCT: u64 = 2 + 4 + 2;
    let mut cv = 0u64; // getct cv right after the first rising edge
    let mut edges = vec![cv];
    for &delay in delays {
        let target = cv + 1_000 + u64::from(delay); // addct1 delayh, then addct2 delay
        cv = target + WAKE_TO_GETCT;
        edges.push(cv);
    }
    edges
}

#[test]
fn p2_period_is_delay_plus_pulse_plus_the_cogs_overhead() {
    assert_eq!(P2_STEP_OVERHEAD_TICKS, 8);
    assert_eq!(p2_period_ticks(10_000, P2_PULSE_TICKS), 11_008);
    assert_eq!(
        p2_period_ticks(u32::MAX, u32::MAX),
        2 * u64::from(u32::MAX) + 8
    );
    let steps = steps_of(Arithmetic::P2Exact, 20_000, 20_000);
    let delays: Vec<u32> = steps.iter().map(|s| s.delay_ticks).collect();
    let edges = reference_edge_times(&delays);
    for (pair, step) in edges.windows(2).zip(&steps) {
        assert_eq!(
            pair[1] - pair[0],
            p2_period_ticks(step.delay_ticks, P2_PULSE_TICKS)
        );
    }
}

#[test]
fn the_p2_board_runs_slower_than_asked() {
    // The issue's figures: about 18,180 steps/s when asked for 20,000, about
    // 36,700 for 45,000 (slew rate, 200 MHz).
    for (asked, about, tolerance) in [(20_000u32, 18_180.0, 0.001), (45_000, 36_700.0, 0.002)] {
        let steps = steps_of(Arithmetic::P2Exact, asked, 4 * asked);
        let slew = steps[2 * asked as usize];
        assert_eq!(slew.phase, Phase::Slew);
        let rate = 200e6 / p2_period_ticks(slew.delay_ticks, P2_PULSE_TICKS) as f64;
        assert!(
            ((rate - about) / about).abs() < tolerance,
            "{asked}: {rate}"
        );
    }
}
