//! The programmed path, piece by piece, and a point's distance from it.
//!
//! Each planner line the export pushes is one [`Piece`]: a straight line
//! between two programmed points (mm, every axis), or one chord's share of
//! an arc's true circle (G2/G3 in XY, the other axes linear along it).
//! The stepped position is measured against the pieces around the line it
//! is in, so a corner (where two pieces meet) and a chord of an arc (whose
//! circle bulges past it by up to the arc tolerance) are measured as
//! programmed.

use cogstep_motion::planner::MAX_AXES;

/// An arc's circle in the XY plane (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// The axes (indices in the machine's order) of X and Y.
    pub axes: [usize; 2],
    /// The centre (mm).
    pub centre: [f64; 2],
    /// The radius (mm, > 0).
    pub radius: f64,
}

/// One programmed piece of the path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// Where it starts (mm, every axis).
    pub start_mm: [f64; MAX_AXES],
    /// Where it ends (mm, every axis).
    pub end_mm: [f64; MAX_AXES],
    /// For a chord of an arc: the circle it stands for.
    pub circle: Option<Circle>,
}

impl Piece {
    /// The distance (mm) from `point` to the piece, over the first `axes`
    /// axes.
    pub fn distance_mm(&self, point: &[f64; MAX_AXES], axes: usize) -> f64 {
        match self.circle {
            None => segment_distance(&self.start_mm, &self.end_mm, point, axes),
            Some(circle) => self.arc_distance(&circle, point, axes),
        }
    }

    /// The distance to the circle's arc from this chord's start to its end
    /// (the short way round), the other axes linear in the angle.
    fn arc_distance(&self, circle: &Circle, point: &[f64; MAX_AXES], axes: usize) -> f64 {
        let [ix, iy] = circle.axes;
        let angle =
            |p: &[f64; MAX_AXES]| (p[iy] - circle.centre[1]).atan2(p[ix] - circle.centre[0]);
        let start = angle(&self.start_mm);
        let sweep = wrap(angle(&self.end_mm) - start);
        let offset = wrap(angle(point) - start);
        // The fraction of the chord's turn the point is at, held to the piece.
        let fraction = if sweep.abs() < 1e-15 {
            0.0
        } else {
            (offset / sweep).clamp(0.0, 1.0)
        };
        let on_circle = start + fraction * sweep;
        let mut nearest = [0.0; MAX_AXES];
        for (axis, value) in nearest.iter_mut().enumerate().take(axes) {
            *value = self.start_mm[axis] + fraction * (self.end_mm[axis] - self.start_mm[axis]);
        }
        nearest[ix] = circle.centre[0] + circle.radius * on_circle.cos();
        nearest[iy] = circle.centre[1] + circle.radius * on_circle.sin();
        let mut squares = 0.0;
        for axis in 0..axes {
            let d = point[axis] - nearest[axis];
            squares += d * d;
        }
        squares.sqrt()
    }
}

/// An angle in (−π, π].
fn wrap(angle: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let mut a = angle % TAU;
    if a > PI {
        a -= TAU;
    } else if a <= -PI {
        a += TAU;
    }
    a
}

/// The distance from `point` to the segment from `a` to `b`.
fn segment_distance(
    a: &[f64; MAX_AXES],
    b: &[f64; MAX_AXES],
    point: &[f64; MAX_AXES],
    axes: usize,
) -> f64 {
    let (mut along, mut length2) = (0.0, 0.0);
    for axis in 0..axes {
        let d = b[axis] - a[axis];
        along += (point[axis] - a[axis]) * d;
        length2 += d * d;
    }
    let fraction = if length2 > 0.0 {
        (along / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut squares = 0.0;
    for axis in 0..axes {
        let nearest = a[axis] + fraction * (b[axis] - a[axis]);
        let d = point[axis] - nearest;
        squares += d * d;
    }
    squares.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64, y: f64) -> [f64; MAX_AXES] {
        let mut p = [0.0; MAX_AXES];
        p[0] = x;
        p[1] = y;
        p
    }

    #[test]
    fn a_segment_measures_to_its_nearest_point() {
        let piece = Piece {
            start_mm: at(0.0, 0.0),
            end_mm: at(10.0, 0.0),
            circle: None,
        };
        assert_eq!(piece.distance_mm(&at(5.0, 2.0), 2), 2.0);
        assert_eq!(piece.distance_mm(&at(13.0, 4.0), 2), 5.0);
        assert_eq!(piece.distance_mm(&at(-3.0, 0.0), 2), 3.0);
    }

    #[test]
    fn a_chord_of_an_arc_measures_to_the_circle() {
        // A quarter of the unit circle at the origin, anticlockwise.
        let circle = Circle {
            axes: [0, 1],
            centre: [0.0, 0.0],
            radius: 1.0,
        };
        let piece = Piece {
            start_mm: at(1.0, 0.0),
            end_mm: at(0.0, 1.0),
            circle: Some(circle),
        };
        let half = std::f64::consts::FRAC_1_SQRT_2;
        // The chord's middle is 1 − 1/√2 inside the circle.
        let middle = piece.distance_mm(&at(0.5, 0.5), 2);
        assert!((middle - (1.0 - half)).abs() < 1e-12, "{middle}");
        assert!(piece.distance_mm(&at(half, half), 2) < 1e-12);
        // Past the chord's end: to the end point.
        assert!((piece.distance_mm(&at(-1.0, 1.0), 2) - 1.0).abs() < 1e-12);
        // Clockwise the same way.
        let back = Piece {
            start_mm: at(0.0, 1.0),
            end_mm: at(1.0, 0.0),
            circle: Some(circle),
        };
        assert!(back.distance_mm(&at(half, half), 2) < 1e-12);
    }
}
