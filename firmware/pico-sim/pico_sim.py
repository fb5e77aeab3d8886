"""cogstep's Raspberry Pi Pico firmware under the rp2040py emulator.

Run by `firmware/run-pico-sim` (see its header for the options). One
thread runs everything: the emulated RP2040 in batches, the
pseudo-terminal that stands for the Pico's UART0, the control lines on
standard input, and the VCD writer. So nothing inside the emulator is
ever touched from two threads.

- **Time.** The simulated clock (the chip's 125 MHz system clock, and
  the microsecond timer the firmware uses as its CT) never runs ahead of
  the wall clock since the start: an emulator faster than the chip
  waits, one slower (the usual case) makes the board slow, never early.
  A host sees a board that keeps real-time promises (a jog's 150 ms
  timeout, say) at the emulator's pace.
- **UART0.** Bytes from the pseudo-terminal reach the UART's receive
  FIFO at 115,200 baud in simulated time (one byte each 86.8 µs, none
  while the 32-byte FIFO is full); the firmware's bytes leave at 115,200
  baud too (`uart_tx.py`: 32 bytes in the transmit FIFO, one sent each
  86.8 µs, `TXFF` and the transmit interrupt from it), where rp2040py
  sends each byte the moment it is written.
- **USB CDC** (`--usb`, `usb_link.py`): the pseudo-terminal is the
  Pico's USB serial port instead; rp2040py's host model enumerates the
  firmware's device and raises DTR, as a host opening the port does.
  UART0's bytes are dropped (nobody on its line).
- **Pins.** Every change of an axis's output and input pins goes to the
  VCD file (`--vcd`) with its simulated time in ns, the wires named by
  role as the hub names them (axis N is the protocol's axis N − 1).
- **PIO.** With the PIO build (`firmware/build rp-pico --features pio`,
  `run-pico-sim --pio`; picked by the ELF's `COGSTEP_PIO_REFUSED` symbol,
  or `--pio-model on|off`), PIO0 is the model in `pio_model.py`: every
  word the firmware writes to a TX FIFO is recorded at its simulated time
  and made into pin writes by the step program's closed form (8 ns
  cycles), FLEVEL, FSTAT and PIO0_IRQ_0 follow from the words' `pull`s,
  and a FIFO that runs dry is printed on stderr and counted. Its edges go
  to the VCD and the axis positions like any other (at the end of each
  slice, and at their own time once a `switch` is set).
- **Core 1** (`core1.py`). rp2040py runs core 0 only; the harness adds
  core 1 on the same bus, with each core's own SIO (CPUID, divider, its
  ends of the inter-core FIFOs), NVIC and MPU registers, started through
  the boot ROM when the firmware releases it (rp2040-hal's launch). While
  core 1 sleeps, core 0 runs in rp2040py's native loop; while it works,
  both step in Python, side by side in simulated time. `--core1 off`
  patches the firmware's COGSTEP_CORE1 byte: core 1 is then never
  started and core 0 computes every ramp run.
- **Inputs.** Driven by control lines (standard input), each answered on
  standard output with `ok ...` or `error ...` once it has taken effect:

      set PIN LEVEL                  drive PIN now (LEVEL 0/1, low/high)
      at TIME PIN LEVEL              drive PIN at simulated TIME (ns; or 12us, 3.5ms, 2s)
      switch PIN LEVEL when axisN <= POS   (or >= POS) PIN reads LEVEL while
                                     axis N's position (counted from its
                                     step edges) is there, the other level
                                     elsewhere: a home or limit switch
      release PIN                    stop driving PIN (its pull decides)
      now                            answers `ok now NS`
      epoch                          answers `ok epoch NS`: the simulated time at
                                     which the microsecond timer (the CT) read 0
      ct                             answers `ok ct CT`: the firmware's CT (µs,
                                     or in the PIO build 125 MHz cycles; low
                                     32 bits) when its last protocol byte
                                     came (COGSTEP_COMMAND_CT); its command
                                     reached the axis core 5 µs later
      position axisN                 answers `ok position axisN STEPS`
      dtr LEVEL                      (--usb) the host drops (0) or raises (1)
                                     DTR and RTS: closes or opens the port
      pio                            (PIO build) answers `ok pio start NS words
                                     W0/W1/W2/W3 late N worst_late_ns NS
                                     overflows N problems N refused N
                                     made_late N`: the state machines' first
                                     cycle, the words written, those that
                                     came after their `pull` was due (a FIFO
                                     run dry), the worst such lateness,
                                     words written to a full FIFO, set-up
                                     problems, the firmware's
                                     COGSTEP_PIO_REFUSED (edges not made)
                                     and COGSTEP_PIO_MADE_LATE (edges made
                                     after their CT)

  PIN is a role name (`axis1_stop`, `axis2_home`, `axis3_limit_min`,
  `axis4_limit_max`) or `gpN`.
"""

