//! The demo program itself, sans I/O: [`DemoSession`] over a
//! [`DemoMotor`], with the wire time of every byte.

use core::fmt::{self, Write as _};

use super::answer::Answer;
use super::{demo_move, DemoPlan, DemoPrompt, DemoScreen, CLEAR, CR, SPEED_PROMPT, STEPS_PROMPT};

/// The position the demo presets before its first display.
pub const PRESET_POSITION: i32 = 1000;
/// The demo's terminal baud rate (`BR_TERM`); 8N1, so a byte takes 10 bits.
pub const DEMO_BAUD: u32 = 115_200;
/// One byte on the demo's serial line, ns (10 bits at [`DEMO_BAUD`]).
pub const BYTE_NS: u64 = 10 * 1_000_000_000 / DEMO_BAUD as u64;

/// The cog's longs the demo shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CogLongs {
    /// `cpos`.
    pub position: i32,
    /// `modeb` (the display shows its low 6 bits).
    pub mode: u32,
    /// `vel`: written when a deceleration starts.
    pub max_velocity: i32,
}

/// What a board running the demo offers: the driver's cog and its hub
/// longs.
pub trait DemoMotor {
    /// Writes the position long (`long[cpos][0] := 1000`; the cog reads it
    /// when it takes its next command).
    fn preset_position(&mut self, position: i32);
    /// `move()` has written the plan's speed and steps: the cog takes the
    /// command (never if its steps are 0). The demo never refuses.
    fn start_move(&mut self, plan: &DemoPlan);
    /// The mode's bit 0 (moving).
    fn is_moving(&mut self) -> bool;
    /// The cog's longs now.
    fn cog(&mut self) -> CogLongs;
}

/// Where the demo program is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DemoPhase {
    /// Waiting for any key after power-up (`wait_for_terminal`).
    #[default]
    WaitingForKey,
    /// `Enter steps: ` shown, reading an answer.
    EnterSteps,
    /// `Enter speed: ` shown, reading an answer.
    EnterSpeed,
    /// A move runs: displays, no reading.
    Running,
}

/// A [`fmt::Write`] that counts what goes through it.
struct Counting<'a, W: ?Sized> {
    out: &'a mut W,
    bytes: u64,
}

impl<W: fmt::Write + ?Sized> fmt::Write for Counting<'_, W> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        self.bytes += text.len() as u64;
        self.out.write_str(text)
    }
}

/// The demo program (`main()` of `step_driver2_demo.spin2`), sans I/O:
/// feed it every received byte with the time it arrived, and call
/// [`poll`](DemoSession::poll) often (every few ms) with the time.
///
/// Time is in ns since power-up. Printing takes the wire time of its
/// bytes at [`DEMO_BAUD`] (the demo waits for each byte to go out), and
/// received bytes take theirs too: a byte that arrives while the program
/// prints or runs a move lands in the receive pin's one-byte buffer,
/// overwriting the one before, and is read when the program reads again.
#[derive(Clone, Debug, Default)]
pub struct DemoSession {
    phase: DemoPhase,
    answer: Answer,
    steps: i32,
    /// `offset`, `asteps` and `ss` as the last `move()` wrote them.
    plan: DemoPlan,
    start_ms: u32,
    end_ms: u32,
    /// The program prints until then (ns).
    busy_until: u64,
    /// The receive line is free from then (ns).
    line_free: u64,
    /// The receive pin's one-byte buffer.
    latch: Option<u8>,
    /// A display went out: the loop's `while` check comes next.
    check_pending: bool,
}

impl DemoSession {
    /// The program at power-up, waiting for the first key.
    pub fn new() -> Self {
        Self::default()
    }

    /// Where the program is.
    pub fn phase(&self) -> DemoPhase {
        self.phase
    }

    /// When what the program has printed so far has gone out on the wire
    /// (ns since power-up): a board simulator releases its bytes then, so
    /// that a host sees a prompt when the program starts to read.
    pub fn printed_by_ns(&self) -> u64 {
        self.busy_until
    }

    /// Takes one received byte (that reached the board at `now_ns`) and
    /// writes what the board prints in answer.
    pub fn feed<M, W>(&mut self, byte: u8, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let arrival = now_ns.max(self.line_free);
        self.line_free = arrival + BYTE_NS;
        self.catch_up(arrival, motor, out)?;
        if self.phase == DemoPhase::Running || arrival < self.busy_until {
            self.latch = Some(byte);
            return Ok(());
        }
        self.take(byte, arrival, motor, out)
    }

