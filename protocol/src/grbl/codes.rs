//! grbl's numbered replies: `error:N` for a line and `ALARM:N` for the machine.

use core::fmt;

/// A line's refusal, `error:N` with grbl 1.1's numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum GrblError {
    /// A word without its letter, or a line that does not start with a letter.
    ExpectedCommandLetter = 1,
    /// A number that does not read.
    BadNumberFormat = 2,
    /// A `$` command grbl does not know.
    InvalidStatement = 3,
    /// A negative value for a setting that must not be negative.
    NegativeValue = 4,
    /// `$H` with homing disabled (`$22=0`).
    SettingDisabled = 5,
    /// A `$` command that needs the machine idle.
    IdleError = 8,
    /// G-code locked out: the machine is in Alarm (or a jog runs).
    SystemGcLock = 9,
    /// Soft limits need homing enabled.
    SoftLimitError = 10,
    /// A line longer than the line buffer.
    Overflow = 11,
    /// Steps/mm × max rate above the board's step rate.
    MaxStepRateExceeded = 12,
    /// A jog target beyond the machine's travel (soft limits on).
    TravelExceeded = 15,
    /// A `$J=` line with a word a jog may not have, or without a feed.
    InvalidJogCommand = 16,
    /// A G or M code the board does not support.
    UnsupportedCommand = 20,
    /// Two words of one modal group in a line.
    ModalGroupViolation = 21,
    /// A feed move without a feed rate.
    UndefinedFeedRate = 22,
    /// A G or M number that must be an integer and is not.
    CommandValueNotInteger = 23,
    /// Two commands that both want the axis words.
    AxisCommandConflict = 24,
    /// A word repeated in one line.
    WordRepeated = 25,
    /// A motion command without axis words.
    NoAxisWords = 26,
    /// A bad `N` line number.
    InvalidLineNumber = 27,
    /// A command without a value word it needs (G4 without P, …).
    ValueWordMissing = 28,
    /// A coordinate system other than those supported.
    UnsupportedCoordSys = 29,
    /// Axis words no command uses.
    AxisWordsExist = 31,
    /// An arc without axis words in its plane.
    NoAxisWordsInPlane = 32,
    /// A target the motion cannot reach (zero-length arc, out of range).
    InvalidTarget = 33,
    /// An arc whose radius does not fit its end points.
    ArcRadiusError = 34,
    /// An arc without offsets in its plane.
    NoOffsetsInPlane = 35,
    /// Words left unused by the line's commands.
    UnusedWords = 36,
}

impl GrblError {
    /// The number after `error:`.
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// `error:N`.
impl fmt::Display for GrblError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "error:{}", self.code())
    }
}

/// Why the machine is locked, `ALARM:N` with grbl 1.1's numbers. The
/// machine stays in Alarm until `$X` or `$H`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum GrblAlarm {
    /// A hard limit switch tripped.
    HardLimit = 1,
    /// A target beyond the machine's travel (soft limits on); nothing moved.
    SoftLimit = 2,
    /// A soft reset while the machine moved.
    AbortCycle = 3,
    /// A soft reset during homing.
    HomingFailReset = 6,
    /// Homing could not pull off the switch.
    HomingFailPulloff = 8,
    /// Homing did not find the switch within its travel.
    HomingFailApproach = 9,
}

impl GrblAlarm {
    /// The number after `ALARM:`.
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// `ALARM:N`.
impl fmt::Display for GrblAlarm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ALARM:{}", self.code())
    }
}
