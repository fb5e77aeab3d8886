"""The RP2040's second core beside rp2040py's first.

rp2040py 0.3.6 runs core 0 only: its SIO answers CPUID 0 and has no
inter-core FIFO (its docs/records/0053). The harness adds core 1:

- **A second `CortexM0Core`** on the same bus (RAM, flash, peripherals),
  held in reset until the firmware releases it through the power-on state
  machine (PSM `FRCE_OFF`, as rp2040-hal's `Core::spawn` and the Pico
  SDK's `multicore_reset_core1` do), then started at the boot ROM's reset
  vector: the ROM's own core 1 code waits for the launch sequence on the
  FIFO and jumps to the firmware's entry.
- **SIO per core**: each core's view answers its own CPUID, has its own
  hardware divider and interpolators, and its own end of the two FIFOs
  (8 words each way: `FIFO_ST`'s VLD, RDY, WOF and ROE, `FIFO_WR`,
  `FIFO_RD`, the `SIO_IRQ_PROC0`/`1` line of the core that reads). GPIO and
  the spinlocks are one block, shared.
- **Each core its own NVIC, SysTick pend, VTOR and MPU registers (kept,
  not enforced)**: rp2040py's PPB
  reaches "the core" through `RP2040.core`, which is set to the core that
  runs each instruction. An interrupt line (a timer alarm, UART0) reaches
  both cores' NVICs, as on the chip; each enables its own.
- **Events**: SEV on either core sets both cores' event registers (ARMv6-M:
  every PE's). A FIFO write also wakes the reading core: every writer here
  (rp2040-hal's `SioFifo::write`, the firmware's doorbell) follows it with
  SEV, and while core 1 sleeps core 0 runs in rp2040py's native loop, which
  cannot see a SEV.
- **Time**: the cores run side by side at 125 MHz. While core 1 is held
  or asleep (WFE, WFI) core 0 runs alone in rp2040py's native loop, as
  fast as without core 1. While core 1 runs, both step in Python, one
  instruction at a time, the core that is behind first; the clock follows
  the one further behind (within an instruction, 1 to 3 cycles, of each),
  and jumps to the next alarm when both sleep. Each instruction's cycles
  advance the PIO blocks as the native loop does.
"""

from collections import deque

from rp2040py.execute_batch import execute_batch
from rp2040py.native._cortex_m0_core import CortexM0Core
from rp2040py.sio import RPSIO

#: SIO offsets.
CPUID = 0x000
FIFO_ST = 0x050
FIFO_WR = 0x054
FIFO_RD = 0x058
#: The divider and interpolators: each core's own.
PER_CORE_FIRST = 0x060
PER_CORE_LAST = 0x0FC
#: FIFO_ST bits.
VLD, RDY, WOF, ROE = 1, 2, 4, 8
FIFO_DEPTH = 8
#: The FIFO interrupt of the core that reads (SIO_IRQ_PROC0, SIO_IRQ_PROC1).
SIO_IRQ = (15, 16)
#: PSM FRCE_OFF's bit for core 1, and the register's offset.
PSM_PROC1 = 1 << 16
PSM_FRCE_OFF = 0x04
#: The MPU's registers (PPB offsets) and its regions on the RP2040.
MPU_TYPE = 0xD90
MPU_RASR = 0xDA0
MPU_REGIONS = 8
#: One cycle of the 125 MHz system clock.
CYCLE_NS = 8.0


class SioView:
    """SIO as core `index` sees it (see the module docs)."""

    def __init__(self, cores, index, shared, own):
        self.cores = cores
        self.index = index
        self.shared = shared
        self.own = own

    def __getattr__(self, name):
        # The shared block's state (GPIO levels the pins read).
        return getattr(self.shared, name)

    def read_uint32(self, offset):
        if offset == CPUID:
            return self.index
        if offset == FIFO_ST:
            return self.cores.fifo_status(self.index)
        if offset == FIFO_RD:
            return self.cores.fifo_read(self.index)
        if PER_CORE_FIRST <= offset <= PER_CORE_LAST:
            return self.own.read_uint32(offset)
        return self.shared.read_uint32(offset)

    def write_uint32(self, offset, value):
        if offset == FIFO_WR:
            self.cores.fifo_write(self.index, value)
        elif offset == FIFO_ST:
            self.cores.fifo_clear(self.index)
        elif PER_CORE_FIRST <= offset <= PER_CORE_LAST:
            self.own.write_uint32(offset, value)
        else:
            self.shared.write_uint32(offset, value)

    def reset(self):
        self.shared.reset()
        self.own.reset()


