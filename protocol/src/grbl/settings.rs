//! The `$N=value` settings, with grbl's numbers, defaults and checks.
//!
//! Only the settings that exist in cogstep's machine model are here; `$$`
//! lists them in grbl's order and a number not among them is `error:3`.

use core::fmt;

use super::codes::GrblError;
use super::GRBL_AXES;

/// A board's settings (grbl's defaults: [`Settings::default`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// `$10`: status report mask; bit 0 MPos (else WPos), bit 1 `Bf:`.
    pub status_report_mask: u8,
    /// `$11`: junction deviation, mm.
    pub junction_deviation_mm: f64,
    /// `$12`: arc tolerance, mm.
    pub arc_tolerance_mm: f64,
    /// `$13`: report inches.
    pub report_inches: bool,
    /// `$20`: soft limits.
    pub soft_limits: bool,
    /// `$21`: hard limits.
    pub hard_limits: bool,
    /// `$22`: homing cycle.
    pub homing: bool,
    /// `$23`: homing direction invert mask.
    pub homing_dir_mask: u8,
    /// `$24`: homing feed, mm/min.
    pub homing_feed_mm_min: f64,
    /// `$25`: homing seek, mm/min.
    pub homing_seek_mm_min: f64,
    /// `$27`: homing pull-off, mm.
    pub homing_pull_off_mm: f64,
    /// `$100`–`$102`: steps per mm.
    pub steps_per_mm: [f64; GRBL_AXES],
    /// `$110`–`$112`: max rate, mm/min.
    pub max_rate_mm_min: [f64; GRBL_AXES],
    /// `$120`–`$122`: acceleration, mm/s².
    pub accel_mm_s2: [f64; GRBL_AXES],
    /// `$130`–`$132`: max travel, mm.
    pub max_travel_mm: [f64; GRBL_AXES],
}

impl Default for Settings {
    /// grbl 1.1's generic defaults.
    fn default() -> Self {
        Settings {
            status_report_mask: 1,
            junction_deviation_mm: 0.010,
            arc_tolerance_mm: 0.002,
            report_inches: false,
            soft_limits: false,
            hard_limits: false,
            homing: false,
            homing_dir_mask: 0,
            homing_feed_mm_min: 25.0,
            homing_seek_mm_min: 500.0,
            homing_pull_off_mm: 1.0,
            steps_per_mm: [250.0; GRBL_AXES],
            max_rate_mm_min: [500.0; GRBL_AXES],
            accel_mm_s2: [10.0; GRBL_AXES],
            max_travel_mm: [200.0; GRBL_AXES],
        }
    }
}

/// The setting numbers, in `$$`'s order.
const NUMBERS: [u16; 23] = [
    10, 11, 12, 13, 20, 21, 22, 23, 24, 25, 27, 100, 101, 102, 110, 111, 112, 120, 121, 122, 130,
    131, 132,
];

/// Why a `$N=value` was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SettingsError(pub GrblError);

