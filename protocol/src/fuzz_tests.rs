//! Random and mutated input: a million lines from a seeded generator, a
//! proptest of mutated valid lines, and raw byte streams. No input may
//! panic, every reply line must be well formed, every non-blank line must
//! get exactly one final reply, and a line that gets an error must leave
//! the board's recorded calls unchanged.

extern crate std;
use std::string::String;
use std::vec::Vec;

use super::fake_board::{send, FakeBoard};
use super::*;
use proptest::prelude::*;

/// SplitMix64: tiny, fast and good enough to drive a fuzzer, and seeded so
/// that a failure can be replayed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (n > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Bytes a line body may hold in these tests: anything but the line ends
/// and the realtime bytes that act on the board (`!`, 0x18); `?` only reads.
fn line_byte(byte: u8) -> u8 {
    match byte {
        b'\r' | b'\n' | b'!' | 0x18 => b'~',
        other => other,
    }
}

const NUMBERS: &[&str] = &[
    "0",
    "1",
    "-1",
    "+1",
    "2",
    "7",
    "100",
    "20000",
    "-20000",
    "4294967295",
    "4294967296",
    "2147483647",
    "-2147483647",
    "-2147483648",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999",
    "00000000000000000000001",
    "-0",
    "1e3",
    "0x10",
    "",
];

const WORDS: &[&str] = &[
    "M", "J", "S", "R", "E", "P", "I", "m", "j", "X", "MM", "*", "+", "-", "?", "*00", "*FF",
];

/// A valid command line, sometimes with its checksum.
fn valid_line(rng: &mut Rng) -> Vec<u8> {
    let axis = rng.below(3);
    let speed = *rng.pick(&[1u32, 100, 20_000, u32::MAX]);
    let steps = *rng.pick(&[1i32, -1, 500, -20_000, i32::MAX, -i32::MAX]);
    let command = match rng.below(7) {
        0 => Command::Identify,
        1 => Command::EmergencyStop,
        2 => Command::Move {
            axis,
            speed_steps_per_s: speed,
            steps,
        },
        3 => Command::Jog {
            axis,
            speed_steps_per_s: speed,
            direction: *rng.pick(&[
                cogstep_motion::axis::Direction::Forward,
                cogstep_motion::axis::Direction::Reverse,
            ]),
        },
        4 => Command::Stop(*rng.pick(&[Target::All, Target::Axis(axis)])),
        5 => Command::Run(*rng.pick(&[Target::All, Target::Axis(axis)])),
        _ => Command::SetPosition {
            axis,
            position: i64::from(steps) * 3,
        },
    };
    let mut line = String::new();
    if rng.below(3) == 0 {
        command.write_checked(&mut line).expect("String");
    } else {
        line = std::format!("{command}");
    }
    line.into_bytes()
}

/// Inserts, deletes, replaces, duplicates or swaps a few bytes.
fn mutate(rng: &mut Rng, line: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(line.len() + 1);
        let byte = match rng.below(3) {
            0 => line_byte(rng.next() as u8),
            1 => *rng.pick(b"0123456789 -+*MJSREPI?abcdefABCDEF"),
            _ => *rng.pick(b" \t\x00\x7f\xff"),
        };
        match rng.below(6) {
            0 => line.insert(at, byte),
            1 if at < line.len() => {
                line.remove(at);
            }
            2 if at < line.len() => line[at] = byte,
            3 => {
                let end = (at + 1 + rng.below(8)).min(line.len());
                let copy = line[at.min(end)..end].to_vec();
                line.splice(at..at, copy);
            }
            4 if line.len() >= 2 => {
                let other = rng.below(line.len());
                let at = at.min(line.len() - 1);
                line.swap(at, other);
            }
            _ => line.truncate(at),
        }
    }
}

/// Words and numbers from the protocol, glued with random spacing.
fn token_soup(rng: &mut Rng) -> Vec<u8> {
    let mut line = Vec::new();
    for _ in 0..rng.below(7) {
        let token = if rng.below(2) == 0 {
            rng.pick(WORDS)
        } else {
            rng.pick(NUMBERS)
        };
        line.extend_from_slice(token.as_bytes());
        let spaces = rng.below(3);
        line.extend(std::iter::repeat_n(b' ', spaces));
    }
    line
}

