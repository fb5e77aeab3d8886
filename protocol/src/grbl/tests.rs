//! The grbl engine against a fake motion and a fake interpreter: bytes in,
//! replies out.

extern crate std;
use std::string::String;
use std::vec::Vec;

use proptest::prelude::*;

use super::*;

/// A planner of `capacity` blocks that runs one block per [`FakeMotion::run`].
#[derive(Clone, Debug)]
struct FakeMotion {
    capacity: usize,
    queue: std::collections::VecDeque<MotionBlock>,
    ran: Vec<MotionBlock>,
    steps: [i64; GRBL_AXES],
    state: MotionState,
    fault: Option<MotionFault>,
    overrides: Overrides,
    holds: u32,
    resets: u32,
    /// `GrblMotion::blocks_per_poll`.
    per_poll: usize,
}

impl FakeMotion {
    fn new(capacity: usize) -> Self {
        FakeMotion {
            capacity,
            queue: Default::default(),
            ran: Vec::new(),
            steps: [0; GRBL_AXES],
            state: MotionState::Idle,
            fault: None,
            overrides: Overrides::default(),
            holds: 0,
            resets: 0,
            per_poll: usize::MAX,
        }
    }

    /// Runs the oldest block to its end.
    fn run(&mut self) {
        if matches!(self.state, MotionState::Held | MotionState::Holding) {
            return;
        }
        if let Some(block) = self.queue.pop_front() {
            if let MotionBlock::Line { target_steps, .. } = block {
                self.steps = target_steps;
            }
            self.ran.push(block);
        }
        self.state = self.moving_state();
    }

    fn moving_state(&self) -> MotionState {
        match self.queue.front() {
            None => MotionState::Idle,
            Some(MotionBlock::Line { jog: true, .. }) => MotionState::Jog,
            Some(_) => MotionState::Run,
        }
    }
}

impl GrblMotion for FakeMotion {
    fn queue(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal> {
        if self.queue.len() >= self.capacity {
            return Err(MotionRefusal::Full);
        }
        self.queue.push_back(*block);
        if self.state == MotionState::Idle {
            self.state = self.moving_state();
        }
        Ok(())
    }
    fn free_blocks(&self) -> usize {
        self.capacity - self.queue.len()
    }
    fn capacity(&self) -> usize {
        self.capacity
    }
    fn hold(&mut self) {
        self.holds += 1;
        self.state = MotionState::Held;
    }
    fn resume(&mut self) {
        self.state = self.moving_state();
    }
    fn cancel_jog(&mut self) {
        self.queue.clear();
        self.state = MotionState::Idle;
    }
    fn reset(&mut self) {
        self.resets += 1;
        self.queue.clear();
        self.state = MotionState::Idle;
    }
    fn status(&self) -> MotionStatus {
        MotionStatus {
            steps: self.steps,
            state: self.state,
            feed_mm_s: if self.state == MotionState::Run {
                10.0
            } else {
                0.0
            },
            line: None,
        }
    }
    fn take_fault(&mut self) -> Option<MotionFault> {
        self.fault.take()
    }
    fn home(&mut self, _: &HomeRequest) -> Result<(), MotionRefusal> {
        self.state = MotionState::Homing;
        Ok(())
    }
    fn set_overrides(&mut self, overrides: Overrides) {
        self.overrides = overrides;
    }
    fn configure(&mut self, _: &Settings) {}
    fn max_step_rate_hz(&self) -> u32 {
        100_000
    }

    fn blocks_per_poll(&self) -> usize {
        self.per_poll
    }
}

/// A line interpreter for tests: `X<n>` moves X to n mm (one block),
/// `S<k>` emits k one-step segments on Y (an arc's worth), `BAD` is
/// `error:20`; every line taken is recorded.
#[derive(Clone, Debug, Default)]
struct FakeGcode {
    seen: Vec<String>,
    position: [i64; GRBL_AXES],
}

impl GcodeInterpreter for FakeGcode {
    fn interpret(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        emit: &mut dyn FnMut(&MotionBlock),
    ) -> Result<(), GrblError> {
        if text.contains("BAD") {
            return Err(GrblError::UnsupportedCommand);
        }
        self.seen.push(String::from(text));
        let line = |target: [i64; GRBL_AXES]| MotionBlock::Line {
            line: line_no,
            target_steps: target,
            feed_mm_s: 10.0,
            length_mm: 1.0,
            rapid: false,
            jog,
        };
        if let Some(ms) = text.strip_prefix("G4P") {
            emit(&MotionBlock::Dwell {
                line: line_no,
                ms: ms.parse().unwrap_or(0),
            });
        } else if let Some(count) = text.strip_prefix('S') {
            for _ in 0..count.parse::<u32>().unwrap_or(0) {
                self.position[1] += 1;
                emit(&line(self.position));
            }
        } else if let Some(x) = text.find('X') {
            let digits: String = text[x + 1..]
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '-' || *c == '.')
                .collect();
            let mm: f64 = digits.parse().map_err(|_| GrblError::BadNumberFormat)?;
            self.position[0] = (mm * settings.steps_per_mm[0]).round() as i64;
            emit(&line(self.position));
        }
        Ok(())
    }
    fn sync_position(&mut self, steps: &[i64; GRBL_AXES], _: &Settings) {
        self.position = *steps;
    }
    fn reset(&mut self) {}
    fn parser_state(&self) -> ParserState {
        ParserState::default()
    }
    fn offsets(&self) -> Offsets {
        Offsets {
            g54: [0.0; GRBL_AXES],
            g92: [1.5, 0.0, 0.0],
        }
    }
}

