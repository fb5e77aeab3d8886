//! Host tests: the words, their splitting, the closed form, and the
//! program's export for the emulator check (`firmware/pico-sim`).

use super::*;

/// A small deterministic generator (xorshift64*), for streams that the
/// export and the emulator check share.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

#[test]
fn the_program_is_nine_instructions_that_wrap_to_the_pull() {
    let program = program();
    assert_eq!(program.code.len(), 9);
    assert_eq!((program.wrap.source, program.wrap.target), (8, 0));
    assert_eq!(program.side_set.bits(), 0);
    // pull block; out x, 1; jmp !x 6; out pins, 2; set x, 19 [3];
    // jmp x-- 5 [30]; out pins, 2; out y, 27; jmp y-- 8
    assert_eq!(
        program.code.as_slice(),
        &[0x80a0, 0x6021, 0x0026, 0x6002, 0xe333, 0x1e45, 0x6002, 0x605b, 0x0088]
    );
}

#[test]
fn words_round_trip_at_their_bounds() {
    for pins in 0..4 {
        for other in 0..4 {
            for period_cycles in [STEP_MIN_CYCLES, STEP_MIN_CYCLES + 1, STEP_MAX_CYCLES] {
                let word = Word::Step {
                    high: Pins::from_bits(pins),
                    low: Pins::from_bits(other),
                    period_cycles,
                };
                assert_eq!(Word::decode(word.encode().unwrap()), word);
            }
        }
        for cycles in [HOLD_MIN_CYCLES, HOLD_MIN_CYCLES + 1, HOLD_MAX_CYCLES] {
            let word = Word::Hold {
                pins: Pins::from_bits(pins),
                cycles,
            };
            assert_eq!(Word::decode(word.encode().unwrap()), word);
        }
    }
}

#[test]
fn words_out_of_range_are_refused() {
    let step = |period_cycles| Word::Step {
        high: Pins::sd(true, false),
        low: Pins::LOW,
        period_cycles,
    };
    let hold = |cycles| Word::Hold {
        pins: Pins::LOW,
        cycles,
    };
    for cycles in [0, STEP_MIN_CYCLES - 1, STEP_MAX_CYCLES + 1, u32::MAX] {
        assert_eq!(
            step(cycles).encode(),
            Err(WordError::StepPeriod {
                cycles: cycles.into()
            })
        );
    }
    for cycles in [0, HOLD_MIN_CYCLES - 1, HOLD_MAX_CYCLES + 1, u32::MAX] {
        assert_eq!(
            hold(cycles).encode(),
            Err(WordError::Hold {
                cycles: cycles.into()
            })
        );
    }
    assert!(step_words(Pins::LOW, Pins::LOW, u64::from(STEP_MIN_CYCLES) - 1).is_err());
    assert!(hold_words(Pins::LOW, u64::from(HOLD_MIN_CYCLES) - 1).is_err());
}

#[test]
fn every_word_decodes_to_one_the_encoder_makes_again() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for _ in 0..100_000 {
        let raw = rng.next() as u32;
        let word = Word::decode(raw);
        let again = word.encode().unwrap();
        assert_eq!(Word::decode(again), word);
        // Only a hold's unused top bits may differ.
        let mask = if raw & 1 == 1 { u32::MAX } else { 0x3FFF_FFFF };
        assert_eq!(again, raw & mask);
    }
}