fn random_bytes(rng: &mut Rng) -> Vec<u8> {
    let len = rng.below(130);
    (0..len).map(|_| line_byte(rng.next() as u8)).collect()
}

/// What a line is expected to produce.
#[derive(Debug, PartialEq, Eq)]
enum Expect {
    Nothing,
    Error(u8),
    OkOrAxisRefusal,
}

/// What the protocol says about `body` (realtime `?` bytes removed) on a
/// board of `axes` axes.
fn expectation(body: &[u8], axes: usize) -> Expect {
    if body.len() > LINE_MAX {
        Expect::Error(ErrorCode::LineTooLong.number())
    } else if body.iter().all(|&b| b == b' ') {
        Expect::Nothing
    } else {
        match parse_line_on(body, axes) {
            Ok(_) => Expect::OkOrAxisRefusal,
            Err(error) => Expect::Error(error.code().number()),
        }
    }
}

/// Sends one line and checks everything the protocol promises about it.
/// Returns the final reply's code: 0 for `ok`, `None` for no reply.
fn check_line(
    session: &mut Session,
    board: &FakeBoard,
    line: &[u8],
    terminator: &[u8],
) -> Option<u8> {
    let calls_before = board.call_count();
    let mut bytes = line.to_vec();
    bytes.extend_from_slice(terminator);
    let out = send(session, board, &bytes);

    let body: Vec<u8> = line.iter().copied().filter(|&b| b != b'?').collect();
    let status_bytes = line.len() - body.len();
    let expect = expectation(&body, board.axis_count());

    let lines: Vec<&str> = out.split_inclusive('\n').collect();
    for reply in &lines {
        assert!(reply.ends_with(LINE_END), "{reply:?} for {line:?}");
        assert!(reply.len() <= REPLY_LINE_MAX, "{reply:?}");
        let text = &reply[..reply.len() - LINE_END.len()];
        assert!(
            text.bytes().all(|b| (b' '..=b'~').contains(&b)),
            "{reply:?}"
        );
        assert!(Reply::parse(text).is_some(), "{reply:?}");
    }
    let (finals, others): (Vec<&str>, Vec<&str>) = lines
        .iter()
        .map(|l| l.trim_end())
        .partition(|l| Reply::parse(l).is_some_and(|r| r.is_final()));
    let status_lines = others.iter().filter(|l| l.starts_with('<')).count();
    assert_eq!(status_lines, status_bytes * board.axis_count(), "{out:?}");
    // The only information line a command line can bring is `I`'s.
    let info_lines = others.len() - status_lines;
    assert!(
        info_lines == 0 || (info_lines == 1 && finals == ["ok"]),
        "{out:?}"
    );
    match expect {
        Expect::Nothing => assert!(finals.is_empty(), "{line:?} gave {out:?}"),
        _ => {
            assert_eq!(finals.len(), 1, "{line:?} gave {out:?}");
            assert!(
                out.trim_end().ends_with(finals[0]),
                "the final reply comes last"
            );
        }
    }
    match (&expect, finals.first().and_then(|l| Reply::parse(l))) {
        (Expect::Error(code), Some(Reply::Error { code: got, .. })) => {
            assert_eq!(*code, got, "{line:?} gave {out:?}")
        }
        (Expect::OkOrAxisRefusal, Some(Reply::Ok | Reply::Error { .. }))
        | (Expect::Nothing, None) => {}
        (expect, reply) => panic!("{line:?}: expected {expect:?}, got {reply:?} ({out:?})"),
    }
    match finals.first().and_then(|l| Reply::parse(l)) {
        Some(Reply::Error { code, .. }) => {
            assert_eq!(
                board.call_count(),
                calls_before,
                "an erroring line changed the board: {line:?}"
            );
            Some(code)
        }
        Some(_) => Some(0),
        None => None,
    }
}

const TERMINATORS: [&[u8]; 3] = [b"\n", b"\r", b"\r\n"];