import argparse
import os
import re
import select
import signal
import sys
import termios
import time
import tty

from elftools.elf.elffile import ELFFile
from rp2040py.device.bootrom import BOOTROM_B1
from rp2040py.device.load_flash import load_uf2
from rp2040py.rp2040 import RP2040
from rp2040py.simulator import Simulator
from rp2040py.utils.logging import ConsoleLogger, LogLevel

from core1 import Cores
from pio_model import PioModel
from timer_alarm import install as install_timer_alarms
from uart_tx import UartTx

#: The Pico's pins (boards/rp-pico/README.md): axis i's two outputs on
#: GP2+2i and GP3+2i; its inputs on the pins below.
FIRST_OUTPUT = 2
STOP_PINS = (10, 11, 12, 13)
HOME_PINS = (14, 15, 16, 17)
LIMIT_MIN_PINS = (18, 19, 20, 21)
LIMIT_MAX_PINS = (22, 26, 27, 28)
AXES_MAX = 4
#: 10 bits (start, 8 data, stop) at 115,200 baud.
UART_BYTE_NS = 10 * 1e9 / 115_200
#: How far simulated time may run in one batch before the harness looks
#: at its inputs again (it also never passes the wall clock).
SLICE_NS = 2_000_000


def role_pins(axes):
    """{name: gpio} of every pin of `axes` axes, outputs first."""
    pins = {}
    for axis in range(axes):
        number = axis + 1
        first, second = ("step", "dir") if axis % 2 == 0 else ("cw", "ccw")
        pins[f"axis{number}_{first}"] = FIRST_OUTPUT + 2 * axis
        pins[f"axis{number}_{second}"] = FIRST_OUTPUT + 2 * axis + 1
    for axis in range(axes):
        number = axis + 1
        pins[f"axis{number}_stop"] = STOP_PINS[axis]
        pins[f"axis{number}_home"] = HOME_PINS[axis]
        pins[f"axis{number}_limit_min"] = LIMIT_MIN_PINS[axis]
        pins[f"axis{number}_limit_max"] = LIMIT_MAX_PINS[axis]
    return pins


def parse_time_ns(text):
    match = re.fullmatch(r"([0-9]+(?:\.[0-9]+)?)(ns|us|ms|s)?", text)
    if not match:
        raise ValueError(f"bad time {text!r}")
    scale = {"ns": 1, "us": 1e3, "ms": 1e6, "s": 1e9, None: 1}[match.group(2)]
    return float(match.group(1)) * scale


def parse_level(text):
    levels = {"0": False, "low": False, "1": True, "high": True}
    if text not in levels:
        raise ValueError(f"bad level {text!r}")
    return levels[text]


class Vcd:
    """A VCD file of the pins, written as the changes come (time in ns)."""

    def __init__(self, path, pins, levels):
        self.out = open(path, "w", buffering=1 << 16)
        self.ids = {}
        self.last_ns = None
        self.out.write("$comment cogstep Raspberry Pi Pico firmware under rp2040py: simulated time, ns $end\n")
        self.out.write("$timescale 1 ns $end\n$scope module cogstep $end\n")
        for index, name in enumerate(pins):
            ident = chr(33 + index)
            self.ids[pins[name]] = ident
            self.out.write(f"$var wire 1 {ident} {name} $end\n")
        self.out.write("$upscope $end\n$enddefinitions $end\n#0\n$dumpvars\n")
        for name, gpio in pins.items():
            self.out.write(f"{int(levels[gpio])}{self.ids[gpio]}\n")
        self.out.write("$end\n")
        self.last_ns = 0

    def change(self, ns, gpio, level):
        ident = self.ids.get(gpio)
        if ident is None:
            return
        ns = max(int(round(ns)), self.last_ns)
        if ns != self.last_ns:
            self.out.write(f"#{ns}\n")
            self.last_ns = ns
        self.out.write(f"{int(level)}{ident}\n")

    def close(self):
        self.out.close()


