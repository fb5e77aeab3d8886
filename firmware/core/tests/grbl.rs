//! grbl 1.1 on the board-independent firmware, on the host: the protocol
//! crate's `GrblSession` over [`PathMotion`] on a fake board whose clock
//! moves in slices of a quarter millisecond: each slice is one turn of a
//! board's main loop (bytes in, `advance`, `poll`) and then the step
//! interrupt at every wake-up it asks for. Exact end positions, and the
//! pins: every step the positions count is a pulse on a step pin.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};

use cogstep_firmware::{core_config, Firmware, Hardware, Output, PathMotion, Variant};
use driver::serial::grbl::{GrblGcode, GrblSession, Settings};

const CLKFREQ: u32 = 50_000_000;
/// A main loop turn every 250 µs.
const SLICE_TICKS: u64 = CLKFREQ as u64 / 4_000;

struct FakeState {
    now: AtomicU64,
}

#[derive(Clone, Copy)]
struct FakeBoard(&'static FakeState);

impl Hardware for FakeBoard {
    fn now_ticks(&self) -> u64 {
        self.0.now.load(Ordering::SeqCst)
    }
    fn request_step_interrupt(&self) {}
    fn set_pin(&self, _axis: usize, _output: Output, _level: bool) {}
}

type Session = GrblSession<PathMotion<'static, FakeBoard>, GrblGcode>;

struct Rig {
    board: FakeBoard,
    firmware: &'static Firmware<FakeBoard>,
    session: Session,
    /// What the board wrote.
    out: String,
    /// Bytes sent and not yet read by the board.
    wire: VecDeque<u8>,
}

impl Rig {
    fn new() -> Rig {
        let board = FakeBoard(Box::leak(Box::new(FakeState {
            now: AtomicU64::new(0),
        })));
        let firmware: &'static Firmware<FakeBoard> = Box::leak(Box::new(
            Firmware::new(board, 3, |index| {
                let variant = if index.is_multiple_of(2) {
                    Variant::Sd
                } else {
                    Variant::Cc
                };
                core_config(CLKFREQ, variant)
            })
            .unwrap(),
        ));
        let mut settings = Settings::default();
        for axis in 0..3 {
            settings.max_rate_mm_min[axis] = 3_000.0;
            settings.accel_mm_s2[axis] = 2_000.0;
        }
        let mut session = GrblSession::new(
            PathMotion::new(firmware, Box::leak(Box::new(None)), &settings),
            GrblGcode::new(&settings),
            settings,
            "test",
        );
        let mut out = String::new();
        session.start(&mut out).unwrap();
        assert_eq!(out, "\r\nGrbl 1.1h ['$' for help]\r\n");
        out.clear();
        Rig {
            board,
            firmware,
            session,
            out,
            wire: VecDeque::new(),
        }
    }

    fn now(&self) -> u64 {
        self.board.0.now.load(Ordering::SeqCst)
    }

    /// Bytes onto the wire, then one main loop turn.
    fn send(&mut self, bytes: &[u8]) {
        self.wire.extend(bytes);
        self.turn();
    }

    /// One turn of the firmware's main loop: bytes in as far as the
    /// receive buffer has room (the rest wait on the wire), the path's
    /// edges pushed, lines taken.
    fn turn(&mut self) {
        while self.session.room() > 0 {
            let Some(byte) = self.wire.pop_front() else {
                break;
            };
            self.session.receive(byte, &mut self.out).unwrap();
        }
        self.session.motion_mut().advance();
        self.session.poll(&mut self.out).unwrap();
    }

    /// Runs main loop turns and step interrupts for `ms`.
    fn run_ms(&mut self, ms: u64) {
        let end = self.now() + ms * u64::from(CLKFREQ) / 1_000;
        while self.now() < end {
            self.turn();
            let slice_end = (self.now() + SLICE_TICKS).min(end);
            loop {
                let (next, _) = self.firmware.step_interrupt();
                match next {
                    Some(t) if t <= slice_end => {
                        let t = t.max(self.now());
                        self.board.0.now.store(t, Ordering::SeqCst);
                    }
                    _ => break,
                }
            }
            self.board.0.now.store(slice_end, Ordering::SeqCst);
        }
        self.turn();
    }

    fn report(&mut self) -> String {
        self.out.clear();
        self.send(b"?");
        let report = self.out.trim_end().to_string();
        self.out.clear();
        report
    }

    /// Runs until the report starts with `<state|` (at most `limit_ms`).
    fn run_until(&mut self, state: &str, limit_ms: u64) -> String {
        for _ in 0..limit_ms {
            let report = self.report();
            if report.starts_with(&format!("<{state}|")) {
                return report;
            }
            self.run_ms(1);
        }
        panic!("never {state}: {}", self.report());
    }

    /// Pulses on each axis's step pins so far (sd: the step pin; cc: both).
    fn pulses(&self) -> [u64; 3] {
        let mut pulses = [0; 3];
        for (axis, count) in pulses.iter_mut().enumerate() {
            let edges = self.firmware.axes()[axis].edge_counts();
            *count = if axis % 2 == 0 {
                edges.rising[0]
            } else {
                edges.rising[0] + edges.rising[1]
            };
        }
        pulses
    }
}

