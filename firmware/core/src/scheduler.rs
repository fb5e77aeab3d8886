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

use core::cell::{Cell, RefCell, RefMut};
use core::fmt;

use critical_section::{CriticalSection, Mutex};
use driver::axis::{AxisContract, AxisError, AxisStatus, Direction, HomeConfig, LimitStatus};
use driver::axis_core::{AxisCoreConfig, CoreCommand};
use driver::profile::scurve::SCurve;
use driver::refusal::bad_setting;
use driver::serial::{Board, Session};

use crate::axis::{AxisRunner, EdgeCounts, Output, RunAheadTicks, TrainRises, Work, NEVER};
use crate::fast::{FastTrain, Returned};
use cogstep_handoff::AheadSlot;

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

    /// Drive output `output` of axis `axis` to `level` at CT `ct`, later
    /// than now: for a board that queues its edges ahead of the pins,
    /// each with its CT, and runs [`Firmware::step_interrupt_ahead`]. Only
    /// step edges come here: a pulse's falling edge, the pulse's width
    /// after its rising edge (a board whose hardware ends each pulse
    /// itself, the Pico's PIO build, has it already), and, from
    /// [`Firmware::step_interrupt_ahead_trains`], a train's rising edge.
    /// Their CTs never go back. The default, for a board that drives its
    /// pins at once, never called then, drives it now.
    fn set_pin_at(&self, axis: usize, output: Output, level: bool, ct: u64) {
        let _ = ct;
        self.set_pin(axis, output, level);
    }

    /// Drive output `output` of axis `axis` to `level` now: an edge its
    /// core decided for CT `ct`. That is now when the board keeps up; not
    /// when several edges go out together (a train's edges due by one late
    /// wake-up, or the oldest of an axis's few pending edges, driven at
    /// once when a command's catch-up overflows them: `ct` may then be
    /// before or after now). For a board that encodes each edge with its
    /// own CT (the Pico's PIO build: each axis's words keep their own
    /// time), so that edges driven together keep their spacing. The
    /// default: [`Hardware::set_pin`], now.
    fn drive_pin(&self, axis: usize, output: Output, level: bool, ct: u64) {
        let _ = ct;
        self.set_pin(axis, output, level);
    }

    /// Whether the board's hardware ends each step pulse itself, the
    /// pulse's width after its rising edge (the Pico's PIO build: its
    /// state machine does). Then [`Firmware::step_interrupt_ahead_trains`]
    /// ends the pulse of a train's step it makes ahead with the step, and
    /// that falling edge never reaches [`Hardware::set_pin_at`] (a board
    /// whose pulses end themselves has it already): one pass of the loop a
    /// step instead of two. The default: no, every falling edge is driven.
    fn pulses_end_themselves(&self) -> bool {
        false
    }

    /// Whether the board keeps each axis's edges in that axis's own CT
    /// order, owing nothing to the other axes' (the Pico's PIO build: one
    /// state machine per axis, each keeping its own time), and ends each
    /// step pulse itself ([`Hardware::pulses_end_themselves`]). Then
    /// [`Firmware::step_interrupt_ahead_trains`] makes a train's steps up
    /// to the frontier at once, passing their rising edges to
    /// [`Hardware::set_rises_at`], instead of one step a pass of its loop
    /// in the CT order of all the axes. The default: no.
    fn rises_per_axis(&self) -> bool {
        false
    }

    /// Rising edges of output `output` of axis `axis`, each at its own CT
    /// (the iterator's items, in CT order, after every edge of the axis
    /// before): a train's steps made ahead on a board that answers yes to
    /// [`Hardware::rises_per_axis`], their pulses ending themselves. Each
    /// item taken is a step made; a board takes them all. The default
    /// passes each to [`Hardware::set_pin_at`]; a board overrides it to do
    /// the per-call work (finding the axis's encoder, say) once a run.
    fn set_rises_at(&self, axis: usize, output: Output, rises: &mut TrainRises<'_>) {
        for ct in rises {
            self.set_pin_at(axis, output, true, ct);
        }
    }

    /// The board's name for output `output` of axis `axis`, which the
    /// fast path passes back to its step interrupt to drive that pin (say,
    /// the address of the pin's data register). The default numbers the
    /// outputs `2·axis + output`.
    fn fast_pin(&self, axis: usize, output: Output) -> u32 {
        (2 * axis + output.index()) as u32
    }

    /// Runs `use_it` on the board's [`FastTrain`], the one its step
    /// interrupt passes to [`Firmware::step_interrupt_lending`], inside a
    /// critical section (so the interrupt cannot run meanwhile). A board
    /// without a fast path keeps the default: a train never lent.
    fn with_fast_train<R>(
        &self,
        cs: CriticalSection<'_>,
        use_it: impl FnOnce(&mut FastTrain) -> R,
    ) -> R {
        let _ = cs;
        use_it(&mut FastTrain::new())
    }

    /// The pins a host may name as home and limit switches (bit per pin,
    /// in the numbering the board gives its inputs, and in which it passes
    /// their levels to [`FirmwareAxis::set_inputs`]). The default, none:
    /// a board that reads no switches answers homing and hard limits with
    /// `AxisError::Unsupported`.
    fn switch_pins(&self) -> u64 {
        0
    }
}

