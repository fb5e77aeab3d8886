//! The firmware's axes, the protocol's [`Board`] over them, and the step
//! interrupt that makes their edges on time.
//!
//! Time is one 64-bit CT in ticks of the board's clock ([`Hardware::now_ticks`]).
//! A command from the protocol acts on its axis at CT now and then asks for
//! the step interrupt ([`Hardware::request_step_interrupt`]), because the
//! command may have made an event due earlier than the one the timer waits
//! for. The interrupt ([`Firmware::step_interrupt`]) makes every event of
//! every axis up to CT now and returns the CT of the next one, for the board
//! to arm its one-shot timer with. A late interrupt makes its edges late but
//! keeps the schedule: step times are absolute CTs, so a delay is never
//! stretched by the time the interrupt took.

use core::cell::RefCell;
use core::fmt;

use critical_section::Mutex;
use driver::axis::{AxisContract, AxisError, AxisStatus, Direction, LimitStatus};
use driver::axis_core::{AxisCoreConfig, CoreCommand};
use driver::serial::{Board, Session};

use crate::axis::{AxisRunner, EdgeCounts, Output, Work};

/// The most axes a firmware drives.
pub const AXES_MAX: usize = 4;

/// What the board-independent part needs from a board.
pub trait Hardware {
    /// CT now: ticks of the board's clock since boot, never going back.
    fn now_ticks(&self) -> u64;
    /// Make the step interrupt run as soon as possible (it re-plans).
    fn request_step_interrupt(&self);
    /// Drive output `output` of axis `axis` to `level`.
    fn set_pin(&self, axis: usize, output: Output, level: bool);
}

/// One axis of the firmware: its logic behind a critical section, and the
/// hardware to read the time from.
pub struct FirmwareAxis<H> {
    logic: Mutex<RefCell<AxisRunner>>,
    hardware: H,
}

impl<H: Hardware> FirmwareAxis<H> {
    fn with<R>(&self, action: impl FnOnce(&mut AxisRunner, u64) -> R) -> R {
        let result = critical_section::with(|cs| {
            let now = self.hardware.now_ticks();
            action(&mut self.logic.borrow_ref_mut(cs), now)
        });
        self.hardware.request_step_interrupt();
        result
    }

    fn read<R>(&self, look: impl FnOnce(&AxisRunner) -> R) -> R {
        critical_section::with(|cs| look(&self.logic.borrow_ref(cs)))
    }

    /// The axis core's settings.
    pub fn config(&self) -> AxisCoreConfig {
        self.read(|logic| *logic.config())
    }

    /// Steps the last stop left unmade.
    pub fn dropped_steps(&self) -> u32 {
        self.read(AxisRunner::dropped_steps)
    }

    /// The rising and falling edges made on each output.
    pub fn edge_counts(&self) -> EdgeCounts {
        self.read(AxisRunner::edge_counts)
    }
}

impl<H: Hardware> AxisContract for FirmwareAxis<H> {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::Move { speed, steps }))
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::Jog { speed, direction }))
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::JogRelease))
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.with(|axis, now| axis.set_stop_pin(now, high));
        Ok(())
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::EmergencyStop))
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::SetPosition(position)))
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        Ok(self.read(AxisRunner::status))
    }

    // Soft limits come with the shared axis core. Homing and hard limits
    // need switch inputs read on the step, which this firmware does not
    // read yet: `H` and `K` answer `error:1 not supported`.
    fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::SetSoftLimits(Some((min, max)))))
    }

    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        self.with(|axis, now| axis.command(now, CoreCommand::SetSoftLimits(None)))
    }

    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        Ok(self.read(AxisRunner::limit_status))
    }
}

/// The firmware: its axes and the protocol session over them.
pub struct Firmware<H> {
    axes: [FirmwareAxis<H>; AXES_MAX],
    axis_count: usize,
    clkfreq: u32,
    hardware: H,
}

/// Why a firmware cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// The axis count must be 1 to [`AXES_MAX`].
    #[error("{0} axes: a firmware drives 1 to {AXES_MAX}")]
    AxisCount(usize),
}

impl<H: Hardware + Copy> Firmware<H> {
    /// `axis_count` axes, each with the core settings `config(index)`
    /// gives (the board chooses the output variant of each; see
    /// [`crate::axis::core_config`]), idle with their stop pins high.
    pub fn new(
        hardware: H,
        axis_count: usize,
        config: impl Fn(usize) -> AxisCoreConfig,
    ) -> Result<Self, ConfigError> {
        if !(1..=AXES_MAX).contains(&axis_count) {
            return Err(ConfigError::AxisCount(axis_count));
        }
        let clkfreq = config(0).scurve.clkfreq;
        let now = hardware.now_ticks();
        Ok(Firmware {
            axes: core::array::from_fn(|index| FirmwareAxis {
                logic: Mutex::new(RefCell::new(AxisRunner::new(config(index), now))),
                hardware,
            }),
            axis_count,
            clkfreq,
            hardware,
        })
    }
}

impl<H: Hardware> Firmware<H> {
    /// The axes in use.
    pub fn axes(&self) -> &[FirmwareAxis<H>] {
        &self.axes[..self.axis_count]
    }

    /// The identity line a board sends when it starts, as `I` reports it.
    pub fn announce<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        // `I` writes the identity line and then `ok`; the boot line is the
        // identity alone.
        let mut filter = IdentityOnly { out, done: false };
        driver::serial::dispatch(self, &driver::serial::Command::Identify, &mut filter)
    }

    /// Feeds one received byte to the session; replies go to `out`.
    pub fn feed<W: fmt::Write + ?Sized>(
        &self,
        session: &mut Session,
        byte: u8,
        out: &mut W,
    ) -> fmt::Result {
        session.feed(byte, self, out)
    }

    /// The step interrupt's body: makes every event due by CT now on every
    /// axis and returns the CT of the next one (`None`: nothing to wait
    /// for), with what was done.
    pub fn step_interrupt(&self) -> (Option<u64>, Work) {
        let mut work = Work::default();
        loop {
            let (now, next) = critical_section::with(|cs| {
                let now = self.hardware.now_ticks();
                let mut next: Option<u64> = None;
                for (index, axis) in self.axes().iter().enumerate() {
                    let mut logic = axis.logic.borrow_ref_mut(cs);
                    let hardware = &self.hardware;
                    let mut drive = |output: Output, level: bool| {
                        hardware.set_pin(index, output, level);
                    };
                    work.add(logic.advance(now, &mut drive));
                    if let Some(t) = logic.next_wake() {
                        next = Some(next.map_or(t, |n| n.min(t)));
                    }
                }
                (now, next)
            });
            match next {
                // Came due while the axes were worked through: go round
                // rather than arm the timer in the past.
                Some(t) if t <= now || t <= self.hardware.now_ticks() => continue,
                _ => return (next, work),
            }
        }
    }
}

impl<H: Hardware> Board for Firmware<H> {
    fn axis_count(&self) -> usize {
        self.axis_count
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes().get(index).map(|axis| axis as &dyn AxisContract)
    }

    fn clkfreq_hz(&self) -> u32 {
        self.clkfreq
    }
}

/// Passes the identity line on and swallows the `ok` after it.
struct IdentityOnly<'a, W: ?Sized> {
    out: &'a mut W,
    done: bool,
}

impl<W: fmt::Write + ?Sized> fmt::Write for IdentityOnly<'_, W> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        if self.done {
            return Ok(());
        }
        if let Some(end) = text.find('\n') {
            self.done = true;
            self.out.write_str(&text[..=end])
        } else {
            self.out.write_str(text)
        }
    }
}
