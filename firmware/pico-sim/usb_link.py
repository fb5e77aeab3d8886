"""The host's end of the Pico's USB CDC port under rp2040py (`run-pico-sim --usb`).

rp2040py's `USBCDC` is the host: it enumerates the firmware's device
(bus reset, SET_ADDRESS, the configuration descriptor, SET_CONFIGURATION),
finds the CDC data interface's bulk endpoints, then asserts DTR and RTS
(SET_CONTROL_LINE_STATE), which is what a host's `cdc_acm` driver does
when a program opens `/dev/ttyACM0`. This class adds what `pico_sim.py`
needs on top, called only from its one thread, between batches:

- **Host to device.** Bytes wait here and enter `USBCDC`'s 512-byte queue
  as it has room. `USBCDC` answers every OUT buffer the firmware arms at
  once, with an empty packet when it has no bytes; a real host sends an
  OUT packet only when it has data, and the device NAKs until then. So a
  buffer armed while nothing waits is held here and answered when bytes
  come: the firmware is not woken every 10 µs by empty packets.
- **Device to host.** Each IN packet's bytes go to `on_bytes`.
- **DTR.** `set_dtr(level)` drops or raises DTR (and RTS) as a host
  closing or opening the port would.
"""

from rp2040py.usb.cdc import USBCDC


class UsbLink:
    def __init__(self, mcu, on_bytes):
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
        self.cdc.set_control_lines(dtr=level, rts=level)
