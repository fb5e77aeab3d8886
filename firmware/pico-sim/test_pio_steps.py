"""Link 1 of the Pico's PIO proof: the step program's edges are an exact
closed form of the FIFO words it is fed, cycle for cycle.

The program and the constants come from `pio_steps.json`, which the Rust
crate `firmware/pio-steps` exports and checks in its own tests (so the
program run here is the one the board installs, and a change to either side
that is not carried to the other fails a test), with words its closed form
and its encoder (`AxisWords`, the firmware's) made, and the edges they are
to give. pioemu runs one state
machine cycle by cycle; every pin change it makes is compared with the
closed form of the crate's docs:

  word 0's first pin write at cycle 3; word k + 1's at t(k) + d(k), with
  d = 631 + count for a step and 6 + count for a hold; a step writes its
  high pins at t(k) and its low pins at t(k) + 625 (5 us at 125 MHz).

Run: firmware/pico-sim/.venv/bin/python -m pytest firmware/pico-sim/test_pio_steps.py
"""

import json
import pathlib
from collections import deque

from hypothesis import given, settings
from hypothesis import strategies as st
from pioemu import State, emulate

SPEC = json.loads((pathlib.Path(__file__).parent / "pio_steps.json").read_text())
PULSE = SPEC["pulse_cycles"]
STEP_MIN = SPEC["step_min_cycles"]
HOLD_MIN = SPEC["hold_min_cycles"]
FIRST_WRITE = SPEC["first_write_cycle"]
COUNT_MAX = (1 << SPEC["count_bits"]) - 1
# The firmware's direction set-up and pulse: 5 us at 125 MHz.
SETUP = 625
PIO_CLOCK_HZ = 125_000_000

# pioemu runs about 100,000 cycles a second: counts stay small.
SMALL_COUNT = 250
CHECKED = settings(max_examples=150, deadline=None, derandomize=True, database=None)


def step_word(high, low, period):
    """A step word, packed as the crate's docs lay it out."""
    assert STEP_MIN <= period <= STEP_MIN + COUNT_MAX
    return 1 | high << 1 | low << 3 | (period - STEP_MIN) << 5


def hold_word(pins, cycles, top_bits=0):
    """A hold word; `top_bits` fills bits 30-31, which the program ignores."""
    assert HOLD_MIN <= cycles <= HOLD_MIN + COUNT_MAX
    return pins << 1 | (cycles - HOLD_MIN) << 3 | top_bits << 30


def closed_form(words):
    """Every pin write (cycle, pins) the words make, and the cycle at which
    the word after them would make its first."""
    writes = []
    t = FIRST_WRITE
    for word in words:
        pins = word >> 1 & 3
        if word & 1:
            writes.append((t, pins))
            writes.append((t + PULSE, word >> 3 & 3))
            t += STEP_MIN + (word >> 5)
        else:
            writes.append((t, pins))
            t += HOLD_MIN + (word >> 3 & COUNT_MAX)
    return writes, t


def changes(writes):
    """The writes that change a pin (both start low)."""
    level = 0
    out = []
    for cycle, pins in writes:
        if pins != level:
            out.append((cycle, pins))
            level = pins
    return out


def run_pio(words, until):
    """Pin changes (cycle, pins) of the program run on `words` (all in the
    FIFO at cycle 0) up to cycle `until`, pins at OUT base 0."""
    out = []
    for before, after in emulate(
        SPEC["opcodes"],
        initial_state=State(transmit_fifo=deque(words)),
        stop_when=lambda _opcode, state: state.clock >= until,
        out_base=0,
        out_count=SPEC["out_pin_count"],
        shift_osr_right=True,
        auto_pull=False,
        wrap_target=SPEC["wrap_target"],
        wrap_top=SPEC["wrap_source"],
    ):
        if after.pin_values & 3 != before.pin_values & 3:
            out.append((before.clock, after.pin_values & 3))
    return out


def edges(pin_changes, bit):
    """(cycle, level) of every change of one pin."""
    level = 0
    out = []
    for cycle, pins in pin_changes:
        new = pins >> bit & 1
        if new != level:
            out.append((cycle, new))
            level = new
    return out


def test_the_export_is_the_documented_program():
    assert len(SPEC["opcodes"]) == 9
    assert (SPEC["wrap_target"], SPEC["wrap_source"]) == (0, 8)
    assert PULSE * 1_000_000_000 // PIO_CLOCK_HZ == 5_000  # ns
    assert STEP_MIN == PULSE + HOLD_MIN


def test_the_rust_closed_form_is_this_one_and_the_pio_makes_it():
    words = SPEC["golden_words"]
    rust_writes = [tuple(w) for w in SPEC["golden_writes"]]
    writes, end = closed_form(words)
    assert writes == rust_writes
    assert run_pio(words, end + 50) == changes(writes)


