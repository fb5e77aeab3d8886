"""The PIO build keeps standing axes fed while another runs fast.

Run (the PIO build's ELF from `firmware/build rp-pico --snapshot --features pio`):

    COGSTEP_PIO_ELF=<elf> firmware/pico-sim/.venv/bin/python -m pytest \\
        firmware/pico-sim/test_pio_idle.py

A board of four axes; axis 0 moves at 74,875 steps/s (pio_rates.py's
slew case: the Smooth ramp up, 200 ms at speed, the ramp down) while
axes 1 to 3 stand still, their state machines living on the holds the
main loop closes for them (`firmware/boards/rp-pico/src/pio.rs`,
`hold`). At this speed the main loop is busy making axis 0's steps and
its rounds run milliseconds long, back to back. With holds only at the
end of each round, the standing axes' FIFOs ran dry by up to 28 ms at
slew; the holds within a round (`Hold::RunningLow`) keep them fed. The
judge is pio_rates.py's: every word of the slew's middle half, of every
state machine (the ramp up is past what the core can decide on a board
of four, about 33,000 steps/s, and is not judged). About 30 s.

And from boot: the grbl dialect makes its session before its first
round, 1.18 ms after the state machines start, and a first hold of 1 ms
ran all three dry by 180 µs (every later edge as late). The first hold
now lasts to the frontier. And a G-code program from rest: the first
line's plan and first edges (the runner's `f64`, in software on the
M0+) must not outlast the holds. Three axes ramping together in the
grbl dialect keep time at 2,000 steps/s (each ramp step a solve in
software `f64`), and an arc's chords are planned a few a turn. And a
fast grbl line: every step on the pins, none
refused. And four axes at 50,000 steps/s each at slew (the issue's rate).
"""

import os

import pytest

import pio_rates

ELF = os.environ.get("COGSTEP_PIO_ELF")
pytestmark = pytest.mark.skipif(not ELF, reason="COGSTEP_PIO_ELF (the PIO build's ELF) is not set")


def test_standing_axes_stay_fed_while_one_axis_of_four_runs_at_74875_steps_s():
    clean, detail = pio_rates.run(ELF, 1, 74_875, slew=True, board_axes=4)
    assert clean, detail


def test_four_axes_at_50000_steps_s_keep_every_edge_at_speed():
    """The issue's rate at slew: four axes at 50,000 steps/s each (200,000
    in all), every word of the slew's middle half on time (pio_rates.py's
    judge; the ramps, up to 21,800 steps/s on four axes, are not judged).
    A train's steps a run at a time and the words by DMA: f5c9e3f (a step
    at a time, TXNFULL's interrupt a word) kept time up to 23,315. About
    20 s."""
    clean, detail = pio_rates.run(ELF, 4, 50_000, slew=True)
    assert clean, detail


def test_standing_axes_stay_fed_from_boot_in_the_grbl_dialect():
    # The harness runs until grbl's welcome line has come (its `]`).
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    reports = []
    harness.model.report = reports.append
    harness.run_ms(30)
    assert b"Grbl 1.1h" in harness.out
    machines = harness.model.machines[:3]
    assert all(m.words > 1 for m in machines)
    late = [m.late_words for m in machines]
    assert late == [0, 0, 0], f"late words per machine {late}\n" + "\n".join(reports)


def test_a_program_starts_from_rest_with_no_fifo_run_dry_in_the_grbl_dialect():
    # Three lines, each planned as it comes (the planner's `f64` on the
    # M0+): the first line's plan and its first edges kept the main loop
    # busy for 4.8 ms (soft doubles: longer), past the holds' 4 ms, and
    # every state machine ran dry by 3.1 ms (by 6.6 ms with soft
    # doubles): each axis's later edges all came that late.
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    reports = []
    harness.model.report = reports.append
    for line in ("G1 X10 Y5 F3000", "G1 X20 Y0", "G1 X30 Y10"):
        harness.feed(line)
    harness.run_ms(60 - harness.now_ms())
    assert harness.out.count(b"ok") == 3, harness.out
    machines = harness.model.machines[:3]
    late = [m.late_words for m in machines]
    assert late == [0, 0, 0], f"late words per machine {late}\n" + "\n".join(reports)
    # And the axes moved: the path's steps came out of the state machines.
    assert all(m.words > 20 for m in machines)


