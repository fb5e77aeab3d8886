//! The board-independent firmware on the host: a fake board whose clock
//! jumps to each wake-up the step interrupt asks for, the protocol fed
//! byte by byte, and the pins it drives recorded with their CTs.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Mutex;

use cogstep_firmware::{
    core_config, Firmware, Hardware, Output, RunAheadTicks, TrainRises, Variant,
};
use cogstep_handoff::AheadSlot;
use driver::axis::{AxisContract, AxisError, Direction};
use driver::axis_core::{AxisCore, CoreCommand, Edge};
use driver::profile::scurve::SCurve;
use driver::serial::Session;
use proptest::prelude::*;

const CLKFREQ: u32 = 50_000_000;

/// One pin change the firmware made: CT, axis, output, level.
type Drive = (u64, usize, Output, bool);

struct FakeState {
    now: AtomicU64,
    requested: AtomicBool,
    drives: Mutex<Vec<Drive>>,
    /// The switch inputs the board reads (bit per pin; none by default).
    switches: u64,
    /// Whether the board ends its step pulses itself, as the Pico's PIO
    /// state machines do.
    pulses_end_themselves: bool,
    /// Whether it keeps each axis's edges in that axis's own order (and
    /// ends its pulses), as the Pico's PIO build: trains' steps come a
    /// run at a time.
    rises_per_axis: bool,
    /// Whether it takes a train's steps a run at a time
    /// (`TrainRises::fill`, in runs of 1 to 5 steps in turn), as the
    /// Pico's PIO build does, rather than one `next` each.
    fills: bool,
    /// Runs filled so far (their lengths go round 1..=5).
    filled: AtomicU32,
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
    fn switch_pins(&self) -> u64 {
        self.0.switches
    }
    fn pulses_end_themselves(&self) -> bool {
        self.0.pulses_end_themselves
    }
    fn rises_per_axis(&self) -> bool {
        self.0.rises_per_axis
    }
    fn set_rises_at(&self, axis: usize, output: Output, rises: &mut TrainRises<'_>) {
        if !self.0.fills {
            for ct in rises {
                self.set_pin_at(axis, output, true, ct);
            }
            return;
        }
        let mut run = [0; 5];
        loop {
            let len = 1 + self.0.filled.fetch_add(1, Ordering::SeqCst) as usize % run.len();
            let made = rises.fill(&mut run[..len]);
            for &ct in &run[..made] {
                self.set_pin_at(axis, output, true, ct);
            }
            if made < len {
                return;
            }
        }
    }
}

fn board() -> FakeBoard {
    board_reading(0)
}

/// A fake board that reads the switch inputs `switches` (bit per pin).
fn board_reading(switches: u64) -> FakeBoard {
    FakeBoard(Box::leak(Box::new(FakeState {
        now: AtomicU64::new(0),
        requested: AtomicBool::new(false),
        drives: Mutex::new(Vec::new()),
        switches,
        pulses_end_themselves: false,
        rises_per_axis: false,
        fills: false,
        filled: AtomicU32::new(0),
    })))
}