type Session = GrblSession<FakeMotion, FakeGcode>;

fn session(capacity: usize) -> Session {
    GrblSession::new(
        FakeMotion::new(capacity),
        FakeGcode::default(),
        Settings::default(),
        "0.1.0",
    )
}

/// Feeds every byte (polling between them) and returns the replies.
fn talk(session: &mut Session, bytes: &[u8]) -> String {
    let mut out = String::new();
    for &byte in bytes {
        assert_ne!(session.receive(byte, &mut out).unwrap(), Received::Full);
        session.poll(&mut out).unwrap();
    }
    out
}

#[test]
fn welcome_and_build_info() {
    let mut s = session(16);
    let mut out = String::new();
    s.start(&mut out).unwrap();
    assert_eq!(out, "\r\nGrbl 1.1h ['$' for help]\r\n");
    assert_eq!(
        talk(&mut s, b"$I\n"),
        "[VER:1.1h.cogstep-0.1.0:]\r\n[OPT:,15,128]\r\nok\r\n"
    );
}

#[test]
fn realtime_bytes_act_at_once_and_never_enter_a_line() {
    let mut s = session(16);
    s.settings.status_report_mask = 1;
    let out = talk(&mut s, b"G1?X5\n");
    assert!(out.starts_with("<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:1.500,0.000,0.000>\r\n"));
    assert!(out.ends_with("ok\r\n"));
    assert_eq!(s.gcode.seen, ["G1X5"]);
    // Extended bytes (0x80–0xFF) are realtime or ignored, never line bytes.
    talk(&mut s, b"G1\xA5X6\n");
    assert_eq!(s.gcode.seen, ["G1X5", "G1X6"]);
}

#[test]
fn every_realtime_byte_names_itself_back() {
    for byte in 0..=u8::MAX {
        if let Some(command) = GrblRealtime::from_byte(byte) {
            assert_eq!(command.byte(), byte, "{command:?}");
        }
    }
    assert_eq!(GrblRealtime::FeedHold.byte(), b'!');
    assert_eq!(GrblRealtime::FeedPlus10.byte(), 0x91);
}

#[test]
fn lines_are_assembled_as_grbl_does() {
    let mut s = session(16);
    let out = talk(
        &mut s,
        b"g1 x 7 (a comment) ; another\r\n\n(only a comment)\n",
    );
    // CR and LF each end a line; empty lines get their ok too.
    assert_eq!(out, "ok\r\nok\r\nok\r\nok\r\n");
    assert_eq!(s.gcode.seen, ["G1X7"]);
}

#[test]
fn an_overlong_line_is_error_11_and_the_next_line_runs() {
    let mut s = session(16);
    let mut bytes = Vec::new();
    bytes.extend(std::iter::repeat_n(b'1', 100));
    bytes.extend_from_slice(b"\nX2\n");
    let out = talk(&mut s, &bytes);
    assert_eq!(out, "error:11\r\nok\r\n");
    assert_eq!(s.gcode.seen, ["X2"]);
    // 79 kept characters fit, 80 do not.
    let mut bytes = b"X".to_vec();
    bytes.extend(std::iter::repeat_n(b'0', 77));
    bytes.push(b'1');
    bytes.push(b'\n');
    assert_eq!(talk(&mut s, &bytes), "ok\r\n");
    bytes.insert(1, b'0');
    assert_eq!(talk(&mut s, &bytes), "error:11\r\n");
}