/// One axis of the firmware: its logic behind a critical section, and the
/// hardware to read the time from.
pub struct FirmwareAxis<H> {
    pub(crate) logic: Mutex<RefCell<AxisRunner>>,
    pub(crate) index: usize,
    hardware: H,
}

impl<H: Hardware> FirmwareAxis<H> {
    /// Runs `action` on the axis at CT now, with a way to drive its pins,
    /// then asks for the step interrupt (the action may have made an event
    /// due earlier than the one the timer waits for).
    fn with<R>(
        &self,
        action: impl FnOnce(&mut AxisRunner, u64, &mut dyn FnMut(Output, bool, u64)) -> R,
    ) -> R {
        let result = self.synced(action);
        self.hardware.request_step_interrupt();
        result
    }

    /// The axis's runner inside the critical section `cs`, a train lent
    /// to the fast path back first (the caller may change the core).
    pub(crate) fn runner<'cs>(&'cs self, cs: CriticalSection<'cs>) -> RefMut<'cs, AxisRunner> {
        let mut logic = self.logic.borrow_ref_mut(cs);
        self.hardware.with_fast_train(cs, |fast| {
            if fast.lent_axis() == Some(self.index) {
                give_back(fast, &mut logic);
            }
        });
        logic
    }

    /// Runs `action` on the axis at CT now, with a way to drive its pins.
    fn synced<R>(
        &self,
        action: impl FnOnce(&mut AxisRunner, u64, &mut dyn FnMut(Output, bool, u64)) -> R,
    ) -> R {
        critical_section::with(|cs| {
            let mut logic = self.logic.borrow_ref_mut(cs);
            // A train lent to the fast path comes back first.
            self.hardware.with_fast_train(cs, |fast| {
                if fast.lent_axis() == Some(self.index) {
                    give_back(fast, &mut logic);
                }
            });
            let now = self.hardware.now_ticks();
            let (hardware, index) = (&self.hardware, self.index);
            let mut drive =
                |output: Output, level: bool, ct: u64| hardware.drive_pin(index, output, level, ct);
            action(&mut logic, now, &mut drive)
        })
    }

    /// Looks at what a lent train does not change (settings, counts of
    /// dropped steps, limits).
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

    /// Whether the axis is on a look-ahead path (see [`crate::grbl`]).
    pub fn on_path(&self) -> bool {
        self.read(AxisRunner::on_path)
    }

    /// Puts the idle axis on a look-ahead path at CT now: from then on it
    /// makes the steps [`FirmwareAxis::push_path_step`] gives it, and
    /// refuses every other motion (see `driver::axis_core`'s path part).
    pub fn start_path(&self) -> Result<(), AxisError> {
        self.with(|axis, now, drive| axis.command(now, CoreCommand::PathStart, drive))
    }

    /// Pushes the path's next step of this axis, its rising edge at `ct`;
    /// refused with nothing changed (`Busy`: its queue is full; `NotIdle`:
    /// not on a path). The caller asks for the step interrupt once it has
    /// pushed ([`Firmware::request_step_interrupt`]).
    pub fn push_path_step(&self, ct: u64, forward: bool) -> Result<(), AxisError> {
        self.synced(|axis, now, drive| axis.push_path_step(now, ct, forward, drive))
    }