fn mpos(report: &str) -> &str {
    let start = report.find("MPos:").expect("MPos") + 5;
    let end = report[start..]
        .find('|')
        .map_or(report.len() - 1, |end| start + end);
    &report[start..end]
}

#[test]
fn lines_and_an_arc_end_exactly_and_every_step_is_a_pulse() {
    let mut rig = Rig::new();
    // All forward on X and Y (and Z up): pulses = steps.
    for line in [
        "G21G90\n",
        "G1X2Y1F1200\n",
        "G1X4Y1.5Z0.2\n",
        "G3X6Y3.5I0J2\n",
        "G0X6.5Y4\n",
    ] {
        rig.send(line.as_bytes());
        // An arc's chords go in a few a turn (`BLOCKS_PER_TURN`): its `ok`
        // once all are queued.
        for _ in 0..64 {
            if !rig.out.is_empty() {
                break;
            }
            rig.turn();
        }
        assert_eq!(rig.out, "ok\r\n", "{line}");
        rig.out.clear();
    }
    let report = rig.run_until("Idle", 10_000);
    assert_eq!(mpos(&report), "6.500,4.000,0.200");
    assert_eq!(rig.pulses(), [1_625, 1_000, 50]);
}

#[test]
fn a_feed_hold_comes_to_rest_and_resume_finishes_exactly() {
    let mut rig = Rig::new();
    rig.send(b"G1X10Y5F1200\n");
    rig.run_ms(150);
    rig.send(b"!");
    let held = rig.run_until("Hold:0", 5_000);
    rig.run_ms(100);
    assert_eq!(mpos(&rig.report()), mpos(&held), "at rest");
    assert_ne!(mpos(&held), "10.000,5.000,0.000");
    rig.send(b"~");
    let report = rig.run_until("Idle", 10_000);
    assert_eq!(mpos(&report), "10.000,5.000,0.000");
    assert_eq!(rig.pulses(), [2_500, 1_250, 0]);
}

#[test]
fn a_soft_reset_stops_at_once_keeps_every_step_and_locks() {
    let mut rig = Rig::new();
    rig.send(b"G1X20F1200\n");
    rig.run_ms(200);
    rig.out.clear();
    rig.send(b"\x18");
    assert!(rig.out.starts_with("ALARM:3\r\n"), "{}", rig.out);
    rig.run_ms(20);
    let report = rig.report();
    assert!(report.starts_with("<Alarm|"), "{report}");
    rig.run_ms(100);
    assert_eq!(mpos(&rig.report()), mpos(&report), "stopped at once");
    // Every step the position counts is a pulse on the pin.
    let x_steps = rig.pulses()[0];
    assert!(x_steps > 0 && x_steps < 5_000);
    assert_eq!(
        mpos(&report),
        format!("{:.3},0.000,0.000", x_steps as f64 / 250.0)
    );
    rig.out.clear();
    rig.send(b"$X\n");
    assert_eq!(rig.out, "[MSG:Caution: Unlocked]\r\nok\r\n");
    rig.out.clear();
    rig.send(b"G0X2\n");
    assert_eq!(mpos(&rig.run_until("Idle", 10_000)), "2.000,0.000,0.000");
}

