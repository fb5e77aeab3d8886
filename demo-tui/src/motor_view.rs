//! `--motor`: a virtual motor behind an axis's pins.
//!
//! Each frame, the emulated hub's recorded pin edges go through a driver
//! chip's decoding ([`driver::motor::StepDecoder`]: step/dir or cw/ccw) into
//! the rotor model of [`driver::motor`], at the edges' own clock times; the
//! model then runs on to the present. The selected axis's rotor shows in a
//! line under the header: its lag behind the command, the largest lag so
//! far, and, once the lag has passed half an electrical cycle, "LOST
//! SYNCHRONISM at step N" (N counted from the start of that move): what a
//! real machine would have done. A lost position stays lost, as on a real
//! machine, until the demo is restarted (homed).
//!
//! `--motor FILE` puts the motor of `FILE` (the motor files of
//! `spreadsheet-export`, with `damping_nm_s_per_rad`) behind every axis;
//! `--motor 2=FILE` behind axis 2 only. Later flags win for their axes.

use std::path::PathBuf;

use driver::motor::{PullOutCurve, Rotor, StepDecoder, StepLine, TorquePoints};
use driver::{Edge, Outputs};
use ratatui::style::{Color, Style};
use ratatui::text::{Line, Span};
use spreadsheet_export::motor::Motor;

use crate::app::App;

/// A new move starts when a step follows the last one after this long, s.
const NEW_MOVE_GAP_S: f64 = 0.2;
/// The model stays this far behind the present, s: edges still on their
/// way from a cog's ring are then applied at their own time.
const EDGE_SLACK_S: f64 = 0.002;

/// One `--motor` flag: which axis (all when `None`) and the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MotorSpec {
    /// The axis, from 1; `None`: every axis.
    pub axis: Option<usize>,
    /// The motor file.
    pub path: PathBuf,
}

/// Parses `FILE` or `AXIS=FILE` (clap's value parser for `--motor`).
pub fn parse_motor_spec(text: &str) -> Result<MotorSpec, String> {
    match text.split_once('=') {
        Some((axis, path)) if !axis.is_empty() && axis.chars().all(|c| c.is_ascii_digit()) => {
            let axis: usize = axis
                .parse()
                .map_err(|_| format!("{axis} is not an axis number"))?;
            if !(1..=8).contains(&axis) || path.is_empty() {
                return Err("expected AXIS=FILE with AXIS from 1 to 8, or FILE".into());
            }
            Ok(MotorSpec {
                axis: Some(axis),
                path: PathBuf::from(path),
            })
        }
        _ if text.is_empty() => Err("expected FILE or AXIS=FILE".into()),
        _ => Ok(MotorSpec {
            axis: None,
            path: PathBuf::from(text),
        }),
    }
}

/// A pull-out curve the rotor owns.
#[derive(Clone, Debug)]
struct OwnedCurve(Vec<(f64, f64)>);

impl PullOutCurve for OwnedCurve {
    fn pull_out_nm(&self, rate_steps_per_s: f64) -> f64 {
        TorquePoints::new(&self.0).pull_out_nm(rate_steps_per_s)
    }
}

/// What the screen shows of one axis's rotor.
#[derive(Clone, Debug, PartialEq)]
pub struct RotorReadout {
    /// The motor file's name, without its extension.
    pub name: String,
    /// Lag behind the command now, full steps (signed).
    pub lag_steps: f64,
    /// The largest |lag| so far, full steps.
    pub largest_lag_steps: f64,
    /// The lag at which synchronism is lost, full steps.
    pub limit_steps: f64,
    /// Where synchronism was lost: the step of its move (from 0).
    pub lost_at_step: Option<u64>,
}

/// One axis's motor.
#[derive(Clone, Debug)]
struct AxisMotor {
    name: String,
    rotor: Rotor<OwnedCurve>,
    decoder: StepDecoder,
    pins: [(u8, StepLine); 2],
    /// When the last step came, s (model time).
    last_step_s: Option<f64>,
    /// The rotor's step count when the current move began.
    move_start: u64,
    largest_lag_steps: f64,
    lost_at_step: Option<u64>,
}

