//! `--plot`: velocity and acceleration against time, as PNG or SVG
//! (`plotters`).
//!
//! Two panels share the time axis: velocity (steps/s) above, acceleration
//! (steps/s², the table's, see [`crate::table`]) below. With `--dynamics`
//! the rotor's speed is drawn beside the command's, and a third panel shows
//! the rotor's lag behind the command (steps) with the synchronism limit
//! either side of it. A long move is drawn
//! from at most [`PLOT_POINTS`] of its steps, chosen so that its extremes
//! stay ([`crate::table::Sampler`]).
//!
//! Text is rasterised with `ab_glyph` and Noto Sans Regular embedded in the
//! binary (crate `ttf-noto-sans`), so drawing needs no system font library
//! or installed font; SVG text names the `sans-serif` family and the viewer
//! picks the face.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

use crate::cli::PlotFormat;
use crate::error::ExportError;
use crate::output::PendingFile;
use crate::table::SamplePoint;

/// The most points a panel draws.
pub const PLOT_POINTS: u32 = 4_000;

/// Picture size, pixels.
const SIZE: (u32, u32) = (1200, 800);

/// Draws the plot into `pending` (not yet committed). `end_s` is when the
/// move ends (the last step's edge plus its delay): the last velocity holds
/// until then. `sync_limit_steps`: with the rotor, the lag at which
/// synchronism is lost.
pub fn draw(
    pending: &PendingFile,
    format: PlotFormat,
    title: &str,
    points: &[SamplePoint],
    end_s: f64,
    sync_limit_steps: Option<f64>,
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
            draw_on(&root, title, points, end_s, sync_limit_steps)
                .map_err(|error| fail(error.to_string()))?;
            root.present().map_err(|error| fail(error.to_string()))
        }
        PlotFormat::Svg => {
            let root = SVGBackend::new(path, SIZE).into_drawing_area();
            draw_on(&root, title, points, end_s, sync_limit_steps)
                .map_err(|error| fail(error.to_string()))?;
            root.present().map_err(|error| fail(error.to_string()))
        }
    }
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    points: &[SamplePoint],
    end_s: f64,
    sync_limit_steps: Option<f64>,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 26))?;
    let rotor = points.iter().all(|point| point.rotor.is_some()) && !points.is_empty();
    let panels = root.split_evenly((if rotor { 3 } else { 2 }, 1));
    let end_s = end_s.max(f64::MIN_POSITIVE);
    let mut time: Vec<f64> = points.iter().map(|point| point.time_s).collect();
    let mut velocity: Vec<f64> = points.iter().map(|p| p.velocity_steps_per_s).collect();
    if let Some(last) = points.last() {
        time.push(end_s);
        velocity.push(last.velocity_steps_per_s);
    }
    let mut velocity_series = vec![Series {
        name: "command",
        time: &time,
        values: &velocity,
        colour: BLUE,
    }];
    let rotor_velocity: Vec<f64> = points
        .iter()
        .filter_map(|p| p.rotor.map(|rotor| rotor.velocity_steps_per_s))
        .collect();
    if rotor {
        velocity_series.push(Series {
            name: "rotor",
            time: &time[..rotor_velocity.len()],
            values: &rotor_velocity,
            colour: RGBColor(230, 120, 0),
        });
    }
    panel(
        &panels[0],
        "velocity (steps/s)",
        end_s,
        &velocity_series,
        &[],
    )?;
    // The last step has no next interval, so no acceleration to draw.
    let accel_points = points.len().saturating_sub(1).max(1).min(points.len());
    let accel: Vec<f64> = points[..accel_points]
        .iter()
        .map(|p| p.accel_steps_per_s2)
        .collect();
    let accel_series = [Series {
        name: "command",
        time: &time[..accel_points],
        values: &accel,
        colour: RED,
    }];
    panel(
        &panels[1],
        "acceleration (steps/s²)",
        end_s,
        &accel_series,
        &[],
    )?;
    if rotor {
        let lag: Vec<f64> = points
            .iter()
            .filter_map(|p| p.rotor.map(|rotor| rotor.lag_steps))
            .collect();
        let lag_series = [Series {
            name: "rotor lag",
            time: &time[..lag.len()],
            values: &lag,
            colour: RGBColor(230, 120, 0),
        }];
        let limits: Vec<f64> = sync_limit_steps
            .map(|limit| vec![-limit, limit])
            .unwrap_or_default();
        panel(&panels[2], "rotor lag (steps)", end_s, &lag_series, &limits)?;
    }
    Ok(())
}