#[test]
fn a_malformed_line_is_an_error_and_queues_nothing() {
    let mut s = session(16);
    assert_eq!(talk(&mut s, b"G1BAD\n"), "error:20\r\n");
    assert!(s.motion.queue.is_empty());
    assert_eq!(talk(&mut s, b"$bogus\n$999=1\n"), "error:3\r\nerror:3\r\n");
}

/// Each block's Y target (-1 for a block that is not a line).
fn ys<'a>(blocks: impl IntoIterator<Item = &'a MotionBlock>) -> Vec<i64> {
    blocks
        .into_iter()
        .map(|block| match block {
            MotionBlock::Line { target_steps, .. } => target_steps[1],
            _ => -1,
        })
        .collect()
}

#[test]
fn a_line_waits_for_the_planner_and_its_blocks_come_once_in_order() {
    let mut s = session(4);
    let out = talk(&mut s, b"S10\nX3\n");
    // Four segments fit; no ok until the rest are in.
    assert_eq!(out, "");
    assert_eq!(s.motion.queue.len(), 4);
    let mut out = String::new();
    for _ in 0..20 {
        s.motion.run();
        s.poll(&mut out).unwrap();
    }
    assert_eq!(out, "ok\r\nok\r\n");
    assert_eq!(ys(&s.motion.ran), [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 10]);
    assert_eq!(s.motion.steps[0], 750);
}

