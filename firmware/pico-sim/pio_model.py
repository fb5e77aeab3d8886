"""A recording model of PIO0 for the Pico's PIO build (link 2 of the PIO proof).

rp2040py's own PIO runs at most one state machine instruction per CPU
instruction, so its pins cannot show edges exact to the 125 MHz clock.
`pico_sim.py` puts this model in its place when the firmware is the PIO
build (`firmware/build rp-pico --features pio`; its ELF has the symbol
`COGSTEP_PIO_REFUSED`). The model does not run PIO instructions: it
checks that the firmware installed the step program of
`firmware/pio-steps` (`pio_steps.json`, the opcodes link 1 runs in
pioemu) and set each state machine up as that program needs (clock
divider 1, OSR shifting right, no autopull), then applies the program's
closed form (`pio_steps::pin_writes`) to every word the firmware writes
to a TX FIFO, at the simulated time it writes it:

- **Cycles.** A state machine's cycle 0 is the CTRL write that sets its
  SM_ENABLE bit (its first `pull`); cycle c is 8 ns × c later. Word 0's
  `pull` is due at cycle 0, and word k + 1's at the cycle word k's pins
  leave room for it: P(k + 1) = P(k) + c + 631 after a step, + c + 6
  after a hold (its first pin write is 3 cycles after its `pull`).
- **A FIFO that runs dry.** A word written in cycle a ≥ its `pull`'s due
  cycle D is pulled at a + 1: its edges and every later edge of that
  machine come a + 1 − D cycles late. Each such word is counted, the
  first ones printed on stderr (`run-pico-sim: PIO0 SM1 ran dry ...`),
  and the `pio` control line reports them.
- **FIFO levels.** FLEVEL and FSTAT count the words written and not yet
  pulled at the simulated time of the read: 8 deep with FJOIN_TX (the
  firmware's `Buffers::OnlyTx`), 4 without. A word written to a full FIFO
  is dropped and counted (TXOVER, as the chip does).
- **The interrupt.** INTR's TXNFULL bits are the FIFOs with room;
  PIO0_IRQ_0 is raised while (INTR & IRQ0_INTE) | IRQ0_INTF is not 0,
  looked at after every register access and at each `pull` of a machine
  whose FIFO is full and whose TXNFULL interrupt is enabled (a clock
  alarm), so the firmware's feeder is woken when the chip would wake it.
- **DMA.** A TX FIFO's data request (DREQ_PIO0_TXn) is raised while the
  FIFO has room and lowered while it is full, for each machine an
  enabled DMA channel is paced by (TREQ_SEL): looked at after every
  register access of the model's or of the DMA's, and at each `pull` of
  such a machine whose FIFO is full (a clock alarm). rp2040py's DMA then
  writes a word to the FIFO when the chip's would.
- **Pins.** Each machine's two OUT pins (PINCTRL's OUT_BASE) get the pin
  writes of the closed form, handed to `on_pins(ns, gpio_levels)` in
  time order: lazily (when `catch_up(now)` is called, at the end of each
  slice and before any control line), or at their own time while
  `eager` is set (for switches at axis positions).

Other registers (CLKDIV, EXECCTRL, SHIFTCTRL, PINCTRL, INSTR_MEM, SM_INSTR,
IRQ1, ...) are stored and read back as written; writes the model does
not act on are kept for the checks above and otherwise ignored.
"""

import json
import os
import sys

from rp2040py.irq import IRQ
from rp2040py.peripherals.peripheral import BasePeripheral

#: Register offsets (RP2040 data sheet 3.7).
CTRL = 0x000
FSTAT = 0x004
FDEBUG = 0x008
FLEVEL = 0x00C
TXF0 = 0x010
RXF0 = 0x020
IRQ_FLAGS = 0x030
IRQ_FORCE = 0x034
DBG_PADOUT = 0x03C
DBG_PADOE = 0x040
DBG_CFGINFO = 0x044
INSTR_MEM0 = 0x048
SM0_CLKDIV = 0x0C8
SM_STRIDE = 0x18
SM_CLKDIV, SM_EXECCTRL, SM_SHIFTCTRL, SM_ADDR, SM_INSTR, SM_PINCTRL = range(0, 0x18, 4)
INTR = 0x128
IRQ0_INTE = 0x12C
IRQ0_INTF = 0x130
IRQ0_INTS = 0x134
IRQ1_INTE = 0x138
IRQ1_INTF = 0x13C
IRQ1_INTS = 0x140

