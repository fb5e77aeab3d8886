//! Arcs in the XY plane as chords: the circle, the sweep, and how many
//! chords keep the sagitta (the chord-to-arc distance) within the
//! tolerance.
//!
//! A chord of turn `φ` on a circle of radius `r` is `r·(1 − cos(φ/2)) =
//! 2r·sin²(φ/4)` from the arc at its middle, so the largest turn within a
//! tolerance `t` is `φ_max = 4·asin(√(t/2r))` (no cancellation for small
//! `t/r`, unlike `2·acos(1 − t/r)`). An arc of sweep `Φ` gets `n =
//! ⌈|Φ|/φ_max⌉` equal chords, at least one per quarter turn (so that a
//! full circle is never one chord back to its start). Every point is
//! computed from the centre and its own angle (no rotation carried from
//! chord to chord, so no drift), and the last one is the programmed end
//! exactly.

use core::f64::consts::{FRAC_PI_2, PI, TAU};

/// The most chords one arc may have (a larger count is a number out of
/// range: a radius of kilometres at a micrometre's tolerance).
pub const MAX_ARC_CHORDS: u32 = 1 << 20;

/// grbl's: an I/J arc whose end is within this angle (rad) of its start is
/// a full circle.
const FULL_CIRCLE_EPSILON: f64 = 5e-7;

/// grbl's tolerance for an arc's end off its circle: more than 0.5 mm is
/// always an error; more than 0.005 mm is one when it is also more than
/// 0.1 % of the radius.
pub const RADIUS_ERROR_MAX_MM: f64 = 0.5;
/// See [`RADIUS_ERROR_MAX_MM`].
pub const RADIUS_ERROR_MM: f64 = 0.005;
/// See [`RADIUS_ERROR_MAX_MM`].
pub const RADIUS_ERROR_FRACTION: f64 = 0.001;

/// Which way an arc turns, seen from +Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Turn {
    /// G2.
    Clockwise,
    /// G3.
    CounterClockwise,
}

/// What is wrong with an arc's geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArcFault {
    /// The radius is 0.
    ZeroRadius,
    /// The end is off the circle beyond the tolerance.
    RadiusMismatch,
    /// An R arc that ends at its start.
    EndIsStart,
    /// More than [`MAX_ARC_CHORDS`] chords.
    TooManyChords,
}

/// An arc in the XY plane (mm), cut into chords.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcPath {
    /// The centre.
    pub centre: [f64; 2],
    /// The radius the chords' points are on (the start's distance from
    /// the centre).
    pub radius: f64,
    /// The start's angle from the centre (rad).
    pub start_angle: f64,
    /// The signed sweep (rad): negative clockwise; up to a full turn.
    pub sweep: f64,
    /// The programmed end (the last chord's end, exactly).
    pub end: [f64; 2],
    /// The number of chords (≥ 1).
    pub chords: u32,
}

fn within_radius_tolerance(error_mm: f64, radius: f64) -> bool {
    error_mm <= RADIUS_ERROR_MAX_MM
        && (error_mm <= RADIUS_ERROR_MM || error_mm <= RADIUS_ERROR_FRACTION * radius)
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    libm::hypot(b[0] - a[0], b[1] - a[1])
}

impl ArcPath {
    /// The arc from `start` to `end` around `start + offset` (the I/J
    /// form); `end == start` is a full circle.
    pub fn from_centre(
        start: [f64; 2],
        end: [f64; 2],
        offset: [f64; 2],
        turn: Turn,
        tolerance_mm: f64,
    ) -> Result<ArcPath, ArcFault> {
        let centre = [start[0] + offset[0], start[1] + offset[1]];
        let radius = distance(centre, start);
        if radius == 0.0 || !radius.is_finite() {
            return Err(ArcFault::ZeroRadius);
        }
        if !within_radius_tolerance((distance(centre, end) - radius).abs(), radius) {
            return Err(ArcFault::RadiusMismatch);
        }
        let start_angle = angle(centre, start);
        let mut sweep = angle(centre, end) - start_angle;
        match turn {
            Turn::Clockwise if sweep >= -FULL_CIRCLE_EPSILON => sweep -= TAU,
            Turn::CounterClockwise if sweep <= FULL_CIRCLE_EPSILON => sweep += TAU,
            _ => {}
        }
        Self::with_chords(centre, radius, start_angle, sweep, end, tolerance_mm)
    }