#[test]
fn a_long_line_goes_in_a_few_blocks_a_turn_when_the_motion_says_so() {
    // A board whose planning is slow takes an arc's chords a few a turn
    // (`GrblMotion::blocks_per_poll`): the line's `ok` once all are in, the
    // blocks once each and in order, as when the planner is full.
    let mut s = session(16);
    s.motion.per_poll = 3;
    let out = talk(&mut s, b"S10\n");
    assert_eq!(out, "");
    assert_eq!(s.motion.queue.len(), 3);
    let mut out = String::new();
    for _ in 0..3 {
        s.poll(&mut out).unwrap();
    }
    assert_eq!(out, "ok\r\n");
    assert_eq!(ys(&s.motion.queue), [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
}

#[test]
fn the_receive_buffer_holds_128_bytes_and_refuses_the_next() {
    let mut s = session(1);
    let mut out = String::new();
    // The planner is full and a line waits: nothing is taken out.
    talk(&mut s, b"S3\n");
    for i in 0..128 {
        assert_eq!(
            s.receive(b'0' + (i % 10) as u8, &mut out).unwrap(),
            Received::Stored
        );
    }
    assert_eq!(s.room(), 0);
    assert_eq!(s.receive(b'1', &mut out).unwrap(), Received::Full);
    assert_eq!(s.overruns(), 1);
    // A realtime byte still acts.
    assert!(matches!(
        s.receive(b'?', &mut out).unwrap(),
        Received::Realtime(GrblRealtime::StatusReport)
    ));
    assert!(out.starts_with("<Run|"));
}

#[test]
fn status_report_cadence_wco_then_ov() {
    let mut s = session(16);
    let mut reports = Vec::new();
    for _ in 0..12 {
        reports.push(talk(&mut s, b"?"));
    }
    assert_eq!(
        reports[0],
        "<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:1.500,0.000,0.000>\r\n"
    );
    assert_eq!(
        reports[1],
        "<Idle|MPos:0.000,0.000,0.000|FS:0,0|Ov:100,100,100>\r\n"
    );
    for report in &reports[2..10] {
        assert_eq!(report, "<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n");
    }
    assert!(reports[10].contains("|WCO:"));
    assert!(reports[11].contains("|Ov:"));
    // An override shows on the next report.
    assert!(talk(&mut s, b"?").ends_with("FS:0,0>\r\n"));
    assert!(talk(&mut s, b"\x91?").contains("|Ov:110,100,100>"));
    assert_eq!(s.motion.overrides.feed_pct, 110);
    for _ in 0..20 {
        talk(&mut s, b"\x91");
    }
    assert_eq!(s.motion.overrides.feed_pct, 200);
    talk(&mut s, b"\x90\x96");
    assert_eq!(s.motion.overrides.feed_pct, 100);
    assert_eq!(s.motion.overrides.rapid_pct, 50);
}

#[test]
fn report_mask_wpos_and_buffer_state() {
    let mut s = session(16);
    assert_eq!(talk(&mut s, b"$10=2\n"), "ok\r\n");
    let report = talk(&mut s, b"X3\n?");
    assert!(
        report.contains("<Run|WPos:-1.500,0.000,0.000|Bf:15,128|FS:600,0|"),
        "{report}"
    );
}

#[test]
fn mpos_is_steps_over_steps_per_mm_exactly() {
    let mut s = session(16);
    talk(&mut s, b"$100=3\n$102=80\n");
    s.motion.steps = [1, -2, 804];
    let report = talk(&mut s, b"?");
    assert!(report.contains("MPos:0.333,-0.008,10.050"), "{report}");
    s.motion.steps = [-1, 0, 0];
    talk(&mut s, b"$13=1\n");
    // Inches, 4 decimals.
    assert!(talk(&mut s, b"?").contains("MPos:-0.0131,0.0000,0.0000"));
}

#[test]
fn settings_list_defaults_and_checks() {
    let mut s = session(16);
    let out = talk(&mut s, b"$$\n");
    assert!(out.starts_with("$10=1\r\n$11=0.010\r\n$12=0.002\r\n$13=0\r\n$20=0\r\n"));
    assert!(out.contains("$24=25.000\r\n$25=500.000\r\n$27=1.000\r\n$100=250.000\r\n"));
    assert!(out.ends_with("$132=200.000\r\nok\r\n"));
    assert_eq!(out.matches("\r\n").count(), 24);
    assert_eq!(talk(&mut s, b"$100=-1\n"), "error:4\r\n");
    assert_eq!(talk(&mut s, b"$100=1e3\n"), "error:2\r\n");
    assert_eq!(talk(&mut s, b"$20=1\n"), "error:10\r\n");
    // 100,000 steps/s at most: 1,000 steps/mm × 6,000 mm/min passes, 6,001 not.
    assert_eq!(talk(&mut s, b"$110=6000\n$100=1000\n"), "ok\r\nok\r\n");
    assert_eq!(talk(&mut s, b"$110=6001\n"), "error:12\r\n");
    assert_eq!(talk(&mut s, b"$22=1\n$20=1\n$22=0\n"), "ok\r\nok\r\nok\r\n");
    assert!(!s.settings().soft_limits);
    assert!(s.take_settings_changed());
    assert!(!s.take_settings_changed());
}

proptest! {
    #[test]
    fn settings_round_trip_through_their_lines(
        values in proptest::collection::vec(0u32..1_000_000, 23),
    ) {
        let mut settings = Settings::default();
        for (&number, &value) in Settings::numbers().iter().zip(&values) {
            let value = f64::from(value + 1) / 1000.0;
            // Some settings refuse some values; the others must round trip.
            let _ = settings.set(number, value, u32::MAX);
        }
        let mut text = String::new();
        settings.write_all(&mut text).unwrap();
        let mut read = Settings { homing: settings.homing, ..Settings::default() };
        for line in text.lines() {
            read.set_from_text(line.strip_prefix('$').unwrap(), u32::MAX).unwrap();
        }
        prop_assert_eq!(read, settings);
    }

    /// Lines with realtime bytes anywhere in them, fed as a board reads
    /// its UART (never more than the room left) while the planner runs
    /// blocks at random: every line arrives once, whole and in order, one
    /// `ok` each, and one report per `?`.
    #[test]
    fn realtime_bytes_anywhere_lose_and_reorder_nothing(
        lines in proptest::collection::vec((0u32..1000, 0u32..4), 1..60),
        realtime in proptest::collection::vec((any::<prop::sample::Index>(), prop::sample::select(vec![b'?', b'!', b'~', 0x85u8, 0x90, 0x91, 0x94, 0x96, 0x9A, 0x9D, 0xA0, 0xC3])), 0..80),
        chunks in proptest::collection::vec(1usize..40, 1..50),
        runs in proptest::collection::vec(0usize..3, 1..50),
    ) {
        let mut s = session(16);
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        for (n, segments) in &lines {
            let line = if *segments > 0 { std::format!("S{segments}") } else { std::format!("G1X{n}") };
            stream.extend_from_slice(line.as_bytes());
            stream.push(b'\n');
            expected.push(line);
        }
        let mut statuses = 0;
        let mut positions: Vec<usize> = realtime.iter().map(|(index, _)| index.index(stream.len() + 1)).collect();
        positions.sort_unstable();
        for (position, (_, byte)) in positions.iter().zip(&realtime).rev() {
            stream.insert(*position, *byte);
            if *byte == b'?' { statuses += 1; }
        }
        let mut out = String::new();
        let mut sent = 0;
        let mut turn = 0;
        while sent < stream.len() || s.is_busy() {
            let chunk = chunks[turn % chunks.len()].min(s.room()).min(stream.len() - sent);
            for &byte in &stream[sent..sent + chunk] {
                prop_assert_ne!(s.receive(byte, &mut out).unwrap(), Received::Full);
            }
            sent += chunk;
            s.poll(&mut out).unwrap();
            // Now and then the planner runs at least one block.
            let run = runs[turn % runs.len()].max(usize::from(turn % 5 == 4));
            for _ in 0..run { s.motion.run(); }
            // A hold would stop the fake planner for good: resume it.
            if s.motion.state == MotionState::Held { s.motion.resume(); }
            s.poll(&mut out).unwrap();
            turn += 1;
            prop_assert!(turn < 100_000);
        }
        prop_assert_eq!(&s.gcode.seen, &expected);
        prop_assert_eq!(out.matches("ok\r\n").count(), lines.len());
        prop_assert_eq!(out.matches('<').count(), statuses);
        prop_assert_eq!(s.overruns(), 0);
    }
}

#[test]
fn reset_while_moving_is_alarm_3_until_unlock() {
    let mut s = session(16);
    talk(&mut s, b"X5\n");
    assert_eq!(s.state(), GrblState::Run);
    let out = talk(&mut s, b"\x18");
    assert_eq!(
        out,
        "ALARM:3\r\n\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n"
    );
    assert!(talk(&mut s, b"?").starts_with("<Alarm|"));
    assert_eq!(talk(&mut s, b"X1\n"), "error:9\r\n");
    assert_eq!(talk(&mut s, b"$J=G91X1F100\n"), "error:9\r\n");
    // Settings and reports still answer in Alarm.
    assert_eq!(
        talk(&mut s, b"$G\n"),
        "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n"
    );
    assert_eq!(talk(&mut s, b"$X\n"), "[MSG:Caution: Unlocked]\r\nok\r\n");
    assert_eq!(talk(&mut s, b"X1\n"), "ok\r\n");
    // A reset at rest is no alarm.
    s.motion.run();
    assert_eq!(talk(&mut s, b"\x18"), "\r\nGrbl 1.1h ['$' for help]\r\n");
}

#[test]
fn a_reset_forgets_the_buffered_lines() {
    let mut s = session(1);
    talk(&mut s, b"S2\nX1\nX2");
    let out = talk(&mut s, b"\x18");
    assert!(out.starts_with("ALARM:3"));
    talk(&mut s, b"$X\n\n");
    s.motion.run();
    // S2 never finished (its ok never came): it left no trace in the
    // program's state, and X1, X2 were forgotten unread.
    assert!(s.gcode.seen.is_empty());
    assert!(s.motion.ran.is_empty());
}

#[test]
fn hard_limit_and_homing_faults_lock() {
    let mut s = session(16);
    talk(&mut s, b"X5\n");
    s.motion.fault = Some(MotionFault::HardLimit);
    s.motion.queue.clear();
    s.motion.state = MotionState::Idle;
    let mut out = String::new();
    s.poll(&mut out).unwrap();
    assert_eq!(
        out + &talk(&mut s, b"?"),
        "ALARM:1\r\n<Alarm|MPos:0.000,0.000,0.000|FS:0,0|WCO:1.500,0.000,0.000>\r\n"
    );
    assert_eq!(talk(&mut s, b"X1\n"), "error:9\r\n");
    assert_eq!(talk(&mut s, b"$H\n"), "error:5\r\n");
    talk(&mut s, b"$22=1\n");
    assert_eq!(talk(&mut s, b"$H\n"), "");
    assert!(talk(&mut s, b"?").starts_with("<Home|"));
    s.motion.state = MotionState::Idle;
    s.motion.fault = Some(MotionFault::HomingSwitchNotFound);
    assert_eq!(talk(&mut s, b"\n"), "ALARM:9\r\nok\r\nok\r\n");
    talk(&mut s, b"$H\n");
    s.motion.state = MotionState::Idle;
    s.motion.steps = [250, 0, 0];
    assert_eq!(talk(&mut s, b"\n"), "ok\r\nok\r\n");
    assert_eq!(s.alarm(), None);
    assert_eq!(s.gcode.position, [250, 0, 0]);
}

#[test]
fn boot_with_homing_enabled_is_locked() {
    let settings = Settings {
        homing: true,
        ..Settings::default()
    };
    let mut s = GrblSession::new(FakeMotion::new(16), FakeGcode::default(), settings, "0.1.0");
    let mut out = String::new();
    s.start(&mut out).unwrap();
    assert_eq!(
        out,
        "\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n"
    );
    assert_eq!(talk(&mut s, b"X1\n"), "error:9\r\n");
}

#[test]
fn soft_limits_alarm_on_a_line_and_refuse_a_jog() {
    let mut s = session(16);
    talk(&mut s, b"$22=1\n$20=1\n");
    assert_eq!(talk(&mut s, b"$J=X-1F100\n"), "ok\r\n");
    assert_eq!(s.motion.queue.len(), 1);
    assert_eq!(talk(&mut s, b"$J=X1F100\n"), "error:15\r\n");
    assert_eq!(s.motion.queue.len(), 1);
    s.motion.run();
    assert_eq!(talk(&mut s, b"X1\n"), "ALARM:2\r\nok\r\n");
    assert!(s.motion.ran.iter().all(|block| !matches!(
        block,
        MotionBlock::Line {
            target_steps: [250, ..],
            ..
        }
    )));
    assert_eq!(talk(&mut s, b"X-1\n"), "error:9\r\n");
}

#[test]
fn hold_resume_and_jog_cancel() {
    let mut s = session(16);
    talk(&mut s, b"X5\n");
    talk(&mut s, b"!");
    assert!(talk(&mut s, b"?").starts_with("<Hold:0|"));
    // Lines are still taken during a hold.
    assert_eq!(talk(&mut s, b"X6\n"), "ok\r\n");
    talk(&mut s, b"~");
    assert!(talk(&mut s, b"?").starts_with("<Run|"));
    s.motion.run();
    s.motion.run();
    assert_eq!(s.motion.steps[0], 1500);
    talk(&mut s, b"$J=G91X1F100\n");
    assert!(talk(&mut s, b"?").starts_with("<Jog|"));
    assert_eq!(talk(&mut s, b"X9\n"), "error:9\r\n");
    talk(&mut s, b"\x85");
    assert!(talk(&mut s, b"?").starts_with("<Idle|"));
    assert_eq!(s.gcode.position, [1500, 0, 0]);
}

#[test]
fn check_mode_moves_nothing_and_leaves_with_a_reset() {
    let mut s = session(16);
    assert_eq!(talk(&mut s, b"$C\n"), "[MSG:Enabled]\r\nok\r\n");
    assert_eq!(talk(&mut s, b"X5\nS40\nBAD\n"), "ok\r\nok\r\nerror:20\r\n");
    assert!(s.motion.queue.is_empty());
    assert!(talk(&mut s, b"?").starts_with("<Check|"));
    assert_eq!(
        talk(&mut s, b"$C\n"),
        "[MSG:Disabled]\r\nok\r\n\r\nGrbl 1.1h ['$' for help]\r\n"
    );
    assert!(talk(&mut s, b"?").starts_with("<Idle|"));
}

#[test]
fn a_dwell_is_answered_once_the_planner_is_empty_and_it_is_over() {
    let mut s = session(16);
    assert_eq!(talk(&mut s, b"X5\nG4P100\nX6\n"), "ok\r\n");
    s.motion.run();
    assert_eq!(talk(&mut s, b""), "");
    s.motion.run();
    let mut out = String::new();
    s.poll(&mut out).unwrap();
    assert_eq!(out, "ok\r\nok\r\n");
    assert_eq!(s.motion.queue.len(), 1);
}

#[test]
fn offsets_report() {
    let mut s = session(16);
    let out = talk(&mut s, b"$#\n");
    assert!(out.starts_with("[G54:0.000,0.000,0.000]\r\n[G55:0.000,0.000,0.000]\r\n"));
    assert!(out
        .contains("[G92:1.500,0.000,0.000]\r\n[TLO:0.000]\r\n[PRB:0.000,0.000,0.000:0]\r\nok\r\n"));
}

#[test]
fn dollar_commands_need_idle() {
    let mut s = session(16);
    talk(&mut s, b"X5\n");
    assert_eq!(talk(&mut s, b"$$\n"), "error:8\r\n");
    assert_eq!(talk(&mut s, b"$100=10\n"), "error:8\r\n");
    assert!(talk(&mut s, b"$G\n").ends_with("ok\r\n"));
}
