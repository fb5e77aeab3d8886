//! `gcode --plot`: the XY path coloured by the speed along it, and the
//! speed against time (PNG or SVG, `plotters`, the embedded font as in
//! [`crate::plot`]).
//!
//! The rows are kept as a thinned sample ([`PathSampler`]): every row
//! while there are few, every second, fourth, … as there are more, so
//! memory stays bounded whatever the program's length.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

use super::job::Row;
use crate::cli::PlotFormat;
use crate::error::ExportError;
use crate::output::PendingFile;

/// The most points a sample keeps (twice this before it is thinned).
pub const PATH_POINTS: usize = 6_000;

/// One point of the path: time, X and Y (mm), speed (mm/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// Seconds.
    pub time_s: f64,
    /// X (mm).
    pub x_mm: f64,
    /// Y (mm).
    pub y_mm: f64,
    /// The speed along the path (mm/s).
    pub feed_mm_s: f64,
}

/// Every `stride`-th row, the stride doubling as the rows grow.
#[derive(Clone, Debug)]
pub struct PathSampler {
    xy: [Option<usize>; 2],
    points: Vec<PathPoint>,
    stride: u64,
    seen: u64,
    last: Option<PathPoint>,
}

impl PathSampler {
    /// A sampler drawing axes `xy` (indices; `None`: that axis is drawn at 0).
    pub fn new(xy: [Option<usize>; 2]) -> Self {
        PathSampler {
            xy,
            points: Vec::new(),
            stride: 1,
            seen: 0,
            last: None,
        }
    }

    /// Offers a row.
    pub fn offer(&mut self, row: &Row) {
        let point = PathPoint {
            time_s: row.time_s,
            x_mm: self.xy[0].map_or(0.0, |axis| row.positions_mm[axis]),
            y_mm: self.xy[1].map_or(0.0, |axis| row.positions_mm[axis]),
            feed_mm_s: row.feed_mm_s,
        };
        if self.seen.is_multiple_of(self.stride) {
            self.points.push(point);
            if self.points.len() >= 2 * PATH_POINTS {
                let kept: Vec<PathPoint> = self.points.iter().copied().step_by(2).collect();
                self.points = kept;
                self.stride *= 2;
            }
        }
        self.seen += 1;
        self.last = Some(point);
    }

    /// The points, the last row's included.
    pub fn into_points(mut self) -> Vec<PathPoint> {
        if let Some(last) = self.last {
            if self.points.last() != Some(&last) {
                self.points.push(last);
            }
        }
        self.points
    }
}

/// Picture size, pixels.
const SIZE: (u32, u32) = (1000, 1100);

/// Draws the plot into `pending` (not yet committed).
pub fn draw(
    pending: &PendingFile,
    format: PlotFormat,
    title: &str,
    points: &[PathPoint],
    end_s: f64,
) -> Result<(), ExportError> {
    let fail = |reason: String| ExportError::Plot {
        path: pending.destination().to_path_buf(),
        reason,
    };
    register_font("sans-serif", FontStyle::Normal, ttf_noto_sans::REGULAR)
        .map_err(|_| fail("the embedded font could not be loaded".into()))?;
    let path = pending.temp_path();
    match format {
        PlotFormat::Png => {
            let root = BitMapBackend::new(path, SIZE).into_drawing_area();
            draw_on(&root, title, points, end_s).map_err(|error| fail(error.to_string()))?;
            root.present().map_err(|error| fail(error.to_string()))
        }
        PlotFormat::Svg => {
            let root = SVGBackend::new(path, SIZE).into_drawing_area();
            draw_on(&root, title, points, end_s).map_err(|error| fail(error.to_string()))?;
            root.present().map_err(|error| fail(error.to_string()))
        }
    }
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Slow is blue, fast is red.
fn speed_colour(feed: f64, top: f64) -> HSLColor {
    let fraction = if top > 0.0 {
        (feed / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    HSLColor((1.0 - fraction) * 240.0 / 360.0, 0.9, 0.45)
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    points: &[PathPoint],
    end_s: f64,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 24))?;
    let (upper, lower) = root.split_vertically(720);
    let top = points.iter().map(|p| p.feed_mm_s).fold(0.0f64, f64::max);

    // The path, square in mm.
    let (mut x0, mut x1, mut y0, mut y1) = points.iter().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(x0, x1, y0, y1), p| {
            (
                x0.min(p.x_mm),
                x1.max(p.x_mm),
                y0.min(p.y_mm),
                y1.max(p.y_mm),
            )
        },
    );
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let span = (x1 - x0).max(y1 - y0).max(1e-3) * 1.08;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let mut chart = ChartBuilder::on(&upper)
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .caption(
            format!("XY path, coloured by speed (blue 0 → red {top:.1} mm/s)"),
            ("sans-serif", 18),
        )
        .build_cartesian_2d(
            cx - span / 2.0..cx + span / 2.0,
            cy - span / 2.0..cy + span / 2.0,
        )?;
    chart
        .configure_mesh()
        .x_desc("X (mm)")
        .y_desc("Y (mm)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()?;
    chart.draw_series(points.windows(2).map(|pair| {
        PathElement::new(
            [(pair[0].x_mm, pair[0].y_mm), (pair[1].x_mm, pair[1].y_mm)],
            speed_colour(pair[1].feed_mm_s, top).stroke_width(3),
        )
    }))?;

    // Speed against time.
    let end_s = end_s.max(f64::MIN_POSITIVE);
    let mut speed = ChartBuilder::on(&lower)
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..end_s, 0.0..(top * 1.08).max(1e-3))?;
    speed
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("speed along the path (mm/s)")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()?;
    speed.draw_series(LineSeries::new(
        points.iter().map(|p| (p.time_s, p.feed_mm_s)),
        BLUE.stroke_width(2),
    ))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cogstep_motion::planner::MAX_AXES;

    #[test]
    fn the_sample_stays_bounded_and_keeps_the_end() {
        let mut sampler = PathSampler::new([Some(0), Some(1)]);
        for i in 0..100_000u64 {
            let mut positions_mm = [0.0; MAX_AXES];
            positions_mm[0] = i as f64;
            sampler.offer(&Row {
                ct: i,
                time_s: i as f64,
                line: 1,
                positions: [0; MAX_AXES],
                positions_mm,
                feed_mm_s: 1.0,
                deviation_mm: 0.0,
            });
        }
        let points = sampler.into_points();
        assert!(points.len() <= 2 * PATH_POINTS + 1, "{}", points.len());
        assert!(points.len() >= PATH_POINTS / 2);
        assert_eq!(points.last().unwrap().x_mm, 99_999.0);
        assert_eq!(points[0].x_mm, 0.0);
    }
}
