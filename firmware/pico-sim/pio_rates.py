"""The highest step rates at which no PIO FIFO runs dry, on the Pico's PIO build.

    firmware/build rp-pico --features pio
    firmware/pico-sim/.venv/bin/python firmware/pico-sim/pio_rates.py \
        --elf firmware/target/thumbv6m-none-eabi/release/cogstep-rp-pico-pio

Runs the PIO build under rp2040py with PIO0 as the step program's closed
form (`pio_model.py`), in one process and as fast as the emulator goes
(no wall clock, no pseudo-terminal: the protocol's lines go straight
into UART0's receive FIFO), and bisects the speed (steps/s an axis) for
four cases: one axis and four axes together, each ramping (a move of
speed / 5 steps: the Smooth ramp up to the speed and straight back down)
and at slew (the same move with 200 ms at speed between the ramps). A
run is clean when the model counts no word that reached its FIFO after
its `pull` was due (a FIFO run dry), none written to a full FIFO, and
the firmware refused no edge. For slew, only the words in the slew's
middle half (in time, from its first step at speed) count: a ramp that
ran dry (up or down) is the ramp's figure, and the slew has had a
quarter of its time to catch up. Prints one line a case, and a Markdown
table at the end (docs/performance.md).

    --cases 1s --at 20000   one run per case at that speed, no bisection
                            (`.ci/run` keeps the script working so)
    --core1 off             core 0 computes every ramp run (run-pico-sim's
                            --core1; by default core 1 computes them ahead)
    --board-axes 4          the board's axis count (run-pico-sim's --axes),
                            when more than the axes that move: the others
                            stand still, their state machines fed holds
                            (by default the board has just the moving axes)
"""

import argparse
import sys
import time
from types import SimpleNamespace


import pico_sim

#: The program's shortest step (pio_steps.json's step_min_cycles):
#: 125 MHz / 631, the most one state machine makes.
MAX_RATE = 198_000
CLOCK_HZ = 125_000_000


def steps_of(word_log, program):
    """The steps of a state machine's `word_log` ((word, pull cycle), as
    `pio_model.Machine` logs it): (pull cycle of its step word, period in
    cycles), a step being its step word and the hold words after it (a
    hold splits a step where the feeder held its axis up to another axis's
    edge, or up to a frontier mark). Holds before the first step are none's."""
    count_mask = (1 << program["count_bits"]) - 1
    start, period = None, 0
    for word, pull in word_log:
        if word & 1:
            if start is not None:
                yield start, period
            start, period = pull, program["step_min_cycles"] + (word >> 5)
        elif start is not None:
            period += program["hold_min_cycles"] + (word >> 3 & count_mask)
    if start is not None:
        yield start, period


def first_at_speed(machine, program, speed):
    """The `pull` cycle of the machine's first step at `speed` (its period
    to 0.5 %: not the top of the ramp, whose steps come within 3 %), or
    None."""
    period = CLOCK_HZ / speed
    return next(
        (pull for pull, cycles in steps_of(machine.word_log, program) if abs(cycles - period) <= period * 0.005),
        None,
    )