/// One line of a panel.
struct Series<'a> {
    name: &'static str,
    time: &'a [f64],
    values: &'a [f64],
    colour: RGBColor,
}

/// A panel: its series (a legend when there are several) and dashed
/// horizontal lines at `marks`.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    quantity: &str,
    end_s: f64,
    series: &[Series],
    marks: &[f64],
) -> DrawResult<DB> {
    let all: Vec<f64> = series
        .iter()
        .flat_map(|line| line.values.iter().copied())
        .chain(marks.iter().copied())
        .collect();
    let (low, high) = value_range(&all);
    let mut chart = ChartBuilder::on(area)
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(96)
        .build_cartesian_2d(0.0..end_s, low..high)?;
    let time_format = |value: &f64| tick_label(*value, end_s);
    let value_format = |value: &f64| tick_label(*value, high - low);
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc(quantity)
        .x_label_formatter(&time_format)
        .y_label_formatter(&value_format)
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()?;
    for &mark in marks {
        chart.draw_series(DashedLineSeries::new(
            [(0.0, mark), (end_s, mark)],
            8,
            6,
            BLACK.mix(0.5).stroke_width(1),
        ))?;
    }
    for line in series {
        let colour = line.colour;
        chart
            .draw_series(LineSeries::new(
                line.time.iter().copied().zip(line.values.iter().copied()),
                colour.stroke_width(2),
            ))?
            .label(line.name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    if series.len() > 1 {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()?;
    }
    Ok(())
}

/// A range that holds every value and 0, with a little room above and below.
fn value_range(values: &[f64]) -> (f64, f64) {
    let (low, high) = values
        .iter()
        .filter(|value| value.is_finite())
        .fold((0.0_f64, 0.0_f64), |(low, high), &value| {
            (low.min(value), high.max(value))
        });
    let span = high - low;
    if span == 0.0 {
        return (-1.0, 1.0);
    }
    let room = span * 0.05;
    (
        if low < 0.0 { low - room } else { low },
        if high > 0.0 { high + room } else { high },
    )
}

/// A tick label with as many decimals as an axis spanning `span` needs.
fn tick_label(value: f64, span: f64) -> String {
    let tick = (span / 10.0).abs();
    let decimals = if tick > 0.0 && tick < 1.0 {
        (-tick.log10()).ceil().clamp(0.0, 9.0) as usize
    } else {
        0
    };
    let text = format!("{value:.decimals$}");
    // "-0" and "-0.00" read as 0.
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        text.trim_start_matches('-').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_fit_the_span() {
        assert_eq!(tick_label(0.2, 1.2), "0.2");
        assert_eq!(tick_label(12_345.6, 20_000.0), "12346");
        assert_eq!(tick_label(0.0004, 0.003), "0.0004");
        assert_eq!(tick_label(-0.0, 1.0), "0.0");
    }

    #[test]
    fn ranges_include_zero() {
        assert_eq!(value_range(&[]), (-1.0, 1.0));
        let (low, high) = value_range(&[100.0, 200.0]);
        assert_eq!(low, 0.0);
        assert!(high > 200.0);
        let (low, high) = value_range(&[-5.0, -1.0]);
        assert!(low < -5.0);
        assert_eq!(high, 0.0);
    }

    fn points() -> Vec<SamplePoint> {
        (0..50)
            .map(|step| SamplePoint {
                step,
                time_s: f64::from(step) * 1e-3,
                velocity_steps_per_s: f64::from(step) * 10.0,
                accel_steps_per_s2: 10_000.0,
                rotor: None,
            })
            .collect()
    }

    #[test]
    fn draws_png_and_svg() {
        let directory = tempfile::tempdir().unwrap();
        for (name, format) in [("v.png", PlotFormat::Png), ("v.svg", PlotFormat::Svg)] {
            let destination = directory.path().join(name);
            let pending = PendingFile::create(&destination).unwrap();
            draw(&pending, format, "test move", &points(), 0.05, None).unwrap();
            pending.commit().unwrap();
            let bytes = std::fs::read(&destination).unwrap();
            match format {
                PlotFormat::Png => assert_eq!(&bytes[1..4], b"PNG"),
                PlotFormat::Svg => {
                    let text = String::from_utf8(bytes).unwrap();
                    assert!(text.contains("<svg"));
                    assert!(text.contains("velocity (steps/s)"));
                    assert!(text.contains("time (s)"));
                }
            }
        }
    }
}