    /// The board's stop input for this axis reads `high` (CT now): low
    /// holds the axis as `S` does; it runs while both this and the
    /// protocol's level (`S`, `R`, `!`) are high.
    pub fn set_stop_input(&self, high: bool) {
        self.with(|axis, now, drive| axis.set_stop_input(now, high, drive));
    }

    /// The switch inputs read `levels` (bit per pin, as
    /// [`Hardware::switch_pins`] numbers them) since the axis's physical
    /// position was `physical_then` (`None`: now); see [`crate::inputs`].
    pub fn set_inputs(&self, levels: u64, physical_then: Option<i64>) {
        self.with(|axis, now, drive| axis.set_inputs(now, levels, physical_then, drive));
    }

    /// The axis core's physical position (the signed count of the step
    /// edges it has decided).
    pub fn physical_position(&self) -> i64 {
        self.synced(|axis, now, drive| {
            axis.sync(now, drive);
            axis.physical_position()
        })
    }

    /// Refuses a switch pin the board does not read (`what` names the
    /// feature for a board with no switches at all).
    fn check_switch_pins(
        &self,
        pins: impl IntoIterator<Item = u8>,
        what: &'static str,
    ) -> Result<(), AxisError> {
        let readable = self.hardware.switch_pins();
        if readable == 0 {
            return Err(AxisError::Unsupported(what));
        }
        // Pins past 63 are the core's to refuse (out of range).
        let unreadable = pins
            .into_iter()
            .any(|pin| pin < 64 && readable & (1u64 << pin) == 0);
        if unreadable {
            return Err(AxisError::BadSetting(bad_setting::PIN_NOT_A_SWITCH_INPUT));
        }
        Ok(())
    }

    /// Lets another core compute this axis's ramp runs ahead through
    /// `slot` ([`cogstep_handoff`]); the axis is the slot's owner. Steps and
    /// edges stay exactly what they are without it.
    pub fn set_run_ahead(&self, slot: &'static AheadSlot<SCurve>, answer_ticks: RunAheadTicks) {
        critical_section::with(|cs| {
            self.logic
                .borrow_ref_mut(cs)
                .set_run_ahead(slot, answer_ticks)
        });
    }

    /// The ramp runs computed ahead that this axis took so far.
    pub fn runs_taken(&self) -> u32 {
        self.read(AxisRunner::runs_taken)
    }

    /// The rising and falling edges made on each output (a train lent
    /// to the fast path stays there: this is read while it runs).
    pub fn edge_counts(&self) -> EdgeCounts {
        critical_section::with(|cs| {
            let mut counts = self.logic.borrow_ref(cs).edge_counts();
            self.hardware.with_fast_train(cs, |fast| {
                if fast.lent_axis() == Some(self.index) {
                    fast.add_edges(&mut counts);
                }
            });
            counts
        })
    }
}

impl<H: Hardware> AxisContract for FirmwareAxis<H> {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        let command = CoreCommand::Move { speed, steps };
        self.with(|axis, now, drive| axis.command(now, command, drive))
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        let command = CoreCommand::Jog { speed, direction };
        self.with(|axis, now, drive| axis.command(now, command, drive))
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        self.with(|axis, now, drive| axis.command(now, CoreCommand::JogRelease, drive))
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.with(|axis, now, drive| axis.set_stop_pin(now, high, drive));
        Ok(())
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        self.with(|axis, now, drive| axis.command(now, CoreCommand::EmergencyStop, drive))
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        let command = CoreCommand::SetPosition(position);
        self.with(|axis, now, drive| axis.command(now, command, drive))
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        Ok(self.synced(|axis, now, drive| axis.status(now, drive)))
    }

    // Soft limits come with the shared axis core. Homing and hard limits
    // need a board that reads switch inputs (`Hardware::switch_pins`);
    // elsewhere `H`, `K` and `C` answer `error:1 not supported`.
    fn home(&self, config: HomeConfig) -> Result<(), AxisError> {
        self.check_switch_pins([config.switch_pin], "homing")?;
        self.with(|axis, now, drive| axis.command(now, CoreCommand::Home(config), drive))
    }

    fn set_limit_pins(
        &self,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        let pins = [min, max].into_iter().flatten().map(|(pin, _)| pin);
        self.check_switch_pins(pins, "hard limits")?;
        let command = CoreCommand::SetLimitPins { min, max };
        self.with(|axis, now, drive| axis.command(now, command, drive))
    }

    fn clear_limit_fault(&self) -> Result<(), AxisError> {
        self.check_switch_pins([], "hard limits")?;
        self.with(|axis, now, drive| axis.command(now, CoreCommand::ClearLimitFault, drive))
    }

    fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        self.with(|axis, now, drive| {
            axis.command(now, CoreCommand::SetSoftLimits(Some((min, max))), drive)
        })
    }

    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        self.with(|axis, now, drive| axis.command(now, CoreCommand::SetSoftLimits(None), drive))
    }

    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        Ok(self.read(AxisRunner::limit_status))
    }
}