def test_three_axes_ramping_together_in_the_grbl_dialect_keep_time_at_2000_steps_s():
    # `G1 X8 Y5 Z3` on gentle ramps (50 mm/s²), X at 2,000 steps/s: most
    # of the line is ramp, and each of its steps is a solve of the ramp's
    # inverse for each axis (`ramp_time.rs`, the path's `f64` in software
    # on the M0+). At 56,000 cycles a solve the main loop kept time only up
    # to 500 steps/s: at 1,000 every state machine ran dry, by up to
    # 3.4 ms. One evaluation a solve, from where the axis's last landed,
    # with the table's sine and cosine: about 14,000.
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    reports = []
    harness.model.report = reports.append
    for line in ("$120=50", "$121=50", "$122=50", "G1 X8 Y5 Z3 F594"):
        harness.send(line)
    sim = harness.sim
    while sim.axes[0].position < 2000 and harness.now_ms() < 10_000:
        harness.run_ms(100)
    harness.run_ms(50)
    assert [a.position for a in sim.axes[:3]] == [2000, 1250, 750]
    late = [m.late_words for m in harness.model.machines[:3]]
    assert late == [0, 0, 0], f"late words per machine {late}\n" + "\n".join(reports)
    assert sim.made_late() == 0


def test_an_arcs_chords_are_planned_over_several_turns_with_no_long_pause():
    # `G2 X11 Y0 I5 J0` (56 chords) at F150 after a short line. Its turn of
    # the main loop used to interpret the whole arc twice and plan every
    # chord the planner had room for, each a plan in software `f64`: every
    # state machine ran dry for 25 ms at the arc's start (36 ms before the
    # table's sines and the boot ROM's square root). Now two blocks a turn
    # (`BLOCKS_PER_TURN`) and the dry run from the arc's bounds.
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    harness.send("G1 X1 F150")
    # Its `ok` comes once the last chord is queued, seconds later.
    harness.feed("G2 X11 Y0 I5 J0")
    # The arc's start and its first refills (the planner holds 32 blocks).
    harness.run_ms(500)
    machines = harness.model.machines[:3]
    gaps = [max([cycles for _, _, cycles in m.late_log] or [0]) for m in machines]
    # The worst gap of each state machine, in cycles (125 per µs).
    assert max(gaps) <= 125 * 1000, f"worst gaps {[g / 125 for g in gaps]} µs"
    assert [a.position for a in harness.sim.axes[:2]] != [0, 0]


def test_a_fast_line_in_the_grbl_dialect_makes_every_step_on_the_pins():
    # 5,000 steps/s on X. The main loop's turns then bring the path's
    # axes up to the frontier (`FirmwareAxis::synced`) before the turn's
    # wake-ups had run, and the catch-up's edges past an axis's few
    # pending slots went out with an old CT: the PIO encoder refused
    # them, and grbl reported `MPos:8.000` with the pins 1,100 steps
    # short. Now the wake-ups run first, and an edge that comes late
    # anyway is made late and counted (COGSTEP_PIO_MADE_LATE), not lost.
    run_a_fast_line_to_its_end("F1200")