/// A fake board whose hardware ends each step pulse itself (the Pico's
/// PIO build), its axes' edges in one CT order or (`rises_per_axis`)
/// each axis's in its own.
fn board_ending_pulses(rises_per_axis: bool, fills: bool) -> FakeBoard {
    FakeBoard(Box::leak(Box::new(FakeState {
        now: AtomicU64::new(0),
        requested: AtomicBool::new(false),
        drives: Mutex::new(Vec::new()),
        switches: 0,
        pulses_end_themselves: true,
        rises_per_axis,
        fills,
        filled: AtomicU32::new(0),
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
    run_with(firmware, board, until, Way::AtTheirCt);
}

/// How the board runs the step interrupt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Way {
    /// At each wake-up, its edges driven then ([`Firmware::step_interrupt`]).
    AtTheirCt,
    /// As the Pico's main loop did: falling edges queued ahead up to the
    /// run's end ([`Firmware::step_interrupt_ahead`]).
    FallsAhead,
    /// As the Pico's main loop does: trains' steps too, up to
    /// [`RISES_AHEAD`] a call ([`Firmware::step_interrupt_ahead_trains`]).
    TrainsAhead,
    /// As the Pico's PIO build does: [`Way::TrainsAhead`] on a board whose
    /// pulses end themselves (a step made ahead takes its falling edge
    /// with it, and the board does not get it).
    PulsesEndThemselves,
    /// As the Pico's PIO build does: [`Way::PulsesEndThemselves`] on a
    /// board that keeps each axis's edges in their own order, a train's
    /// steps up to the frontier at once.
    RisesPerAxis,
    /// [`Way::RisesPerAxis`], the board taking each train's steps a run
    /// at a time (`TrainRises::fill`), as the Pico's PIO build does.
    RisesPerAxisFilled,
}

/// The rising edges one call may queue ahead, as the Pico's main loop.
const RISES_AHEAD: usize = 8;

fn way() -> impl Strategy<Value = Way> {
    prop_oneof![
        Just(Way::AtTheirCt),
        Just(Way::FallsAhead),
        Just(Way::TrainsAhead),
        Just(Way::PulsesEndThemselves)
    ]
}

/// [`run`], the way `way`, up to `until` (the board's frontier: no
/// command acts before it). Returns the wake-ups it took.
fn run_with(firmware: &Firmware<FakeBoard>, board: FakeBoard, until: u64, way: Way) -> usize {
    run_helped(firmware, board, until, way, &mut || {})
}

/// [`run_with`], `helper` run before each wake-up (a second core).
fn run_helped(
    firmware: &Firmware<FakeBoard>,
    board: FakeBoard,
    until: u64,
    way: Way,
    helper: &mut dyn FnMut(),
) -> usize {
    let mut wakes = 0;
    loop {
        helper();
        wakes += 1;
        let now = board.now_ticks();
        let (next, _) = match way {
            Way::AtTheirCt => firmware.step_interrupt(),
            Way::FallsAhead => firmware.step_interrupt_ahead(now, until),
            Way::TrainsAhead
            | Way::PulsesEndThemselves
            | Way::RisesPerAxis
            | Way::RisesPerAxisFilled => {
                firmware.step_interrupt_ahead_trains(now, until, until, RISES_AHEAD)
            }
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
    /// A jog (or its heartbeat) forward (true) or back.
    Jog(u32, bool),
    JogRelease,
    StopPin(bool),
    EmergencyStop,
}

fn act_strategy() -> impl Strategy<Value = Act> {
    prop_oneof![
        6 => (500u32..40_000, -300i32..300)
            .prop_filter("a move has steps", |(_, steps)| *steps != 0)
            .prop_map(|(speed, steps)| Act::Move(speed, steps)),
        2 => (500u32..40_000, any::<bool>()).prop_map(|(speed, forward)| Act::Jog(speed, forward)),
        1 => Just(Act::JogRelease),
        1 => any::<bool>().prop_map(Act::StopPin),
        1 => Just(Act::EmergencyStop),
    ]
}

/// Every pin change of the script `acts` (gap before it, axis, act),
/// run one way or the other, with the wake-ups it took.
fn drives_of(axes: usize, acts: &[(u64, usize, Act)], way: Way) -> (Vec<Drive>, usize) {
    let (drives, wakes, _) = drives_helped(axes, acts, way, None, always);
    (drives, wakes)
}

/// A board whose helper answers at once: it is always asked.
fn always() -> u64 {
    0
}

/// A board whose helper is, one request in three, too far behind to be
/// asked.
fn now_and_then() -> u64 {
    static ASKED: AtomicU32 = AtomicU32::new(0);
    if ASKED.fetch_add(1, Ordering::Relaxed).is_multiple_of(3) {
        u64::MAX
    } else {
        0
    }
}

/// [`drives_of`] with ramp runs computed ahead by a helper (a second core)
/// that serves every axis's request at every `every`-th wake-up, when
/// given, each asked when its run lasts `answer_ticks`; also returns the
/// runs the axes took from it.
fn drives_helped(
    axes: usize,
    acts: &[(u64, usize, Act)],
    way: Way,
    every: Option<usize>,
    answer_ticks: RunAheadTicks,
) -> (Vec<Drive>, usize, u32) {
    use driver::axis::AxisContract;
    let board = match way {
        Way::PulsesEndThemselves => board_ending_pulses(false, false),
        Way::RisesPerAxis => board_ending_pulses(true, false),
        Way::RisesPerAxisFilled => board_ending_pulses(true, true),
        _ => board(),
    };
    let firmware = firmware(board, axes);
    let slots: Vec<&'static AheadSlot<SCurve>> = (0..axes)
        .map(|_| &*Box::leak(Box::new(AheadSlot::new())))
        .collect();
    if every.is_some() {
        for (axis, slot) in firmware.axes().iter().zip(&slots) {
            axis.set_run_ahead(slot, answer_ticks);
        }
    }
    let mut turn = 0;
    let mut helper = || {
        turn += 1;
        if every.is_some_and(|every| turn % every == 0) {
            for slot in &slots {
                slot.serve(SCurve::arm_run_ahead_from);
            }
        }
    };
    let mut wakes = 0;
    for &(gap, axis, act) in acts {
        let at = board.now_ticks() + gap;
        wakes += run_helped(&firmware, board, at, way, &mut helper);
        let axis = &firmware.axes()[axis % axes];
        // Refusals (a move while one reverses, say) are the same both ways.
        let _ = match act {
            Act::Move(speed, steps) => axis.move_steps(speed, steps),
            Act::Jog(speed, forward) => axis.jog(
                speed,
                if forward {
                    Direction::Forward
                } else {
                    Direction::Reverse
                },
            ),
            Act::JogRelease => axis.jog_release(),
            Act::StopPin(level) => axis.set_stop_pin(level),
            Act::EmergencyStop => axis.emergency_stop(),
        };
    }
    wakes += run_helped(&firmware, board, u64::MAX, way, &mut helper);
    let drives = board.0.drives.lock().unwrap().clone();
    let taken = firmware.axes().iter().map(|axis| axis.runs_taken()).sum();
    (drives, wakes, taken)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Falling edges queued ahead, and trains' steps (the Pico's main
    /// loop): on up to four axes, with moves, stop pins and emergency stops
    /// arriving mid-move, the very edges the step interrupt drives at their
    /// CTs, reaching the board in CT order, with fewer wake-ups.
    #[test]
    fn falls_queued_ahead_are_the_same_edges_in_ct_order(
        axes in 1usize..=4,
        acts in proptest::collection::vec((0u64..400_000, 0usize..4, act_strategy()), 1..8),
    ) {
        let (at_their_ct, plain_wakes) = drives_of(axes, &acts, Way::AtTheirCt);
        // The same edges: compared in one order (edges of different axes at
        // one CT may reach the board in either order).
        let key = |drive: &Drive| (drive.0, drive.1, drive.2.index(), drive.3);
        let mut sorted = at_their_ct.clone();
        sorted.sort_by_key(key);
        let pulses = at_their_ct.iter().filter(|drive| !drive.3).count();
        let mut fewer_than = plain_wakes;
        let mut trains = Vec::new();
        for way in [Way::FallsAhead, Way::TrainsAhead] {
            let (ahead, ahead_wakes) = drives_of(axes, &acts, way);
            prop_assert!(
                ahead.windows(2).all(|pair| pair[0].0 <= pair[1].0),
                "{:?}: out of CT order: {:?}",
                way,
                ahead.windows(2).find(|pair| pair[0].0 > pair[1].0)
            );
            let mut ahead_sorted = ahead.clone();
            ahead_sorted.sort_by_key(key);
            prop_assert_eq!(ahead_sorted, sorted.clone(), "{:?}", way);
            prop_assert!(ahead_wakes <= fewer_than, "{:?}: {} > {}", way, ahead_wakes, fewer_than);
            if pulses > 20 && way == Way::FallsAhead {
                prop_assert!(ahead_wakes < plain_wakes, "{} pulses, {} wake-ups both ways", pulses, plain_wakes);
            }
            fewer_than = ahead_wakes;
            trains = ahead;
        }
        // A board whose pulses end themselves: the same rising edges, in
        // CT order; of the falling edges, those of steps made ahead do not
        // reach it (the rest do, as they did); no more wake-ups.
        let (ended, ended_wakes) = drives_of(axes, &acts, Way::PulsesEndThemselves);
        let rising = |drives: &[Drive]| -> Vec<Drive> {
            drives.iter().copied().filter(|drive| drive.3).collect()
        };
        prop_assert_eq!(rising(&ended), rising(&trains));
        prop_assert!(ended.windows(2).all(|pair| pair[0].0 <= pair[1].0));
        let mut ended_falls: Vec<Drive> = ended.iter().copied().filter(|drive| !drive.3).collect();
        ended_falls.sort_by_key(key);
        let all_falls: Vec<Drive> = sorted.iter().copied().filter(|drive| !drive.3).collect();
        prop_assert!(
            ended_falls.iter().all(|fall| all_falls.binary_search_by_key(&key(fall), key).is_ok()),
            "a falling edge the step interrupt never drives"
        );
        prop_assert!(ended_wakes <= fewer_than, "{} > {}", ended_wakes, fewer_than);
        // A board that keeps each axis's edges in their own order: each
        // axis gets the very rising edges it got in one CT order, in its
        // own CT order; of the falling edges, those of steps made ahead
        // (more of them now) do not reach it.
        let (per_axis, _) = drives_of(axes, &acts, Way::RisesPerAxis);
        for axis in 0..axes {
            let of = |drives: &[Drive]| -> Vec<Drive> {
                drives.iter().copied().filter(|drive| drive.1 == axis).collect()
            };
            let mine = of(&per_axis);
            prop_assert!(mine.windows(2).all(|pair| pair[0].0 <= pair[1].0), "axis {}", axis);
            prop_assert_eq!(rising(&mine), rising(&of(&ended)), "axis {}", axis);
        }
        prop_assert!(
            per_axis
                .iter()
                .filter(|drive| !drive.3)
                .all(|fall| all_falls.binary_search_by_key(&key(fall), key).is_ok()),
            "a falling edge the step interrupt never drives"
        );
        // Taking a train's steps a run at a time: the very same edges in
        // the very same order.
        let (filled, _) = drives_of(axes, &acts, Way::RisesPerAxisFilled);
        prop_assert_eq!(filled, per_axis);
    }

    /// Trains' steps queued ahead, the Pico's way: the steps of moves that
    /// started apart (as commands over a serial line do), at speed and on
    /// their ramps, take a fraction of the wake-ups that falls ahead alone
    /// take, for the same edges. (Axes that step on the very same CTs share
    /// their wake-ups instead.)
    #[test]
    fn trains_ahead_take_a_wake_up_per_run_of_steps(
        axes in 1usize..=4,
        speed in 2_000u32..40_000,
        steps in 200i32..2_000,
        gap in 1u64..20_000,
    ) {
        let acts: Vec<(u64, usize, Act)> =
            (0..axes).map(|axis| (gap, axis, Act::Move(speed, steps))).collect();
        let (falls, falls_wakes) = drives_of(axes, &acts, Way::FallsAhead);
        let (trains, trains_wakes) = drives_of(axes, &acts, Way::TrainsAhead);
        prop_assert_eq!(&trains, &falls);
        // Every rising edge a wake-up before; now most come RISES_AHEAD at a time.
        let rising = falls.iter().filter(|drive| drive.3).count();
        prop_assert!(rising >= axes * steps as usize);
        prop_assert!(
            trains_wakes * 2 < falls_wakes,
            "{} wake-ups with trains ahead, {} with falls ahead, {} rising edges",
            trains_wakes, falls_wakes, rising
        );
        // Pulses that end themselves, and then each axis's steps a run
        // at a time: the same rising edges, and about as few wake-ups. (A
        // run of one axis ends where that axis's ramp run does, so a
        // wake-up the one CT order shared between axes may fall apart:
        // with block ramp runs, 3 axes at 2,000 steps/s, 380 steps, 13,334
        // ticks apart take 162 against 161.)
        let (ended, ended_wakes) = drives_of(axes, &acts, Way::PulsesEndThemselves);
        let (per_axis, per_axis_wakes) = drives_of(axes, &acts, Way::RisesPerAxis);
        let rising_of = |drives: &[Drive], axis: usize| -> Vec<u64> {
            drives.iter().filter(|drive| drive.1 == axis && drive.3).map(|drive| drive.0).collect()
        };
        for axis in 0..axes {
            prop_assert_eq!(rising_of(&per_axis, axis), rising_of(&trains, axis));
            prop_assert_eq!(rising_of(&ended, axis), rising_of(&trains, axis));
        }
        prop_assert!(ended_wakes <= trains_wakes, "{} > {}", ended_wakes, trains_wakes);
        prop_assert!(
            per_axis_wakes <= ended_wakes + axes,
            "{} > {} + {}", per_axis_wakes, ended_wakes, axes
        );
        prop_assert!(per_axis_wakes * 2 < falls_wakes, "{} against {}", per_axis_wakes, falls_wakes);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Ramp runs computed ahead by a second core (the Pico's core 1),
    /// answering at once, late or never, and asked always or only now and
    /// then (a board's judge that it would answer late): the very same
    /// edges at the very same CTs, in the same order, with moves, jogs,
    /// stop pins and emergency stops arriving mid-move, the Pico's two
    /// ways.
    #[test]
    fn runs_computed_ahead_change_no_edge(
        axes in 1usize..=4,
        acts in proptest::collection::vec((0u64..400_000, 0usize..4, act_strategy()), 1..8),
        every in prop_oneof![Just(1usize), 1usize..40],
        per_axis in any::<bool>(),
        behind in any::<bool>(),
    ) {
        let way = if per_axis { Way::RisesPerAxisFilled } else { Way::TrainsAhead };
        let answer_ticks: RunAheadTicks = if behind { now_and_then } else { always };
        let (alone, _) = drives_of(axes, &acts, way);
        let (helped, _, _) = drives_helped(axes, &acts, way, Some(every), answer_ticks);
        prop_assert_eq!(helped, alone);
    }
}

/// Four axes ramping to 20,000 steps/s, a helper answering at every
/// wake-up: nearly every ramp run after an axis's first comes from it,
/// and the edges are the ones the axes make alone.
#[test]
fn runs_computed_ahead_are_taken_on_long_ramps() {
    let acts: Vec<(u64, usize, Act)> = (0..4)
        .map(|axis| (1_000, axis, Act::Move(20_000, 10_000)))
        .collect();
    for way in [Way::TrainsAhead, Way::RisesPerAxis] {
        let (alone, _) = drives_of(4, &acts, way);
        let (helped, _, taken) = drives_helped(4, &acts, way, Some(1), always);
        assert_eq!(helped, alone, "{way:?}");
        // 2,002 ramp steps each side, in runs of a cosine block (64 steps
        // on a host) or to a block's end.
        let runs = 4 * 2 * 2_002 / 64;
        assert!(
            taken * 10 >= runs * 9,
            "{way:?}: {taken} runs taken of about {runs}"
        );
        // A board whose helper would answer late asks nothing: the axes
        // compute every run, the same edges.
        let (unasked, _, taken) = drives_helped(4, &acts, way, Some(1), never);
        assert_eq!(unasked, alone, "{way:?}");
        assert_eq!(taken, 0, "{way:?}: runs taken from a helper never asked");
    }
}

/// A board whose helper is always too far behind to be asked.
fn never() -> u64 {
    u64::MAX
}

/// Trains' steps go ahead only up to the frontier the board gives (no
/// command acts before it), however far the pulses' falling edges may go:
/// a rising edge past it waits for a wake-up at its CT.
#[test]
fn trains_ahead_stop_at_the_frontier() {
    use driver::axis::AxisContract;
    let frontier = CLKFREQ as u64 * 3 / 10;
    let rising_by = |way: Way| {
        let board = board();
        let firmware = firmware(board, 1);
        firmware.axes()[0].move_steps(5_000, 4_000).unwrap();
        let mut now = 0;
        let next = loop {
            let (next, _) = match way {
                Way::TrainsAhead => {
                    firmware.step_interrupt_ahead_trains(now, frontier + 50_000, frontier, 1_000)
                }
                _ => firmware.step_interrupt_ahead(now, frontier),
            };
            match next {
                Some(t) if t <= frontier => {
                    now = t;
                    board.0.now.store(t, Ordering::SeqCst);
                }
                other => break other,
            }
        };
        let drives = board.0.drives.lock().unwrap().clone();
        let rising: Vec<u64> = drives
            .iter()
            .filter(|drive| drive.3)
            .map(|drive| drive.0)
            .collect();
        (rising, next)
    };
    let (ahead, next) = rising_by(Way::TrainsAhead);
    let (falls_only, _) = rising_by(Way::FallsAhead);
    // 0.3 s into a move at 5,000 steps/s: hundreds of steps, at speed.
    assert!(ahead.len() > 500, "{} rising edges", ahead.len());
    assert_eq!(ahead, falls_only);
    assert!(ahead.iter().all(|&ct| ct <= frontier));
    assert!(next.is_some_and(|t| t > frontier), "{next:?}");
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

/// What a test does in a group-move script, over the protocol.
#[derive(Clone, Debug)]
enum GroupAct {
    /// `G <speed> <steps…>`.
    Group(u32, Vec<i32>),
    /// `M <axis> <speed> <steps>`.
    Move(usize, u32, i32),
    /// `S <axis>` (false) or `R <axis>` (true).
    StopPin(usize, bool),
    /// `!`: every stop pin low.
    StopAll,
    /// `E`.
    EmergencyStop,
}

fn group_act() -> impl Strategy<Value = GroupAct> {
    prop_oneof![
        4 => (2_000u32..40_000, proptest::collection::vec(-1_500i32..1_500, 1..=4))
            .prop_map(|(speed, steps)| GroupAct::Group(speed, steps)),
        2 => (0usize..4, 2_000u32..30_000, -800i32..800)
            .prop_filter("a move has steps", |(_, _, steps)| *steps != 0)
            .prop_map(|(axis, speed, steps)| GroupAct::Move(axis, speed, steps)),
        3 => (0usize..4, any::<bool>()).prop_map(|(axis, high)| GroupAct::StopPin(axis, high)),
        1 => Just(GroupAct::StopAll),
        1 => Just(GroupAct::EmergencyStop),
    ]
}

/// The reference for group moves on the firmware: one motion-crate core
/// per axis, driven directly, with the firmware's group rules written out
/// (reserve every member or none, start all on the CT a move would take,
/// a member's stop pin low stops every member of a group still running
/// after the same CT, an axis leaves its group with a move of its own).
struct GroupModel {
    cores: Vec<AxisCore>,
    edges: Vec<Vec<Edge>>,
    /// Each axis's group: (number, members as a bit set).
    records: Vec<Option<(u32, u8)>>,
    next_id: u32,
}

impl GroupModel {
    fn new(axes: usize) -> Self {
        let cores = (0..axes)
            .map(|index| {
                let mut core = AxisCore::new(core_config(CLKFREQ, variant(index)), 0);
                core.set_stop_pin(0, true);
                core
            })
            .collect();
        GroupModel {
            cores,
            edges: vec![Vec::new(); axes],
            records: vec![None; axes],
            next_id: 0,
        }
    }

    /// Every core's events up to core CT `ct`.
    fn run_to(&mut self, ct: u64) {
        for (core, edges) in self.cores.iter_mut().zip(&mut self.edges) {
            core.run_until(ct, &mut |edge| edges.push(edge));
        }
    }

    fn group(&mut self, ct: u64, speed: u32, steps: &[i32]) -> Result<(), AxisError> {
        let lead_steps = steps.iter().map(|s| s.unsigned_abs()).max().unwrap();
        if lead_steps > 0 {
            let config = *self.cores[0].config();
            AxisCore::check_move(&config, speed, i32::try_from(lead_steps).unwrap())?;
        }
        for (index, &part) in steps.iter().enumerate() {
            if let Err(error) =
                self.cores[index].command(ct, CoreCommand::GroupReserve { steps: part })
            {
                for core in &mut self.cores[..index] {
                    core.command(ct, CoreCommand::GroupCancel).unwrap();
                }
                return Err(error);
            }
        }
        let record = (self.next_id, (1u8 << steps.len()) - 1);
        self.next_id += 1;
        for (index, &part) in steps.iter().enumerate() {
            let group = driver::axis_core::GroupMove {
                speed,
                lead_steps,
                steps: part,
                start_ct: ct,
            };
            self.cores[index]
                .command(ct, CoreCommand::GroupStart(group))
                .unwrap();
            self.records[index] = Some(record);
        }
        Ok(())
    }

    /// The members of axis `index`'s group, while a part of it runs.
    fn live_members(&self, index: usize) -> Vec<usize> {
        let Some(record) = self.records[index] else {
            return Vec::new();
        };
        let members: Vec<usize> = (0..self.cores.len())
            .filter(|&member| self.records[member] == Some(record))
            .collect();
        if members.iter().any(|&member| self.cores[member].in_group()) {
            members
        } else {
            Vec::new()
        }
    }

    /// A stop pin low on any member of a running group stops them all
    /// after `ct`.
    fn pass_stops(&mut self, ct: u64) {
        for index in 0..self.cores.len() {
            if !self.cores[index].stop_pin_high() {
                for member in self.live_members(index) {
                    self.cores[member].stop_group_after(ct);
                }
            }
        }
    }
}

fn group_line(speed: u32, steps: &[i32]) -> String {
    let steps: Vec<String> = steps.iter().map(i32::to_string).collect();
    format!("G {speed} {}\n", steps.join(" "))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Group moves over the protocol, with moves, stop pins (of members and
    /// not), `!` and `E` arriving mid-move: every reply is the reference's
    /// (ok, or the same refusal with nothing changed), every status line
    /// agrees after every line, and every axis's pins get the reference's
    /// very edges, each at its CT (so every member starts on one CT and
    /// stays on its line through a stop), in the interrupt's way and the
    /// Pico's queue-ahead way.
    #[test]
    fn group_moves_keep_the_references_edges_and_replies(
        axes in 2usize..=4,
        way in way(),
        acts in proptest::collection::vec(
            (prop_oneof![0u64..3_000_000, 3_000_000u64..60_000_000], group_act()),
            1..10,
        ),
    ) {
        let board = board();
        let firmware = firmware(board, axes);
        let mut session = Session::new();
        let mut model = GroupModel::new(axes);
        let lookahead = u64::from(core_config(CLKFREQ, Variant::Sd).dir_setup_ticks);
        let mut at = 0;
        for (gap, act) in acts {
            at += gap;
            run_with(&firmware, board, at, way);
            let core_at = at + lookahead;
            model.run_to(core_at);
            let (line, expected) = match act {
                GroupAct::Group(speed, mut steps) => {
                    steps.truncate(axes);
                    let result = model.group(core_at, speed, &steps);
                    (group_line(speed, &steps), result.is_ok())
                }
                GroupAct::Move(axis, speed, steps) => {
                    let axis = axis % axes;
                    let result = model.cores[axis].command(core_at, CoreCommand::Move { speed, steps });
                    if result.is_ok() && !model.cores[axis].in_group() {
                        model.records[axis] = None;
                    }
                    (format!("M {axis} {speed} {steps}\n"), result.is_ok())
                }
                GroupAct::StopPin(axis, high) => {
                    let axis = axis % axes;
                    model.cores[axis].set_stop_pin(core_at, high);
                    let letter = if high { 'R' } else { 'S' };
                    (format!("{letter} {axis}\n"), true)
                }
                GroupAct::StopAll => {
                    for core in &mut model.cores {
                        core.set_stop_pin(core_at, false);
                    }
                    ("!".to_string(), true)
                }
                GroupAct::EmergencyStop => {
                    for core in &mut model.cores {
                        core.command(core_at, CoreCommand::EmergencyStop).unwrap();
                    }
                    ("E\n".to_string(), true)
                }
            };
            model.pass_stops(core_at);
            // A status line brings each core up to the firmware's CT.
            model.run_to(core_at);
            let reply = send(&firmware, &mut session, line.as_bytes());
            if line != "!" {
                prop_assert_eq!(reply == "ok\n", expected, "{} got {}", line.trim(), reply);
            }
            for (index, core) in model.cores.iter().enumerate() {
                let status = firmware.axes()[index].status().unwrap();
                prop_assert_eq!(
                    (status.position, status.steps_to_go, status.mode),
                    (core.position(), core.steps_to_go(), core.mode()),
                    "axis {} after {}", index, line.trim()
                );
            }
        }
        run_with(&firmware, board, u64::MAX, way);
        model.run_to(u64::MAX);
        let key = |drive: &Drive| (drive.0, drive.1, drive.2.index(), drive.3);
        let mut drives = board.0.drives.lock().unwrap().clone();
        drives.sort_by_key(key);
        let mut expected: Vec<Drive> = model
            .edges
            .iter()
            .enumerate()
            .flat_map(|(index, edges)| {
                edges.iter().map(move |edge| {
                    let output = if edge.pin == 0 { Output::First } else { Output::Second };
                    (edge.ct, index, output, edge.level)
                })
            })
            .collect();
        expected.sort_by_key(key);
        prop_assert_eq!(drives, expected);
        for (index, core) in model.cores.iter().enumerate() {
            prop_assert_eq!(firmware.axes()[index].dropped_steps(), core.dropped_steps());
        }
    }
}

#[test]
fn a_group_move_starts_on_one_ct_and_a_members_stop_keeps_the_line() {
    let board = board();
    let firmware = firmware(board, 3);
    let mut session = Session::new();
    assert_eq!(
        send(&firmware, &mut session, b"G 20000 3000 -1000 0\n"),
        "ok\n"
    );
    // While it runs every member refuses a move of its own.
    assert_eq!(
        send(&firmware, &mut session, b"M 1 1000 10\n"),
        "error:3 busy\n"
    );
    assert_eq!(
        send(&firmware, &mut session, b"G 20000 10\n"),
        "error:3 busy\n"
    );
    run(&firmware, board, 2_500_000);
    // Axis 2 (no steps, in the group) stops the whole line.
    assert_eq!(send(&firmware, &mut session, b"S 2\n"), "ok\n");
    run(&firmware, board, u64::MAX);
    let drives = board.0.drives.lock().unwrap().clone();
    let first_rise = |axis: usize| {
        drives
            .iter()
            .find(|drive| drive.1 == axis && drive.3 && (axis == 1 || drive.2 == Output::First))
            .map(|drive| drive.0)
    };
    // Axis 1 is cc (cw/ccw), so any rising edge of it is a step.
    assert_eq!(first_rise(0), first_rise(1));
    assert!(first_rise(0).is_some());
    assert_eq!(first_rise(2), None);
    let lead = firmware.axes()[0].status().unwrap().position;
    let follower = firmware.axes()[1].status().unwrap().position;
    assert!(lead > 100 && lead < 3_000, "the lead stopped at {lead}");
    let line = -1_000.0 * lead as f64 / 3_000.0;
    assert!(
        (follower as f64 - line).abs() <= 1.0,
        "{follower} against {line}"
    );
    // The steps not made complete the line.
    let rest = [3_000 - lead, -1_000 - follower, 0];
    assert_eq!(
        firmware.axes()[0].dropped_steps(),
        u32::try_from(rest[0]).unwrap()
    );
    assert_eq!(send(&firmware, &mut session, b"R 2\n"), "ok\n");
    let line = format!("G 20000 {} {} 0\n", rest[0], rest[1]);
    assert_eq!(send(&firmware, &mut session, line.as_bytes()), "ok\n");
    run(&firmware, board, u64::MAX);
    assert_eq!(firmware.axes()[0].status().unwrap().position, 3_000);
    assert_eq!(firmware.axes()[1].status().unwrap().position, -1_000);
}

#[test]
fn a_members_hard_limit_stops_the_whole_line_and_refuses_a_group_towards_it() {
    const LIMIT_PIN: u8 = 22;
    let board = board_reading(1 << LIMIT_PIN);
    let firmware = firmware(board, 2);
    let mut session = Session::new();
    assert_eq!(send(&firmware, &mut session, b"K 1 - 22/1\n"), "ok\n");
    assert_eq!(
        send(&firmware, &mut session, b"G 20000 3000 2000\n"),
        "ok\n"
    );
    run(&firmware, board, 5_000_000);
    // Axis 1's max limit switch closes mid-move.
    firmware.axes()[1].set_inputs(1 << LIMIT_PIN, None);
    run(&firmware, board, u64::MAX);
    let lead = firmware.axes()[0].status().unwrap();
    let member = firmware.axes()[1].status().unwrap();
    assert!(lead.position > 100 && lead.position < 3_000, "{lead:?}");
    let line = 2_000.0 * lead.position as f64 / 3_000.0;
    assert!(
        (member.position as f64 - line).abs() <= 1.0,
        "{} against its line {line}",
        member.position
    );
    assert!(lead.mode.has(driver::axis::Mode::STOP_LATCHED));
    let limits = send(&firmware, &mut session, b"L 1\n");
    assert!(limits.contains("[fault 1 max"), "{limits}");
    // A group heading into the tripped limit is refused, nothing moves.
    let before = send(&firmware, &mut session, b"?");
    assert_eq!(
        send(&firmware, &mut session, b"G 20000 10 10\n"),
        "error:9 limit: max limit\n"
    );
    run(&firmware, board, u64::MAX);
    assert_eq!(send(&firmware, &mut session, b"?"), before);
    // Away from it, after a reservation of axis 0 was given back, runs.
    assert_eq!(send(&firmware, &mut session, b"G 20000 10 -10\n"), "ok\n");
    run(&firmware, board, u64::MAX);
    assert_eq!(
        firmware.axes()[1].status().unwrap().position,
        member.position - 10
    );
}
