//! `--gcode`: the program's screen, a pure function of the [`App`] as the
//! rest of [`crate::ui`].
//!
//! ```text
//! header: the program, its machine, the hub · feed override · frame rate
//! ┌ Program ─────────┐┌ XY view ──────────────────────────┐
//! │State: Run        ││  the programmed path (made: green, │
//! │line n of N · %   ││  to come: grey, rapids: dark), the │
//! │time left, speed  ││  tool ● at the axes' positions     │
//! │X: mm, steps ...  ││                                    │
//! └──────────────────┘└────────────────────────────────────┘
//! the last message
//! the keys
//! ```

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::canvas::{Canvas, Line as CanvasLine};
use ratatui::widgets::{Block, Borders, Paragraph};
use ratatui::Frame;

use crate::app::program::RunState;
use crate::app::{App, Tone};

/// The program's keys, as the help line shows them.
pub const PROGRAM_KEYS: [(&str, &str); 6] = [
    ("space/s", "hold"),
    ("r", "resume (space too, once Held)"),
    ("c/Esc", "cancel"),
    ("+/-", "feed override ±10 %"),
    ("x", "emergency stop"),
    ("q", "quit (stops the axes at once if they move)"),
];

/// The program panel's width, columns.
const PANEL_WIDTH: u16 = 46;

/// Draws the program's screen.
pub fn render(frame: &mut Frame, app: &App) {
    let Some(view) = &app.program else { return };
    let area = frame.area();
    let fault_rows = u16::from(app.fault.is_some());
    let [header, fault, middle, message, help] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(fault_rows),
        Constraint::Min(5),
        Constraint::Length(1),
        Constraint::Length(2),
    ])
    .areas(area);
    let right = format!("feed override {} % · {} fps ", view.feed_percent, app.fps);
    let [left_header, right_header] = Layout::horizontal([
        Constraint::Min(0),
        Constraint::Length(u16::try_from(right.chars().count()).unwrap_or(0)),
    ])
    .areas(header);
    frame.render_widget(
        Paragraph::new(Line::from(vec![
            Span::styled(" cogstep ", Style::new().black().on_yellow().bold()),
            Span::raw(" "),
            Span::styled(app.info.title.clone(), Style::new().bold()),
        ])),
        left_header,
    );
    frame.render_widget(Paragraph::new(right), right_header);
    if let Some(text) = &app.fault {
        frame.render_widget(
            Paragraph::new(text.clone()).style(Style::new().white().on_red()),
            fault,
        );
    }
    let [panel, canvas] =
        Layout::horizontal([Constraint::Length(PANEL_WIDTH), Constraint::Min(10)]).areas(middle);
    render_panel(frame, app, panel);
    render_xy(frame, app, canvas);
    if let Some(text) = &app.message {
        let style = match text.tone {
            Tone::Info => Style::new(),
            Tone::Warn => Style::new().yellow(),
            Tone::Refused => Style::new().red(),
        };
        frame.render_widget(Paragraph::new(text.text.clone()).style(style), message);
    }
    frame.render_widget(Paragraph::new(help_lines(help.width)), help);
}

/// The keys on as many lines as the width needs (two at most).
fn help_lines(width: u16) -> Vec<Line<'static>> {
    let mut lines = vec![Vec::new()];
    let mut used = 0usize;
    for (key, what) in PROGRAM_KEYS {
        let item = key.chars().count() + 1 + what.chars().count() + 3;
        if used + item > usize::from(width) && used > 0 {
            lines.push(Vec::new());
            used = 0;
        }
        let spans = lines.last_mut().expect("a line");
        if used > 0 {
            spans.push(Span::raw(" · "));
        }
        spans.push(Span::styled(key, Style::new().yellow().bold()));
        spans.push(Span::raw(format!(" {what}")));
        used += item;
    }
    lines.into_iter().map(Line::from).collect()
}