    /// The arc from `start` to `end` of radius `|radius|` (the R form):
    /// the short way (at most half a turn) for `radius > 0`, the long way
    /// for `radius < 0`. An end just beyond the diameter (within the radius
    /// tolerance) is taken as a half circle.
    pub fn from_radius(
        start: [f64; 2],
        end: [f64; 2],
        radius: f64,
        turn: Turn,
        tolerance_mm: f64,
    ) -> Result<ArcPath, ArcFault> {
        let size = radius.abs();
        if size == 0.0 || !size.is_finite() {
            return Err(ArcFault::ZeroRadius);
        }
        let chord = distance(start, end);
        if chord == 0.0 {
            return Err(ArcFault::EndIsStart);
        }
        let half = chord / 2.0;
        let (size, rise) = if half > size {
            if !within_radius_tolerance(half - size, size) {
                return Err(ArcFault::RadiusMismatch);
            }
            (half, 0.0)
        } else {
            (size, libm::sqrt((size - half) * (size + half)))
        };
        let unit = [(end[0] - start[0]) / chord, (end[1] - start[1]) / chord];
        // Clockwise the short arc's centre is on the right of the chord,
        // counter-clockwise on its left; the long arc's on the other side.
        let right = matches!(turn, Turn::Clockwise) == (radius > 0.0);
        let side = if right {
            [unit[1], -unit[0]]
        } else {
            [-unit[1], unit[0]]
        };
        let middle = [(start[0] + end[0]) / 2.0, (start[1] + end[1]) / 2.0];
        let centre = [middle[0] + rise * side[0], middle[1] + rise * side[1]];
        let short = 2.0 * libm::asin((half / size).min(1.0));
        let magnitude = if radius > 0.0 { short } else { TAU - short };
        let sweep = match turn {
            Turn::Clockwise => -magnitude,
            Turn::CounterClockwise => magnitude,
        };
        let start_angle = angle(centre, start);
        Self::with_chords(centre, size, start_angle, sweep, end, tolerance_mm)
    }

    fn with_chords(
        centre: [f64; 2],
        radius: f64,
        start_angle: f64,
        sweep: f64,
        end: [f64; 2],
        tolerance_mm: f64,
    ) -> Result<ArcPath, ArcFault> {
        let chords = chord_count(radius, sweep, tolerance_mm).ok_or(ArcFault::TooManyChords)?;
        Ok(ArcPath {
            centre,
            radius,
            start_angle,
            sweep,
            end,
            chords,
        })
    }

    /// The end of chord `index` (0-based, below [`Self::chords`]): on the
    /// circle, except the last, which is the programmed end.
    pub fn point(&self, index: u32) -> [f64; 2] {
        if index + 1 >= self.chords {
            return self.end;
        }
        let fraction = f64::from(index + 1) / f64::from(self.chords);
        let theta = self.start_angle + self.sweep * fraction;
        // The P2 CORDIC's table (within 2^-40 of the exact values: a
        // nanometre off on a radius of a kilometre), a fifth of `libm`'s
        // cycles where `f64` is software: an arc's chords are all computed
        // in one turn of a board's main loop, twice (checked, then run).
        let (sin, cos) = cordic_core::sin_cos(theta);
        [
            self.centre[0] + self.radius * cos,
            self.centre[1] + self.radius * sin,
        ]
    }

    /// The arc's length (mm).
    pub fn length_mm(&self) -> f64 {
        self.radius * self.sweep.abs()
    }
}

fn angle(centre: [f64; 2], point: [f64; 2]) -> f64 {
    libm::atan2(point[1] - centre[1], point[0] - centre[0])
}

/// The chords for a sweep on a circle of `radius` with sagittas within
/// `tolerance_mm`; `None` beyond [`MAX_ARC_CHORDS`].
pub fn chord_count(radius: f64, sweep: f64, tolerance_mm: f64) -> Option<u32> {
    let ratio = libm::sqrt(tolerance_mm / (2.0 * radius));
    // A hair under the largest turn, so that rounding never puts a
    // sagitta above the tolerance.
    let max_turn = if ratio >= 1.0 {
        PI
    } else {
        4.0 * libm::asin(ratio) * (1.0 - 1e-6)
    }
    .min(FRAC_PI_2);
    let chords = libm::ceil(sweep.abs() / max_turn).max(1.0);
    if chords.is_nan() || chords > f64::from(MAX_ARC_CHORDS) {
        return None;
    }
    // At most MAX_ARC_CHORDS, checked above.
    Some(chords as u32)
}

/// The sagitta of a chord of turn `turn` (rad) on a circle of `radius`.
pub fn sagitta(radius: f64, turn: f64) -> f64 {
    let quarter = libm::sin(turn / 4.0);
    2.0 * radius * quarter * quarter
}
