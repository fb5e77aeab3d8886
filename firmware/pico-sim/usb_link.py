"""The host's end of the Pico's USB CDC port under rp2040py (`run-pico-sim --usb`).

rp2040py's `USBCDC` is the host: it enumerates the firmware's device
(bus reset, SET_ADDRESS, the configuration descriptor, SET_CONFIGURATION),
finds the CDC data interface's bulk endpoints, then asserts DTR and RTS
(SET_CONTROL_LINE_STATE), which is what a host's `cdc_acm` driver does
when a program opens `/dev/ttyACM0`. This class adds what `pico_sim.py`
needs on top, called only from its one thread, between batches:

- **Control transfers, paced.** `USBCDC` sends each setup packet 10 µs
  after the last status stage. A real host leaves the device 2 ms after
  SET_ADDRESS (USB 2.0, 9.2.6.3) and runs its requests frames apart; at
  10 µs a busy main loop sees the next SETUP and SET_ADDRESS's finished
  status stage in one poll, and usb-device then applies the address late,
  after SET_CONFIGURATION, which drops the device back to Addressed. So
  every setup packet is delivered `SETUP_GAP_NS` after it was sent.
- **Host to device.** Bytes wait here and enter `USBCDC`'s 512-byte queue
  as it has room. `USBCDC` answers every OUT buffer the firmware arms at
  once, with an empty packet when it has no bytes; a real host sends an
  OUT packet only when it has data, and the device NAKs until then. So a
  buffer armed while nothing waits is held here and answered when bytes
  come: the firmware is not woken every 10 µs by empty packets.
- **Device to host.** Each IN packet's bytes go to `on_bytes`.
- **DTR.** `set_dtr(level)` drops or raises DTR (and RTS) as a host
  closing or opening the port would. One request at a time, as on a real
  bus: the next waits for the device's status stage (its empty EP0 IN
  packet), or its setup packet would overwrite the last one unread.
"""

from rp2040py.usb.cdc import USBCDC

#: Simulated time between the host model's sending a setup packet and the
#: device's seeing it (the spec's SET_ADDRESS recovery time).
SETUP_GAP_NS = 2_000_000


class UsbLink:
    def __init__(self, mcu, on_bytes):
        self._send_setup = mcu.usb_ctrl.send_setup_packet
        self._setups = []
        self._setup_alarm = mcu.clock.create_alarm(self._deliver_setup)
        mcu.usb_ctrl.send_setup_packet = self._queue_setup
        self.cdc = USBCDC(mcu.usb_ctrl)
        self.on_bytes = on_bytes
        self.cdc.on_serial_data = lambda data: self.on_bytes(data)
        self.configured = False
        self.cdc.on_device_connected = self._configured
        self.pending = bytearray()
        #: (endpoint, size) of a bulk OUT buffer armed while nothing waited.
        self.held_read = None
        self._model_read = mcu.usb_ctrl.on_endpoint_read
        mcu.usb_ctrl.on_endpoint_read = self._endpoint_read
        self._model_write = mcu.usb_ctrl.on_endpoint_write
        mcu.usb_ctrl.on_endpoint_write = self._endpoint_write
        #: DTR levels still to send; whether a request awaits its status.
        self.dtr_queue = []
        self.control_busy = False

    def _queue_setup(self, packet):
        self._setups.append(bytes(packet))
        if len(self._setups) == 1:
            self._setup_alarm.schedule(SETUP_GAP_NS)

    def _deliver_setup(self):
        self._send_setup(self._setups.pop(0))
        if self._setups:
            self._setup_alarm.schedule(SETUP_GAP_NS)

    def _configured(self):
        self.configured = True
        self.pump()

    def _endpoint_read(self, endpoint, size):
        # Endpoint 0's OUT stages stay USBCDC's; a bulk OUT buffer with
        # nothing to send waits for bytes, as on a real bus.
        if endpoint != 0 and self.cdc.tx_fifo.empty:
            self.held_read = (endpoint, size)
            return
        self._model_read(endpoint, size)

    def _endpoint_write(self, endpoint, buffer):
        self._model_write(endpoint, buffer)
        if endpoint == 0 and len(buffer) == 0 and self.control_busy:
            self.control_busy = False
            self._next_dtr()

    def _next_dtr(self):
        if self.dtr_queue and not self.control_busy:
            level = self.dtr_queue.pop(0)
            self.control_busy = True
            self.cdc.set_control_lines(dtr=level, rts=level)

    def send(self, data):
        """Bytes from the host program (the pseudo-terminal)."""
        self.pending.extend(data)
        self.pump()

    def pump(self):
        fifo = self.cdc.tx_fifo
        moved = 0
        while moved < len(self.pending) and not fifo.full:
            fifo.push(self.pending[moved])
            moved += 1
        del self.pending[:moved]
        if self.held_read and not fifo.empty:
            endpoint, size = self.held_read
            self.held_read = None
            self._model_read(endpoint, size)

    def set_dtr(self, level):
        self.dtr_queue.append(level)
        self._next_dtr()