fn state_style(state: &RunState) -> Style {
    match state {
        RunState::Run => Style::new().green().bold(),
        RunState::Hold | RunState::Held => Style::new().yellow().bold(),
        RunState::Done => Style::new().cyan().bold(),
        RunState::Cancelled => Style::new().magenta().bold(),
        RunState::Fault(_) => Style::new().white().on_red().bold(),
    }
}

fn render_panel(frame: &mut Frame, app: &App, area: Rect) {
    let Some(view) = &app.program else { return };
    let program = &view.program;
    let state = app.run_state().unwrap_or(RunState::Run);
    let line = app.program_line();
    let mut lines = vec![
        Line::from(vec![
            Span::raw("State: "),
            Span::styled(state.word(), state_style(&state)),
        ]),
        Line::from(format!(
            "Progress: line {line} of {} · {:.0} %",
            program.line_count(),
            app.program_percent()
        )),
        Line::from(format!("Time left: ~{:.1} s", app.program_time_left_s())),
        Line::from("  (the lines left at their feeds, no ramps)"),
        Line::from(format!(
            "Speed: {:.1} mm/s along the path",
            app.program_speed_mm_s()
        )),
    ];
    if let Some(reading) = &view.reading {
        lines.push(Line::from(format!(
            "Lines on the path: {} queued, {} done",
            reading.progress.queued, reading.progress.done
        )));
    }
    lines.push(Line::from(""));
    for (index, axis) in program.spec.axes().iter().enumerate() {
        let letter = axis.letter.to_ascii_uppercase();
        lines.push(Line::from(match app.program_position(index) {
            Some((mm, steps)) => format!("{letter}: {mm:>10.3} mm {steps:>9} steps"),
            None => format!("{letter}: n/a"),
        }));
    }
    lines.push(Line::from(""));
    if let Some(text) = line
        .checked_sub(1)
        .and_then(|index| program.lines.get(index))
    {
        lines.push(Line::from(format!("Line {line}: {}", text.trim())));
    }
    if let RunState::Fault(why) = &state {
        lines.push(Line::from(Span::styled(
            format!("Fault: {why}"),
            Style::new().red(),
        )));
    }
    let block = Block::new()
        .borders(Borders::ALL)
        .title(format!(" Program · {} ", program.name));
    frame.render_widget(
        Paragraph::new(lines)
            .block(block)
            .wrap(ratatui::widgets::Wrap { trim: false }),
        area,
    );
}

/// The XY view's bounds, widened so that a mm is as long across as up
/// (a terminal cell is about twice as high as it is wide).
fn square_bounds(bounds: [[f64; 2]; 2], area: Rect) -> [[f64; 2]; 2] {
    let [[x0, x1], [y0, y1]] = bounds;
    let (width, height) = (x1 - x0, y1 - y0);
    let cells_w = f64::from(area.width.saturating_sub(2).max(1));
    let cells_h = f64::from(area.height.saturating_sub(2).max(1)) * 2.0;
    // mm per cell-width unit, the larger of the two needs.
    let scale = (width / cells_w).max(height / cells_h);
    let (half_w, half_h) = (scale * cells_w / 2.0, scale * cells_h / 2.0);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    [[cx - half_w, cx + half_w], [cy - half_h, cy + half_h]]
}