#[test]
fn homing_is_refused_without_switches() {
    let mut rig = Rig::new();
    rig.send(b"$H\n");
    assert_eq!(rig.out, "error:5\r\n");
    rig.out.clear();
    rig.send(b"$22=1\n$H\n");
    assert_eq!(rig.out, "ok\r\nALARM:9\r\nok\r\n");
    assert!(rig.report().starts_with("<Alarm|MPos:0.000,0.000,0.000"));
}

mod props {
    use super::*;
    use proptest::prelude::*;

    /// What the sender does at a main loop turn.
    #[derive(Clone, Copy, Debug)]
    enum Event {
        Hold,
        Resume,
        Reset,
        Unlock,
        FeedUp,
    }

    fn event() -> impl Strategy<Value = Event> {
        prop_oneof![
            3 => Just(Event::Hold),
            3 => Just(Event::Resume),
            1 => Just(Event::Reset),
            1 => Just(Event::Unlock),
            1 => Just(Event::FeedUp),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// Lines that only go forward (so that every step is a pulse on a
        /// step pin, whatever the direction pin), with holds, resumes,
        /// resets, unlocks and overrides at random times: every step the
        /// positions count is a pulse, none is made after a reset, and
        /// without a reset the program ends exactly on its last point.
        #[test]
        fn every_step_is_a_pulse_and_the_end_is_exact(
            moves in prop::collection::vec((0u32..800, 0u32..800, 0u32..100), 1..8),
            events in prop::collection::vec((1u64..400, event()), 0..10),
        ) {
            let mut rig = Rig::new();
            let mut end = [0u32; 3];
            let mut program = String::from("G21G90\n");
            for (dx, dy, dz) in &moves {
                end[0] += dx;
                end[1] += dy;
                end[2] += dz;
                program.push_str(&format!(
                    "G1X{:.3}Y{:.3}Z{:.3}F1500\n",
                    f64::from(end[0]) / 250.0,
                    f64::from(end[1]) / 250.0,
                    f64::from(end[2]) / 250.0
                ));
            }
            rig.send(program.as_bytes());
            let mut reset = false;
            for (after_ms, event) in events {
                rig.run_ms(after_ms);
                match event {
                    Event::Hold => rig.send(b"!"),
                    Event::Resume => rig.send(b"~"),
                    Event::Reset => {
                        rig.send(b"\x18");
                        reset = true;
                    }
                    Event::Unlock => rig.send(b"$X\n"),
                    Event::FeedUp => rig.send(&[0x91]),
                }
            }
            // Whatever was held goes on; then everything comes to rest.
            rig.send(b"~");
            let mut report = rig.report();
            for _ in 0..20_000 {
                if report.starts_with("<Idle|") || report.starts_with("<Alarm|") {
                    break;
                }
                if report.starts_with("<Hold:0|") {
                    rig.send(b"~");
                }
                rig.run_ms(1);
                report = rig.report();
            }
            prop_assert!(
                report.starts_with("<Idle|") || report.starts_with("<Alarm|"),
                "{}", report
            );
            rig.run_ms(50);
            let pulses = rig.pulses();
            let steps: Vec<u64> = mpos(&rig.report())
                .split(',')
                .map(|mm| (mm.parse::<f64>().unwrap() * 250.0).round() as u64)
                .collect();
            prop_assert_eq!(steps, pulses.to_vec());
            if !reset {
                prop_assert_eq!(pulses, end.map(u64::from));
            }
        }
    }
}