def late_in_slew(machines, program, speed, slew_steps, firsts=None):
    """The late words (machine index, word, cycles late) of a slew's middle
    half, in time: from a quarter of the slew after a machine's first step
    at `speed` (`first_at_speed`) to three quarters, once a ramp that fell
    behind has had a quarter of the slew to catch up, and before the ramp
    down. Every
    word in it counts, hold words and split steps too: judging step words
    at speed alone missed every late word of a run whose steps were all
    split. A machine with no step at speed (an axis standing still) is
    judged in the window of the earliest that has one. None while no
    machine has one (the slew has not begun, or never came). `firsts`, a
    dict kept between calls on a growing run, keeps each machine's first
    step at speed once found, so that a call does not scan every word
    again."""
    firsts = {} if firsts is None else firsts
    for machine in machines:
        if firsts.get(machine.index) is None:
            firsts[machine.index] = first_at_speed(machine, program, speed)
    starts = [firsts[machine.index] for machine in machines]
    moving = [start for start in starts if start is not None]
    if not moving:
        return None
    slew_cycles = slew_steps * CLOCK_HZ // speed
    late = []
    for machine, start in zip(machines, starts):
        start = min(moving) if start is None else start
        window = (start + slew_cycles // 4, start + slew_cycles * 3 // 4)
        late += [
            (machine.index, word, cycles)
            for index, word, cycles in machine.late_log
            if index < len(machine.word_log) and window[0] <= machine.word_log[index][1] <= window[1]
        ]
    return late


class Harness:
    """The PIO build under rp2040py in this process, PIO0 the model, as
    fast as the emulator goes: the protocol's lines go straight into
    UART0's receive FIFO at 115,200 baud, replies collect in `out`."""

    def __init__(self, elf, axes, dialect="v1", core1="on"):
        args = SimpleNamespace(
            elf=elf,
            axes=axes,
            vcd=None,
            dialect=dialect,
            arithmetic="smooth",
            usb=False,
            bench=False,
            pio_model="on",
            core1=core1,
        )
        self.sim = pico_sim.PicoSim(args)
        self.model = self.sim.pio_model
        self.model.report = lambda _text: None
        self.out = bytearray()
        self.sim.mcu.uart[0].on_byte = self.out.append
        while b"]" not in self.out:
            self.run_ms(1)

    def now_ms(self):
        return self.sim.clock.nanos / 1e6

    def run_ms(self, ms):
        """Runs `ms` of simulated time (nothing for none)."""
        if ms <= 0:
            return
        sim = self.sim
        sim.slice_alarm.schedule(ms * 1e6)
        sim.cores.run()
        sim.slice_alarm.cancel()
        sim.catch_up()

    def feed(self, line):
        """`line` at 115,200 baud, as the UART would bring it (a burst of
        lines planned back to back can outlast the main loop's 4 ms lead:
        the emulator's UART alone would not show that)."""
        for byte in (line + "\n").encode():
            self.sim.mcu.uart[0].feed_byte(byte)
            self.run_ms(pico_sim.UART_BYTE_NS / 1e6)

    def send(self, line):
        """`line`, then its reply."""
        before = self.out.count(b"\n")
        self.feed(line)
        while self.out.count(b"\n") == before:
            self.run_ms(0.2)

    def late_words(self):
        return sum(m.late_words for m in self.model.machines)


def run(elf, axes, speed, slew, board_axes=None, core1="on"):
    """One run: the first `axes` axes of a board with `board_axes` (at
    least `axes`) move at `speed`, core 1 computing ramp runs ahead or
    not (`core1`); returns (clean, detail)."""
    harness = Harness(elf, max(axes, board_axes or 0), core1=core1)
    sim, model, run_ms, send = harness.sim, harness.model, harness.run_ms, harness.send
    # Every word from the first, so that a late word's index (late_log)
    # is its place in word_log.
    for machine in model.machines:
        machine.log_words = slew

    ramp_steps = max(speed // 5, 10)
    slew_steps = speed // 5 if slew else 0
    steps = ramp_steps + slew_steps
    for axis in range(axes):
        send(f"M {axis} {speed} {steps if axis % 2 == 0 else -steps}")
    firsts = {}

    def counted(final=False):
        def every():
            return [(m.index, word, cycles) for m in model.machines for _index, word, cycles in m.late_log]

        late = late_in_slew(model.machines, model.program, speed, slew_steps, firsts) if slew else every()
        if late is None:
            # No step at speed yet: nothing judged, unless the run is over
            # (a slew that never came counts every late word).
            late = every() if final else []
        # An edge made later than its CT (COGSTEP_PIO_MADE_LATE) is as
        # late as one after a dry FIFO: not clean either.
        refused = sim.mcu.read_uint32(sim.refused_address) + sim.made_late()
        overflows = sum(m.overflows for m in model.machines)
        return late, refused, overflows

    deadline = time.monotonic() + 1800
    while any(abs(a.position) < steps for a in sim.axes[:axes]):
        run_ms(10)
        late, refused, overflows = counted()
        # The first fault decides: no need to run the rest.
        if late or refused or overflows:
            break
        if time.monotonic() > deadline:
            return False, "never finished"
    run_ms(10)
    late, refused, overflows = counted(final=True)
    clean = not late and not refused and not overflows
    worst = max((c for _, _, c in late), default=0) * 8
    detail = f"{len(late)} late words (worst {worst} ns), {overflows} overflows, {refused} refused or made late (the run stops at the first)"
    return clean, detail


def label_of(axes, slew, board_axes):
    """A case's name in the output."""
    of = f" of {board_axes}" if board_axes and board_axes > axes else ""
    return f"{axes}{of} {'axes' if axes > 1 or of else 'axis'}, {'slew' if slew else 'ramp'}"


def highest(elf, axes, slew, low, high, board_axes=None, core1="on"):
    """Bisects the speed between a clean `low` and `high`, to 5 %."""
    label = label_of(axes, slew, board_axes)
    clean, detail = run(elf, axes, low, slew, board_axes, core1)
    print(f"{label}: {low} steps/s: {'clean' if clean else detail}", flush=True)
    if not clean:
        return None
    clean, detail = run(elf, axes, high, slew, board_axes, core1)
    print(f"{label}: {high} steps/s: {'clean' if clean else detail}", flush=True)
    if clean:
        return high
    while high - low > low // 20:
        middle = (low + high) // 2
        clean, detail = run(elf, axes, middle, slew, board_axes, core1)
        print(f"{label}: {middle} steps/s: {'clean' if clean else detail}", flush=True)
        if clean:
            low = middle
        else:
            high = middle
    return low


def main():
    parser = argparse.ArgumentParser(prog="pio_rates")
    parser.add_argument("--elf", required=True, help="the PIO build's ELF (its UF2 file beside it)")
    parser.add_argument("--cases", default="1r,1s,4r,4s", help="axes and r(amp)/s(lew), comma-separated")
    parser.add_argument(
        "--at",
        type=int,
        help="one run of each case at this speed (steps/s an axis) instead of the bisection: "
        "prints clean or what ran dry, and exits 0 either way (CI's smoke run)",
    )
    parser.add_argument(
        "--board-axes",
        type=int,
        help="the board's axes (1 to 4) when more than a case's moving axes: the rest stand still",
    )
    parser.add_argument(
        "--core1",
        choices=["on", "off"],
        default="on",
        help="whether core 1 computes the ramp runs ahead (run-pico-sim's --core1)",
    )
    args = parser.parse_args()
    if args.at:
        for case in args.cases.split(","):
            axes, slew = int(case[:-1]), case[-1] == "s"
            label = label_of(axes, slew, args.board_axes)
            clean, detail = run(args.elf, axes, args.at, slew, args.board_axes, args.core1)
            print(f"{label}: {args.at} steps/s: {'clean' if clean else detail}", flush=True)
        return 0
    results = []
    for case in args.cases.split(","):
        axes, slew = int(case[:-1]), case[-1] == "s"
        rate = highest(args.elf, axes, slew, 1_000, MAX_RATE, args.board_axes, args.core1)
        results.append((axes, "slew" if slew else "ramp", rate))
    if args.board_axes:
        print(f"\n(a board of {args.board_axes} axes; the ones not moving stand still)")
    print("\n| axes | phase | highest steps/s an axis, no FIFO dry | total steps/s |")
    print("|---|---|---|---|")
    for axes, phase, rate in results:
        shown = f"{rate:,}" if rate else "below 1,000"
        total = f"{rate * axes:,}" if rate else "-"
        print(f"| {axes} | {phase} | {shown} | {total} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
