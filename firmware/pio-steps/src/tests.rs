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
            "  \"golden_writes\": [{}]\n",
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
    )
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