impl AxisMotor {
    fn step(&mut self, at_s: f64, forward: bool) {
        self.rotor.run_until(at_s);
        if self
            .last_step_s
            .is_none_or(|last| at_s - last > NEW_MOVE_GAP_S)
        {
            self.move_start = self.rotor.steps_seen();
        }
        self.last_step_s = Some(at_s);
        self.rotor.step(forward);
        self.note();
    }

    fn run_until(&mut self, at_s: f64) {
        self.rotor.run_until(at_s);
        self.note();
    }

    fn note(&mut self) {
        let lag = self.rotor.error_steps().abs();
        self.largest_lag_steps = self.largest_lag_steps.max(lag);
        if self.lost_at_step.is_none() {
            self.lost_at_step = self
                .rotor
                .lost_at_step()
                .map(|step| step.saturating_sub(self.move_start));
        }
    }
}

/// The motors behind the axes (none without `--motor`).
#[derive(Clone, Debug, Default)]
pub struct Motors {
    axes: Vec<Option<AxisMotor>>,
    clkfreq_hz: f64,
    /// The hub's clock at the first update, ticks (model time 0).
    start_ct: Option<u64>,
}

impl Motors {
    /// Reads the motor files of `specs` for `axis_count` axes whose outputs
    /// are `outputs` (by axis index), on a `clkfreq_hz` clock.
    pub fn load(
        specs: &[MotorSpec],
        outputs: &[Option<Outputs>],
        clkfreq_hz: u32,
    ) -> Result<Self, String> {
        let mut chosen: Vec<Option<&PathBuf>> = vec![None; outputs.len()];
        for spec in specs {
            match spec.axis {
                None => chosen.iter_mut().for_each(|slot| *slot = Some(&spec.path)),
                Some(axis) => {
                    let slot = chosen
                        .get_mut(axis - 1)
                        .ok_or_else(|| format!("--motor {axis}=...: there is no axis {axis}"))?;
                    *slot = Some(&spec.path);
                }
            }
        }
        let mut axes = Vec::with_capacity(outputs.len());
        for (index, (path, outputs)) in chosen.into_iter().zip(outputs).enumerate() {
            let (Some(path), Some(outputs)) = (path, outputs) else {
                axes.push(None);
                continue;
            };
            let motor = Motor::load(path).map_err(|error| error.to_string())?;
            let params = motor.rotor_params().map_err(|error| error.to_string())?;
            let pins = match *outputs {
                Outputs::StepDir { step, dir } => [(step, StepLine::Step), (dir, StepLine::Dir)],
                Outputs::CwCcw { cw, ccw } => [(cw, StepLine::Cw), (ccw, StepLine::Ccw)],
            };
            let name = path.file_stem().map_or_else(
                || format!("axis {}", index + 1),
                |stem| stem.to_string_lossy().into_owned(),
            );
            axes.push(Some(AxisMotor {
                name,
                rotor: Rotor::new(params, OwnedCurve(motor.torque_curve.clone())),
                decoder: StepDecoder::new(),
                pins,
                last_step_s: None,
                move_start: 0,
                largest_lag_steps: 0.0,
                lost_at_step: None,
            }));
        }
        Ok(Self {
            axes,
            clkfreq_hz: f64::from(clkfreq_hz.max(1)),
            start_ct: None,
        })
    }

    /// Whether any axis has a motor.
    pub fn any(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }

    /// Edges (in time order) and the clock now, ticks.
    pub fn apply(&mut self, edges: &[Edge], now_ct: u64) {
        let start = *self
            .start_ct
            .get_or_insert(edges.first().map_or(now_ct, |edge| edge.ct.min(now_ct)));
        let seconds = |ct: u64| ct.saturating_sub(start) as f64 / self.clkfreq_hz;
        for edge in edges {
            for motor in self.axes.iter_mut().flatten() {
                let Some(&(_, line)) = motor.pins.iter().find(|(pin, _)| *pin == edge.pin) else {
                    continue;
                };
                if let Some(forward) = motor.decoder.edge(line, edge.level) {
                    motor.step(seconds(edge.ct), forward);
                }
            }
        }
        let until = seconds(now_ct) - EDGE_SLACK_S;
        for motor in self.axes.iter_mut().flatten() {
            motor.run_until(until);
        }
    }