#[test]
fn long_periods_split_into_a_step_and_holds_that_add_up() {
    let high = Pins::sd(true, true);
    let low = Pins::sd(false, true);
    let mut rng = Rng(7);
    let mut periods: Vec<u64> = (0..2_000)
        .map(|_| u64::from(STEP_MIN_CYCLES) + rng.below(5 * u64::from(STEP_MAX_CYCLES)))
        .collect();
    let max = u64::from(STEP_MAX_CYCLES);
    let hold_max = u64::from(HOLD_MAX_CYCLES);
    periods.extend([
        u64::from(STEP_MIN_CYCLES),
        max,
        max + 1,
        max + 5,
        max + 6,
        max + 7,
        max + hold_max,
        max + hold_max + 1,
        u64::from(u32::MAX) * 3,
    ]);
    for period in periods {
        let words: Vec<Word> = step_words(high, low, period).unwrap().collect();
        // One word is `only` that word; more are none.
        let only = step_words(high, low, period).unwrap().only();
        assert_eq!(only, (words.len() == 1).then(|| words[0]), "{period}");
        let holds: Vec<Word> = hold_words(low, period).unwrap().collect();
        let only = hold_words(low, period).unwrap().only();
        assert_eq!(only, (holds.len() == 1).then(|| holds[0]), "{period}");
        assert_eq!(
            holds.iter().map(|w| u64::from(w.cycles())).sum::<u64>(),
            period
        );
        assert!(matches!(words[0], Word::Step { high: h, low: l, .. } if h == high && l == low));
        for word in &words[1..] {
            assert!(matches!(word, Word::Hold { pins, .. } if *pins == low));
        }
        let total: u64 = words.iter().map(|w| u64::from(w.cycles())).sum();
        assert_eq!(total, period);
        for word in &words {
            word.encode().unwrap();
        }
    }
}

#[test]
fn the_closed_form_of_a_step_hold_and_step() {
    let dir = Pins::sd(false, true);
    let words = [
        Word::Step {
            high: Pins::sd(true, false),
            low: Pins::LOW,
            period_cycles: 700,
        },
        Word::Hold {
            pins: dir,
            cycles: 650,
        },
        Word::Step {
            high: Pins::sd(true, true),
            low: dir,
            period_cycles: 631,
        },
    ];
    let writes: Vec<(u64, u8)> = pin_writes(words.iter().map(|w| w.encode().unwrap()))
        .map(|w| (w.cycle, w.pins.bits()))
        .collect();
    assert_eq!(
        writes,
        [
            (3, 0b01),
            (3 + 625, 0b00),
            (3 + 700, 0b10),
            (3 + 700 + 650, 0b11),
            (3 + 700 + 650 + 625, 0b10)
        ]
    );
}

/// The export for `firmware/pico-sim/test_pio_steps.py`: the program's
/// opcodes and wrap, the constants of the closed form, and a stream of
/// words with the pin writes this crate's closed form gives them.
fn export() -> String {
    let program = program();
    let mut rng = Rng(0x00C0_65DE_u64);
    let words: Vec<u32> = (0..120)
        .map(|_| {
            let count = rng.below(200) as u32;
            let word = if rng.below(3) == 0 {
                Word::Hold {
                    pins: Pins::from_bits(rng.below(4) as u8),
                    cycles: HOLD_MIN_CYCLES + count,
                }
            } else {
                Word::Step {
                    high: Pins::from_bits(rng.below(4) as u8),
                    low: Pins::from_bits(rng.below(4) as u8),
                    period_cycles: STEP_MIN_CYCLES + count,
                }
            };
            word.encode().unwrap()
        })
        .collect();
    let writes: Vec<String> = pin_writes(words.iter().copied())
        .map(|w| format!("[{}, {}]", w.cycle, w.pins.bits()))
        .collect();
    let list = |items: Vec<String>| items.join(", ");
    format!(
        concat!(
            "{{\n",
            "  \"about\": \"The PIO step program of firmware/pio-steps, exported by its tests; COGSTEP_BLESS=1 cargo test -p cogstep-pio-steps rewrites it. Do not edit.\",\n",
            "  \"opcodes\": [{}],\n",
            "  \"wrap_target\": {},\n",
            "  \"wrap_source\": {},\n",
            "  \"out_pin_count\": {},\n",
            "  \"first_write_cycle\": {},\n",
            "  \"pulse_cycles\": {},\n",
            "  \"step_min_cycles\": {},\n",
            "  \"hold_min_cycles\": {},\n",
            "  \"count_bits\": {},\n",
            "  \"golden_words\": [{}],\n",
            "  \"golden_writes\": [{}],\n",
            "  \"encoder_streams\": [\n{}\n  ]\n",
            "}}\n"
        ),
        list(program.code.iter().map(|op| op.to_string()).collect()),
        program.wrap.target,
        program.wrap.source,
        OUT_PIN_COUNT,
        FIRST_WRITE_CYCLE,
        PULSE_CYCLES,
        STEP_MIN_CYCLES,
        HOLD_MIN_CYCLES,
        COUNT_BITS,
        list(words.iter().map(|w| w.to_string()).collect()),
        list(writes),
        encoder_streams().join(",\n"),
    )
}