class Cores:
    """Both cores of an `RP2040` run by `Simulator` `sim` (see the module
    docs). `run()` replaces the native loop `while not sim.stopped:
    execute_batch(sim, 1)`; `stop()` ends it (a slice's end)."""

    def __init__(self, mcu, sim):
        self.mcu = mcu
        self.sim = sim
        self.clock = sim.clock
        self.core0 = mcu.core
        self.core1 = CortexM0Core(mcu)
        shared = mcu.sio
        self.sio = (SioView(self, 0, shared, shared), SioView(self, 1, shared, RPSIO(mcu)))
        mcu.sio = self.sio[0]
        # FIFO `i` holds the words core `i` reads.
        self.fifos = (deque(), deque())
        self.sticky = [0, 0]
        self.held = True
        self.stopping = False
        # Cycles each core ran in the Python loop (all of core 1's; core
        # 0's only while core 1 ran).
        self.cycles = [0, 0]
        # Both cores' interrupt lines: each core's NVIC enables its own.
        mcu.set_interrupt = self.set_interrupt
        psm = mcu.psm
        psm_write = psm.write_uint32

        def write_psm(offset, value):
            before = psm.read_uint32(PSM_FRCE_OFF)
            psm_write(offset, value)
            after = psm.read_uint32(PSM_FRCE_OFF)
            if after & PSM_PROC1 and not before & PSM_PROC1:
                self.hold_core1()
            elif before & PSM_PROC1 and not after & PSM_PROC1:
                self.start_core1()

        psm.write_uint32 = write_psm
        # Each core's MPU registers (rp2040py has none: its reads of them
        # are all ones, and rp2040-hal's core 1 start-up takes a set CTRL
        # for an MPU already in use and stops). Kept, not enforced: a stack
        # guard written there guards nothing here.
        self.mpu = ({}, {})
        ppb = mcu.ppb
        ppb_read, ppb_write = ppb.read_uint32, ppb.write_uint32

        def read_ppb(offset):
            if MPU_TYPE <= offset <= MPU_RASR:
                if offset == MPU_TYPE:
                    return MPU_REGIONS << 8
                return self.mpu[self.current()].get(offset, 0)
            return ppb_read(offset)

        def write_ppb(offset, value):
            if MPU_TYPE < offset <= MPU_RASR:
                self.mpu[self.current()][offset] = value & 0xFFFFFFFF
            else:
                ppb_write(offset, value)

        ppb.read_uint32 = read_ppb
        ppb.write_uint32 = write_ppb
        self.start_core1()

    def current(self):
        """The core whose instruction runs (or core 0 between them)."""
        return 1 if self.mcu.core is self.core1 else 0

    # Core 1's power.

    def hold_core1(self):
        self.held = True

    def start_core1(self):
        """Core 1 from its reset: the boot ROM's vector, its FIFO empty."""
        core = self.core1
        core.reset()
        core.sp = self.mcu.read_uint32(0x0)
        core.pc = self.mcu.read_uint32(0x4) & ~1
        self.fifos[1].clear()
        self.sticky[1] = 0
        self.update_irq(1)
        self.held = False

    # Interrupts and the FIFOs.

    def set_interrupt(self, irq, value):
        self.core0.set_interrupt(irq, value)
        self.core1.set_interrupt(irq, value)

    def update_irq(self, index):
        core = (self.core0, self.core1)[index]
        core.set_interrupt(SIO_IRQ[index], bool(self.fifos[index]) or bool(self.sticky[index]))

    def fifo_status(self, index):
        status = (VLD if self.fifos[index] else 0) | self.sticky[index]
        if len(self.fifos[1 - index]) < FIFO_DEPTH:
            status |= RDY
        return status

    def fifo_read(self, index):
        fifo = self.fifos[index]
        if not fifo:
            self.sticky[index] |= ROE
            self.update_irq(index)
            return 0
        word = fifo.popleft()
        self.update_irq(index)
        return word

    def fifo_write(self, index, value):
        other = 1 - index
        fifo = self.fifos[other]
        if len(fifo) >= FIFO_DEPTH:
            self.sticky[index] |= WOF
            self.update_irq(index)
            return
        fifo.append(value & 0xFFFFFFFF)
        self.update_irq(other)
        self.event(other)

    def fifo_clear(self, index):
        self.sticky[index] = 0
        self.update_irq(index)

    def event(self, index):
        """An event for core `index`: its WFE falls through or ends."""
        core = (self.core0, self.core1)[index]
        if core.waiting:
            core.waiting = False
        else:
            core.event_registered = True
        if index == 1 and not self.held:
            # Core 0 may be in the native loop: let core 1 run now.
            self.sim.stopped = True

    # Running.

    def stop(self):
        """Ends `run()` (and the native batch under way)."""
        self.stopping = True
        self.sim.stopped = True

    def core1_sleeps(self):
        return self.held or self.core1.waiting

    def run(self):
        """Runs until `stop()`."""
        self.stopping = False
        while not self.stopping:
            if self.core1_sleeps():
                self.sim.stopped = False
                execute_batch(self.sim, 1)
            else:
                self.run_both()

    def run_both(self):
        """Both cores, an instruction at a time, until core 1 sleeps or
        `stop()`. `behind[i]`: the cycles core `i` has run past the clock."""
        mcu, clock = self.mcu, self.clock
        cores = (self.core0, self.core1)
        sios = self.sio
        pios = mcu.pio
        behind = [0, 0]
        spent = self.cycles
        while not self.stopping:
            running0 = not self.core0.waiting
            running1 = not self.held and not self.core1.waiting
            if not running1:
                break
            index = 0 if running0 and behind[0] <= behind[1] else 1
            core = cores[index]
            mcu.core = core
            mcu.sio = sios[index]
            event = core.event_registered
            ipsr = core.ipsr
            cycles = core.execute_instruction()
            spent[index] += cycles
            if core.event_registered and not event and core.ipsr == ipsr:
                # SEV (an exception's entry or return changes IPSR): the
                # other core's event register too.
                self.event(1 - index)
            behind[index] += cycles
            if not running0 or self.core0.waiting:
                behind[0] = behind[1]
            # The clock follows the core further behind.
            step = min(behind)
            if step:
                behind[0] -= step
                behind[1] -= step
                mcu.core = self.core0
                mcu.sio = sios[0]
                clock.tick(step * CYCLE_NS)
                for pio in pios:
                    if not pio.stopped:
                        pio.advance(step)
        mcu.core = self.core0
        mcu.sio = sios[0]
        # Core 0 ran past the clock by at most an instruction: it goes on
        # from there in the native loop.
