//! USB CDC: the serial device a host sees when the Pico is plugged in.
//!
//! `usb-device` and `usbd-serial` on rp2040-hal's `UsbBus`, one CDC ACM
//! function (a host's `cdc_acm` driver makes it `/dev/ttyACM0`), VID:PID
//! [`VID_PID`], pid.codes' test pair. Nothing here runs in an interrupt:
//! `USBCTRL_IRQ` only masks itself and wakes the main loop, which calls
//! [`UsbSerial::poll`] (`usb-device`'s state machine and the CDC class)
//! in thread mode, where the edge interrupt preempts it like any other
//! main-loop work. The stack's own critical sections (rp2040-hal's bus
//! takes one per register access) are the board's (`cs.rs`): the edge
//! interrupt stays live in them.
//!
//! A host that opens the port raises DTR (`SET_CONTROL_LINE_STATE`): that
//! is when someone listens, so [`UsbSerial::poll`] reports it and the
//! main loop sends the identity line (or grbl's welcome) then, not at boot.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::peripheral::NVIC;
use rp2040_hal as hal;
use rp2040_hal::pac;
use rp2040_hal::pac::interrupt;
use usb_device::bus::UsbBusAllocator;
use usb_device::device::{
    StringDescriptors, UsbDevice, UsbDeviceBuilder, UsbDeviceState, UsbVidPid,
};
use usb_device::UsbError;
use usbd_serial::{SerialPort, USB_CLASS_CDC};

/// pid.codes' test VID:PID (1209:0001, "pid.codes Test PID"): for testing
/// only. A build that is handed out needs a PID of its own (pid.codes
/// gives open-source hardware one free).
pub const VID_PID: UsbVidPid = UsbVidPid(0x1209, 0x0001);

/// Bytes from the host that wait for the main loop (it takes them a few
/// at a time; the host is held off by NAKs when this is full).
const RX_BYTES: usize = 256;
/// Replies that wait for the host's IN tokens: the longest reply (four
/// status lines) fits, so a reply never waits for the host.
const TX_BYTES: usize = 1024;
/// How long a reply may wait for room before the rest is dropped (µs):
/// well under the cores' lead over the timer (`edges::LEAD_TICKS`, 4 ms),
/// so that a host that holds the port open and stops reading never
/// starves the edge queue. A host that reads its replies never leaves
/// [`TX_BYTES`] waiting, so only such a host loses bytes.
const WRITE_PATIENCE_US: u64 = 1_000;

/// `USBCTRL_IRQ` fired since the main loop last looked.
static WOKEN: AtomicBool = AtomicBool::new(false);

type Serial = SerialPort<'static, hal::usb::UsbBus, [u8; RX_BYTES], [u8; TX_BYTES]>;

/// The USB device and its one CDC ACM port.
pub struct UsbSerial {
    device: UsbDevice<'static, hal::usb::UsbBus>,
    serial: Serial,
    /// DTR as the last poll saw it.
    dtr: bool,
    /// Bytes read from the port, not yet taken (`staged[taken..filled]`).
    staged: [u8; 64],
    taken: usize,
    filled: usize,
}

impl UsbSerial {
    /// Brings the USB controller up as a device (on the 48 MHz USB clock)
    /// and connects to the bus; `None` if called twice.
    pub fn new(
        regs: pac::USBCTRL_REGS,
        dpram: pac::USBCTRL_DPRAM,
        clock: hal::clocks::UsbClock,
        resets: &mut pac::RESETS,
    ) -> Option<UsbSerial> {
        // VBUS is not wired to a GPIO on the Pico: detection forced on.
        let bus = hal::usb::UsbBus::new(regs, dpram, clock, true, resets);
        let allocator: &'static UsbBusAllocator<hal::usb::UsbBus> =
            cortex_m::singleton!(: UsbBusAllocator<hal::usb::UsbBus> = UsbBusAllocator::new(bus))?;
        let serial = SerialPort::new_with_store(allocator, [0; RX_BYTES], [0; TX_BYTES]);
        let strings = StringDescriptors::default()
            .manufacturer("cogstep")
            .product("cogstep stepper controller (Raspberry Pi Pico)")
            .serial_number(env!("CARGO_PKG_VERSION"));
        let device = UsbDeviceBuilder::new(allocator, VID_PID)
            .strings(&[strings])
            .ok()?
            .device_class(USB_CLASS_CDC)
            // 64, not the default 8: the whole device descriptor in one
            // packet (rp2040-hal's note on small EP0 packets).
            .max_packet_size_0(64)
            .ok()?
            .build();
        Some(UsbSerial {
            device,
            serial,
            dtr: false,
            staged: [0; 64],
            taken: 0,
            filled: 0,
        })
    }

    /// Serves the bus (enumeration, control requests, finished packets);
    /// `true` when a host has just raised DTR: a port was opened.
    pub fn poll(&mut self) -> bool {
        WOKEN.store(false, Ordering::Relaxed);
        self.device.poll(&mut [&mut self.serial]);
        let dtr = self.device.state() == UsbDeviceState::Configured && self.serial.dtr();
        let opened = dtr && !self.dtr;
        self.dtr = dtr;
        opened
    }

    /// The next byte from the host, if one has come.
    pub fn read_byte(&mut self) -> Option<u8> {
        if self.taken == self.filled {
            self.taken = 0;
            self.filled = self.serial.read(&mut self.staged).unwrap_or(0);
        }
        (self.taken < self.filled).then(|| {
            self.taken += 1;
            self.staged[self.taken - 1]
        })
    }

    /// Queues `bytes` for the host. Waits (serving the bus) only while the
    /// host is configured and takes packets, at most
    /// [`WRITE_PATIENCE_US`] without progress; then drops the rest, as a
    /// UART with nobody on the line would.
    pub fn write(&mut self, mut bytes: &[u8], now_us: impl Fn() -> u64) {
        let mut since = now_us();
        while !bytes.is_empty() && self.device.state() == UsbDeviceState::Configured {
            match self.serial.write(bytes) {
                Ok(written) => {
                    bytes = &bytes[written..];
                    since = now_us();
                }
                Err(UsbError::WouldBlock) if now_us() - since < WRITE_PATIENCE_US => {
                    self.device.poll(&mut [&mut self.serial]);
                }
                Err(_) => return,
            }
        }
    }

    /// Whether the main loop has USB work: an event, a packet, or bytes
    /// already read and not taken.
    pub fn has_work(&self) -> bool {
        // SAFETY: a read of the controller's interrupt status.
        let regs = unsafe { &*pac::USBCTRL_REGS::ptr() };
        self.taken < self.filled || WOKEN.load(Ordering::Relaxed) || regs.ints().read().bits() != 0
    }

    /// Lets `USBCTRL_IRQ` wake the main loop's WFE (it masks itself again
    /// when it fires).
    pub fn arm_wake(&self) {
        // SAFETY: the handler below only masks itself and sets a flag.
        unsafe { NVIC::unmask(pac::Interrupt::USBCTRL_IRQ) };
    }
}

/// USB wants the main loop: wake it and stay masked until it sleeps again
/// (the interrupt is a level; the loop's poll clears its cause).
#[interrupt]
fn USBCTRL_IRQ() {
    NVIC::mask(pac::Interrupt::USBCTRL_IRQ);
    WOKEN.store(true, Ordering::Relaxed);
    crate::wake_main_loop();
}