/// Step schedules as the axis core makes them (CT 0 = the state
/// machine's first `pull`), the words `AxisWords` makes of them and the
/// pin changes they ask for, one JSON object each: the emulator check
/// runs the words and compares.
fn encoder_streams() -> Vec<String> {
    let mut rng = Rng(0x05EE_D0F5_7E95);
    [StepPins::Sd, StepPins::Cc, StepPins::Sd, StepPins::Cc]
        .into_iter()
        .map(|step_pins| {
            let start = u64::from(FIRST_WRITE_CYCLE);
            let edges = core_schedule(&mut rng, step_pins, start, false);
            let (words, taken, refused, until) = encode_edges(step_pins, start, &edges);
            assert_eq!(refused, []);
            let asked: Vec<(u64, Pins)> = taken.into_iter().filter(|&(ct, _)| ct < until).collect();
            let changes: Vec<String> = changes(&asked)
                .iter()
                .map(|(ct, pins)| format!("[{ct}, {pins}]"))
                .collect();
            format!(
                "    {{\"step_pins\": \"{:?}\", \"until\": {until}, \"words\": [{}], \"changes\": [{}]}}",
                step_pins,
                words.iter().map(|w| w.to_string()).collect::<Vec<_>>().join(", "),
                changes.join(", ")
            )
        })
        .collect()
}

#[test]
fn the_emulator_check_runs_this_program() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../pico-sim/pio_steps.json");
    let current = export();
    if std::env::var_os("COGSTEP_BLESS").is_some() {
        std::fs::write(&path, &current).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == current,
        "firmware/pico-sim/pio_steps.json is not this program's export: \
         COGSTEP_BLESS=1 cargo test -p cogstep-pio-steps rewrites it"
    );
}

/// The pins after each CT's edges, where they change (both pins start low).
fn changes(edges: &[(u64, Pins)]) -> Vec<(u64, u8)> {
    let mut by_ct: Vec<(u64, Pins)> = Vec::new();
    for &(ct, pins) in edges {
        match by_ct.last_mut() {
            Some(last) if last.0 == ct => last.1 = pins,
            _ => by_ct.push((ct, pins)),
        }
    }
    let mut level = Pins::LOW;
    let mut out = Vec::new();
    for (ct, pins) in by_ct {
        if pins != level {
            out.push((ct, pins.bits()));
            level = pins;
        }
    }
    out
}

/// Feeds `edges` (ct, output, level) and promises (ct, None) to an
/// encoder started at `start`; returns the words, the pins after every
/// edge it took, and the CT up to which the words are complete.
#[allow(clippy::type_complexity)]
fn encode_edges(
    step_pins: StepPins,
    start: u64,
    edges: &[(u64, Option<(usize, bool)>)],
) -> (Vec<u32>, Vec<(u64, Pins)>, Vec<EdgeError>, u64) {
    let mut axis = AxisWords::new(step_pins, start);
    let mask = match step_pins {
        StepPins::Sd => 0b01,
        StepPins::Cc => 0b11,
    };
    let mut words = Vec::new();
    let mut taken: Vec<(u64, Pins)> = Vec::new();
    let mut refused = Vec::new();
    // A step's pulse ends by itself, a pulse after its rising edge.
    let mut pulse_end: Option<(u64, Pins)> = None;
    for &(ct, edge) in edges {
        if let Some((end, low)) = pulse_end.filter(|&(end, _)| ct >= end) {
            taken.push((end, low));
            pulse_end = None;
        }
        let before = taken.last().map_or(Pins::LOW, |&(_, pins)| pins);
        let closed = match edge {
            Some((output, level)) => match axis.edge(ct, output, level) {
                Ok(closed) => {
                    // An edge that changes no pin writes nothing (one
                    // inside a pulse that has ended for the model, but not
                    // yet for the encoder, changes nothing either).
                    let pins = axis.pins();
                    let in_order = taken.last().is_none_or(|&(last, _)| ct >= last);
                    if pins != before && in_order {
                        taken.push((ct, pins));
                        if pins.bits() & !before.bits() & mask != 0 {
                            let low = Pins::from_bits(pins.bits() & !mask);
                            pulse_end = Some((ct + u64::from(PULSE_CYCLES), low));
                        }
                    }
                    closed
                }
                Err(error) => {
                    refused.push(error);
                    None
                }
            },
            None => axis.hold_until(ct),
        };
        words.extend(closed.into_iter().flatten().map(|w| w.encode().unwrap()));
    }
    taken.extend(pulse_end);
    (words, taken, refused, axis.open_since())
}

