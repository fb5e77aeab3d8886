"""pio_rates.py's judge of a slew run: which late words count.

Run: firmware/pico-sim/.venv/bin/python -m pytest firmware/pico-sim/test_pio_rates.py
"""

import json
import pathlib
from types import SimpleNamespace

import pio_model
from pio_rates import CLOCK_HZ, late_in_slew, steps_of

PROGRAM = json.loads((pathlib.Path(__file__).parent / "pio_steps.json").read_text())


def step(cycles):
    """A step word (step pin high, then low) of `cycles`."""
    return 1 | 0b01 << 1 | 0b00 << 3 | (cycles - PROGRAM["step_min_cycles"]) << 5


def hold(cycles):
    """A hold word (pins low) of `cycles`."""
    return (cycles - PROGRAM["hold_min_cycles"]) << 3


def machine(words, late, index=0):
    """State machine `index`, whose words follow one another from cycle 0,
    each pulled when the last ends; `late` (word indexes) ran dry by 100
    cycles."""
    log, pull = [], 0
    for word in words:
        log.append((word, pull))
        if word & 1:
            pull += PROGRAM["step_min_cycles"] + (word >> 5)
        else:
            pull += PROGRAM["hold_min_cycles"] + (word >> 3)
    late_log = [(index, words[index], 100) for index in late]
    return SimpleNamespace(index=index, word_log=log, late_log=late_log)


SPEED = 10_000
PERIOD = CLOCK_HZ // SPEED


def test_a_step_split_by_holds_is_one_step_of_their_sum():
    words = [hold(5_000), step(20_000), step(3_000), hold(4_000), hold(PERIOD - 7_000), step(PERIOD)]
    steps = list(steps_of(machine(words, []).word_log, PROGRAM))
    assert [period for _pull, period in steps] == [20_000, PERIOD, PERIOD]
    assert [pull for pull, _period in steps] == [5_000, 25_000, 25_000 + PERIOD]


def test_late_words_count_in_the_slews_middle_half_whatever_their_kind():
    # A ramp of 3 steps, then 100 steps at speed, each split into a step
    # word and a hold (as the feeder splits a step when it holds its axis).
    ramp = [step(40_000), step(25_000), step(PERIOD + PERIOD // 10)]
    slew = [word for _ in range(100) for word in (step(PERIOD // 2), hold(PERIOD - PERIOD // 2))]
    words = ramp + slew
    first_slew = len(ramp)
    # Late: a ramp word, a hold early in the slew (before its quarter), a
    # hold and a step word in its middle half, a step near its end.
    late = [1, first_slew + 11, first_slew + 101, first_slew + 120, first_slew + 190]
    moving = machine(words, late)
    counted = late_in_slew([moving], PROGRAM, SPEED, 100)
    assert counted == [(0, words[first_slew + 101], 100), (0, words[first_slew + 120], 100)]
    # An axis standing still beside it (holds only) is judged in its window.
    holds = [hold(PERIOD)] * 130
    still = machine(holds, [2, 60], index=1)
    counted = late_in_slew([moving, still], PROGRAM, SPEED, 100)
    assert counted[2:] == [(1, holds[60], 100)]


def test_with_no_machine_at_speed_yet_nothing_is_judged():
    words = [step(40_000), step(30_000), step(20_000)]
    machines = [machine(words, [0, 2]), machine([hold(PERIOD)] * 3, [1], index=1)]
    assert late_in_slew(machines, PROGRAM, SPEED, 100) is None


def test_a_model_logging_every_word_keeps_every_late_one():
    # A ramp that ran dry more than LATE_LOG times must not hide the late
    # words of the slew after it: a run at a speed far past the core's
    # (four axes at 198,000 steps/s) was judged clean so.
    logged = pio_model.Machine(0, PROGRAM)
    logged.log_words = True
    logged.start_ns = 0
    unlogged = pio_model.Machine(1, PROGRAM)
    unlogged.start_ns = 0
    late = pio_model.LATE_LOG + 5
    for machine in (logged, unlogged):
        for _ in range(late):
            # Each word comes 100 cycles after its `pull` was due.
            machine.enqueue(machine.next_due + 99, step(PERIOD), lambda _text: None)
    assert logged.late_words == unlogged.late_words == late
    assert len(logged.late_log) == late
    assert [index for index, _word, _late in logged.late_log[-5:]] == list(range(late - 5, late))
    assert len(unlogged.late_log) == pio_model.LATE_LOG