#[test]
fn a_million_random_and_mutated_lines() {
    let mut rng = Rng(0x00C0_65E9_5EED);
    let board = FakeBoard::new(3);
    let mut session = Session::new();
    // Final replies seen, by code (0 = ok).
    let mut replies = [0u32; 9];
    for iteration in 0..1_000_000u32 {
        if iteration % 4096 == 0 {
            board.reset();
            board.log.borrow_mut().clear();
        }
        let line = match rng.below(10) {
            0..=3 => {
                let mut line = valid_line(&mut rng);
                mutate(&mut rng, &mut line);
                line
            }
            4..=6 => token_soup(&mut rng),
            7 | 8 => random_bytes(&mut rng),
            _ => valid_line(&mut rng),
        };
        let terminator = *rng.pick(&TERMINATORS);
        if let Some(code) = check_line(&mut session, &board, &line, terminator) {
            replies[usize::from(code)] += 1;
        }
    }
    // The generator reaches every reply the fake board can give (it never
    // reports busy) often enough to matter.
    for code in [0, 1, 2, 4, 5, 6, 7, 8] {
        assert!(replies[code] >= 1_000, "code {code}: {replies:?}");
    }
}

fn any_valid_line() -> impl Strategy<Value = Vec<u8>> {
    any::<u64>().prop_map(|seed| valid_line(&mut Rng(seed)))
}

#[derive(Clone, Debug)]
enum Mutation {
    Insert(usize, u8),
    Delete(usize),
    Replace(usize, u8),
    Truncate(usize),
}

fn any_mutation() -> impl Strategy<Value = Mutation> {
    let byte = any::<u8>().prop_map(line_byte);
    prop_oneof![
        (any::<usize>(), byte.clone()).prop_map(|(at, b)| Mutation::Insert(at, b)),
        any::<usize>().prop_map(Mutation::Delete),
        (any::<usize>(), byte).prop_map(|(at, b)| Mutation::Replace(at, b)),
        any::<usize>().prop_map(Mutation::Truncate),
    ]
}

fn apply(line: &mut Vec<u8>, mutation: &Mutation) {
    match *mutation {
        Mutation::Insert(at, byte) => line.insert(at % (line.len() + 1), byte),
        Mutation::Delete(at) if !line.is_empty() => {
            line.remove(at % line.len());
        }
        Mutation::Replace(at, byte) if !line.is_empty() => {
            let at = at % line.len();
            line[at] = byte;
        }
        Mutation::Truncate(at) => line.truncate(at % (line.len() + 1)),
        _ => {}
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn mutated_valid_lines_never_panic_and_errors_change_nothing(
        line in any_valid_line(),
        mutations in proptest::collection::vec(any_mutation(), 0..6),
        padding in proptest::collection::vec(Just(b' '), 0..100),
        terminator in 0usize..3,
    ) {
        let mut line = line;
        for mutation in &mutations {
            apply(&mut line, mutation);
        }
        // Sometimes long enough to be overlong.
        if padding.len() > 60 {
            line.splice(1.min(line.len())..1.min(line.len()), padding);
        }
        let board = FakeBoard::new(2);
        let mut session = Session::new();
        check_line(&mut session, &board, &line, TERMINATORS[terminator]);
        // The next good line works.
        let before = board.call_count();
        check_line(&mut session, &board, b"M 0 100 200", b"\n");
        prop_assert_eq!(board.call_count(), before + 1);
    }
}

#[test]
fn raw_byte_streams_never_wedge_the_receiver() {
    let mut rng = Rng(0x05EE_D0FB_17E5);
    let board = FakeBoard::new(2);
    let mut session = Session::new();
    for _ in 0..20_000 {
        let len = rng.below(300);
        let mut out = String::new();
        for _ in 0..len {
            // Any byte at all, realtime bytes and line ends included.
            let byte = rng.next() as u8;
            session.feed(byte, &board, &mut out).expect("String");
            assert!(session.receiver().pending() <= LINE_MAX);
        }
        for reply in out.split_inclusive('\n') {
            assert!(reply.ends_with(LINE_END) && reply.len() <= REPLY_LINE_MAX);
            assert!(Reply::parse(reply).is_some(), "{reply:?}");
        }
        // Whatever came before, one line end and then a good line works.
        send(&mut session, &board, b"\n");
        assert_eq!(send(&mut session, &board, b"S *\n"), "ok\n");
        board.reset();
        board.log.borrow_mut().clear();
    }
}