def test_the_words_the_rust_encoder_makes_of_core_schedules_make_their_edges():
    """`pio_steps::AxisWords` (the firmware's encoder) made these words of
    step schedules as the axis core makes them, CT 0 at the first pull:
    the state machine makes exactly the pin changes the schedule asks for."""
    streams = SPEC["encoder_streams"]
    assert {s["step_pins"] for s in streams} == {"Sd", "Cc"}
    for stream in streams:
        asked = [tuple(change) for change in stream["changes"]]
        assert len(asked) >= 4, "a schedule with steps"
        assert run_pio(stream["words"], stream["until"]) == asked


def word_strategy():
    pins = st.integers(0, 3)
    count = st.integers(0, SMALL_COUNT)
    steps = st.builds(lambda h, l, c: step_word(h, l, STEP_MIN + c), pins, pins, count)
    holds = st.builds(
        lambda p, c, top: hold_word(p, HOLD_MIN + c, top), pins, count, st.integers(0, 3)
    )
    return st.one_of(steps, holds)


@CHECKED
@given(st.lists(word_strategy(), min_size=1, max_size=14))
def test_any_word_stream_makes_the_closed_form_edges(words):
    writes, end = closed_form(words)
    # Up to the cycle the next word would write, and past it: the state
    # machine stalls at the pull with the pins as the last word left them.
    assert run_pio(words, end + 40) == changes(writes)


def schedule_strategy():
    """Steps as the axis core schedules them: (direction, cycles from the
    previous rising edge to this one, set-up if the direction changes)."""
    step = st.tuples(
        st.booleans(),
        st.integers(0, SMALL_COUNT),
        st.integers(SETUP, SETUP + 60),
    )
    return st.tuples(st.integers(HOLD_MIN, 200), st.lists(step, min_size=1, max_size=8))


def plan(lead, steps, variant):
    """Words for a step schedule, and the rising edges (cycle, direction) it
    asks for. `sd`: a hold writes the new direction a set-up before a step
    that changes it; `cc`: the step's pulse goes to cw or ccw."""
    words = []
    rising = []
    # The word being made: its first write's cycle, and how to pack it once
    # the next word's cycle is known.
    start = FIRST_WRITE
    pack = lambda cycles: hold_word(0, cycles)  # the lead: both pins low
    next_write = start + lead
    direction = False
    for new_direction, extra, setup in steps:
        if variant == "sd" and new_direction != direction:
            words.append(pack(next_write - start))
            start = next_write
            pack = lambda cycles, d=new_direction: hold_word(int(d) << 1, cycles)
            next_write += setup
        direction = new_direction
        words.append(pack(next_write - start))
        start = next_write
        if variant == "sd":
            high, low = 1 | int(direction) << 1, int(direction) << 1
        else:
            high, low = (2 if direction else 1), 0
        pack = lambda cycles, h=high, l=low: step_word(h, l, cycles)
        rising.append((start, direction))
        next_write = start + STEP_MIN + extra
    words.append(pack(next_write - start))
    return words, rising


@CHECKED
@given(schedule_strategy())
def test_sd_steps_rise_where_the_words_say_with_the_direction_set_up(schedule):
    lead, steps = schedule
    words, rising = plan(lead, steps, "sd")
    _, end = closed_form(words)
    pins = run_pio(words, end + 10)
    step_edges = edges(pins, 0)
    dir_edges = edges(pins, 1)
    rises = [c for c, level in step_edges if level == 1]
    falls = [c for c, level in step_edges if level == 0]
    assert rises == [at for at, _ in rising]
    assert [f - r for r, f in zip(rises, falls)] == [PULSE] * len(rises)
    for at, direction in rising:
        before = [(c, level) for c, level in dir_edges if c <= at]
        level = before[-1][1] if before else 0
        assert level == int(direction), f"direction wrong at the step at cycle {at}"
        if before:
            assert at - before[-1][0] >= SETUP, f"direction set-up short at cycle {at}"
        # Nothing moves the direction during the pulse.
        assert not [c for c, _ in dir_edges if at < c <= at + PULSE]


@CHECKED
@given(schedule_strategy())
def test_cc_steps_pulse_the_pin_of_their_direction(schedule):
    lead, steps = schedule
    words, rising = plan(lead, steps, "cc")
    _, end = closed_form(words)
    pins = run_pio(words, end + 10)
    for bit, direction in ((0, False), (1, True)):
        pin_edges = edges(pins, bit)
        mine = [at for at, d in rising if d == direction]
        assert [c for c, level in pin_edges if level == 1] == mine
        assert [c for c, level in pin_edges if level == 0] == [at + PULSE for at in mine]