def run_a_fast_line_to_its_end(feed, log_words=False):
    """`G1 X8` at `feed` (grbl's 250 steps/mm, `$110=4800 $120=2000`):
    checks that grbl reports the end and that all 2,000 steps are on the
    pins, none refused; returns the harness."""
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    harness.model.machines[0].log_words = log_words
    for line in ("$110=4800", "$120=2000", f"G1 X8 {feed}"):
        harness.send(line)
    sim = harness.sim
    while sim.axes[0].position < 2000 and harness.now_ms() < 1500:
        harness.run_ms(50)
    harness.run_ms(50)
    harness.send("?")
    report = [line for line in bytes(harness.out).decode(errors="replace").split("\r\n") if "MPos" in line][-1]
    assert "MPos:8.000," in report, report
    refused = sim.mcu.read_uint32(sim.refused_address)
    assert [a.position for a in sim.axes[:3]] == [2000, 0, 0], f"refused {refused}, made late {sim.made_late()}"
    assert refused == 0
    return harness


def test_a_line_faster_than_the_core_keeps_up_with_loses_no_step_and_bunches_none():
    # 10,000 steps/s on X: past what the main loop can time (the path's
    # `f64` on the M0+), so its steps come late. They used to go out back
    # to back at the program's fastest step (631 cycles, a burst at
    # 198,000 steps/s that a real motor cannot follow), edges driven
    # together shared one CT, and once an axis's ring was full its words
    # were dropped: the pins got 1,465 of 2,000 steps while grbl reported
    # `MPos:8.000`. Now every edge goes in at its own CT
    # (`Hardware::drive_pin`), late steps keep their periods one lag
    # behind, and the main loop waits for room in a full ring.
    machine = run_a_fast_line_to_its_end("F2400", log_words=True).model.machines[0]
    # Step words' periods (cycles): none shorter than a quarter of the
    # line's own (12,500 at 10,000 steps/s).
    periods = [(word >> 5) + 631 for word, _ in machine.word_log if word & 1]
    assert len(periods) == 2000
    bursts = [period for period in periods if period < 12_500 // 4]
    assert not bursts, f"{len(bursts)} steps faster than 40,000 steps/s, the shortest {min(bursts)} cycles"


def test_a_sender_streaming_past_an_arc_loses_no_byte_on_uart0():
    # A sender that counts characters (as grbl senders do, up to 128 bytes
    # in flight) streams a small arc and lines after it. The arc's first
    # line keeps the main loop busy for milliseconds (its chords
    # interpreted and planned in one turn), longer than UART0's 32-byte
    # FIFO lasts at 115,200 baud; the harness drops bytes at a full FIFO,
    # as the chip does. The main loop used to read the FIFO itself: 4 of
    # 10 lines answered, one run into another, and the program ended at
    # X 3.2 instead of 3.8. Now UART0's interrupt moves the bytes to a
    # ring (`uart.rs`), live inside critical sections.
    harness = pio_rates.Harness(ELF, 3, dialect="grbl")
    for line in ("$120=1000", "$121=1000", "$122=1000"):
        harness.send(line)
    answered = lambda: harness.out.count(b"ok") + harness.out.count(b"error")  # noqa: E731
    before = answered()
    lines = ["G1 X1 F600", "G2 X3 Y0 I1 J0"] + ["G1 X%.1f Y%.1f" % (3 + 0.1 * k, 0.1 * (k % 2)) for k in range(1, 9)]
    sent = 0
    while sent < len(lines) and harness.now_ms() < 5000:
        in_flight = lines[answered() - before : sent]
        if sum(len(line) + 1 for line in in_flight) + len(lines[sent]) + 1 <= 128:
            harness.feed(lines[sent])
            sent += 1
        else:
            harness.run_ms(0.5)
    while answered() - before < len(lines) and harness.now_ms() < 5000:
        harness.run_ms(20)
    text = bytes(harness.out).decode(errors="replace")
    assert "error" not in text, text
    assert answered() - before == len(lines), text
    while harness.now_ms() < 5000:
        harness.send("?")
        report = [line for line in bytes(harness.out).decode(errors="replace").split("\r\n") if "MPos" in line][-1]
        if report.startswith("<Idle"):
            break
        harness.run_ms(50)
    assert "MPos:3.800,0.000,0.000" in report, report