/// The firmware: its axes and the protocol session over them.
pub struct Firmware<H> {
    pub(crate) axes: [FirmwareAxis<H>; AXES_MAX],
    pub(crate) axis_count: usize,
    clkfreq: u32,
    pub(crate) hardware: H,
    /// The group moves' numbers, and whether one may still run
    /// (see [`crate::group`]).
    pub(crate) groups: Mutex<Cell<Groups>>,
}

/// The group moves a firmware has started.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Groups {
    /// The number the next group move gets.
    pub(crate) next_id: u32,
    /// A group move may still run: the step interrupt looks at its
    /// members' stop pins and requests ([`crate::group`]).
    pub(crate) live: bool,
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
                index,
                hardware,
            }),
            axis_count,
            clkfreq,
            hardware,
            groups: Mutex::new(Cell::new(Groups::default())),
        })
    }
}

impl<H: Hardware> Firmware<H> {
    /// The axes in use.
    pub fn axes(&self) -> &[FirmwareAxis<H>] {
        &self.axes[..self.axis_count]
    }

    /// CT now, from the board's clock.
    pub fn now_ticks(&self) -> u64 {
        self.hardware.now_ticks()
    }

    /// Makes the step interrupt run as soon as possible (it re-plans).
    pub fn request_step_interrupt(&self) {
        self.hardware.request_step_interrupt();
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
    ///
    /// Only the axes whose wake-up has come are run; the others cost a
    /// comparison. A wake-up that comes due while the axes are worked
    /// through is the board's to catch when it arms its timer (a target
    /// in the past runs the interrupt again at once).
    pub fn step_interrupt(&self) -> (Option<u64>, Work) {
        self.step_interrupt_at(self.hardware.now_ticks())
    }

    /// [`Firmware::step_interrupt`] with CT now read by the caller (a
    /// board that reads its clock cheaply at the interrupt's start and
    /// arms its timer from the same reading).
    #[inline]
    pub fn step_interrupt_at(&self, now: u64) -> (Option<u64>, Work) {
        critical_section::with(|cs| {
            self.hardware
                .with_fast_train(cs, |fast| self.run_axes(cs, now, fast, false))
        })
    }

    /// [`Firmware::step_interrupt_at`] for a board that queues its edges
    /// ahead of the pins, each with its CT (the Pico's main loop): then
    /// each step pulse's falling edge that comes by `until`, before any
    /// other edge or wake-up of any axis, is queued at once with its own
    /// CT ([`Hardware::set_pin_at`]) instead of at a wake-up of its own.
    /// The board still gets every edge in the order of their CTs, and
    /// every axis stands where driving that edge at its CT would leave it.
    /// (A board with a fast path, [`Firmware::step_interrupt_lending`],
    /// lends nothing here: it does not call this.)
    pub fn step_interrupt_ahead(&self, now: u64, until: u64) -> (Option<u64>, Work) {
        self.step_interrupt_ahead_trains(now, until, 0, 0)
    }

    /// [`Firmware::step_interrupt_ahead`], and up to `rises` steps of the
    /// axes' trains ahead as well: while the wake-up that comes first is
    /// a train's next rising edge, by `rise_until` (the board's frontier:
    /// no command acts before it) and before any other axis's wake-up,
    /// its step is made at once and its rising edge queued with its own
    /// CT ([`Hardware::set_pin_at`]), then its pulse's falling edge
    /// likewise. A train's steps at speed or on a ramp then cost no
    /// wake-up each: the board gets the very edges, in CT order, and
    /// every axis stands where running each wake-up at its CT would leave
    /// it. Axes that step on the very same CT (moves started together)
    /// share their wake-ups instead, which costs less than picking them
    /// one by one. Not while a group move is under way (a member's stop is
    /// passed on at each wake-up). `rises` bounds the steps one call makes
    /// ahead (a board's queue has room for so many). On a board whose
    /// pulses end themselves ([`Hardware::pulses_end_themselves`]) a step
    /// made ahead takes its falling edge with it, which the board never
    /// gets; and on one that keeps each axis's edges in their own order
    /// ([`Hardware::rises_per_axis`]) the axis that comes first makes its
    /// train's steps up to `rise_until` at once (at most `rises`), through
    /// [`Hardware::set_rises_at`], whatever the other axes' wake-ups.
    pub fn step_interrupt_ahead_trains(
        &self,
        now: u64,
        until: u64,
        rise_until: u64,
        rises: usize,
    ) -> (Option<u64>, Work) {
        critical_section::with(|cs| {
            self.pass_group_stops(cs, now, true);
            let mut work = Work::default();
            // Each axis's next wake-up, after this one's work.
            let mut wakes = [NEVER; AXES_MAX];
            for axis in self.axes() {
                let mut logic = axis.logic.borrow_ref_mut(cs);
                if logic.wake() <= now {
                    self.share_lead(cs, axis.index, &mut logic);
                    let (hardware, index) = (&self.hardware, axis.index);
                    let mut drive = |output: Output, level: bool, ct: u64| {
                        hardware.drive_pin(index, output, level, ct);
                    };
                    work.add(logic.advance(now, &mut drive));
                }
                wakes[axis.index] = logic.wake();
            }
            let pulses_end_themselves = self.hardware.pulses_end_themselves();
            let per_axis = pulses_end_themselves && self.hardware.rises_per_axis();
            let mut rises = if self.groups.borrow(cs).get().live {
                0
            } else {
                rises
            };
            let wakes = &mut wakes[..self.axis_count];
            loop {
                // The axis that comes first, and when the next other does.
                let (mut first, mut first_wake, mut second_wake) = (0, NEVER, NEVER);
                for (index, &wake) in wakes.iter().enumerate() {
                    if wake < first_wake {
                        (first, first_wake, second_wake) = (index, wake, first_wake);
                    } else {
                        second_wake = second_wake.min(wake);
                    }
                }
                if first_wake > until {
                    break;
                }
                let mut logic = self.axes[first].logic.borrow_ref_mut(cs);
                let hardware = &self.hardware;
                if let Some(ct) = logic.fall_ahead().filter(|&ct| ct <= second_wake) {
                    debug_assert_eq!(ct, first_wake);
                    logic.drive_fall_ahead(&mut |output: Output, level: bool, _: u64| {
                        hardware.set_pin_at(first, output, level, ct);
                    });
                    work.edges += 1;
                } else if per_axis && rises > 0 && first_wake <= rise_until {
                    // Its steps up to the frontier at once: the board keeps
                    // this axis's edges in their own order (none when it has
                    // no train step to make ahead: `made` is 0).
                    let max = u32::try_from(rises).unwrap_or(u32::MAX);
                    let made = logic.drive_rises_ahead(
                        rise_until,
                        max,
                        |output, run| hardware.set_rises_at(first, output, run),
                        &mut work,
                    );
                    if made == 0 {
                        break;
                    }
                    rises -= made as usize;
                } else if let Some(ct) =
                    (rises > 0 && first_wake <= rise_until && first_wake < second_wake)
                        .then(|| logic.rise_ahead())
                        .flatten()
                {
                    debug_assert_eq!(ct, first_wake);
                    logic.drive_rise_ahead(
                        &mut |output: Output, level: bool, _: u64| {
                            hardware.set_pin_at(first, output, level, ct);
                        },
                        &mut work,
                    );
                    rises -= 1;
                    // Its pulse ends by itself: the step's falling edge
                    // with it, out of CT order since it goes nowhere.
                    if pulses_end_themselves && logic.fall_ahead().is_some() {
                        logic.drive_fall_ahead(&mut |_: Output, _: bool, _: u64| {});
                        work.edges += 1;
                    }
                } else {
                    break;
                }
                wakes[first] = logic.wake();
            }
            let next = wakes.iter().copied().min().unwrap_or(NEVER);
            ((next != NEVER).then_some(next), work)
        })
    }

    /// The general step interrupt of a board with a fast path
    /// ([`crate::fast`]): takes back the train `fast` holds, runs
    /// [`Firmware::step_interrupt_at`], and lends the train of the one
    /// axis that needs the interrupt, if that is all there is, to `fast`
    /// (the CT returned is then that of the first edge it serves). `fast` is the
    /// board's own, which [`Hardware::with_fast_train`] also reaches:
    /// call this where that cannot run (the step interrupt).
    pub fn step_interrupt_lending(&self, now: u64, fast: &mut FastTrain) -> (Option<u64>, Work) {
        critical_section::with(|cs| self.run_axes(cs, now, fast, true))
    }

    /// The step interrupt's body over the axes (see
    /// [`Firmware::step_interrupt_lending`]).
    #[inline]
    fn run_axes(
        &self,
        cs: CriticalSection<'_>,
        now: u64,
        fast: &mut FastTrain,
        lend: bool,
    ) -> (Option<u64>, Work) {
        if let Some(index) = fast.lent_axis() {
            give_back(fast, &mut self.axes[index].logic.borrow_ref_mut(cs));
        }
        self.pass_group_stops(cs, now, true);
        let mut work = Work::default();
        let mut next = NEVER;
        let mut waiting = 0;
        let mut last_waiting = 0;
        for axis in self.axes() {
            let mut logic = axis.logic.borrow_ref_mut(cs);
            if logic.wake() <= now {
                self.share_lead(cs, axis.index, &mut logic);
                let (hardware, index) = (&self.hardware, axis.index);
                let mut drive = |output: Output, level: bool, ct: u64| {
                    hardware.drive_pin(index, output, level, ct);
                };
                work.add(logic.advance(now, &mut drive));
            }
            if logic.wake() != NEVER {
                waiting += 1;
                last_waiting = axis.index;
            }
            next = next.min(logic.wake());
        }
        // One axis alone at speed: its train goes to the fast path.
        if lend && waiting == 1 {
            let mut logic = self.axes[last_waiting].logic.borrow_ref_mut(cs);
            if let Some(train) = logic.train() {
                let pin = self.hardware.fast_pin(last_waiting, train.output);
                if let Some(first_ct) = fast.lend(last_waiting, pin, train) {
                    logic.lend_train();
                    next = first_ct;
                }
            } else if let Some((fall, next_ct)) = logic.lend_fall() {
                let output = if fall.pin == 0 {
                    Output::First
                } else {
                    Output::Second
                };
                let pin = self.hardware.fast_pin(last_waiting, output);
                match fast.lend_fall(last_waiting, pin, fall, next_ct) {
                    Some(first_ct) => next = first_ct,
                    None => logic.take_back_fall(fall, false),
                }
            }
        }
        ((next != NEVER).then_some(next), work)
    }
}

/// What the fast path holds goes back to its axis.
fn give_back(fast: &mut FastTrain, logic: &mut AxisRunner) {
    if let Some((fall, driven)) = fast.take_back_fall() {
        logic.take_back_fall(fall, driven);
        return;
    }
    match fast.take_back() {
        Some(Returned::Train(train, edges)) => logic.take_back(train, &edges),
        Some(Returned::Fall(fall, driven)) => logic.take_back_fall(fall, driven),
        None => {}
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

    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        self.start_group(steps, speed)
    }

    fn after_command(&self) {
        // A member's stop reaches its whole line before the reply.
        critical_section::with(|cs| {
            self.pass_group_stops(cs, self.hardware.now_ticks(), false);
        });
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
