"""UART0's transmit side at 115,200 baud (`uart_tx.py`), and the firmware's
replies through its ring.

    firmware/pico-sim/.venv/bin/python -m pytest firmware/pico-sim/test_uart_tx.py

The first test needs no firmware. The second runs the Pico firmware's
default build (`firmware/build rp-pico --snapshot`, in `COGSTEP_PICO_ELF`):
a status line of four moving axes leaves back to back, one byte each
86.8 µs, while the axes step. The firmware's main loop used to wait for
room in the 32-byte FIFO for each reply (about 19 ms for this one, with
the axes' cores 4 ms ahead of the pins); the timing scenario
(`tests/tests/firmware_pico.rs`) then made an edge 13.5 ms late at
6,000 steps/s.
"""

import os

import pytest
from elftools.elf.elffile import ELFFile
from rp2040py.rp2040 import RP2040
from rp2040py.simulator import Simulator
from rp2040py.utils.logging import ConsoleLogger, LogLevel

from test_core1 import board, send
from uart_tx import BYTE_NS, DEPTH, TXFE, TXFF, TXINTR, UartTx

ELF = os.environ.get("COGSTEP_PICO_ELF")

UART0 = 0x4003_4000
UARTDR, UARTFR, UARTIMSC, UARTRIS = UART0 + 0x00, UART0 + 0x18, UART0 + 0x38, UART0 + 0x3C


def test_bytes_leave_one_each_86_8_us_and_a_full_fifo_loses_them():
    mcu = RP2040()
    mcu.logger = ConsoleLogger(LogLevel.ERROR)
    sim = Simulator(rp2040=mcu)
    clock = sim.clock
    tx = UartTx(mcu.uart[0], clock)
    sent = []
    mcu.uart[0].on_byte = lambda byte: sent.append((clock.nanos, byte))
    assert mcu.read_uint32(UARTFR) & TXFE
    for byte in range(DEPTH + 3):
        mcu.write_uint32(UARTDR, byte)
    flags = mcu.read_uint32(UARTFR)
    assert flags & TXFF and not flags & TXFE
    assert tx.lost == 3
    # Above half: no transmit interrupt yet.
    assert not mcu.read_uint32(UARTRIS) & TXINTR
    clock.tick(BYTE_NS * (DEPTH // 2) + 1)
    assert mcu.read_uint32(UARTRIS) & TXINTR
    mcu.write_uint32(UARTIMSC, TXINTR)
    assert mcu.core.pending_interrupts & (1 << mcu.uart[0].irq)
    clock.tick(BYTE_NS * DEPTH)
    assert [byte for _, byte in sent] == list(range(DEPTH))
    gaps = {round(b - a) for (a, _), (b, _) in zip(sent, sent[1:])}
    assert gaps == {round(BYTE_NS)}
    assert mcu.read_uint32(UARTFR) & TXFE


def late_edges(sim):
    """The firmware's counts of edges made late: by the edge interrupt
    (COGSTEP_LATE_EDGES) and sent late by the main loop
    (COGSTEP_SHIFTED_EDGES)."""
    with open(ELF, "rb") as f:
        symbols = ELFFile(f).get_section_by_name(".symtab")
        return sum(
            sim.mcu.read_uint32(symbols.get_symbol_by_name(name)[0]["st_value"])
            for name in ("COGSTEP_LATE_EDGES", "COGSTEP_SHIFTED_EDGES")
        )


@pytest.mark.skipif(not ELF, reason="COGSTEP_PICO_ELF (the Pico's default build) is not set")
def test_a_status_line_leaves_back_to_back_while_the_axes_step():
    sim, out, edges, run_ms = board("on")
    for axis in range(4):
        send(sim, run_ms, f"M {axis} 6000 {3000 if axis % 2 == 0 else -3000}")
    run_ms(100)
    times = []
    sim.mcu.uart[0].on_byte = lambda byte: (times.append(sim.clock.nanos), out.append(byte))
    start = len(out)
    steps_before = [axis.position for axis in sim.axes]
    send(sim, run_ms, "?")
    run_ms(40)
    reply = bytes(out[start:])
    assert reply.count(b"|Run|") == 4, reply
    assert len(reply) > 200
    # No gap: the interrupt kept the FIFO fed.
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert max(gaps) < BYTE_NS + 1, max(gaps)
    # The axes went on meanwhile, every edge on time (the main loop that
    # waited for room made 577 of them late here).
    assert all(abs(now) > abs(before) for now, before in zip((a.position for a in sim.axes), steps_before))
    assert late_edges(sim) == 0
    assert sim.uart_tx.lost == 0