class Axis:
    """An axis's position as its step edges say (for switches)."""

    def __init__(self, index):
        self.index = index
        self.sd = index % 2 == 0
        self.position = 0
        self.reverse = False


class PicoSim:
    def __init__(self, args):
        self.args = args
        self.axes = [Axis(i) for i in range(args.axes)]
        self.pins = role_pins(args.axes)
        self.names = {gpio: name for name, gpio in self.pins.items()}
        self.stopping = False
        self.timed = []  # (ns, gpio, level), sorted
        self.switches = []  # (gpio, level, axis, op, position)
        self.control_buffer = b""

        self.mcu = RP2040()
        self.sim = Simulator(rp2040=self.mcu)
        self.clock = self.sim.clock
        self.mcu.logger = ConsoleLogger(LogLevel.ERROR)
        self.mcu.load_bootrom(BOOTROM_B1)
        # Alarms at the microsecond they match (timer_alarm.py).
        install_timer_alarms(self.mcu)
        load_uf2(args.elf + ".uf2", self.mcu)
        self.patch_axes(args.elf, args.axes)
        self.patch_dialect(args.elf, args.dialect)
        self.patch_arithmetic(args.elf, args.arithmetic)
        if getattr(args, "bench_apart", False):
            self.patch_byte(args.elf, "COGSTEP_BENCH_APART", 1)
        if self.has_symbol(args.elf, "COGSTEP_CORE1"):
            self.patch_byte(args.elf, "COGSTEP_CORE1", 1 if args.core1 == "on" else 0)
        self.mcu.core.pc = 0x10000000
        # Core 1 beside rp2040py's core 0 (core1.py).
        self.cores = Cores(self.mcu, self.sim)
        # The PIO build's edges come from the model of PIO0 (pio_model.py).
        self.pio_model = None
        if args.pio_model == "on" or (args.pio_model == "auto" and self.has_symbol(args.elf, "COGSTEP_PIO_REFUSED")):
            self.pio_model = PioModel(self.mcu, self.clock, self.pio_edges)
            self.pio_model.install()

        # Inputs idle as the pull-ups leave them: stop pins high (run),
        # switches high (open; the firmware's active level is low).
        for name, gpio in self.pins.items():
            if not self.is_output(gpio):
                self.mcu.gpio[gpio].set_input_value(True)
        self.levels = {gpio: self.level(gpio) for gpio in self.pins.values()}
        # Pins a `release` line left to their pulls (driven again by the
        # next `set`, `at` or switch).
        self.released = set()
        self.vcd = Vcd(args.vcd, self.pins, self.levels) if args.vcd else None
        for gpio in self.pins.values():
            self.mcu.gpio[gpio].add_listener(self.listener(gpio))

        self.master, slave = os.openpty()
        tty.setraw(slave)
        attributes = termios.tcgetattr(slave)
        attributes[3] &= ~termios.ECHO
        termios.tcsetattr(slave, termios.TCSANOW, attributes)
        self.slave_path = os.ttyname(slave)
        # Kept open: the pseudo-terminal then lives while hosts come and go.
        self.slave = slave
        os.set_blocking(self.master, False)
        self.rx_pending = bytearray()
        self.tx_pending = bytearray()
        # What the firmware has sent on the pseudo-terminal's port, kept
        # until its identity line has come (`identified`).
        self.seen = bytearray()
        self.mcu.uart[0].on_byte = lambda byte: self.from_firmware(bytes([byte]))
        self.usb = None
        if args.usb:
            from usb_link import UsbLink

            self.usb = UsbLink(self.mcu, self.from_firmware)
            self.mcu.uart[0].on_byte = lambda _byte: None
        # UART0's bytes leave at 115,200 baud, 32 in its FIFO (uart_tx.py).
        self.uart_tx = UartTx(self.mcu.uart[0], self.clock)
        self.uart_alarm = self.clock.create_alarm(self.uart_byte_due)
        self.uart_busy = False
        self.slice_alarm = self.clock.create_alarm(self.slice_ends)

    def timer_epoch_ns(self):
        """The simulated ns at which the microsecond timer read 0 (its last
        reset: the firmware resets the block at boot)."""
        return self.clock.nanos - self.mcu.timer._micros() * 1000

    def has_symbol(self, elf_path, name):
        with open(elf_path, "rb") as f:
            symbols = ELFFile(f).get_section_by_name(".symtab")
            return bool(symbols and symbols.get_symbol_by_name(name))

    def patch_axes(self, elf_path, axes):
        """The firmware's axis count is the COGSTEP_AXES byte of its flash."""
        with open(elf_path, "rb") as f:
            symbols = ELFFile(f).get_section_by_name(".symtab")
            found = symbols.get_symbol_by_name("COGSTEP_AXES") if symbols else None
            if not found:
                raise SystemExit("run-pico-sim: the firmware has no COGSTEP_AXES symbol")
            address = found[0]["st_value"]
            command_ct = symbols.get_symbol_by_name("COGSTEP_COMMAND_CT")
            self.command_ct_address = command_ct[0]["st_value"] if command_ct else None
            refused = symbols.get_symbol_by_name("COGSTEP_PIO_REFUSED")
            self.refused_address = refused[0]["st_value"] if refused else None
            made_late = symbols.get_symbol_by_name("COGSTEP_PIO_MADE_LATE")
            self.made_late_address = made_late[0]["st_value"] if made_late else None
        self.mcu.flash[address - 0x10000000] = axes

    def from_firmware(self, data):
        """Bytes the firmware sent on the pseudo-terminal's port."""
        self.tx_pending.extend(data)
        if self.seen is not None:
            self.seen.extend(data)

    def identified(self):
        """Whether the firmware's identity line (or grbl's welcome) has
        come: the sign of a firmware that listens."""
        if self.seen is not None and (b"]\r\n" in self.seen or b"]\n" in self.seen):
            self.seen = None
        return self.seen is None

    def patch_dialect(self, elf_path, dialect):
        """The firmware's dialect is the COGSTEP_DIALECT byte of its flash
        (0 protocol v1, 1 grbl 1.1)."""
        self.patch_byte(elf_path, "COGSTEP_DIALECT", 1 if dialect == "grbl" else 0)

    def patch_arithmetic(self, elf_path, arithmetic):
        """The axis cores' S-curve arithmetic is the COGSTEP_ARITHMETIC byte
        of its flash (0 Smooth, 1 P2Exact)."""
        self.patch_byte(elf_path, "COGSTEP_ARITHMETIC", 1 if arithmetic == "p2exact" else 0)

    def patch_byte(self, elf_path, name, value):
        """Sets the flash byte of the firmware's symbol `name` to `value`."""
        with open(elf_path, "rb") as f:
            symbols = ELFFile(f).get_section_by_name(".symtab")
            found = symbols.get_symbol_by_name(name) if symbols else None
            if not found:
                raise SystemExit(f"run-pico-sim: the firmware has no {name} symbol")
            address = found[0]["st_value"]
        self.mcu.flash[address - 0x10000000] = value

    def made_late(self):
        """Edges the PIO build made later than their CT (COGSTEP_PIO_MADE_LATE)."""
        return self.mcu.read_uint32(self.made_late_address) if self.made_late_address else 0

    def is_output(self, gpio):
        return FIRST_OUTPUT <= gpio < FIRST_OUTPUT + 2 * AXES_MAX

    def level(self, gpio):
        pin = self.mcu.gpio[gpio]
        return bool(pin.output_value) if self.is_output(gpio) else bool(pin.input_value)

    def listener(self, gpio):
        def changed(new, old):
            if self.pio_model is not None and self.is_output(gpio):
                return  # the model hands these over (pio_edges)
            self.pin_changed(self.clock.nanos, gpio, self.level(gpio))

        return changed

    def pin_changed(self, ns, gpio, level):
        # The pad's state changes too when a pin becomes an output: only a
        # level that changes is an edge.
        if self.levels.get(gpio) == level:
            return
        self.levels[gpio] = level
        if self.vcd:
            self.vcd.change(ns, gpio, level)
        if self.is_output(gpio) and level:
            self.count_step(gpio)
        elif self.is_output(gpio):
            self.direction(gpio, level)

    def pio_edges(self, ns, levels):
        """The PIO model's pin write at `ns`: ((gpio, level), ...)."""
        for gpio, level in levels:
            if gpio in self.names:
                self.pin_changed(ns, gpio, level)

    def catch_up(self):
        """The PIO model's edges up to now, before anything else is written."""
        if self.pio_model is not None:
            self.pio_model.catch_up(self.clock.nanos)

    def direction(self, gpio, level):
        axis = self.axes[(gpio - FIRST_OUTPUT) // 2]
        if axis.sd and (gpio - FIRST_OUTPUT) % 2 == 1:
            axis.reverse = level

    def count_step(self, gpio):
        index = (gpio - FIRST_OUTPUT) // 2
        axis = self.axes[index]
        second = (gpio - FIRST_OUTPUT) % 2 == 1
        if axis.sd:
            if second:
                axis.reverse = True
                return
            axis.position += -1 if axis.reverse else 1
        else:
            axis.position += -1 if second else 1
        self.check_switches(axis.index)

    def check_switches(self, axis_index):
        for gpio, level, axis, op, position in self.switches:
            if axis != axis_index:
                continue
            there = self.axes[axis].position
            inside = there <= position if op == "<=" else there >= position
            self.drive(gpio, level if inside else not level)

    def drive(self, gpio, level):
        self.catch_up()
        pin = self.mcu.gpio[gpio]
        before = self.levels.get(gpio, bool(pin.input_value))
        if before == level and gpio in self.levels and gpio not in self.released:
            # rp2040py sets a pin's edge bits on every drive, changed or
            # not: a switch placed on an axis is driven at every step, and
            # each would interrupt the firmware where the chip would not.
            return
        self.released.discard(gpio)
        pin.set_input_value(level)
        self.levels[gpio] = level
        if self.vcd and before != level and not self.is_output(gpio):
            self.vcd.change(self.clock.nanos, gpio, level)

    # UART0: one byte each UART_BYTE_NS while bytes wait and the FIFO has room.
    def uart_byte_due(self):
        self.uart_busy = False
        uart = self.mcu.uart[0]
        if self.rx_pending and not uart.rx_fifo.full:
            uart.feed_byte(self.rx_pending.pop(0))
        if self.rx_pending:
            self.uart_busy = True
            self.uart_alarm.schedule(UART_BYTE_NS)

    def slice_ends(self):
        self.cores.stop()

    def pin_of(self, name):
        if name.startswith("gp") and name[2:].isdigit():
            return int(name[2:])
        if name not in self.pins:
            raise ValueError(f"no pin {name!r}")
        return self.pins[name]

    def axis_of(self, name):
        match = re.fullmatch(r"axis([1-9])", name)
        if not match or int(match.group(1)) > len(self.axes):
            raise ValueError(f"no axis {name!r}")
        return int(match.group(1)) - 1

    def control(self, line):
        self.catch_up()
        words = line.split()
        if not words:
            return None
        verb = words[0]
        if verb == "set" and len(words) == 3:
            gpio, level = self.pin_of(words[1]), parse_level(words[2])
            self.drive(gpio, level)
            return f"ok set {words[1]} {int(level)} at {int(self.clock.nanos)}"
        if verb == "release" and len(words) == 2:
            self.mcu.gpio[self.pin_of(words[1])].release_input()
            self.released.add(self.pin_of(words[1]))
            return f"ok release {words[1]}"
        if verb == "at" and len(words) == 4:
            at, gpio, level = parse_time_ns(words[1]), self.pin_of(words[2]), parse_level(words[3])
            self.timed.append((at, gpio, level))
            self.timed.sort(key=lambda item: item[0])
            return f"ok at {int(at)} {words[2]} {int(level)}"
        if verb == "switch" and len(words) == 7 and words[3] == "when" and words[5] in ("<=", ">="):
            gpio, level = self.pin_of(words[1]), parse_level(words[2])
            axis, position = self.axis_of(words[4]), int(words[6])
            self.switches.append((gpio, level, axis, words[5], position))
            if self.pio_model is not None:
                # Switches act at the edge that reaches them, not a slice later.
                self.pio_model.eager = True
                self.pio_model.schedule()
            self.check_switches(axis)
            return f"ok switch {words[1]}"
        if verb == "now" and len(words) == 1:
            return f"ok now {int(self.clock.nanos)}"
        if verb == "ct" and len(words) == 1 and self.command_ct_address is not None:
            return f"ok ct {self.mcu.read_uint32(self.command_ct_address)}"
        if verb == "epoch" and len(words) == 1:
            return f"ok epoch {int(self.timer_epoch_ns())}"
        if verb == "dtr" and len(words) == 2 and self.usb:
            level = parse_level(words[1])
            self.usb.set_dtr(level)
            return f"ok dtr {int(level)} at {int(self.clock.nanos)}"
        if verb == "pio" and len(words) == 1:
            if self.pio_model is None:
                raise ValueError("no PIO model: the firmware is not the PIO build")
            refused = self.mcu.read_uint32(self.refused_address) if self.refused_address else 0
            return f"ok pio {self.pio_model.summary()} refused {refused} made_late {self.made_late()}"
        if verb == "position" and len(words) == 2:
            axis = self.axis_of(words[1])
            return f"ok position {words[1]} {self.axes[axis].position}"
        raise ValueError(f"unknown control line {line!r}")

    def answer(self, text):
        sys.stdout.write(text + "\n")
        sys.stdout.flush()

    def read_control(self):
        try:
            data = os.read(sys.stdin.fileno(), 4096)
        except (BlockingIOError, InterruptedError):
            return
        if not data:
            self.control_open = False
            return
        self.control_buffer += data
        while b"\n" in self.control_buffer:
            line, self.control_buffer = self.control_buffer.split(b"\n", 1)
            try:
                reply = self.control(line.decode())
            except ValueError as error:
                reply = f"error {error}"
            if reply:
                self.answer(reply)

    def read_pty(self):
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return
        if self.usb:
            self.usb.send(data)
            return
        self.rx_pending.extend(data)
        if self.rx_pending and not self.uart_busy:
            self.uart_busy = True
            self.uart_alarm.schedule(UART_BYTE_NS)

    def write_pty(self):
        if not self.tx_pending:
            return
        try:
            written = os.write(self.master, self.tx_pending)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            # Nobody reads: a real UART's bytes would be lost too.
            written = len(self.tx_pending)
        del self.tx_pending[:written]

    def run_timed(self):
        while self.timed and self.timed[0][0] <= self.clock.nanos:
            _at, gpio, level = self.timed.pop(0)
            self.drive(gpio, level)

    def run(self, ready):
        self.control_open = True
        os.set_blocking(sys.stdin.fileno(), False)
        start = time.monotonic()
        announced = False
        while not self.stopping:
            wall_ns = (time.monotonic() - start) * 1e9
            ahead = self.clock.nanos - wall_ns
            sources = [self.master] + ([sys.stdin.fileno()] if self.control_open else [])
            wait = max(ahead / 1e9, 0.0) if ahead > 0 else 0.0
            readable, _, _ = select.select(sources, [], [], min(wait, 0.05))
            if self.master in readable:
                self.read_pty()
            if sys.stdin.fileno() in readable:
                self.read_control()
            if ahead > 0:
                self.write_pty()
                continue
            # One slice: up to SLICE_NS of simulated time, never past the
            # wall clock by more than that, nor past a timed input.
            limit = min(SLICE_NS, wall_ns + SLICE_NS - self.clock.nanos)
            if self.timed:
                limit = min(limit, max(self.timed[0][0] - self.clock.nanos, 1))
            self.slice_alarm.schedule(max(limit, 1))
            self.cores.run()
            self.slice_alarm.cancel()
            self.catch_up()
            self.run_timed()
            if self.usb:
                self.usb.pump()
            self.write_pty()
            if not announced and ready():
                announced = True
                self.answer(self.slave_path)

    def close(self):
        if self.pio_model is not None:
            self.catch_up()
            sys.stderr.write(f"run-pico-sim: PIO model: {self.pio_model.summary()}\n")
        if self.vcd:
            self.vcd.close()


def run_bench(sim, wall_limit_s=900):
    """Runs a bench build until its `bench done` line; prints its `bench`
    lines on stdout. Exit status 1 if it never finishes or its positions
    are not exact."""
    out = bytearray()
    sim.mcu.uart[0].on_byte = out.append
    started = time.monotonic()
    while b"bench done" not in out or not out.endswith(b"\n"):
        if time.monotonic() - started > wall_limit_s:
            sys.stderr.write(f"bench-pico: no `bench done` within {wall_limit_s} s: {bytes(out)!r}\n")
            return 1
        # One millisecond of simulated time, as fast as it runs.
        sim.slice_alarm.schedule(1_000_000)
        sim.cores.run()
        sim.slice_alarm.cancel()
    text = out.decode(errors="replace")
    for line in text.splitlines():
        if line.startswith("bench"):
            print(line.strip(), flush=True)
    # Core 1's work (ramp runs computed ahead), counted by the harness.
    print(f"bench core1 cycles={sim.cores.cycles[1]}", flush=True)
    return 0 if "positions_exact=true" in text else 1


def main():
    parser = argparse.ArgumentParser(prog="run-pico-sim")
    parser.add_argument("--elf", required=True, help="the firmware's ELF (its UF2 file beside it is loaded)")
    parser.add_argument("--axes", type=int, default=4)
    parser.add_argument("--vcd")
    parser.add_argument("--dialect", choices=["v1", "grbl"], default="v1")
    parser.add_argument("--arithmetic", choices=["smooth", "p2exact"], default="smooth")
    parser.add_argument("--usb", action="store_true", help="the pseudo-terminal is the USB CDC port, not UART0")
    parser.add_argument(
        "--core1",
        choices=["on", "off"],
        default="on",
        help="whether the firmware computes ramp runs ahead on core 1 (its COGSTEP_CORE1 byte)",
    )
    parser.add_argument(
        "--pio-model",
        choices=["auto", "on", "off"],
        default="auto",
        help="PIO0 as the step program's closed form (pio_model.py): auto = when the ELF is the PIO build",
    )
    parser.add_argument(
        "--bench",
        action="store_true",
        help="a firmware built with its bench feature: print its `bench` lines and exit at `bench done`",
    )
    parser.add_argument(
        "--bench-apart",
        action="store_true",
        help="with --bench: the axes at speeds 1,000 steps/s apart (its COGSTEP_BENCH_APART byte)",
    )
    args = parser.parse_args()
    if args.dialect == "grbl":
        # grbl drives X, Y and Z: the firmware's axes 0, 1 and 2.
        args.axes = 3
    if not 1 <= args.axes <= AXES_MAX:
        sys.stderr.write(f"run-pico-sim: --axes must be 1 to {AXES_MAX}, got {args.axes}\n")
        return 2
    sim = PicoSim(args)
    if args.bench:
        return run_bench(sim)

    def stop(_signal, _frame):
        sim.stopping = True

    for number in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(number, stop)
    def ready():
        if sim.identified():
            port = "USB CDC" if sim.usb else "UART0"
            sys.stderr.write(
                f"run-pico-sim: Raspberry Pi Pico firmware (rp2040py), {args.dialect}, {args.axes} axes, "
                f"{args.arithmetic} arithmetic, {port} on {sim.slave_path}; Ctrl-C to stop\n"
            )
            return True
        return False

    try:
        sim.run(ready)
    finally:
        sim.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
