//! What a G-code line yields: lines in steps, dwells, homing, the blending
//! mode, pauses and the end.

use cogstep_motion::planner::{Blending, Line, MAX_AXES};

/// One thing for the machine to do, from one G-code line. Per-axis arrays
/// are in the machine file's axis order; entries past the machine's axes
/// are 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Block {
    /// A straight move (G0, G1, or one chord of a G2/G3 arc).
    Line {
        /// The G-code line it comes from.
        line: u32,
        /// The signed steps per axis: `target_steps` minus the target
        /// before.
        steps: [i32; MAX_AXES],
        /// The absolute position in steps after this block: the programmed
        /// end point in machine mm times steps/mm, rounded half away from
        /// zero (so the rounding never accumulates).
        target_steps: [i64; MAX_AXES],
        /// The speed along the path (mm/s); `f64::INFINITY` for a rapid,
        /// which only the axes' limits hold.
        feed_mm_s: f64,
        /// The length of the move in mm: the steps per axis over
        /// steps/mm, all axes (> 0).
        length_mm: f64,
        /// Whether this is a G0 rapid.
        rapid: bool,
    },
    /// G4: wait (seconds, ≥ 0) after the moves before it.
    Dwell {
        /// The G-code line.
        line: u32,
        /// How long (s).
        seconds: f64,
    },
    /// G28: home the axes of the bitmask (bit `i` for axis `i`): those
    /// named on the line (each must have a home switch:
    /// [`crate::GcodeErrorKind::NoHomeSwitch`] otherwise), or every axis
    /// with one when none is named. Afterwards each is at its
    /// [`crate::AxisSpec::home_position_mm`].
    Home {
        /// The G-code line.
        line: u32,
        /// The axes to home.
        axes: u8,
    },
    /// G61 (exact stop) or G64 (blending) for the lines after it.
    Blending {
        /// The G-code line.
        line: u32,
        /// The mode.
        mode: Blending,
    },
    /// M0: stop after the moves before it until resumed.
    Pause {
        /// The G-code line.
        line: u32,
    },
    /// M2 or M30: the program's end.
    End {
        /// The G-code line.
        line: u32,
    },
}

impl Block {
    /// The G-code line the block comes from.
    pub fn line(&self) -> u32 {
        match *self {
            Block::Line { line, .. }
            | Block::Dwell { line, .. }
            | Block::Home { line, .. }
            | Block::Blending { line, .. }
            | Block::Pause { line }
            | Block::End { line } => line,
        }
    }

    /// A [`Block::Line`] as the planner's line of `N` axes: the first `N`
    /// axes' steps, the feed in lead steps/s, `L · feed_mm_s / length_mm`
    /// (`L` the largest `|steps|`), `f64::INFINITY` for a rapid. `None`
    /// for any other block, or if an axis from `N` on moves.
    pub fn to_planner_line<const N: usize>(&self) -> Option<Line<N>> {
        let Block::Line {
            steps,
            feed_mm_s,
            length_mm,
            rapid,
            ..
        } = *self
        else {
            return None;
        };
        if steps.iter().skip(N).any(|&axis_steps| axis_steps != 0) {
            return None;
        }
        let mut line_steps = [0; N];
        for (own, &axis_steps) in line_steps.iter_mut().zip(&steps) {
            *own = axis_steps;
        }
        let lead = steps.iter().map(|s| s.unsigned_abs()).max().unwrap_or(0);
        if lead == 0 {
            return None;
        }
        let feed_steps_per_s = if rapid || !feed_mm_s.is_finite() {
            f64::INFINITY
        } else {
            f64::from(lead) * feed_mm_s / length_mm
        };
        Some(Line {
            steps: line_steps,
            feed_steps_per_s,
        })
    }
}
