//! The machine: per axis letter its steps per mm, top speed and
//! acceleration, soft limits and home switch; the planner's settings. In
//! mm; [`MachineSpec::planner_machine`] turns it into the planner's steps.
//!
//! A board builds one with [`MachineSpec::new`]; the host reads the TOML
//! machine file with `MachineSpec::from_toml_str` (feature `std`, in
//! [`crate::machine_file`]).

use core::fmt;

use cogstep_motion::planner::{Blending, Machine, MAX_AXES};

/// The axis letters a machine may use, in the usual order.
pub const AXIS_LETTERS: [char; 9] = ['x', 'y', 'z', 'a', 'b', 'c', 'u', 'v', 'w'];

/// The planner's queue length when the machine file does not set one.
pub const DEFAULT_QUEUE_LEN: usize = 32;

/// Which end of an axis its home switch is at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HomeEnd {
    /// At the low end (`home = "min"`): homing moves towards −.
    Min,
    /// At the high end (`home = "max"`): homing moves towards +.
    Max,
}

/// One axis of the machine, in mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisSpec {
    /// The axis letter, lower case (one of [`AXIS_LETTERS`]).
    pub letter: char,
    /// Steps per mm (> 0).
    pub steps_per_mm: f64,
    /// Top speed (mm/s, > 0).
    pub max_speed_mm_s: f64,
    /// Top acceleration (mm/s², > 0).
    pub max_accel_mm_s2: f64,
    /// The lowest machine position a move may end at (mm).
    pub soft_min_mm: Option<f64>,
    /// The highest machine position a move may end at (mm).
    pub soft_max_mm: Option<f64>,
    /// The end the home switch is at, if the axis has one.
    pub home: Option<HomeEnd>,
    /// The homing seek speed (mm/s, > 0); only with `home`.
    pub home_speed_mm_s: Option<f64>,
}

impl AxisSpec {
    /// An axis with no soft limits and no home switch.
    pub const fn new(
        letter: char,
        steps_per_mm: f64,
        max_speed_mm_s: f64,
        max_accel_mm_s2: f64,
    ) -> Self {
        AxisSpec {
            letter,
            steps_per_mm,
            max_speed_mm_s,
            max_accel_mm_s2,
            soft_min_mm: None,
            soft_max_mm: None,
            home: None,
            home_speed_mm_s: None,
        }
    }

    /// The machine position (mm) the axis is at after homing: the home
    /// switch's point is the soft limit at its end, or 0 where that end
    /// has none. `None` without a home switch.
    pub fn home_position_mm(&self) -> Option<f64> {
        match self.home? {
            HomeEnd::Min => Some(self.soft_min_mm.unwrap_or(0.0)),
            HomeEnd::Max => Some(self.soft_max_mm.unwrap_or(0.0)),
        }
    }
}

/// The planner's settings, in mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannerSpec {
    /// grbl's junction deviation δ (mm, ≥ 0; 0 stops at every corner).
    pub junction_deviation_mm: f64,
    /// The largest distance between an arc and its chords (mm, > 0).
    pub arc_tolerance_mm: f64,
    /// The look-ahead queue's length in lines (≥ 1).
    pub queue_len: usize,
}

/// A key of the machine file, as an error names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    /// A table: `axes` or `planner`.
    Table(&'static str),
    /// One axis's table: `[axes.<letter>]`.
    AxisTable(char),
    /// A key of one axis's table: `axes.<letter>.<name>`.
    Axis(char, &'static str),
    /// A key of the planner table: `planner.<name>`.
    Planner(&'static str),
}

impl fmt::Display for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Key::Table(name) => write!(f, "[{name}]"),
            Key::AxisTable(letter) => write!(f, "[axes.{letter}]"),
            Key::Axis(letter, name) => write!(f, "axes.{letter}.{name}"),
            Key::Planner(name) => write!(f, "planner.{name}"),
        }
    }
}

