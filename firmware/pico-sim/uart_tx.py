"""UART0's transmit side at 115,200 baud in simulated time.

rp2040py sends each byte the moment the firmware writes it and reports
the transmit FIFO always empty (`UARTFR.TXFE`, never `TXFF`), so a
firmware that waits for room in the FIFO never waits, and one that
writes a 300-byte reply at once sends it in no time. The chip's PL011
holds 32 bytes and sends one each 86.8 µs (10 bits at 115,200 baud):
a firmware that waits for room waits about 23 ms for that reply.

`UartTx` puts that in front of rp2040py's UART: a 32-byte FIFO that
sends a byte each 86.8 µs of simulated time (each reaches the harness,
`on_byte`, when its last bit has gone), `UARTFR`'s `TXFF`, `TXFE` and
`BUSY` from it, a byte written to a full FIFO lost (as the PL011 loses
it), and the transmit interrupt (`TXRIS`, bit 5) raised while the FIFO
holds no more than its trigger level (`UARTIFLS`: half, 16 bytes, at
reset) and raised to the NVIC while `TXIM` is set.
"""

from collections import deque

UARTDR = 0x00
UARTFR = 0x18
UARTIFLS = 0x34
UARTRIS = 0x3C
UARTMIS = 0x40
#: UARTFR bits.
BUSY = 1 << 3
TXFF = 1 << 5
TXFE = 1 << 7
#: The transmit interrupt's bit (UARTRIS, UARTIMSC, UARTMIS).
TXINTR = 1 << 5
DEPTH = 32
#: UARTIFLS.TXIFLSEL: the trigger level in eighths of the FIFO.
TRIGGER_EIGHTHS = {0: 1, 1: 2, 2: 4, 3: 6, 4: 7}
#: 10 bits (start, 8 data, stop) at 115,200 baud.
BYTE_NS = 10 * 1e9 / 115_200


class UartTx:
    """UART0's transmit side (see the module docs) over rp2040py's `uart`."""

    def __init__(self, uart, clock):
        self.uart = uart
        self.fifo = deque()
        self.shifting = False
        # UARTIFLS at reset: both triggers at half.
        self.ifls = 0x12
        self.lost = 0
        self.alarm = clock.create_alarm(self.byte_sent)
        self.read_inner = uart.read_uint32
        self.write_inner = uart.write_uint32
        uart.read_uint32 = self.read_uint32
        uart.write_uint32 = self.write_uint32
        uart.check_interrupts = self.check_interrupts

    def trigger(self):
        return DEPTH * TRIGGER_EIGHTHS.get(self.ifls & 0x7, 4) // 8

    def read_uint32(self, offset):
        if offset == UARTFR:
            flags = self.read_inner(offset) & ~(TXFE | TXFF | BUSY)
            if not self.fifo:
                flags |= TXFE
            if len(self.fifo) >= DEPTH:
                flags |= TXFF
            if self.shifting:
                flags |= BUSY
            return flags
        if offset == UARTIFLS:
            return self.ifls
        if offset in (UARTRIS, UARTMIS):
            # The status and the interrupt line as they stand.
            self.check_interrupts()
        return self.read_inner(offset)

    def write_uint32(self, offset, value):
        if offset == UARTDR:
            if len(self.fifo) < DEPTH:
                self.fifo.append(value & 0xFF)
            else:
                self.lost += 1
            if not self.shifting:
                self.shifting = True
                self.alarm.schedule(BYTE_NS)
            self.check_interrupts()
            return
        if offset == UARTIFLS:
            self.ifls = value & 0x3F
            self.check_interrupts()
            return
        self.write_inner(offset, value)

    def byte_sent(self):
        byte = self.fifo.popleft()
        if self.fifo:
            self.alarm.schedule(BYTE_NS)
        else:
            self.shifting = False
        self.check_interrupts()
        if self.uart.on_byte:
            self.uart.on_byte(byte)

    def check_interrupts(self):
        uart = self.uart
        status = uart._interrupt_status & ~TXINTR
        if len(self.fifo) <= self.trigger():
            status |= TXINTR
        uart._interrupt_status = status
        uart.rp2040.set_interrupt(uart.irq, bool(status & uart._interrupt_mask))
