//! The board-independent firmware on the host: a fake board whose clock
//! jumps to each wake-up the step interrupt asks for, the protocol fed
//! byte by byte, and the pins it drives recorded with their CTs.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

use cogstep_firmware::{core_config, Firmware, Hardware, Output, Variant};
use driver::axis_core::{AxisCore, CoreCommand, Edge};
use driver::serial::Session;
use proptest::prelude::*;

const CLKFREQ: u32 = 50_000_000;

/// One pin change the firmware made: CT, axis, output, level.
type Drive = (u64, usize, Output, bool);

struct FakeState {
    now: AtomicU64,
    requested: AtomicBool,
    drives: Mutex<Vec<Drive>>,
}

#[derive(Clone, Copy)]
struct FakeBoard(&'static FakeState);

impl Hardware for FakeBoard {
    fn now_ticks(&self) -> u64 {
        self.0.now.load(Ordering::SeqCst)
    }
    fn request_step_interrupt(&self) {
        self.0.requested.store(true, Ordering::SeqCst);
    }
    fn set_pin(&self, axis: usize, output: Output, level: bool) {
        let now = self.now_ticks();
        self.set_pin_at(axis, output, level, now);
    }
    /// A queue ahead of the pins, as the Pico's: each edge with its CT.
    fn set_pin_at(&self, axis: usize, output: Output, level: bool, ct: u64) {
        self.0
            .drives
            .lock()
            .unwrap()
            .push((ct, axis, output, level));
    }
}

fn board() -> FakeBoard {
    FakeBoard(Box::leak(Box::new(FakeState {
        now: AtomicU64::new(0),
        requested: AtomicBool::new(false),
        drives: Mutex::new(Vec::new()),
    })))
}

fn variant(index: usize) -> Variant {
    if index.is_multiple_of(2) {
        Variant::Sd
    } else {
        Variant::Cc
    }
}

fn firmware(board: FakeBoard, axes: usize) -> Firmware<FakeBoard> {
    Firmware::new(board, axes, |index| core_config(CLKFREQ, variant(index))).unwrap()
}

fn send(firmware: &Firmware<FakeBoard>, session: &mut Session, bytes: &[u8]) -> String {
    let mut out = String::new();
    for &byte in bytes {
        firmware.feed(session, byte, &mut out).unwrap();
    }
    out
}

/// Runs the step interrupt at every wake-up it asks for until `until`
/// (`u64::MAX`: until nothing is left, the clock at the last event).
fn run(firmware: &Firmware<FakeBoard>, board: FakeBoard, until: u64) {
    run_with(firmware, board, until, false);
}

/// [`run`], with `ahead` as the Pico's main loop runs it
/// ([`Firmware::step_interrupt_ahead`]: falling edges queued ahead up
/// to `until`). Returns the wake-ups it took.
fn run_with(firmware: &Firmware<FakeBoard>, board: FakeBoard, until: u64, ahead: bool) -> usize {
    let mut wakes = 0;
    loop {
        wakes += 1;
        let (next, _) = if ahead {
            firmware.step_interrupt_ahead(board.now_ticks(), until)
        } else {
            firmware.step_interrupt()
        };
        match next {
            Some(t) if t <= until => board.0.now.store(t, Ordering::SeqCst),
            _ => {
                if until != u64::MAX {
                    let now = board.0.now.load(Ordering::SeqCst);
                    board.0.now.store(until.max(now), Ordering::SeqCst);
                }
                return wakes;
            }
        }
    }
}

#[test]
fn boots_with_its_identity_and_runs_moves_to_their_targets() {
    let board = board();
    let firmware = firmware(board, 2);
    let mut boot = String::new();
    firmware.announce(&mut boot).unwrap();
    assert_eq!(
        boot,
        format!(
            "[cogstep {} proto:1 axes:2 clkfreq:50000000]\n",
            env!("CARGO_PKG_VERSION")
        )
    );
    let mut session = Session::new();
    assert_eq!(
        send(&firmware, &mut session, b"M 0 5000 -300\nM 1 4000 200\n"),
        "ok\nok\n"
    );
    assert!(board.0.requested.load(Ordering::SeqCst));
    run(&firmware, board, u64::MAX);
    assert_eq!(
        send(&firmware, &mut session, b"?"),
        "<0|Idle|pos:-300|stm:0|togo:0|mode:000000|vel:0|stop:high>\n\
         <1|Idle|pos:200|stm:0|togo:0|mode:000000|vel:0|stop:high>\n"
    );
    let counts = [
        firmware.axes()[0].edge_counts(),
        firmware.axes()[1].edge_counts(),
    ];
    // sd: 300 pulses on the step pin, the direction pin raised once.
    assert_eq!(counts[0].rising, [300, 1]);
    assert_eq!(counts[0].falling, [300, 0]);
    // cc: 200 pulses on cw, none on ccw.
    assert_eq!(counts[1].rising, [200, 0]);
    assert_eq!(counts[1].falling, [200, 0]);
}

#[test]
fn bad_input_is_refused_and_changes_nothing() {
    let board = board();
    let firmware = firmware(board, 1);
    let mut session = Session::new();
    let before = send(&firmware, &mut session, b"?");
    for (line, reply) in [
        ("M 0 0 100\n", "error:6 speed out of range\n"),
        ("M 0 100 0\n", "error:2 bad argument\n"),
        (
            "M 0 1000000 100\n",
            "error:6 speed out of range: no room for the step pulse at 1000000 steps/s\n",
        ),
        (
            "M 0 4294967295 2147483647\n",
            "error:6 speed out of range: 4294967295 steps/s is too fast for 50000000 Hz\n",
        ),
        (
            "M 0 50000000 100\n",
            "error:6 speed out of range: no room for the step pulse at 50000000 steps/s\n",
        ),
        ("M 3 100 100\n", "error:4 no such axis\n"),
        ("Q\n", "error:1 unknown command\n"),
    ] {
        assert_eq!(
            send(&firmware, &mut session, line.as_bytes()),
            reply,
            "{line}"
        );
    }
    run(&firmware, board, u64::MAX);
    assert_eq!(send(&firmware, &mut session, b"?"), before);
    assert!(board.0.drives.lock().unwrap().is_empty());
}

/// The edges the core decides on its own for the same commands, each
/// given the direction set-up time after the firmware got it (the
/// firmware's core runs that far ahead of its clock).
fn core_edges(commands: &[(u64, i32)], speed: u32) -> Vec<Edge> {
    let config = core_config(CLKFREQ, Variant::Sd);
    let lookahead = u64::from(config.dir_setup_ticks);
    let mut core = AxisCore::new(config, 0);
    core.set_stop_pin(lookahead, true);
    let mut edges = Vec::new();
    for &(ct, steps) in commands {
        core.run_until(ct + lookahead, &mut |edge| edges.push(edge));
        core.command(ct + lookahead, CoreCommand::Move { speed, steps })
            .unwrap();
    }
    core.run_until(u64::MAX, &mut |edge| edges.push(edge));
    edges
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Moves given while the axis is idle: the firmware drives exactly the
    /// edges the core decides, each at its CT (the fake clock is never
    /// late), so the direction set-up and the pulse width hold, and the
    /// axis ends at the sum of the moves.
    #[test]
    fn the_pins_follow_the_core_edge_for_edge(
        moves in proptest::collection::vec((-400i32..400, 0u64..2_000_000), 1..5),
        speed in 500u32..40_000,
    ) {
        let moves: Vec<(i32, u64)> = moves.into_iter().filter(|(steps, _)| *steps != 0).collect();
        prop_assume!(!moves.is_empty());
        let board = board();
        let firmware = firmware(board, 1);
        let axis = &firmware.axes()[0];
        let mut commands = Vec::new();
        let mut target = 0i64;
        for (steps, gap) in moves {
            // Until idle, then a gap.
            run(&firmware, board, u64::MAX);
            let at = board.0.now.load(Ordering::SeqCst) + gap;
            run(&firmware, board, at);
            use driver::axis::AxisContract;
            axis.move_steps(speed, steps).unwrap();
            commands.push((at, steps));
            target += i64::from(steps);
        }
        run(&firmware, board, u64::MAX);
        use driver::axis::AxisContract;
        prop_assert_eq!(axis.status().unwrap().position, target);
        let expected: Vec<(u64, Output, bool)> = core_edges(&commands, speed)
            .into_iter()
            .map(|edge| (edge.ct, if edge.pin == 0 { Output::First } else { Output::Second }, edge.level))
            .collect();
        let driven: Vec<(u64, Output, bool)> = board.0.drives.lock().unwrap()
            .iter()
            .map(|&(ct, _, output, level)| (ct, output, level))
            .collect();
        prop_assert_eq!(driven, expected);
    }
}

/// What a test does to an axis at a CT: a move, its stop pin, an
/// emergency stop.
#[derive(Clone, Copy, Debug)]
enum Act {
    Move(u32, i32),
    StopPin(bool),
    EmergencyStop,
}

fn act_strategy() -> impl Strategy<Value = Act> {
    prop_oneof![
        6 => (500u32..40_000, -300i32..300)
            .prop_filter("a move has steps", |(_, steps)| *steps != 0)
            .prop_map(|(speed, steps)| Act::Move(speed, steps)),
        1 => any::<bool>().prop_map(Act::StopPin),
        1 => Just(Act::EmergencyStop),
    ]
}

/// Every pin change of the script `acts` (gap before it, axis, act),
/// run one way or the other, with the wake-ups it took.
fn drives_of(axes: usize, acts: &[(u64, usize, Act)], ahead: bool) -> (Vec<Drive>, usize) {
    use driver::axis::AxisContract;
    let board = board();
    let firmware = firmware(board, axes);
    let mut wakes = 0;
    for &(gap, axis, act) in acts {
        let at = board.now_ticks() + gap;
        wakes += run_with(&firmware, board, at, ahead);
        let axis = &firmware.axes()[axis % axes];
        // Refusals (a move while one reverses, say) are the same both ways.
        let _ = match act {
            Act::Move(speed, steps) => axis.move_steps(speed, steps),
            Act::StopPin(level) => axis.set_stop_pin(level),
            Act::EmergencyStop => axis.emergency_stop(),
        };
    }
    wakes += run_with(&firmware, board, u64::MAX, ahead);
    let drives = board.0.drives.lock().unwrap().clone();
    (drives, wakes)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Falling edges queued ahead (the Pico's main loop): on up to four
    /// axes, with moves, stop pins and emergency stops arriving mid-move,
    /// the very edges the step interrupt drives at their CTs, reaching the
    /// board in CT order, with fewer wake-ups.
    #[test]
    fn falls_queued_ahead_are_the_same_edges_in_ct_order(
        axes in 1usize..=4,
        acts in proptest::collection::vec((0u64..400_000, 0usize..4, act_strategy()), 1..8),
    ) {
        let (at_their_ct, plain_wakes) = drives_of(axes, &acts, false);
        let (ahead, ahead_wakes) = drives_of(axes, &acts, true);
        prop_assert!(
            ahead.windows(2).all(|pair| pair[0].0 <= pair[1].0),
            "out of CT order: {:?}",
            ahead.windows(2).find(|pair| pair[0].0 > pair[1].0)
        );
        // The same edges: compared in one order (edges of different axes at
        // one CT may reach the board in either order).
        let key = |drive: &Drive| (drive.0, drive.1, drive.2.index(), drive.3);
        let mut sorted = at_their_ct.clone();
        sorted.sort_by_key(key);
        let mut ahead_sorted = ahead.clone();
        ahead_sorted.sort_by_key(key);
        prop_assert_eq!(ahead_sorted, sorted);
        let pulses = at_their_ct.iter().filter(|drive| !drive.3).count();
        prop_assert!(ahead_wakes <= plain_wakes, "{} > {}", ahead_wakes, plain_wakes);
        if pulses > 20 {
            prop_assert!(ahead_wakes < plain_wakes, "{} pulses, {} wake-ups both ways", pulses, plain_wakes);
        }
    }
}

#[test]
fn soft_limits_over_the_protocol_and_no_homing_without_switch_inputs() {
    let board = board();
    let firmware = firmware(board, 2);
    let mut session = Session::new();
    assert_eq!(send(&firmware, &mut session, b"W 0 -100 500\n"), "ok\n");
    assert_eq!(
        send(&firmware, &mut session, b"M 0 5000 501\n"),
        "error:9 limit: beyond a soft limit\n"
    );
    assert_eq!(send(&firmware, &mut session, b"M 0 5000 500\n"), "ok\n");
    run(&firmware, board, u64::MAX);
    assert_eq!(
        send(&firmware, &mut session, b"L 0\n"),
        "[limits 0 soft:-100,500 min:- max:-]\n[fault 0 none]\n[home 0 none]\nok\n"
    );
    assert_eq!(
        send(
            &firmware,
            &mut session,
            b"H 0 10 1 - 8000 500 200 100000 0\n"
        ),
        "error:1 not supported: homing\n"
    );
    assert_eq!(
        send(&firmware, &mut session, b"K 0 11/1 -\n"),
        "error:1 not supported: hard limits\n"
    );
}