/// A machine file or machine that cannot be used; each names its key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MachineError {
    /// The file is not TOML (the line is 1-based).
    #[cfg(feature = "std")]
    #[error("the machine file is not valid TOML (line {line}): {message}")]
    Toml {
        /// The line of the error, 1-based (0 when the parser gives none).
        line: usize,
        /// The TOML parser's message.
        message: std::string::String,
    },
    /// A key that is not in the machine file's form.
    #[cfg(feature = "std")]
    #[error("unknown key {0}")]
    UnknownKey(std::string::String),
    /// An `[axes.…]` table whose name is not an axis letter.
    #[cfg(feature = "std")]
    #[error("unknown axis {0:?} (the axis letters are x y z a b c u v w, lower case)")]
    UnknownAxis(std::string::String),
    /// A required key or table is missing.
    #[error("{0} is missing")]
    Missing(Key),
    /// A key whose value has the wrong type (a number, a string or a table
    /// was expected).
    #[error("{key} must be {expected}")]
    WrongType {
        /// The key.
        key: Key,
        /// What it must be: "a number", "a table", ...
        expected: &'static str,
    },
    /// A value that must be above 0 and finite.
    #[error("{key} must be above 0 and finite (it is {value})")]
    NotPositive {
        /// The key.
        key: Key,
        /// Its value.
        value: f64,
    },
    /// A value that must be 0 or more and finite.
    #[error("{key} must be 0 or more and finite (it is {value})")]
    Negative {
        /// The key.
        key: Key,
        /// Its value.
        value: f64,
    },
    /// A soft limit that is not finite.
    #[error("{key} must be finite (it is {value})")]
    NotFinite {
        /// The key.
        key: Key,
        /// Its value.
        value: f64,
    },
    /// A soft minimum at or above the soft maximum.
    #[error("axes.{axis}.soft_min_mm ({min}) must be below axes.{axis}.soft_max_mm ({max})")]
    SoftLimits {
        /// The axis letter.
        axis: char,
        /// The soft minimum (mm).
        min: f64,
        /// The soft maximum (mm).
        max: f64,
    },
    /// `home` is neither `"min"` nor `"max"`.
    #[error("axes.{0}.home must be \"min\" or \"max\"")]
    Home(char),
    /// `home_speed_mm_s` on an axis without `home`.
    #[error("axes.{0}.home_speed_mm_s is set but axes.{0}.home is not")]
    HomeSpeedWithoutHome(char),
    /// An axis letter that is not one of [`AXIS_LETTERS`] (`new`).
    #[error("axis letter {0:?} is not one of x y z a b c u v w")]
    AxisLetter(char),
    /// The same axis letter twice.
    #[error("axis {0} appears twice")]
    DuplicateAxis(char),
    /// No axes, or more than 8.
    #[error("a machine has 1 to 8 axes (this one has {0})")]
    AxisCount(usize),
    /// `queue_len` is not a whole number of 1 or more.
    #[error("planner.queue_len must be a whole number of 1 or more")]
    QueueLen,
}

/// The machine: 1 to 8 axes in the machine file's order, and the planner's
/// settings. Plain data (`Copy`), no allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineSpec {
    axes: [AxisSpec; MAX_AXES],
    letters: [char; MAX_AXES],
    axis_count: usize,
    planner: PlannerSpec,
}

impl MachineSpec {
    /// A machine of `axes` (in this order) and the planner's settings,
    /// checked as the machine file is.
    pub fn new(axes: &[AxisSpec], planner: PlannerSpec) -> Result<MachineSpec, MachineError> {
        if axes.is_empty() || axes.len() > MAX_AXES {
            return Err(MachineError::AxisCount(axes.len()));
        }
        for (index, axis) in axes.iter().enumerate() {
            check_axis(axis)?;
            if axes[..index]
                .iter()
                .any(|other| other.letter == axis.letter)
            {
                return Err(MachineError::DuplicateAxis(axis.letter));
            }
        }
        let deviation = planner.junction_deviation_mm;
        if !(deviation >= 0.0 && deviation.is_finite()) {
            return Err(MachineError::Negative {
                key: Key::Planner("junction_deviation_mm"),
                value: deviation,
            });
        }
        positive(Key::Planner("arc_tolerance_mm"), planner.arc_tolerance_mm)?;
        if planner.queue_len == 0 {
            return Err(MachineError::QueueLen);
        }
        let mut all = [axes[0]; MAX_AXES];
        let mut letters = [axes[0].letter; MAX_AXES];
        for (index, axis) in axes.iter().enumerate() {
            all[index] = *axis;
            letters[index] = axis.letter;
        }
        Ok(MachineSpec {
            axes: all,
            letters,
            axis_count: axes.len(),
            planner,
        })
    }

    /// The axes, in the machine file's order.
    pub fn axes(&self) -> &[AxisSpec] {
        &self.axes[..self.axis_count]
    }

    /// The number of axes (1 to 8).
    pub fn axis_count(&self) -> usize {
        self.axis_count
    }

    /// The axis letters (lower case), in the machine file's order: the
    /// order of every per-axis array of this crate.
    pub fn letters(&self) -> &[char] {
        &self.letters[..self.axis_count]
    }

