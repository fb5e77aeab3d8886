"""Core 1 beside rp2040py's core 0 (`core1.py`), and the firmware's use of it.

    firmware/pico-sim/.venv/bin/python -m pytest firmware/pico-sim/test_core1.py

The first tests need no firmware: the inter-core FIFOs, each core's SIO
view, events and the MPU registers, on a bare emulated chip. The others
run the Pico firmware's default build (the timer's edges; its ELF from
`firmware/build rp-pico --snapshot` in `COGSTEP_PICO_ELF`): core 1 started
by rp2040-hal's launch sequence through the boot ROM, and the same edges,
at the same simulated nanoseconds, whether core 1 computes the ramp runs
ahead or core 0 computes them all (to the edge interrupt's jitter of a few
cycles: core 0 runs other code when an alarm fires).
"""

import os
from types import SimpleNamespace

import pytest
from rp2040py.device.bootrom import BOOTROM_B1
from rp2040py.rp2040 import RP2040
from rp2040py.simulator import Simulator
from rp2040py.utils.logging import ConsoleLogger, LogLevel

import pico_sim
from core1 import FIFO_DEPTH, RDY, ROE, SIO_IRQ, VLD, WOF, Cores

ELF = os.environ.get("COGSTEP_PICO_ELF")
needs_elf = pytest.mark.skipif(not ELF, reason="COGSTEP_PICO_ELF (the Pico's default build) is not set")

SIO = 0xD000_0000
CPUID, FIFO_ST, FIFO_WR, FIFO_RD = SIO + 0x0, SIO + 0x50, SIO + 0x54, SIO + 0x58
DIV_UDIVIDEND, DIV_UDIVISOR, DIV_QUOTIENT = SIO + 0x60, SIO + 0x64, SIO + 0x70
MPU_TYPE, MPU_CTRL = 0xE000_ED90, 0xE000_ED94
PSM_FRCE_OFF = 0x4001_0004


def bare():
    """A chip with the boot ROM and both cores, no firmware."""
    mcu = RP2040()
    mcu.logger = ConsoleLogger(LogLevel.ERROR)
    mcu.load_bootrom(BOOTROM_B1)
    sim = Simulator(rp2040=mcu)
    return mcu, Cores(mcu, sim)


def as_core(cores, index):
    """Accesses from core `index`, as `run_both` sets them up."""
    cores.mcu.core = (cores.core0, cores.core1)[index]
    cores.mcu.sio = cores.sio[index]


def test_each_core_reads_its_own_cpuid_and_divider():
    mcu, cores = bare()
    for index in (0, 1):
        as_core(cores, index)
        assert mcu.read_uint32(CPUID) == index
    as_core(cores, 0)
    mcu.write_uint32(DIV_UDIVIDEND, 100)
    mcu.write_uint32(DIV_UDIVISOR, 7)
    as_core(cores, 1)
    mcu.write_uint32(DIV_UDIVIDEND, 1000)
    mcu.write_uint32(DIV_UDIVISOR, 10)
    assert mcu.read_uint32(DIV_QUOTIENT) == 100
    as_core(cores, 0)
    assert mcu.read_uint32(DIV_QUOTIENT) == 14


def test_the_fifos_carry_words_each_way_in_order_eight_deep():
    mcu, cores = bare()
    as_core(cores, 0)
    assert mcu.read_uint32(FIFO_ST) == RDY
    for word in range(FIFO_DEPTH):
        mcu.write_uint32(FIFO_WR, 0xC0DE_0000 + word)
    # Core 1's FIFO full: core 0 may not write; a write is lost and flagged.
    assert mcu.read_uint32(FIFO_ST) == 0
    mcu.write_uint32(FIFO_WR, 0xDEAD)
    assert mcu.read_uint32(FIFO_ST) == WOF
    assert cores.core0.pending_interrupts & (1 << SIO_IRQ[0])
    mcu.write_uint32(FIFO_ST, 0)
    assert mcu.read_uint32(FIFO_ST) == 0
    assert not cores.core0.pending_interrupts & (1 << SIO_IRQ[0])
    # Core 1 has words, its line raised; it reads them in order.
    assert cores.core1.pending_interrupts & (1 << SIO_IRQ[1])
    as_core(cores, 1)
    assert mcu.read_uint32(FIFO_ST) == VLD | RDY
    assert [mcu.read_uint32(FIFO_RD) for _ in range(FIFO_DEPTH)] == [0xC0DE_0000 + w for w in range(FIFO_DEPTH)]
    assert not cores.core1.pending_interrupts & (1 << SIO_IRQ[1])
    # Reading an empty FIFO: 0, flagged until cleared.
    assert mcu.read_uint32(FIFO_RD) == 0
    assert mcu.read_uint32(FIFO_ST) == RDY | ROE
    mcu.write_uint32(FIFO_ST, 0)
    # And back the other way.
    mcu.write_uint32(FIFO_WR, 42)
    as_core(cores, 0)
    assert mcu.read_uint32(FIFO_ST) == VLD | RDY
    assert mcu.read_uint32(FIFO_RD) == 42


