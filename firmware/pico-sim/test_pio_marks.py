"""The PIO build's feeder across a round that plans a move: no FIFO runs dry.

Run (the PIO build's ELF from `firmware/build rp-pico --snapshot --features pio`):

    COGSTEP_PIO_ELF=<elf> firmware/pico-sim/.venv/bin/python -m pytest \
        firmware/pico-sim/test_pio_marks.py

Homing turns from its seek to its backoff when the seek's stop ends: the
main loop plans the backoff in one wake-up, 1.16 ms of the M0+, and the
frontier mark of that round comes that much later than the main loop's
2 ms between rounds. The seek's last step is 2.13 ms long, so its word
waits for the backoff's first edge, and only a mark's hold keeps the
state machine fed meanwhile. A feeder that held, at a mark, only the axes
whose words ended within 3 ms let the state machine run dry when the
round before the turn fell so that its mark left the axis 3 to 4 ms of
words: 201 µs, and every later edge as late.

Where the rounds fall depends on when the main loop last woke for
something else: here a status line (`?`) sent before the turn. The test
sweeps its time over 2 ms (the main loop's longest sleep, so every phase
of the rounds) in steps of 50 µs, a fresh emulator each time (about 80 s).
With the feeder that held within 3 ms this test fails at 4 of its 41
times (528.05 to 528.20 ms after `H`'s reply, the FIFO 16 to 166 µs dry);
swept from 526 to 536 ms after `H` every 50 µs, that feeder ran dry at
13 of 200 times, in three windows 2 ms apart. The feeder that holds every
axis at a mark passes; so does the main loop that encodes each axis's
edges itself and, at the end of each round, holds every axis whose hold
would close 100 µs or more (`firmware/boards/rp-pico/src/pio.rs`, `hold`).
"""

import os

import pytest

from pio_rates import Harness

ELF = os.environ.get("COGSTEP_PIO_ELF")
pytestmark = pytest.mark.skipif(not ELF, reason="COGSTEP_PIO_ELF (the PIO build's ELF) is not set")

#: Homing towards `-` on GP14 (pressed low) at 4,000 steps/s, latch at 800,
#: a switch the harness closes at -700.
HOME = "H 0 14 0 - 4000 800 60 5000 100"
#: The sweep: 2 ms, from 6.5 ms before the seek's turn, every 50 µs.
SWEEP_MS = 2.0
STEP_MS = 0.05
BEFORE_TURN_MS = 6.5


def start_homing():
    """A fresh board homing on a switch at -700: the harness, and the
    simulated ms at which `H` was answered."""
    harness = Harness(ELF, 1)
    assert harness.sim.control("switch axis1_home 0 when axis1 <= -700") == "ok switch axis1_home"
    harness.send(HOME)
    return harness, harness.now_ms()


def seek_turn():
    """When the seek turns (ms after `H`: the pins' lowest position, once
    they have come back) and that position."""
    harness, start = start_homing()
    lowest, at = 0, None
    while at is None or harness.sim.axes[0].position <= lowest:
        harness.run_ms(0.5)
        position = harness.sim.axes[0].position
        if position < lowest:
            lowest, at = position, harness.now_ms() - start
    assert lowest <= -700, "the seek never reached the switch"
    return at, lowest


def homing_with_status_at(query_ms, until_ms):
    """Homing with a status line sent `query_ms` after `H`, run to
    `until_ms` after `H`: the harness."""
    harness, start = start_homing()
    harness.run_ms(start + query_ms - harness.now_ms())
    harness.feed("?")
    harness.run_ms(start + until_ms - harness.now_ms())
    return harness


def test_no_fifo_runs_dry_across_homings_turn_whenever_the_rounds_fall():
    turn_ms, lowest = seek_turn()
    first = turn_ms - BEFORE_TURN_MS
    dry = []
    for index in range(round(SWEEP_MS / STEP_MS) + 1):
        query_ms = first + index * STEP_MS
        harness = homing_with_status_at(query_ms, turn_ms + 10)
        # The turn was made: the backoff's steps are on the pins.
        assert harness.sim.axes[0].position > lowest
        if harness.late_words():
            worst_ns = max(m.worst_late_cycles for m in harness.model.machines) * 8
            dry.append(f"status line {query_ms:.2f} ms after H: a FIFO ran dry, {worst_ns} ns")
    assert not dry, "\n".join(dry)