/// The pin changes the words make, as CTs, before `until`.
fn made(words: &[u32], start: u64, until: u64) -> Vec<(u64, u8)> {
    let writes: Vec<(u64, Pins)> = pin_writes(words.iter().copied())
        .map(|w| {
            (
                (w.cycle - u64::from(FIRST_WRITE_CYCLE)).wrapping_add(start),
                w.pins,
            )
        })
        .filter(|&(ct, _)| ct < until)
        .collect();
    changes(&writes)
}

/// A step schedule as the axis core makes one: per step, a direction edge
/// a set-up before the rising edge when the direction changes (`sd`), the
/// falling edge a pulse after it; random promises of no edge between.
fn core_schedule(
    rng: &mut Rng,
    step_pins: StepPins,
    start: u64,
    long_idle: bool,
) -> Vec<(u64, Option<(usize, bool)>)> {
    let setup = u64::from(PULSE_CYCLES);
    let pulse = u64::from(PULSE_CYCLES);
    let mut edges = Vec::new();
    let mut direction = false;
    let mut next_free = start + rng.below(3_000);
    for _ in 0..rng.below(60) {
        let new_direction = (rng.below(4) == 0) != direction;
        let changes_dir = step_pins == StepPins::Sd && new_direction != direction;
        let rising = next_free + if changes_dir { setup } else { 0 } + rng.below(2_000);
        // A promise somewhere before this step's first edge.
        if rng.below(2) == 0 {
            let first = rising - if changes_dir { setup } else { 0 };
            edges.push((first - rng.below(first - next_free + 1), None));
        }
        if changes_dir {
            edges.push((rising - setup, Some((1, new_direction))));
        }
        direction = new_direction;
        let pin = if step_pins == StepPins::Cc && direction {
            1
        } else {
            0
        };
        edges.push((rising, Some((pin, true))));
        edges.push((rising + pulse, Some((pin, false))));
        // Long idle spans now and then: words split, promises close them.
        let idle = if long_idle && rng.below(8) == 0 {
            rng.below(3 * u64::from(HOLD_MAX_CYCLES))
        } else {
            0
        };
        next_free = rising + u64::from(STEP_MIN_CYCLES) + idle;
    }
    edges.push((next_free + 50, None));
    edges
}

#[test]
fn the_words_of_core_schedules_make_their_edges_exactly() {
    let mut rng = Rng(0xC06_57E9);
    for round in 0..2_000 {
        let step_pins = if round % 2 == 0 {
            StepPins::Sd
        } else {
            StepPins::Cc
        };
        let start = rng.below(1 << 40);
        let edges = core_schedule(&mut rng, step_pins, start, true);
        let (words, taken, refused, until) = encode_edges(step_pins, start, &edges);
        assert_eq!(refused, [], "round {round}");
        let wanted: Vec<(u64, Pins)> = taken.into_iter().collect();
        assert_eq!(
            made(&words, start, until),
            changes(&wanted),
            "round {round}"
        );
        // Every edge is in the words: the last promise closed the last step.
        assert!(edges
            .iter()
            .all(|&(ct, _)| ct < until + u64::from(HOLD_MIN_CYCLES) + 1));
    }
}