fn render_xy(frame: &mut Frame, app: &App, area: Rect) {
    let Some(view) = &app.program else { return };
    let program = &view.program;
    let [x_axis, y_axis] = program.view_axes;
    let letter = |axis: Option<usize>| {
        axis.and_then(|a| program.spec.letters().get(a).copied())
            .map_or('-', |c| c.to_ascii_uppercase())
    };
    let tool = [x_axis, y_axis].map(|axis| {
        axis.and_then(|a| app.program_position(a))
            .map_or(0.0, |(mm, _)| mm)
    });
    let mut bounds = program.bounds_mm();
    for (axis, value) in tool.iter().enumerate() {
        bounds[axis][0] = bounds[axis][0].min(*value);
        bounds[axis][1] = bounds[axis][1].max(*value);
    }
    let [x_bounds, y_bounds] = square_bounds(bounds, area);
    let running = app.program_line() as u32;
    let done = app.run_state() == Some(RunState::Done);
    let title = format!(
        " XY view, mm · {} → {} ↑ · ● tool · path: made green, to come grey, rapids dark ",
        letter(x_axis),
        letter(y_axis)
    );
    let canvas = Canvas::default()
        .block(Block::new().borders(Borders::ALL).title(title))
        .marker(Marker::Braille)
        .x_bounds(x_bounds)
        .y_bounds(y_bounds)
        .paint(move |ctx| {
            for segment in &program.segments {
                let color = if done || segment.line < running {
                    Color::Green
                } else if segment.rapid {
                    Color::DarkGray
                } else {
                    Color::Gray
                };
                ctx.draw(&CanvasLine::new(
                    segment.from_mm[0],
                    segment.from_mm[1],
                    segment.to_mm[0],
                    segment.to_mm[1],
                    color,
                ));
            }
            ctx.layer();
            ctx.print(
                tool[0],
                tool[1],
                Span::styled("●", Style::new().yellow().bold()),
            );
        });
    frame.render_widget(canvas, area);
}

#[cfg(test)]
mod tests {
    use ratatui::backend::TestBackend;
    use ratatui::Terminal;

    use super::*;
    use crate::app::program::ProgramView;
    use crate::backend::{Capabilities, MachineInfo};
    use crate::program::Program;

    fn app() -> App {
        let spec = driver::gcode::MachineSpec::from_toml_str(
            "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n",
        )
        .unwrap();
        let program = Program::from_text(
            "square.gcode",
            "plotter.toml",
            spec,
            "G1 X10 F600\nG1 Y10\nM2\n",
        )
        .unwrap();
        let info = MachineInfo {
            title: "G-code square.gcode".into(),
            clkfreq_hz: 200_000_000,
            capabilities: Capabilities::all(),
            max_speed: None,
            axis_kinds: vec!["sd".into(); 2],
            axis_pins: vec!["pins".into(); 2],
            jog_timeout: None,
        };
        let mut app = App::new(info, 5_000, std::time::Instant::now());
        app.program = Some(ProgramView::new(program));
        app
    }

    fn text(app: &App, width: u16, height: u16) -> String {
        let mut terminal = Terminal::new(TestBackend::new(width, height)).unwrap();
        terminal
            .draw(|frame| crate::ui::render(frame, app))
            .unwrap();
        let buffer = terminal.backend().buffer().clone();
        (0..height)
            .map(|y| {
                (0..width)
                    .map(|x| buffer[(x, y)].symbol().to_string())
                    .collect::<String>()
                    + "\n"
            })
            .collect()
    }

    #[test]
    fn the_program_screen_shows_progress_positions_the_path_and_the_keys() {
        let app = app();
        let screen = text(&app, 120, 40);
        if std::env::var_os("SHOW_SCREEN").is_some() {
            println!("{screen}");
        }
        for expected in [
            "State: Run",
            "line 0 of 3",
            "Time left:",
            "mm/s along the path",
            "X:",
            "Y:",
            "XY view",
            "space/s hold",
            "r resume",
            "c/Esc cancel",
            "q quit",
        ] {
            assert!(screen.contains(expected), "{expected:?} missing:\n{screen}");
        }
        // The path is drawn (braille dots) and the tool marked.
        assert!(screen.contains('●'), "{screen}");
        assert!(screen
            .chars()
            .any(|c| ('\u{2801}'..='\u{28ff}').contains(&c)));
    }

    #[test]
    fn any_screen_size_renders_without_panicking() {
        let app = app();
        for (width, height) in [(1, 1), (20, 5), (60, 12), (200, 60)] {
            let _ = text(&app, width, height);
        }
    }
}