    /// Lets the program run up to `now_ns`: the next display while a move
    /// runs (once the last one has gone out), or, once the move has ended,
    /// clear, the final display and the steps prompt; and a byte waiting
    /// in the receive buffer once the program reads again.
    pub fn poll<M, W>(&mut self, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        self.catch_up(now_ns, motor, out)?;
        if self.phase != DemoPhase::Running || now_ns < self.busy_until {
            return Ok(());
        }
        // `repeat showvalues(); endt := getms() while moving`: the check
        // comes once the display has gone out.
        if core::mem::take(&mut self.check_pending) && !motor.is_moving() {
            let mut counting = Counting { out, bytes: 0 };
            counting.write_char(char::from(CLEAR))?;
            self.show_values(motor, &mut counting)?;
            self.prompt(DemoPrompt::Steps, &mut counting)?;
            self.busy_until = now_ns + counting.bytes * BYTE_NS;
            return Ok(());
        }
        let mut counting = Counting { out, bytes: 0 };
        self.show_values(motor, &mut counting)?;
        self.busy_until = now_ns + counting.bytes * BYTE_NS;
        self.end_ms = ms(self.busy_until);
        self.check_pending = true;
        Ok(())
    }

    /// Reads the byte waiting in the receive buffer once the program
    /// reads again (at most one: a byte read may start more printing).
    fn catch_up<M, W>(&mut self, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        if self.phase == DemoPhase::Running || now_ns < self.busy_until {
            return Ok(());
        }
        match self.latch.take() {
            Some(byte) => self.take(byte, self.busy_until, motor, out),
            None => Ok(()),
        }
    }

    /// The program reads `byte` at `at_ns`.
    fn take<M, W>(&mut self, byte: u8, at_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let mut counting = Counting { out, bytes: 0 };
        match self.phase {
            DemoPhase::WaitingForKey => {
                counting.write_char(char::from(CLEAR))?;
                motor.preset_position(PRESET_POSITION);
                self.show_values(motor, &mut counting)?;
                self.prompt(DemoPrompt::Steps, &mut counting)?;
            }
            DemoPhase::EnterSteps => {
                if let Some(steps) = self.answer.push(byte) {
                    self.steps = steps;
                    self.prompt(DemoPrompt::Speed, &mut counting)?;
                }
            }
            DemoPhase::EnterSpeed => {
                if let Some(answer) = self.answer.push(byte) {
                    let mut speed = answer.wrapping_abs();
                    if speed == 0 {
                        speed = 1;
                    }
                    self.start_ms = ms(at_ns);
                    self.end_ms = self.start_ms;
                    self.plan = demo_move(speed, self.steps);
                    motor.start_move(&self.plan);
                    counting.write_char(char::from(CLEAR))?;
                    self.phase = DemoPhase::Running;
                }
            }
            DemoPhase::Running => {}
        }
        self.busy_until = at_ns + counting.bytes * BYTE_NS;
        Ok(())
    }

    /// `Showvalues()`.
    fn show_values<M, W>(&mut self, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let cog = motor.cog();
        DemoScreen {
            position: cog.position,
            // The low 6 bits: `fbin(mode, 6)`.
            mode_bits: (cog.mode & 0b11_1111) as u8,
            offset_deg: self.plan.offset_deg,
            accel_steps: self.plan.accel_steps,
            slew_steps: self.plan.slew_steps,
            max_velocity_steps_per_s: cog.max_velocity,
            elapsed_ms: self.end_ms.wrapping_sub(self.start_ms) as i32,
        }
        .write_display(out)
    }

    fn prompt<W: fmt::Write + ?Sized>(&mut self, prompt: DemoPrompt, out: &mut W) -> fmt::Result {
        let cr = char::from(CR);
        let (phase, text) = match prompt {
            DemoPrompt::Steps => (DemoPhase::EnterSteps, STEPS_PROMPT),
            DemoPrompt::Speed => (DemoPhase::EnterSpeed, SPEED_PROMPT),
        };
        self.phase = phase;
        self.answer = Answer::default();
        match prompt {
            DemoPrompt::Steps => write!(out, "{cr}{cr}{text}"),
            DemoPrompt::Speed => write!(out, "{cr}{text}"),
        }
    }
}

/// `getms()`: ms since power-up, a wrapping 32-bit count.
fn ms(ns: u64) -> u32 {
    (ns / 1_000_000) as u32
}