#[test]
fn any_edges_make_exactly_the_edges_taken_and_never_panic() {
    let mut rng = Rng(0xBAD_ED6E);
    let (mut made_count, mut refused_count) = (0, 0);
    for round in 0..5_000 {
        let step_pins = if round % 2 == 0 {
            StepPins::Sd
        } else {
            StepPins::Cc
        };
        let start = if round % 7 == 0 {
            u64::MAX - 100_000 - rng.below(5_000)
        } else {
            rng.below(10_000)
        };
        let mut ct = start.saturating_sub(rng.below(20));
        let mut edges = Vec::new();
        for _ in 0..rng.below(40) {
            ct = match rng.below(7) {
                0 => ct.saturating_sub(rng.below(700)),
                1 => ct.saturating_add(u64::from(PULSE_CYCLES)),
                2 => ct,
                3 => ct.saturating_add(rng.below(20)),
                _ => ct.saturating_add(600 + rng.below(1_500)),
            };
            let edge = if rng.below(5) == 0 {
                None
            } else {
                Some((rng.below(3) as usize, rng.below(2) == 0))
            };
            edges.push((ct, edge));
        }
        let (words, taken, refused, until) = encode_edges(step_pins, start, &edges);
        let wanted: Vec<(u64, Pins)> = taken.into_iter().filter(|&(ct, _)| ct < until).collect();
        assert_eq!(
            made(&words, start, until),
            changes(&wanted),
            "round {round}"
        );
        made_count += wanted.len();
        refused_count += refused.len();
    }
    // Both kinds were exercised.
    assert!(
        made_count > 10_000 && refused_count > 10_000,
        "{made_count} {refused_count}"
    );
}

#[test]
fn edges_the_program_cannot_make_are_refused_and_change_nothing() {
    let mut axis = AxisWords::new(StepPins::Sd, 1_000);
    let pulse = u64::from(PULSE_CYCLES);
    assert!(axis.edge(2_000, 0, true).unwrap().is_some());
    // A pulse of the wrong length, and an edge inside one.
    assert_eq!(
        axis.edge(2_000 + pulse - 1, 0, false),
        Err(EdgeError::Pulse {
            ct: 2_000 + pulse - 1,
            rising_ct: 2_000
        })
    );
    assert_eq!(
        axis.edge(2_010, 1, true),
        Err(EdgeError::Pulse {
            ct: 2_010,
            rising_ct: 2_000
        })
    );
    assert_eq!(axis.pins(), Pins::sd(true, false));
    assert!(axis.edge(2_000 + pulse, 0, false).unwrap().is_none());
    // The next step within 631 cycles of the last one, a write within 6.
    assert_eq!(
        axis.edge(2_630, 0, true),
        Err(EdgeError::TooClose {
            ct: 2_630,
            after_ct: 2_625
        })
    );
    assert!(axis.edge(2_631, 1, true).unwrap().is_some());
    assert_eq!(
        axis.edge(2_636, 1, false),
        Err(EdgeError::TooClose {
            ct: 2_636,
            after_ct: 2_631
        })
    );
    assert_eq!(
        axis.edge(2_000, 1, false),
        Err(EdgeError::Backwards {
            ct: 2_000,
            after_ct: 2_631
        })
    );
    assert_eq!(axis.pins(), Pins::sd(false, true));
    assert_eq!(axis.open_since(), 2_631);
}

/// A new axis for round `round` of a random test (step/dir in even
/// rounds, cw/ccw in odd ones, its first write at a random CT) and a CT
/// after it to go on from.
fn fresh_axis(rng: &mut Rng, round: u32) -> (AxisWords, u64) {
    let step_pins = if round.is_multiple_of(2) {
        StepPins::Sd
    } else {
        StepPins::Cc
    };
    let axis = AxisWords::new(step_pins, rng.below(1_000));
    (axis, 1_000 + rng.below(1_000))
}