    /// The index of the axis `letter` (either case), if the machine has it.
    pub fn axis_index(&self, letter: char) -> Option<usize> {
        let letter = letter.to_ascii_lowercase();
        self.letters().iter().position(|&own| own == letter)
    }

    /// The planner's settings.
    pub fn planner(&self) -> &PlannerSpec {
        &self.planner
    }

    /// The axes with a home switch, as a bitmask (bit `i` for axis `i`).
    pub fn homable_axes(&self) -> u8 {
        self.axes()
            .iter()
            .enumerate()
            .filter(|(_, axis)| axis.home.is_some())
            .fold(0, |mask, (index, _)| mask | 1 << index)
    }

    /// The junction deviation in steps: δ (mm) times the **smallest**
    /// steps/mm of the machine's axes. A path error of `d` steps in step
    /// space is at most `d / min(steps/mm)` mm, so the corners never
    /// deviate more than δ mm, however unequal the axes' steps/mm.
    pub fn junction_deviation_steps(&self) -> f64 {
        let smallest = self
            .axes()
            .iter()
            .map(|axis| axis.steps_per_mm)
            .fold(f64::INFINITY, f64::min);
        self.planner.junction_deviation_mm * smallest
    }

    /// The planner's machine in steps (steps/s and steps/s² per axis, the
    /// junction deviation as [`Self::junction_deviation_steps`], blending
    /// on: G64 until a G61). `N` is at least [`Self::axis_count`]; axes
    /// past the machine's never move (their steps are always 0) and get
    /// the first axis's limits, so that the planner takes the machine.
    ///
    /// # Panics
    ///
    /// If `N` is below the machine's axis count or above 8
    /// ([`Self::try_planner_machine`] does not panic).
    pub fn planner_machine<const N: usize>(&self) -> Machine<N> {
        self.try_planner_machine().unwrap_or_else(|| {
            panic!(
                "planner_machine::<{N}> for a machine of {} axes",
                self.axis_count
            )
        })
    }

    /// [`Self::planner_machine`], or `None` if `N` is below the machine's
    /// axis count or above 8.
    pub fn try_planner_machine<const N: usize>(&self) -> Option<Machine<N>> {
        if N < self.axis_count || N > MAX_AXES {
            return None;
        }
        let mut max_speed_steps_per_s = [0.0; N];
        let mut max_accel_steps_per_s2 = [0.0; N];
        for index in 0..N {
            let axis = self.axes.get(index).filter(|_| index < self.axis_count);
            let axis = axis.unwrap_or(&self.axes[0]);
            max_speed_steps_per_s[index] = axis.max_speed_mm_s * axis.steps_per_mm;
            max_accel_steps_per_s2[index] = axis.max_accel_mm_s2 * axis.steps_per_mm;
        }
        Some(Machine {
            max_speed_steps_per_s,
            max_accel_steps_per_s2,
            junction_deviation_steps: self.junction_deviation_steps(),
            blending: Blending::Blend,
        })
    }
}

fn check_axis(axis: &AxisSpec) -> Result<(), MachineError> {
    let letter = axis.letter;
    if !AXIS_LETTERS.contains(&letter) {
        return Err(MachineError::AxisLetter(letter));
    }
    positive(Key::Axis(letter, "steps_per_mm"), axis.steps_per_mm)?;
    positive(Key::Axis(letter, "max_speed_mm_s"), axis.max_speed_mm_s)?;
    positive(Key::Axis(letter, "max_accel_mm_s2"), axis.max_accel_mm_s2)?;
    for (name, value) in [
        ("soft_min_mm", axis.soft_min_mm),
        ("soft_max_mm", axis.soft_max_mm),
    ] {
        if let Some(value) = value.filter(|value| !value.is_finite()) {
            return Err(MachineError::NotFinite {
                key: Key::Axis(letter, name),
                value,
            });
        }
    }
    if let (Some(min), Some(max)) = (axis.soft_min_mm, axis.soft_max_mm) {
        if min >= max {
            return Err(MachineError::SoftLimits {
                axis: letter,
                min,
                max,
            });
        }
    }
    if let Some(speed) = axis.home_speed_mm_s {
        if axis.home.is_none() {
            return Err(MachineError::HomeSpeedWithoutHome(letter));
        }
        positive(Key::Axis(letter, "home_speed_mm_s"), speed)?;
    }
    Ok(())
}

fn positive(key: Key, value: f64) -> Result<(), MachineError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(MachineError::NotPositive { key, value })
    }
}