impl Settings {
    /// Every setting number this board has, in `$$`'s order.
    pub fn numbers() -> &'static [u16] {
        &NUMBERS
    }

    /// The value of setting `number`, if the board has it.
    pub fn get(&self, number: u16) -> Option<f64> {
        let axis = usize::from(number % 10);
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        Some(match number {
            10 => f64::from(self.status_report_mask),
            11 => self.junction_deviation_mm,
            12 => self.arc_tolerance_mm,
            13 => flag(self.report_inches),
            20 => flag(self.soft_limits),
            21 => flag(self.hard_limits),
            22 => flag(self.homing),
            23 => f64::from(self.homing_dir_mask),
            24 => self.homing_feed_mm_min,
            25 => self.homing_seek_mm_min,
            27 => self.homing_pull_off_mm,
            100..=102 => self.steps_per_mm[axis],
            110..=112 => self.max_rate_mm_min[axis],
            120..=122 => self.accel_mm_s2[axis],
            130..=132 => self.max_travel_mm[axis],
            _ => return None,
        })
    }

    /// Whether setting `number` is an integer (or a flag) rather than a
    /// figure with decimals.
    fn is_integer(number: u16) -> bool {
        matches!(number, 10 | 13 | 20 | 21 | 22 | 23)
    }

    /// Sets `$number=value` with grbl's checks: `error:3` for a number the
    /// board does not have (and, where cogstep is stricter, for a zero
    /// steps/mm, rate, acceleration or arc tolerance), `error:4` for a
    /// negative value, `error:10` for soft limits without homing,
    /// `error:12` when steps/mm × rate passes `max_step_rate_hz`. Integer
    /// settings take the integer part, as grbl does. Turning homing off
    /// turns soft limits off too, as in grbl.
    pub fn set(
        &mut self,
        number: u16,
        value: f64,
        max_step_rate_hz: u32,
    ) -> Result<(), SettingsError> {
        let refuse = |error| Err(SettingsError(error));
        if self.get(number).is_none() {
            return refuse(GrblError::InvalidStatement);
        }
        if value < 0.0 {
            return refuse(GrblError::NegativeValue);
        }
        let axis = usize::from(number % 10);
        let int_value = value as u32;
        let flag = int_value != 0;
        let mask = (int_value & 0xFF) as u8;
        let positive = value > 0.0;
        let step_rate_ok = |steps_per_mm: f64, rate_mm_min: f64| {
            steps_per_mm * rate_mm_min / 60.0 <= f64::from(max_step_rate_hz)
        };
        match number {
            10 => self.status_report_mask = mask,
            11 => self.junction_deviation_mm = value,
            12 if positive => self.arc_tolerance_mm = value,
            13 => self.report_inches = flag,
            20 => {
                if flag && !self.homing {
                    return refuse(GrblError::SoftLimitError);
                }
                self.soft_limits = flag;
            }
            21 => self.hard_limits = flag,
            22 => {
                self.homing = flag;
                if !flag {
                    self.soft_limits = false;
                }
            }
            23 => self.homing_dir_mask = mask,
            24 if positive => self.homing_feed_mm_min = value,
            25 if positive => self.homing_seek_mm_min = value,
            27 => self.homing_pull_off_mm = value,
            100..=102 if positive => {
                if !step_rate_ok(value, self.max_rate_mm_min[axis]) {
                    return refuse(GrblError::MaxStepRateExceeded);
                }
                self.steps_per_mm[axis] = value;
            }
            110..=112 if positive => {
                if !step_rate_ok(self.steps_per_mm[axis], value) {
                    return refuse(GrblError::MaxStepRateExceeded);
                }
                self.max_rate_mm_min[axis] = value;
            }
            120..=122 if positive => self.accel_mm_s2[axis] = value,
            130..=132 => self.max_travel_mm[axis] = value,
            _ => return refuse(GrblError::InvalidStatement),
        }
        Ok(())
    }

    /// Reads a `$N=value` line's part after the `$` (`100=250.5`) and sets
    /// it. A value that does not read is `error:2`.
    pub fn set_from_text(
        &mut self,
        text: &str,
        max_step_rate_hz: u32,
    ) -> Result<(), SettingsError> {
        let (number, value) = text
            .split_once('=')
            .ok_or(SettingsError(GrblError::InvalidStatement))?;
        let number: u16 = number
            .parse()
            .map_err(|_| SettingsError(GrblError::InvalidStatement))?;
        let value = parse_grbl_number(value).ok_or(SettingsError(GrblError::BadNumberFormat))?;
        self.set(number, value, max_step_rate_hz)
    }

    /// One `$N=value` line (grbl's form: integers bare, figures with three
    /// decimals), line end included.
    pub fn write_setting(&self, number: u16, out: &mut impl fmt::Write) -> fmt::Result {
        let Some(value) = self.get(number) else {
            return Ok(());
        };
        if Self::is_integer(number) {
            write!(out, "${number}={}\r\n", value as u32)
        } else {
            write!(out, "${number}={value:.3}\r\n")
        }
    }

    /// `$$`'s lines (without the `ok`).
    pub fn write_all(&self, out: &mut impl fmt::Write) -> fmt::Result {
        for &number in Self::numbers() {
            self.write_setting(number, out)?;
        }
        Ok(())
    }
}

/// A number as grbl reads it: an optional sign, digits, an optional point
/// and digits; no exponent, at least one digit.
pub fn parse_grbl_number(text: &str) -> Option<f64> {
    let bytes = text.as_bytes();
    let digits = bytes
        .strip_prefix(b"-")
        .or_else(|| bytes.strip_prefix(b"+"))
        .unwrap_or(bytes);
    let mut seen_digit = false;
    let mut seen_point = false;
    for &b in digits {
        match b {
            b'0'..=b'9' => seen_digit = true,
            b'.' if !seen_point => seen_point = true,
            _ => return None,
        }
    }
    if !seen_digit {
        return None;
    }
    text.parse().ok()
}