/// `step_rise`, the trains' short way, against `edge` at every rising edge
/// of random edge streams: where it answers, the very word `edge` closes
/// and the very state it leaves; where it does not, nothing changed.
#[test]
fn a_trains_step_rise_is_edge_where_it_answers() {
    let mut rng = Rng(0x57E9_215E);
    let (mut answered, mut declined) = (0, 0);
    for round in 0..3_000 {
        let (mut axis, mut ct) = fresh_axis(&mut rng, round);
        for _ in 0..rng.below(40) {
            ct = match rng.below(6) {
                0 => ct.saturating_sub(rng.below(700)),
                1 => ct + u64::from(PULSE_CYCLES) + rng.below(3),
                2 => ct + u64::from(STEP_MIN_CYCLES) - 1 + rng.below(3),
                3 => ct + u64::from(STEP_MAX_CYCLES) - 1 + rng.below(3),
                _ => ct + 600 + rng.below(1_500),
            };
            let output = rng.below(2) as usize;
            let level = rng.below(4) != 0;
            if level {
                let before = format!("{axis:?}");
                let mut short = axis.clone();
                match short.step_rise(ct, output) {
                    Some(raw) => {
                        let words = axis.edge(ct, output, true).unwrap().unwrap();
                        assert_eq!(
                            words.only().map(Word::encode),
                            Some(Ok(raw)),
                            "round {round}"
                        );
                        assert_eq!(format!("{short:?}"), format!("{axis:?}"), "round {round}");
                        answered += 1;
                        continue;
                    }
                    None => {
                        assert_eq!(format!("{short:?}"), before, "round {round}");
                        declined += 1;
                    }
                }
            }
            let _ = axis.edge(ct, output, level);
        }
    }
    assert!(
        answered > 5_000 && declined > 5_000,
        "{answered} {declined}"
    );
}

/// `step_rises`, a run of a train's steps at once, against `step_rise`
/// one CT at a time, from random states (random edge streams) over runs
/// of random CTs (periods at, around and past the program's bounds, and
/// CTs that go back): the same words, the same count (it stops where
/// `step_rise` first declines, or where the words run out), the very
/// state it leaves.
#[test]
fn a_run_of_step_rises_is_step_rise_one_at_a_time() {
    let mut rng = Rng(0x5E9_2157);
    let (mut whole, mut stopped, mut encoded) = (0, 0, 0);
    for round in 0..3_000 {
        let (mut axis, mut ct) = fresh_axis(&mut rng, round);
        for _ in 0..rng.below(6) {
            ct += 600 + rng.below(1_500);
            let _ = axis.edge(ct, rng.below(2) as usize, rng.below(4) != 0);
        }
        let output = rng.below(2) as usize;
        // Mostly from a step of this pin: a train's run goes on from one.
        if rng.below(4) != 0 {
            ct += 700 + rng.below(1_500);
            let _ = axis.edge(ct, output, true);
        }
        let mut rises = Vec::new();
        for _ in 0..rng.below(24) {
            ct = match rng.below(12) {
                0 => ct.saturating_sub(rng.below(700)),
                1 => ct + u64::from(STEP_MIN_CYCLES) - 1 + rng.below(3),
                2 => ct + u64::from(STEP_MAX_CYCLES) - 1 + rng.below(3),
                _ => ct + 700 + rng.below(5_000),
            };
            rises.push(ct);
        }
        let room = rng.below(30) as usize;
        let mut words = vec![0; room];
        let mut run = axis.clone();
        let count = run.step_rises(&rises, output, &mut words);
        let mut expected = Vec::new();
        for &ct in rises.iter().take(room) {
            match axis.step_rise(ct, output) {
                Some(word) => expected.push(word),
                None => break,
            }
        }
        assert_eq!(&words[..count], &expected[..], "round {round}");
        assert_eq!(format!("{run:?}"), format!("{axis:?}"), "round {round}");
        encoded += count;
        if count == rises.len().min(room) {
            whole += 1;
        } else {
            stopped += 1;
        }
    }
    assert!(
        whole > 500 && stopped > 500 && encoded > 6_000,
        "{whole} {stopped} {encoded}"
    );
}