SHIFTCTRL_FJOIN_TX = 1 << 30
SHIFTCTRL_OUT_SHIFTDIR = 1 << 19
SHIFTCTRL_AUTOPULL = 1 << 17
#: Power-on values of the registers that are not 0 (data sheet 3.7).
RESET_VALUES = {SM_CLKDIV: 0x0001_0000, SM_EXECCTRL: 0x0001_F000, SM_SHIFTCTRL: 0x000C_0000, SM_PINCTRL: 0x1400_0000}

#: ns per state machine cycle (125 MHz, divider 1).
CYCLE_NS = 8
#: Late words printed on stderr before the rest are only counted.
PRINTED_LATE = 10
#: Late words kept in `Machine.late_log` (all of them with `log_words`).
LATE_LOG = 10_000

HERE = os.path.dirname(os.path.abspath(__file__))


def load_program(path=os.path.join(HERE, "pio_steps.json")):
    with open(path) as f:
        return json.load(f)


class Machine:
    """One state machine: its registers, the words written to its FIFO, and
    the cycles their `pull`s run at under the closed form."""

    #: rp2040py's GPIO pins look for machines stalled on a `wait` for them:
    #: the step program has none.
    waiting = False

    def __init__(self, index, program):
        self.index = index
        self.program = program
        self.regs = dict(RESET_VALUES)
        self.enabled = False
        self.start_ns = None
        # The cycle at which the next word's `pull` is due (closed form).
        self.next_due = 0
        # `pull` cycles of the words written and not yet pulled, oldest first.
        self.in_fifo = []
        self.words = 0
        self.late_words = 0
        self.late_cycles = 0
        self.worst_late_cycles = 0
        self.overflows = 0
        # The first late words: (index, word, cycles late), and with
        # `log_words` every word as (word, the cycle of its `pull`), for
        # tools that ask where a FIFO ran dry (firmware/pico-sim/pio_rates.py).
        self.late_log = []
        self.log_words = False
        self.word_log = []
        # Pin writes to come: (ns, pins), in time order.
        self.writes = []
        self.jumped_to = None
        # Words written before the start, in the FIFO for its first `pull`s.
        self.before_start = []

    @property
    def depth(self):
        return 8 if self.regs[SM_SHIFTCTRL] & SHIFTCTRL_FJOIN_TX else 4

    def cycle_at(self, ns):
        """The cycle running at simulated `ns` (negative before the start)."""
        if self.start_ns is None:
            return None
        return int((ns - self.start_ns) // CYCLE_NS)

    def level(self, ns):
        """Words in the FIFO at `ns`: those whose `pull` has not run."""
        cycle = self.cycle_at(ns)
        if cycle is None:
            return len(self.before_start)
        if self.in_fifo:
            pulled = 0
            for pull in self.in_fifo:
                if pull > cycle:
                    break
                pulled += 1
            if pulled:
                del self.in_fifo[:pulled]
        return len(self.in_fifo)

    def next_pull_ns(self):
        """Simulated ns of the next `pull` of a word already written."""
        if self.start_ns is None or not self.in_fifo:
            return None
        return self.start_ns + self.in_fifo[0] * CYCLE_NS

    def push(self, ns, word, report):
        if self.level(ns) >= self.depth:
            self.overflows += 1
            report(f"PIO0 SM{self.index}: word {word:#010x} written to a full TX FIFO at {ns:.0f} ns: dropped")
            return
        if self.start_ns is None:
            self.before_start.append(word)
            return
        self.enqueue(self.cycle_at(ns), word, report)

    def enqueue(self, cycle, word, report):
        """Word `word`, written in cycle `cycle` (None: before the start), to
        the FIFO and its pin writes to `writes`."""
        self.words += 1
        pull = self.next_due
        if cycle is not None and cycle >= pull:
            # Ran dry: the `pull` stalled until this word came.
            late = cycle + 1 - pull
            self.late_words += 1
            self.late_cycles += late
            self.worst_late_cycles = max(self.worst_late_cycles, late)
            # Every late word while every word is logged (pio_rates.py
            # judges the ones of a window, which may come after the first
            # LATE_LOG), else the first LATE_LOG.
            if self.log_words or len(self.late_log) < LATE_LOG:
                self.late_log.append((self.words - 1, word, late))
            if self.late_words <= PRINTED_LATE:
                more = "" if self.late_words < PRINTED_LATE else " (later ones are counted, not printed)"
                report(
                    f"PIO0 SM{self.index} ran dry: word {self.words - 1} ({word:#010x}) came at cycle {cycle}, "
                    f"its pull was due at cycle {pull}: its edges and every later one {late * CYCLE_NS} ns late{more}"
                )
            pull = cycle + 1
        if self.log_words:
            self.word_log.append((word, pull))
        self.in_fifo.append(pull)
        first_write = pull + self.program["first_write_cycle"]
        if word & 1:
            high, low = word >> 1 & 3, word >> 3 & 3
            self.writes.append((self.start_ns + first_write * CYCLE_NS, high))
            self.writes.append((self.start_ns + (first_write + self.program["pulse_cycles"]) * CYCLE_NS, low))
            self.next_due = pull + self.program["step_min_cycles"] + (word >> 5)
        else:
            count = word >> 3 & ((1 << self.program["count_bits"]) - 1)
            self.writes.append((self.start_ns + first_write * CYCLE_NS, word >> 1 & 3))
            self.next_due = pull + self.program["hold_min_cycles"] + count


class PioModel(BasePeripheral):
    """PIO0 as the step program's closed form: see the module docs."""

    def __init__(self, mcu, clock, on_pins, report=None):
        super().__init__(mcu, "PIO0 model")
        self.mcu = mcu
        self.clock = clock
        self.on_pins = on_pins
        self.report = report or (lambda text: sys.stderr.write(f"run-pico-sim: {text}\n"))
        self.program = load_program()
        self.machines = [Machine(i, self.program) for i in range(4)]
        self.instr_mem = [0] * 32
        self.regs = {}
        self.inte0 = self.intf0 = self.inte1 = self.intf1 = 0
        self.irq_flags = 0
        self.txover = 0
        self.problems = []
        self.eager = False
        # What GPIOPin reads for a pin whose function is PIO0: the model
        # hands edges to `on_pins` itself, so these stay 0 (no listener
        # sees the pins twice).
        self.pin_values = 0
        self.pin_directions = 0
        # rp2040py's batch loop steps each PIO block that is not stopped.
        self.stopped = True
        self.alarm = clock.create_alarm(self.alarm_due)
        self.alarm_ns = None
        self.out_base = [None] * 4

    # Installed in place of rp2040py's PIO0.
    def install(self):
        self.mcu.pio[0] = self
        self.mcu.peripherals[0x50200] = self
        # A DMA channel set up or started may be paced by a TX FIFO: its
        # data request is brought up to date after every DMA register write.
        dma = self.mcu.dma
        dma_write = dma.write_uint32

        def write_then_update(offset, value):
            dma_write(offset, value)
            self.update_dreqs()
            self.schedule()

        dma.write_uint32 = write_then_update

    def problem(self, text):
        self.problems.append(text)
        self.report(text)

    def now(self):
        return self.clock.nanos

    # Registers.
    def read_uint32(self, offset):
        now = self.now()
        if offset == CTRL:
            return sum(1 << m.index for m in self.machines if m.enabled)
        if offset == FSTAT:
            value = 0xF << 8  # RX FIFOs empty
            for m in self.machines:
                level = m.level(now)
                if level >= m.depth:
                    value |= 1 << (16 + m.index)
                if level == 0:
                    value |= 1 << (24 + m.index)
            return value
        if offset == FLEVEL:
            return sum(min(m.level(now), 15) << (8 * m.index) for m in self.machines)
        if offset == FDEBUG:
            return self.txover << 16
        if TXF0 <= offset < TXF0 + 16 or RXF0 <= offset < RXF0 + 16:
            return 0
        if offset == IRQ_FLAGS:
            return self.irq_flags
        if offset == DBG_PADOUT:
            return self.pin_values
        if offset == DBG_PADOE:
            return self.pin_directions
        if offset == DBG_CFGINFO:
            return 0x0020_0404
        if INSTR_MEM0 <= offset < INSTR_MEM0 + 128:
            return self.instr_mem[(offset - INSTR_MEM0) >> 2]
        if SM0_CLKDIV <= offset < SM0_CLKDIV + 4 * SM_STRIDE:
            machine = self.machines[(offset - SM0_CLKDIV) // SM_STRIDE]
            register = (offset - SM0_CLKDIV) % SM_STRIDE
            return machine.regs.get(register, 0)
        if offset == INTR:
            return self.intr()
        if offset == IRQ0_INTE:
            return self.inte0
        if offset == IRQ0_INTF:
            return self.intf0
        if offset == IRQ0_INTS:
            return (self.intr() & self.inte0) | self.intf0
        if offset == IRQ1_INTE:
            return self.inte1
        if offset == IRQ1_INTF:
            return self.intf1
        if offset == IRQ1_INTS:
            return (self.intr() & self.inte1) | self.intf1
        return self.regs.get(offset, 0)

    def write_uint32(self, offset, value):
        now = self.now()
        value &= 0xFFFF_FFFF
        if offset == CTRL:
            self.write_ctrl(now, value)
        elif TXF0 <= offset < TXF0 + 16:
            machine = self.machines[(offset - TXF0) >> 2]
            if machine.level(now) >= machine.depth:
                self.txover |= 1 << machine.index
            machine.push(now, value, self.problem)
        elif offset == FDEBUG:
            self.txover &= ~(self.raw_write_value >> 16)
        elif INSTR_MEM0 <= offset < INSTR_MEM0 + 128:
            self.instr_mem[(offset - INSTR_MEM0) >> 2] = value & 0xFFFF
        elif SM0_CLKDIV <= offset < SM0_CLKDIV + 4 * SM_STRIDE:
            machine = self.machines[(offset - SM0_CLKDIV) // SM_STRIDE]
            register = (offset - SM0_CLKDIV) % SM_STRIDE
            if register == SM_INSTR:
                self.exec_instruction(machine, value & 0xFFFF)
            elif register == SM_SHIFTCTRL:
                if (machine.regs[SM_SHIFTCTRL] ^ value) & SHIFTCTRL_FJOIN_TX:
                    machine.in_fifo.clear()  # joining clears the FIFOs
                machine.regs[register] = value
            elif register != SM_ADDR:
                machine.regs[register] = value
        elif offset == IRQ_FLAGS:
            self.irq_flags &= ~self.raw_write_value
        elif offset == IRQ_FORCE:
            self.irq_flags |= value & 0xFF
        elif offset == IRQ0_INTE:
            self.inte0 = value & 0xFFF
        elif offset == IRQ0_INTF:
            self.intf0 = value & 0xFFF
        elif offset == IRQ1_INTE:
            self.inte1 = value & 0xFFF
        elif offset == IRQ1_INTF:
            self.intf1 = value & 0xFFF
        else:
            self.regs[offset] = value
        self.check_interrupts()

    def write_ctrl(self, now, value):
        for machine in self.machines:
            enable = bool(value >> machine.index & 1)
            if enable and not machine.enabled:
                self.start(machine, now)
            elif machine.enabled and not enable:
                self.problem(f"PIO0 SM{machine.index} disabled at {now:.0f} ns: the model does not follow it further")
            machine.enabled = enable

    def exec_instruction(self, machine, instruction):
        # rp2040-hal's build() jumps to the program's start; `set pindirs`
        # (set_pindirs) and the like change nothing the model follows.
        if instruction >> 13 == 0 and instruction >> 5 & 7 == 0:
            machine.jumped_to = instruction & 0x1F

    def start(self, machine, now):
        """Checks the set-up against the program and starts the closed form."""
        program = self.program
        origin = machine.jumped_to
        opcodes = program["opcodes"]
        where = f"PIO0 SM{machine.index}"
        if origin is None:
            self.problem(f"{where}: started with no jump to a program: the model assumes the step program's start")
            origin = 0
        installed = self.instr_mem[origin : origin + len(opcodes)]
        # Jumps are installed relocated by the origin.
        expected = [op + origin if op >> 13 == 0 else op for op in opcodes]
        if installed != expected:
            self.problem(f"{where}: the program at {origin} is not pio_steps.json's: {installed} != {expected}")
        regs = machine.regs
        if regs[SM_CLKDIV] != 0x0001_0000:
            self.problem(f"{where}: clock divider {regs[SM_CLKDIV]:#x}, the closed form needs 1 (0x10000)")
        if not regs[SM_SHIFTCTRL] & SHIFTCTRL_OUT_SHIFTDIR or regs[SM_SHIFTCTRL] & SHIFTCTRL_AUTOPULL:
            self.problem(f"{where}: SHIFTCTRL {regs[SM_SHIFTCTRL]:#x}: the program needs OSR shifting right, no autopull")
        wrap_top = regs[SM_EXECCTRL] >> 12 & 0x1F
        wrap_bottom = regs[SM_EXECCTRL] >> 7 & 0x1F
        if (wrap_top, wrap_bottom) != (origin + program["wrap_source"], origin + program["wrap_target"]):
            self.problem(f"{where}: wrap {wrap_bottom}..{wrap_top}, the program's is its own + {origin}")
        out_count = regs[SM_PINCTRL] >> 20 & 0x3F
        if out_count != program["out_pin_count"]:
            self.problem(f"{where}: OUT count {out_count}, the program writes {program['out_pin_count']} pins")
        self.out_base[machine.index] = regs[SM_PINCTRL] & 0x1F
        # Cycle 0 on a whole ns, so that every edge is on one.
        machine.start_ns = round(now)
        machine.next_due = 0
        waiting, machine.before_start = machine.before_start, []
        for word in waiting:
            machine.enqueue(None, word, self.problem)
        self.schedule()

    # The interrupt.
    def intr(self):
        now = self.now()
        value = self.irq_flags << 8 & 0xF00
        for m in self.machines:
            if m.level(now) < m.depth:
                value |= 1 << (4 + m.index)
        return value

    def check_interrupts(self):
        ints0 = (self.intr() & self.inte0) | self.intf0
        ints1 = (self.intr() & self.inte1) | self.intf1
        self.mcu.set_interrupt(IRQ.PIO0_IRQ0, bool(ints0))
        self.mcu.set_interrupt(IRQ.PIO0_IRQ1, bool(ints1))
        self.update_dreqs()
        self.schedule()

    # DMA: each TX FIFO's data request (DREQ_PIO0_TX0..3), for the DMA
    # channels paced by it.
    def dma_paced(self, machine):
        """Whether an enabled DMA channel is paced by the machine's TX
        FIFO (TREQ_SEL = DREQ_PIO0_TXn): its data request is then kept, and
        a full FIFO's next `pull` is an event."""
        return any(channel._ctrl & 1 and channel.treq == machine.index for channel in self.mcu.dma.channels)

    def update_dreqs(self):
        """Raises each paced machine's TX data request while its FIFO has
        room, and lowers it while it is full (the DMA writes no word to a
        full FIFO)."""
        now = self.now()
        dma = self.mcu.dma
        for m in self.machines:
            if not self.dma_paced(m):
                continue
            if m.level(now) < m.depth:
                dma.set_dreq(m.index)
            else:
                dma.clear_dreq(m.index)

    def schedule(self):
        """Arms the alarm for the next moment the interrupt may change (a
        `pull` from a full FIFO whose TXNFULL interrupt is enabled), or,
        while `eager`, the next pin write."""
        now = self.now()
        due = None
        enabled = (self.inte0 | self.inte1) >> 4 & 0xF
        for m in self.machines:
            watched = enabled >> m.index & 1 or self.dma_paced(m)
            if watched and m.in_fifo and m.level(now) >= m.depth:
                at = m.next_pull_ns()
                if at is not None and (due is None or at < due):
                    due = at
            if self.eager and m.writes and (due is None or m.writes[0][0] < due):
                due = m.writes[0][0]
        if due == self.alarm_ns:
            return
        self.alarm_ns = due
        if due is None:
            self.alarm.cancel()
        else:
            self.alarm.schedule(max(due - now, 0))

    def alarm_due(self):
        self.alarm_ns = None
        self.catch_up(self.now())
        self.check_interrupts()

    # Pins.
    def catch_up(self, now):
        """Hands every pin write up to `now` to `on_pins`, in time order."""
        due = []
        for m in self.machines:
            taken = 0
            for ns, pins in m.writes:
                if ns > now:
                    break
                due.append((ns, m.index, pins))
                taken += 1
            if taken:
                del m.writes[:taken]
        due.sort()
        for ns, index, pins in due:
            base = self.out_base[index]
            if base is None:
                continue
            self.on_pins(ns, ((base, bool(pins & 1)), (base + 1, bool(pins & 2))))

    def summary(self):
        late = sum(m.late_words for m in self.machines)
        worst = max(m.worst_late_cycles for m in self.machines) * CYCLE_NS
        overflows = sum(m.overflows for m in self.machines)
        words = "/".join(str(m.words) for m in self.machines)
        starts = sorted({m.start_ns for m in self.machines if m.start_ns is not None})
        start = starts[0] if len(starts) == 1 else ",".join(str(s) for s in starts) or "none"
        return (
            f"start {start} words {words} late {late} worst_late_ns {worst} overflows {overflows} "
            f"problems {len(self.problems)}"
        )