def test_a_fifo_write_wakes_the_reader_and_the_mpu_is_each_cores():
    mcu, cores = bare()
    cores.core1.waiting = True
    as_core(cores, 0)
    mcu.write_uint32(FIFO_WR, 1)
    assert not cores.core1.waiting
    # Not waiting: the event is kept for its next WFE.
    mcu.write_uint32(FIFO_WR, 2)
    assert cores.core1.event_registered
    for index in (0, 1):
        as_core(cores, index)
        assert mcu.read_uint32(MPU_TYPE) == 8 << 8
        assert mcu.read_uint32(MPU_CTRL) == 0
    mcu.write_uint32(MPU_CTRL, 5)
    assert mcu.read_uint32(MPU_CTRL) == 5
    as_core(cores, 0)
    assert mcu.read_uint32(MPU_CTRL) == 0


def test_the_psm_holds_core_1_and_starts_it_at_the_boot_roms_reset():
    mcu, cores = bare()
    assert not cores.held
    as_core(cores, 0)
    mcu.write_uint32(PSM_FRCE_OFF, 1 << 16)
    assert cores.held
    cores.core1.pc = 0x1234
    mcu.write_uint32(PSM_FRCE_OFF, 0)
    assert not cores.held
    assert cores.core1.pc == mcu.read_uint32(0x4) & ~1
    assert cores.core1.sp == mcu.read_uint32(0x0)


def board(core1, vcd=None):
    """The default build on a board of four axes, booted."""
    args = SimpleNamespace(
        elf=ELF,
        axes=4,
        vcd=vcd,
        dialect="v1",
        arithmetic="smooth",
        usb=False,
        bench=False,
        pio_model="auto",
        core1=core1,
    )
    sim = pico_sim.PicoSim(args)
    out = bytearray()
    sim.mcu.uart[0].on_byte = out.append
    edges = []
    changed = sim.pin_changed

    def record(ns, gpio, level):
        if sim.is_output(gpio):
            edges.append((ns, gpio, level))
        changed(ns, gpio, level)

    sim.pin_changed = record

    def run_ms(ms):
        sim.slice_alarm.schedule(ms * 1e6)
        sim.cores.run()
        sim.slice_alarm.cancel()

    while b"]" not in out:
        run_ms(1)
    return sim, out, edges, run_ms


def send(sim, run_ms, line):
    for byte in (line + "\n").encode():
        sim.mcu.uart[0].feed_byte(byte)
        run_ms(pico_sim.UART_BYTE_NS / 1e6)


@needs_elf
def test_core_1_starts_through_the_boot_rom_and_waits_for_work():
    sim, out, _edges, run_ms = board("on")
    cores = sim.cores
    assert not cores.held
    # Out of the boot ROM, in the firmware's flash, asleep (WFE).
    assert cores.core1.pc >= 0x1000_0000
    assert cores.core1.waiting
    assert not cores.fifos[0] and not cores.fifos[1]
    assert out.startswith(b"[cogstep ")
    off, _out, _edges, _run_ms = board("off")
    # Not started: still in the boot ROM's wait for a launch.
    assert off.cores.core1.pc < 0x4000


@needs_elf
def test_ramp_runs_computed_on_core_1_change_no_edge():
    """Two axes ramping to 6,000 steps/s and back, a merge and a stop
    mid-ramp: every output edge at the same CT either way, and core 1
    worked."""
    seen = {}
    for core1 in ("on", "off"):
        sim, out, edges, run_ms = board(core1)
        send(sim, run_ms, "M 0 6000 2000")
        send(sim, run_ms, "M 1 6000 -1500")
        run_ms(120)
        send(sim, run_ms, "M 0 6000 300")
        run_ms(60)
        send(sim, run_ms, "S 1")
        run_ms(700)
        assert out.count(b"ok") == 4, out
        seen[core1] = (edges, [axis.position for axis in sim.axes], sim.cores.cycles[1])
    (edges_on, positions_on, busy_on), (edges_off, positions_off, busy_off) = seen["on"], seen["off"]
    assert positions_on == positions_off
    assert positions_on[0] == 2300
    assert len(edges_on) > 2 * 2300
    # Each pin's changes in the same order, each within the edge
    # interrupt's jitter of the other run's (a few cycles: its entry
    # waits for the instruction under way, and core 0 runs other code).
    by_pin = lambda edges, gpio: [(ns, level) for ns, pin, level in edges if pin == gpio]
    for gpio in {pin for _ns, pin, _level in edges_off}:
        on, off = by_pin(edges_on, gpio), by_pin(edges_off, gpio)
        assert [level for _ns, level in on] == [level for _ns, level in off], gpio
        worst = max(abs(a - b) for (a, _), (b, _) in zip(on, off))
        assert worst < 1000, (gpio, worst)
    # Core 1 worked (each ramp step costs it about a thousand cycles) with
    # its runs; off, it never left the boot ROM's wait.
    assert busy_on > 1000 * 1000
    assert busy_off < 1000