    /// The rotor of axis `index` (from 0), if it has a motor.
    pub fn readout(&self, index: usize) -> Option<RotorReadout> {
        let motor = self.axes.get(index)?.as_ref()?;
        Some(RotorReadout {
            name: motor.name.clone(),
            lag_steps: motor.rotor.error_steps(),
            largest_lag_steps: motor.largest_lag_steps,
            limit_steps: motor.rotor.params().sync_limit_steps(),
            lost_at_step: motor.lost_at_step,
        })
    }
}

/// The selected axis's rotor, a line under the header (`None` without a
/// motor on it).
pub fn banner(app: &App) -> Option<Line<'static>> {
    let readout = app.motors.readout(app.selected)?;
    let number = app.selected + 1;
    let RotorReadout {
        name,
        lag_steps,
        largest_lag_steps,
        limit_steps,
        lost_at_step,
    } = readout;
    Some(match lost_at_step {
        Some(step) => Line::from(vec![
            Span::styled(
                format!(" Rotor · axis {number} ({name}): LOST SYNCHRONISM at step {step} "),
                Style::new().white().on_red().bold(),
            ),
            Span::styled(
                format!(" lag {lag_steps:.1} steps: a real machine has lost its position"),
                Style::new().fg(Color::Red),
            ),
        ]),
        None => Line::from(vec![
            Span::styled(
                format!(" Rotor · axis {number} ({name}): "),
                Style::new().fg(Color::Cyan).bold(),
            ),
            Span::styled(
                format!("lag {lag_steps:+.2} steps · largest {largest_lag_steps:.2} · synchronous"),
                Style::new().fg(Color::Cyan),
            ),
            Span::styled(
                format!(" (lost beyond {limit_steps} steps)"),
                Style::new().fg(Color::DarkGray),
            ),
        ]),
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::time::Instant;

    use driver::profile::trapezoid::Trapezoid;
    use ratatui::backend::TestBackend;
    use ratatui::Terminal;

    use super::*;
    use crate::backend::{Capabilities, MachineInfo};

    const CLKFREQ: u32 = 200_000_000;

    fn motor_file(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../spreadsheet-export/motors")
            .join(name)
    }

    fn outputs() -> Vec<Option<Outputs>> {
        vec![
            Some(Outputs::StepDir { step: 1, dir: 2 }),
            Some(Outputs::CwCcw { cw: 5, ccw: 6 }),
        ]
    }

    /// The edges of the lecture's move on `pin` (rising and falling), from
    /// `start` ticks.
    fn lecture_edges(pin: u8, start: u64) -> Vec<Edge> {
        let mut ct = start;
        let mut edges = Vec::new();
        for step in Trapezoid::new(CLKFREQ, 4_000.0, 20_000.0, 2_000).unwrap() {
            edges.push(Edge {
                ct,
                pin,
                level: true,
            });
            edges.push(Edge {
                ct: ct + 1_000,
                pin,
                level: false,
            });
            ct += u64::from(step.delay_ticks);
        }
        edges
    }

    fn screen(app: &App) -> String {
        let mut terminal = Terminal::new(TestBackend::new(120, 40)).unwrap();
        terminal
            .draw(|frame| crate::ui::render(frame, app))
            .unwrap();
        let buffer = terminal.backend().buffer().clone();
        let mut text = String::new();
        for y in 0..buffer.area.height {
            for x in 0..buffer.area.width {
                text.push_str(buffer[(x, y)].symbol());
            }
            text.push('\n');
        }
        text
    }

    fn app(motors: Motors) -> App {
        let info = MachineInfo {
            title: "emulated P2 hub · test".into(),
            clkfreq_hz: CLKFREQ,
            capabilities: Capabilities::all(),
            max_speed: Some(199_600),
            axis_kinds: vec!["sd".into(), "cc".into()],
            axis_pins: vec!["pins".into(); 2],
            jog_timeout: None,
        };
        let mut app = App::new(info, 5_000, Instant::now());
        app.motors = motors;
        app
    }

    #[test]
    fn specs_name_an_axis_or_all() {
        assert_eq!(
            parse_motor_spec("m.toml"),
            Ok(MotorSpec {
                axis: None,
                path: "m.toml".into()
            })
        );
        assert_eq!(
            parse_motor_spec("2=motors/a=b.toml"),
            Ok(MotorSpec {
                axis: Some(2),
                path: "motors/a=b.toml".into()
            })
        );
        assert!(parse_motor_spec("9=m.toml").is_err());
        assert!(parse_motor_spec("").is_err());
        assert!(parse_motor_spec("1=").is_err());
        let spec = |text| parse_motor_spec(text).unwrap();
        let error = Motors::load(&[spec("3=m.toml")], &outputs(), CLKFREQ).unwrap_err();
        assert!(error.contains("no axis 3"), "{error}");
        let error = Motors::load(&[spec("no-such.toml")], &outputs(), CLKFREQ).unwrap_err();
        assert!(error.contains("no-such.toml"), "{error}");
    }

    #[test]
    fn the_lecture_move_on_type_100_shows_lost_synchronism_and_on_type_200_the_lag() {
        let specs = [
            parse_motor_spec(motor_file("type-200.toml").to_str().unwrap()).unwrap(),
            parse_motor_spec(&format!("2={}", motor_file("type-100.toml").display())).unwrap(),
        ];
        let mut motors = Motors::load(&specs, &outputs(), CLKFREQ).unwrap();
        assert!(motors.any());
        // Both moves at once, merged in time order, in frames of 30 ms.
        let start = 5_000_000;
        let mut edges = lecture_edges(1, start);
        edges.extend(lecture_edges(5, start));
        edges.sort();
        let end = edges.last().unwrap().ct + 200_000_000;
        let frame = 6_000_000;
        let mut now = start;
        let mut next = 0;
        while now < end {
            now += frame;
            let upto = edges[next..].partition_point(|edge| edge.ct <= now) + next;
            motors.apply(&edges[next..upto], now);
            next = upto;
        }
        let kept = motors.readout(0).unwrap();
        assert_eq!(kept.name, "type-200");
        assert_eq!(kept.lost_at_step, None);
        assert!(kept.lag_steps.abs() < 0.5, "{kept:?}");
        assert!(kept.largest_lag_steps < 2.0);
        let lost = motors.readout(1).unwrap();
        assert_eq!(lost.name, "type-100");
        let step = lost.lost_at_step.expect("lost");
        assert!(step < 400, "lost while accelerating, at {step}");

        let mut app = app(motors);
        let text = screen(&app);
        assert!(text.contains("Rotor · axis 1 (type-200): lag"), "{text}");
        assert!(text.contains("synchronous"));
        app.selected = 1;
        let text = screen(&app);
        assert!(
            text.contains(&format!(
                "Rotor · axis 2 (type-100): LOST SYNCHRONISM at step {step}"
            )),
            "{text}"
        );
        assert!(
            text.contains("a real machine has lost its position"),
            "{text}"
        );
        // The panels are all still there under the extra line.
        assert!(
            text.contains("Axis 1 · sd") && text.contains("Axis 2 · cc"),
            "{text}"
        );
    }

    #[test]
    fn without_a_motor_nothing_changes() {
        let plain = app(Motors::default());
        assert!(!plain.motors.any());
        assert!(banner(&plain).is_none());
        assert!(!screen(&plain).contains("Rotor"));
        // An axis without a motor beside one with.
        let specs =
            [parse_motor_spec(&format!("2={}", motor_file("type-300.toml").display())).unwrap()];
        let mut app = app(Motors::load(&specs, &outputs(), CLKFREQ).unwrap());
        assert!(banner(&app).is_none(), "axis 1 has none");
        app.selected = 1;
        app.motors.apply(&[], 1_000_000);
        assert!(screen(&app).contains("Rotor · axis 2 (type-300): lag +0.00 steps"));
    }
}
