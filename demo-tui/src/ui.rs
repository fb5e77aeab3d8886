//! Rendering: an [`App`] as it is, drawn into a frame (the "view" of the
//! ratatui app pattern). A pure function of the state: the same app gives
//! the same screen, which the tests check with ratatui's `TestBackend`.
//!
//! ```text
//! header: what is driven · jog speed · frame rate
//! (a fault, and what the backend cannot do, when there are any)
//! ┏▶ Axis 1 ┓┌ Axis 2 ┐ ...   one panel per axis: the reference demo's
//! ┃ ...     ┃│ ...    │       fields, STM, stop pin, dropped steps
//!  Velocity · axis 1 ───   All axes ───   velocity against time | a line
//!  │ S-curve as it runs     ▶1 ... 2 ...    per axis, and notes
//!  Command → axis 1 ────────────────────
//! Enter steps: / Enter speed:, then the last message
//! the keys, and how digits are read
//! ```

use ratatui::layout::{Constraint, Layout, Position, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis as ChartAxis, Block, BorderType, Borders, Cell, Chart, Dataset, GraphType, Paragraph, Row,
    Table,
};
use ratatui::Frame;

use driver::{AxisState, Mode};

use crate::app::{App, AxisView, Jogging, LastCommand, Tone, PENDING_KEY};
use crate::prompt::Stage;

/// The narrowest axis panel, columns.
const PANEL_MIN_WIDTH: u16 = 30;
/// An axis panel's height: eleven fields and the borders.
const PANEL_HEIGHT: u16 = 13;
/// The prompt: a title rule, the question, the last message.
const PROMPT_HEIGHT: u16 = 3;
/// The help: two lines of keys and the input rule.
const HELP_HEIGHT: u16 = 3;
/// The least room the chart and the compact view need, rows.
const MIDDLE_MIN_HEIGHT: u16 = 7;
/// The widest axis panel, columns (more only spreads label and value apart).
const PANEL_MAX_WIDTH: u16 = 44;
/// Panels per row at most.
const PANELS_PER_ROW: usize = 4;

/// The keys and what they do, as the help line shows them.
pub const KEYS: [(&str, &str); 8] = [
    ("Tab/1-8", "select axis"),
    ("s", "stop"),
    ("x", "emergency stop all"),
    ("←/→", "hold: jog"),
    ("+/-", "jog speed"),
    ("Enter", "submit"),
    ("Esc", "clear"),
    ("q", "quit"),
];

/// The keys of homing and limits, on a second line.
pub const LIMIT_KEYS: [(&str, &str); 3] = [
    ("g", "move all axes together"),
    ("h", "home the selected axis"),
    ("c", "clear its limit fault"),
];

/// How digits and `-` are read, under the keys.
pub const INPUT_RULE: &str = "Digits go to the prompt; on an empty steps prompt a lone 1-8 selects that axis, a lone - lowers jog speed (0.6 s).";

const ACCENT: Color = Color::Yellow;

pub mod program;

/// Draws the whole screen (the program's, with `--gcode`).
pub fn render(frame: &mut Frame, app: &App) {
    if app.program.is_some() {
        return program::render(frame, app);
    }
    let area = frame.area();
    let extra_header = u16::from(app.fault.is_some())
        + u16::try_from(capability_lines(app).len()).unwrap_or(0)
        + u16::from(crate::motor_view::banner(app).is_some());
    let fixed = 1 + extra_header + PROMPT_HEIGHT + HELP_HEIGHT;
    let count = app.axes.len().max(1);
    let per_row = usize::from((area.width / PANEL_MIN_WIDTH).max(1))
        .min(PANELS_PER_ROW)
        .min(count);
    let rows = count.div_ceil(per_row);
    let grid_height = PANEL_HEIGHT.saturating_mul(u16::try_from(rows).unwrap_or(u16::MAX));
    // Every axis's panel when they fit; the selected one alone otherwise.
    let all_panels = area.height >= fixed + grid_height + MIDDLE_MIN_HEIGHT;
    let panels_height = if all_panels {
        grid_height
    } else {
        PANEL_HEIGHT
    };
    let [header, banners, panels, middle, prompt, help] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(extra_header),
        Constraint::Length(panels_height),
        Constraint::Min(3),
        Constraint::Length(PROMPT_HEIGHT),
        Constraint::Length(HELP_HEIGHT),
    ])
    .areas(area);
    render_header(frame, app, header);
    render_banners(frame, app, banners);
    if all_panels {
        render_panel_grid(frame, app, panels, per_row);
    } else if let Some(view) = app.selected_axis() {
        let [panel, _] = Layout::horizontal([Constraint::Max(PANEL_MAX_WIDTH), Constraint::Min(0)])
            .areas(panels);
        render_panel(frame, app, view, panel);
    }
    let [chart, _, table] = Layout::horizontal([
        Constraint::Percentage(58),
        Constraint::Length(2),
        Constraint::Min(0),
    ])
    .areas(middle);
    render_chart(frame, app, chart);
    render_all_axes(frame, app, table);
    render_prompt(frame, app, prompt);
    render_help(frame, help);
}

/// The least of the header's left (the badge and the start of the title)
/// worth keeping beside the jog speed and frame rate, columns.
const HEADER_LEFT_MIN: u16 = 24;

/// The header: what is driven on the left, the jog speed and frame rate on
/// the right. Items never run into each other: the left is cut with an
/// ellipsis to leave a blank before the right, and the right goes when not
/// even [`HEADER_LEFT_MIN`] columns of the left would be left.
fn render_header(frame: &mut Frame, app: &App, area: Rect) {
    let right = format!("jog speed {} steps/s · {} fps ", app.jog_speed, app.fps);
    let right_width = text_width(&right);
    let left = vec![
        Span::styled(" cogstep ", Style::new().black().on_yellow().bold()),
        Span::raw(" P2 stepper demo · "),
        Span::styled(app.info.title.clone(), Style::new().bold()),
    ];
    let left_full = left
        .iter()
        .map(|span| text_width(&span.content))
        .sum::<u16>();
    let (left_width, right) = if left_full.saturating_add(1 + right_width) <= area.width {
        (left_full, Some(right))
    } else if area.width >= HEADER_LEFT_MIN + 1 + right_width {
        (area.width - 1 - right_width, Some(right))
    } else {
        (area.width, None)
    };
    let left_area = Rect {
        width: left_width.min(area.width),
        ..area
    };
    frame.render_widget(Paragraph::new(Line::from(cut(left, left_width))), left_area);
    if let Some(right) = right {
        let right_area = Rect {
            x: area.right() - right_width,
            width: right_width,
            ..area
        };
        frame.render_widget(Paragraph::new(Line::from(right)), right_area);
    }
}

/// Columns `text` takes on a terminal.
fn text_width(text: &str) -> u16 {
    u16::try_from(Span::raw(text).width()).unwrap_or(u16::MAX)
}

/// `spans` cut to `width` columns, ending in `…` where something was cut.
fn cut(spans: Vec<Span<'static>>, width: u16) -> Vec<Span<'static>> {
    let total = spans
        .iter()
        .map(|span| text_width(&span.content))
        .sum::<u16>();
    if total <= width {
        return spans;
    }
    // One column for the ellipsis.
    let mut room = width.saturating_sub(1);
    let mut kept = Vec::new();
    let mut last_style = Style::new();
    for span in spans {
        if room == 0 {
            break;
        }
        let mut content = String::new();
        for c in span.content.chars() {
            let c_width = text_width(c.encode_utf8(&mut [0; 4]));
            if c_width > room {
                room = 0;
                break;
            }
            room -= c_width;
            content.push(c);
        }
        last_style = span.style;
        kept.push(Span::styled(content, span.style));
    }
    if width > 0 {
        kept.push(Span::styled("…", last_style));
    }
    kept
}

/// What the backend cannot do, a line each.
fn capability_lines(app: &App) -> Vec<String> {
    let caps = &app.info.capabilities;
    [
        ("stop", &caps.stop_pin),
        ("jog", &caps.jog),
        ("emergency stop", &caps.emergency_stop),
    ]
    .into_iter()
    .filter_map(|(what, reason)| reason.as_ref().map(|r| format!("{what}: {r}")))
    .collect()
}

fn render_banners(frame: &mut Frame, app: &App, area: Rect) {
    let mut lines = Vec::new();
    if let Some(fault) = &app.fault {
        lines.push(Line::from(Span::styled(
            format!(" FAULT: {fault} "),
            Style::new().white().on_red().bold(),
        )));
    }
    for missing in capability_lines(app) {
        lines.push(Line::from(Span::styled(
            format!(" {missing}"),
            Style::new().fg(Color::Magenta),
        )));
    }
    lines.extend(crate::motor_view::banner(app));
    frame.render_widget(Paragraph::new(lines), area);
}

fn render_panel_grid(frame: &mut Frame, app: &App, area: Rect, per_row: usize) {
    let rows = app.axes.len().div_ceil(per_row.max(1));
    let row_areas = Layout::vertical(vec![Constraint::Length(PANEL_HEIGHT); rows]).split(area);
    for (row_index, row_area) in row_areas.iter().enumerate() {
        let mut constraints = vec![Constraint::Max(PANEL_MAX_WIDTH); per_row];
        constraints.push(Constraint::Min(0));
        let cells = Layout::horizontal(constraints).split(*row_area);
        for (column, cell) in cells.iter().enumerate() {
            if let Some(view) = app.axes.get(row_index * per_row + column) {
                render_panel(frame, app, view, *cell);
            }
        }
    }
}

/// The words for a mode, with the direction and jog flags.
fn mode_words(mode: Mode) -> String {
    let mut words = mode.describe().to_string();
    if mode.has(Mode::MOVING) {
        if mode.has(Mode::REVERSE) {
            words.push_str(" · reverse");
        }
        if mode.has(Mode::JOG) {
            words.push_str(" · jog");
        }
    }
    words
}

fn mode_style(mode: Mode) -> Style {
    if mode.has(Mode::ESTOP) {
        Style::new().fg(Color::Red).bold()
    } else if mode.has(Mode::HOLD) || mode.has(Mode::STOP_LATCHED) {
        Style::new().fg(Color::Magenta)
    } else if !mode.has(Mode::MOVING) {
        Style::new().fg(Color::Gray)
    } else if mode.has(Mode::ACCEL) {
        Style::new().fg(Color::Green)
    } else if mode.has(Mode::DECEL) {
        Style::new().fg(Color::LightRed)
    } else {
        Style::new().fg(Color::Cyan)
    }
}

/// A label on the left, its value on the right.
fn field<'a>(label: &'a str, value: String, style: Style, width: u16) -> Line<'a> {
    let used = label.chars().count() + value.chars().count();
    let pad = usize::from(width).saturating_sub(used).max(1);
    Line::from(vec![
        Span::raw(label),
        Span::raw(" ".repeat(pad)),
        Span::styled(value, style),
    ])
}

fn known(value: Option<impl ToString>) -> (String, Style) {
    match value {
        Some(v) => (v.to_string(), Style::new().bold()),
        None => ("n/a".to_string(), Style::new().fg(Color::DarkGray)),
    }
}

fn render_panel(frame: &mut Frame, app: &App, view: &AxisView, area: Rect) {
    let selected = app.selected + 1 == view.number;
    let state = view
        .readout
        .map(|r| AxisState::from_mode(r.status.mode, r.status.stop_pin_high).as_str())
        .unwrap_or("?");
    let marker = if selected { "▶" } else { " " };
    let mut title = vec![Span::raw(format!(
        "{marker} Axis {} · {} ",
        view.number, view.kind
    ))];
    if let Some(pressed) = view.switches {
        // Each switch: name and ● pressed / ○ released; a narrow panel
        // says H, - and + for home, min and max.
        let wide = area.width >= 40;
        let names = if wide {
            ["home", "min", "max"]
        } else {
            ["H", "-", "+"]
        };
        if wide {
            title.push(Span::raw("· "));
        }
        for (name, pressed) in names.iter().zip(pressed) {
            let (mark, style) = if pressed {
                ("●", Style::new().fg(Color::Yellow).bold())
            } else {
                ("○", Style::new().fg(Color::DarkGray))
            };
            let gap = if wide { " " } else { "" };
            title.push(Span::styled(format!("{name}{mark}{gap}"), style));
        }
        if !wide {
            title.push(Span::raw(" "));
        }
    }
    let mut block = Block::bordered()
        .title(Line::from(title))
        .title(Line::from(format!(" {state} ")).right_aligned());
    block = if selected {
        block
            .border_type(BorderType::Thick)
            .border_style(Style::new().fg(ACCENT))
            .title_style(Style::new().fg(ACCENT).bold())
    } else {
        block.border_style(Style::new().fg(Color::DarkGray))
    };
    // A failed read (a board fault) replaces the mode words: the figures
    // above it are the last ones read.
    if let (Some(error), Some(_)) = (&view.error, view.readout) {
        block = block.title_bottom(
            Line::from(Span::styled(
                format!(" {error} "),
                Style::new().fg(Color::Red).bold(),
            ))
            .centered(),
        );
    } else if let Some(readout) = view.readout {
        let mode = readout.status.mode;
        let mut spans = vec![Span::styled(
            format!(" {} ", mode_words(mode)),
            mode_style(mode),
        )];
        if let Some(trip) = view.limits.and_then(|limits| limits.trip) {
            spans.push(Span::styled(
                format!("LIMIT {} ", crate::app::side_name(trip.side)),
                Style::new().fg(Color::Red).bold(),
            ));
        }
        block = block.title_bottom(Line::from(spans).centered());
    }

    let inner = block.inner(area);
    frame.render_widget(block, area);
    let width = inner.width;
    let Some(readout) = view.readout else {
        let text = view
            .error
            .clone()
            .unwrap_or_else(|| "waiting for the first reading".into());
        frame.render_widget(
            Paragraph::new(text)
                .style(Style::new().fg(Color::Red))
                .wrap(ratatui::widgets::Wrap { trim: true }),
            inner,
        );
        return;
    };
    let status = readout.status;
    let figures = readout.figures;
    let bold = Style::new().bold();
    let bits = String::from_utf8_lossy(&status.mode.binary()).into_owned();
    let (offset, offset_style) = known(figures.offset_deg);
    let (accel, accel_style) = known(figures.accel_steps);
    // A jog's slew is open-ended: its planned count means nothing here.
    let (slew, slew_style) = if view.last_command == Some(LastCommand::Jog) {
        ("jog".to_string(), Style::new().fg(Color::Cyan))
    } else {
        known(figures.slew_steps)
    };
    let (top, top_style) = known(figures.top_velocity);
    let (elapsed, elapsed_style) = known(figures.elapsed_ms);
    let (dropped, dropped_style) = known(figures.dropped_steps);
    let stop_pin = if status.stop_pin_high {
        ("high (run)".to_string(), Style::new().fg(Color::Green))
    } else {
        ("LOW (stop)".to_string(), Style::new().fg(Color::Red).bold())
    };
    let lines = vec![
        field(
            "Current Position:",
            status.position.to_string(),
            bold,
            width,
        ),
        field("Mode:", bits, mode_style(status.mode).bold(), width),
        field("Offset:", offset, offset_style, width),
        field("Accel steps:", accel, accel_style, width),
        field("Steps at speed:", slew, slew_style, width),
        field("Max Velocity:", top, top_style, width),
        field("Elapsed time (msec):", elapsed, elapsed_style, width),
        field("STM:", status.stm.to_string(), bold, width),
        field("Steps to go:", status.steps_to_go.to_string(), bold, width),
        field("Stop pin:", stop_pin.0, stop_pin.1, width),
        // The ledger counts a homing's unneeded seek travel as dropped: not a loss.
        if view.last_command == Some(LastCommand::Home) {
            field("Homing travel unused:", dropped, dropped_style, width)
        } else {
            field("Dropped steps:", dropped, dropped_style, width)
        },
    ];
    frame.render_widget(Paragraph::new(lines), inner);
}

/// A round number at or above `value` (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8 × 10^n).
fn round_up(value: f64) -> f64 {
    if value <= 0.0 || !value.is_finite() {
        return 0.0;
    }
    let scale = 10f64.powf(value.log10().floor());
    [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0]
        .into_iter()
        .map(|m| m * scale)
        .find(|bound| *bound >= value)
        .unwrap_or(10.0 * scale)
}

/// The velocity axis: from round numbers below and above the samples.
fn velocity_bounds(samples: &[(f64, f64)]) -> [f64; 2] {
    let top = samples.iter().fold(0.0f64, |m, (_, v)| m.max(*v));
    let bottom = samples.iter().fold(0.0f64, |m, (_, v)| m.min(*v));
    // `+ 0.0` turns -0 into 0, so the label reads "0".
    let (low, high) = (-round_up(-bottom * 1.05) + 0.0, round_up(top * 1.05));
    if high - low < 1.0 {
        [low, low + 1_000.0]
    } else {
        [low, high]
    }
}

fn render_chart(frame: &mut Frame, app: &App, area: Rect) {
    let Some(view) = app.selected_axis() else {
        return;
    };
    let samples: Vec<(f64, f64)> = view.trace.samples.iter().copied().collect();
    let title = format!(" Velocity · axis {} · steps/s against time ", view.number);
    let block = Block::new()
        .borders(Borders::TOP)
        .title(title)
        .border_style(Style::new().fg(Color::DarkGray))
        .title_style(Style::new().fg(ACCENT).bold());
    if samples.is_empty() {
        let hint = Paragraph::new(vec![
            Line::raw(""),
            Line::raw("  No move yet on this axis: type its steps and speed at the prompt"),
            Line::raw("  below, and the cosine S-curve is drawn here as it runs."),
        ])
        .style(Style::new().fg(Color::Gray))
        .block(block);
        frame.render_widget(hint, area);
        return;
    }
    let start = samples.first().map_or(0.0, |(t, _)| *t);
    let end = samples.last().map_or(start, |(t, _)| *t).max(start + 0.5);
    let [low, high] = velocity_bounds(&samples);
    let dataset = Dataset::default()
        .marker(Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::new().fg(Color::Cyan))
        .data(&samples);
    let seconds = |t: f64| format!("{:.1} s", t - start);
    let x_axis = ChartAxis::default()
        .style(Style::new().fg(Color::DarkGray))
        .bounds([start, end])
        .labels([
            Span::raw(seconds(start)),
            Span::raw(seconds((start + end) / 2.0)),
            Span::raw(seconds(end)),
        ]);
    let mut y_labels = vec![Span::raw(format!("{low:.0}"))];
    if low < 0.0 && high > 0.0 {
        y_labels.push(Span::raw("0"));
    }
    y_labels.push(Span::raw(format!("{high:.0}")));
    let y_axis = ChartAxis::default()
        .style(Style::new().fg(Color::DarkGray))
        .bounds([low, high])
        .labels(y_labels);
    let chart = Chart::new(vec![dataset])
        .block(block)
        .x_axis(x_axis)
        .y_axis(y_axis);
    frame.render_widget(chart, area);
}

/// A bar of `width` cells filled to `fraction`, in eighths of a cell.
fn bar(fraction: f64, width: usize) -> String {
    const PARTS: [&str; 8] = ["", "▏", "▎", "▍", "▌", "▋", "▊", "▉"];
    let eighths = (fraction.clamp(0.0, 1.0) * (width * 8) as f64).round() as usize;
    let full = eighths / 8;
    let mut text = "█".repeat(full);
    if full < width {
        text.push_str(PARTS[eighths % 8]);
    }
    text
}

fn render_all_axes(frame: &mut Frame, app: &App, area: Rect) {
    // Borders, the fixed columns and the spaces between them.
    let bar_width = usize::from(area.width.saturating_sub(3 + 10 + 8 + 5 + 7 + 5).max(3));
    let rows: Vec<Row> = app
        .axes
        .iter()
        .map(|view| {
            let selected = app.selected + 1 == view.number;
            let marker = if selected { "▶" } else { " " };
            let name = Cell::from(format!("{marker}{}", view.number));
            let Some(readout) = view.readout else {
                return Row::new(vec![name, Cell::from("?")]);
            };
            let status = readout.status;
            let state = AxisState::from_mode(status.mode, status.stop_pin_high);
            let top = readout
                .figures
                .top_velocity
                .unwrap_or(0)
                .max(status.velocity_steps_per_s)
                .max(1);
            let fraction = f64::from(status.velocity_steps_per_s) / f64::from(top);
            let row = Row::new(vec![
                name,
                Cell::from(Line::from(status.position.to_string()).right_aligned()),
                Cell::from(Line::from(status.steps_to_go.to_string()).right_aligned()),
                Cell::from(Span::styled(state.as_str(), mode_style(status.mode))),
                Cell::from(Line::from(status.velocity_steps_per_s.to_string()).right_aligned()),
                Cell::from(Span::styled(
                    bar(fraction, bar_width),
                    Style::new().fg(Color::Cyan),
                )),
            ]);
            if selected {
                row.style(Style::new().fg(ACCENT).bold())
            } else {
                row
            }
        })
        .collect();
    let widths = [
        Constraint::Length(3),
        Constraint::Length(10),
        Constraint::Length(8),
        Constraint::Length(5),
        Constraint::Length(7),
        Constraint::Min(3),
    ];
    let right = |title: &'static str| Cell::from(Line::from(title).right_aligned());
    let header = Row::new(vec![
        Cell::from("Ax"),
        right("Position"),
        right("To go"),
        Cell::from("State"),
        right("steps/s"),
        Cell::from("Velocity"),
    ])
    .style(
        Style::new()
            .fg(Color::Gray)
            .add_modifier(Modifier::UNDERLINED),
    );
    let table = Table::new(rows, widths)
        .header(header)
        .column_spacing(1)
        .block(
            Block::new()
                .borders(Borders::TOP)
                .title(" All axes ")
                .border_style(Style::new().fg(Color::DarkGray))
                .title_style(Style::new().fg(ACCENT).bold()),
        );
    let table_height = u16::try_from(app.axes.len() + 2).unwrap_or(u16::MAX);
    let [table_area, notes_area] =
        Layout::vertical([Constraint::Length(table_height), Constraint::Min(0)]).areas(area);
    frame.render_widget(table, table_area);
    render_notes(frame, app, notes_area);
}

/// Under the compact view, when there is room: the selected axis's pins,
/// how a jog ends here, and what the six mode bits mean.
fn render_notes(frame: &mut Frame, app: &App, area: Rect) {
    if area.height < 2 {
        return;
    }
    let gray = Style::new().fg(Color::Gray);
    let mut lines = vec![Line::raw("")];
    if let Some(view) = app.selected_axis() {
        lines.push(Line::from(Span::styled(
            format!("Axis {}: {} · {}", view.number, view.kind, view.pins),
            gray,
        )));
    }
    let jog_end = app.jog_end();
    lines.push(Line::from(Span::styled(
        format!("jog speed: {} steps/s", app.jog_speed),
        gray,
    )));
    lines.push(Line::from(Span::styled(
        format!("jog ends: {jog_end}"),
        gray,
    )));
    lines.push(Line::from(Span::styled(
        "Mode bits 5-0: stop latched, reverse,",
        gray,
    )));
    lines.push(Line::from(Span::styled(
        "  at speed, decelerating, accelerating, moving",
        gray,
    )));
    frame.render_widget(
        Paragraph::new(lines).wrap(ratatui::widgets::Wrap { trim: false }),
        area,
    );
}

/// The hint under the prompt: how to finish a stopped move, or what a
/// lone key will do.
fn prompt_hint(app: &App) -> Option<Line<'static>> {
    if app.prompt.pending_since.is_some() {
        let text = if app.prompt.field == "-" {
            "more digits: negative steps · a pause: jog speed down".to_string()
        } else {
            format!(
                "more digits: steps · a pause ({} ms): select axis {}",
                PENDING_KEY.as_millis(),
                app.prompt.field
            )
        };
        return Some(Line::from(Span::styled(text, Style::new().fg(Color::Gray))));
    }
    let view = app.selected_axis()?;
    let remaining = view.remaining_after_stop()?;
    Some(Line::from(vec![
        Span::styled(
            format!(
                "axis {} stopped {} steps short: ",
                view.number,
                remaining.abs()
            ),
            Style::new().fg(Color::Magenta),
        ),
        Span::styled(
            format!("type {remaining} at Enter steps: to finish the move"),
            Style::new().fg(Color::Magenta).bold(),
        ),
    ]))
}

fn jog_status(jog: &Jogging, app: &App) -> Span<'static> {
    let arrow = if jog.direction == driver::Direction::Forward {
        "→"
    } else {
        "←"
    };
    Span::styled(
        format!(
            " jogging axis {} {arrow} {} steps/s ",
            jog.axis + 1,
            app.jog_speed
        ),
        Style::new().black().on_cyan(),
    )
}

fn render_prompt(frame: &mut Frame, app: &App, area: Rect) {
    let number = app.selected + 1;
    let kind = app
        .selected_axis()
        .map(|v| v.kind.clone())
        .unwrap_or_default();
    let title = if app.prompt.in_group() {
        format!(
            " Command → axes 1-{} together (one line of steps, axis 1 first) ",
            app.axes.len()
        )
    } else {
        format!(" Command → axis {number} ({kind}) ")
    };
    let mut block = Block::new()
        .borders(Borders::TOP)
        .title(title)
        .border_style(Style::new().fg(Color::DarkGray))
        .title_style(Style::new().fg(ACCENT).bold());
    if let Some(jog) = &app.jogging {
        block = block.title(Line::from(jog_status(jog, app)).right_aligned());
    }
    let inner = block.inner(area);
    frame.render_widget(block, area);

    let answer = Style::new().bold().fg(Color::White);
    let mut spans = vec![];
    match app.prompt.stage {
        Stage::Steps => {
            spans.push(Span::styled("Enter steps: ", Style::new().fg(ACCENT)));
            spans.push(Span::styled(app.prompt.field.clone(), answer));
        }
        Stage::Speed { steps } => {
            spans.push(Span::styled("Enter steps: ", Style::new().fg(Color::Gray)));
            spans.push(Span::styled(
                steps.to_string(),
                Style::new().fg(Color::Gray),
            ));
            spans.push(Span::raw("   "));
            spans.push(Span::styled("Enter speed: ", Style::new().fg(ACCENT)));
            spans.push(Span::styled(app.prompt.field.clone(), answer));
        }
        Stage::GroupSteps => {
            spans.push(Span::styled("Group steps: ", Style::new().fg(ACCENT)));
            spans.push(Span::styled(app.prompt.field.clone(), answer));
        }
        Stage::GroupSpeed => {
            let listed = app
                .prompt
                .group
                .iter()
                .map(i32::to_string)
                .collect::<Vec<_>>()
                .join(" ");
            spans.push(Span::styled("Group steps: ", Style::new().fg(Color::Gray)));
            spans.push(Span::styled(listed, Style::new().fg(Color::Gray)));
            spans.push(Span::raw("   "));
            spans.push(Span::styled("Enter speed: ", Style::new().fg(ACCENT)));
            spans.push(Span::styled(app.prompt.field.clone(), answer));
        }
    }
    let cursor_x: usize = spans.iter().map(|s| s.content.chars().count()).sum();
    if let (Stage::Speed { .. } | Stage::GroupSpeed, true, Some(last)) = (
        app.prompt.stage,
        app.prompt.field.is_empty(),
        app.prompt.last_speed,
    ) {
        spans.push(Span::styled(
            format!(" (Enter = {last} steps/s)"),
            Style::new().fg(Color::DarkGray),
        ));
    }
    if let Some(hint) = prompt_hint(app) {
        spans.push(Span::raw("    "));
        spans.extend(hint.spans);
    }
    let message = match &app.message {
        Some(message) => {
            let style = match message.tone {
                Tone::Info => Style::new().fg(Color::Green),
                Tone::Warn => Style::new().fg(Color::Yellow).bold(),
                Tone::Refused => Style::new().fg(Color::Red),
            };
            let text = if message.tone == Tone::Refused {
                format!("✗ {}", message.text)
            } else {
                message.text.clone()
            };
            Line::from(Span::styled(text, style))
        }
        None => Line::raw(""),
    };
    frame.render_widget(Paragraph::new(vec![Line::from(spans), message]), inner);
    let x = inner
        .x
        .saturating_add(u16::try_from(cursor_x).unwrap_or(u16::MAX));
    if x < inner.right() && inner.height > 0 {
        frame.set_cursor_position(Position::new(x, inner.y));
    }
}

fn key_line(keys: &[(&'static str, &'static str)]) -> Line<'static> {
    let mut spans = Vec::new();
    for (index, (key, action)) in keys.iter().enumerate() {
        if index > 0 {
            spans.push(Span::styled(" · ", Style::new().fg(Color::DarkGray)));
        }
        spans.push(Span::styled(*key, Style::new().fg(ACCENT).bold()));
        spans.push(Span::styled(
            format!(" {action}"),
            Style::new().fg(Color::Gray),
        ));
    }
    Line::from(spans)
}

fn render_help(frame: &mut Frame, area: Rect) {
    let lines = vec![
        key_line(&KEYS),
        key_line(&LIMIT_KEYS),
        Line::from(Span::styled(INPUT_RULE, Style::new().fg(Color::Gray))),
    ];
    frame.render_widget(Paragraph::new(lines), area);
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use driver::AxisStatus;
    use ratatui::backend::TestBackend;
    use ratatui::buffer::Buffer;
    use ratatui::Terminal;

    use super::*;
    use crate::backend::{Capabilities, MachineInfo, MoveFigures};
    use crate::effect::Readout;

    fn info(count: usize) -> MachineInfo {
        MachineInfo {
            title: "emulated P2 hub · test".into(),
            clkfreq_hz: 200_000_000,
            capabilities: Capabilities::all(),
            max_speed: Some(199_600),
            axis_kinds: (0..count)
                .map(|i| if i % 2 == 0 { "sd" } else { "cc" }.to_string())
                .collect(),
            axis_pins: vec!["pins".into(); count],
            jog_timeout: Some(std::time::Duration::from_millis(150)),
        }
    }

    fn readout(position: i64, steps_to_go: u64, mode: u32, velocity: u32) -> Readout {
        Readout {
            status: AxisStatus {
                position,
                stm: 0,
                steps_to_go,
                mode: Mode(mode),
                velocity_steps_per_s: velocity,
                stop_pin_high: true,
            },
            figures: MoveFigures {
                offset_deg: Some(40),
                accel_steps: Some(2_002),
                slew_steps: Some(15_996),
                top_velocity: Some(20_000),
                dropped_steps: Some(0),
                elapsed_ms: Some(1_123),
            },
        }
    }

    fn draw(app: &App, width: u16, height: u16) -> Buffer {
        let mut terminal = Terminal::new(TestBackend::new(width, height)).expect("terminal");
        terminal.draw(|frame| render(frame, app)).expect("draw");
        terminal.backend().buffer().clone()
    }

    fn text(buffer: &Buffer) -> String {
        let mut out = String::new();
        for y in 0..buffer.area.height {
            for x in 0..buffer.area.width {
                out.push_str(buffer[(x, y)].symbol());
            }
            out.push('\n');
        }
        out
    }

    /// The value after `label` in the panel of axis `n` (from 1): panels
    /// come left to right, so the n-th occurrence of a label is axis n's.
    fn value_of(screen: &str, label: &str, n: usize) -> Option<String> {
        let mut seen = 0;
        for line in screen.lines() {
            let mut rest = line;
            while let Some(at) = rest.find(label) {
                rest = &rest[at + label.len()..];
                seen += 1;
                if seen == n {
                    let value: String = rest
                        .trim_start()
                        .chars()
                        .take_while(|c| !c.is_whitespace() && *c != '│' && *c != '┃')
                        .collect();
                    return Some(value);
                }
            }
        }
        None
    }

    fn sample_app(count: usize) -> App {
        let t0 = Instant::now();
        let mut app = App::new(info(count), 5_000, t0);
        let mut readouts: Vec<Result<Readout, String>> = (0..count)
            .map(|i| Ok(readout(i as i64 * 100, 0, 0, 0)))
            .collect();
        readouts[0] = Ok(readout(12_345, 7_655, 0b1011, 20_000));
        app.apply(t0 + Duration::from_millis(100), readouts, None);
        app
    }

    #[test]
    fn the_jog_timeout_shown_is_the_backends() {
        let t0 = Instant::now();
        let mut slow = info(1);
        slow.jog_timeout = Some(Duration::from_millis(400));
        let app = App::new(slow, 5_000, t0);
        assert!(text(&draw(&app, 120, 40)).contains("400 ms after the last key repeat"));
        let mut board = info(1);
        board.jog_timeout = None;
        let app = App::new(board, 5_000, t0);
        assert!(text(&draw(&app, 120, 40)).contains("the board's jog timeout"));
    }

    #[test]
    fn every_axis_shows_the_reference_fields_with_their_labels() {
        let app = sample_app(4);
        let screen = text(&draw(&app, 120, 40));
        for label in [
            "Current Position:",
            "Mode:",
            "Offset:",
            "Accel steps:",
            "Steps at speed:",
            "Max Velocity:",
            "Elapsed time (msec):",
            "STM:",
            "Steps to go:",
            "Stop pin:",
            "Dropped steps:",
        ] {
            assert_eq!(
                screen.matches(label).count(),
                4,
                "{label} once per axis:\n{screen}"
            );
        }
        assert_eq!(
            value_of(&screen, "Current Position:", 1).as_deref(),
            Some("12345")
        );
        assert_eq!(
            value_of(&screen, "Current Position:", 3).as_deref(),
            Some("200")
        );
        assert_eq!(value_of(&screen, "Mode:", 1).as_deref(), Some("001011"));
        assert_eq!(value_of(&screen, "Offset:", 1).as_deref(), Some("40"));
        assert_eq!(
            value_of(&screen, "Accel steps:", 1).as_deref(),
            Some("2002")
        );
        assert_eq!(
            value_of(&screen, "Steps at speed:", 1).as_deref(),
            Some("15996")
        );
        assert_eq!(
            value_of(&screen, "Max Velocity:", 1).as_deref(),
            Some("20000")
        );
        assert_eq!(
            value_of(&screen, "Elapsed time (msec):", 1).as_deref(),
            Some("1123")
        );
        assert_eq!(value_of(&screen, "STM:", 1).as_deref(), Some("0"));
        assert_eq!(
            value_of(&screen, "Steps to go:", 1).as_deref(),
            Some("7655")
        );
        assert_eq!(value_of(&screen, "Stop pin:", 1).as_deref(), Some("high"));
        assert!(screen.contains("at speed"), "mode in words:\n{screen}");
        assert!(screen.contains(" Run "), "state in the title");
        assert!(screen.contains("Enter steps:"));
        assert!(screen.contains("All axes"));
        assert!(screen.contains("Velocity · axis 1"));
    }

    #[test]
    fn switches_and_a_tripped_limit_show_on_the_panel() {
        let mut app = sample_app(2);
        app.axes[0].switches = Some([true, false, false]);
        app.axes[0].limits = Some(driver::LimitStatus {
            trip: Some(driver::LimitTrip {
                side: driver::Direction::Reverse,
                position: -4_000,
                physical: -6_000,
                stopping_steps: 1_002,
            }),
            ..driver::LimitStatus::default()
        });
        let screen = text(&draw(&app, 120, 40));
        assert!(screen.contains("home● min○ max○"), "{screen}");
        assert!(screen.contains("LIMIT min"), "{screen}");
        assert_eq!(
            screen.matches("home●").count() + screen.matches("home○").count(),
            1
        );
        // Four panels to a row: the short form, whole.
        let mut four = sample_app(4);
        four.axes[2].switches = Some([false, false, true]);
        let screen = text(&draw(&four, 120, 40));
        assert!(screen.contains("Axis 3 · sd H○-○+● "), "{screen}");
        for (key, action) in LIMIT_KEYS {
            assert!(screen.contains(&format!("{key} {action}")), "{screen}");
        }
    }

    #[test]
    fn the_selected_axis_is_highlighted() {
        let mut app = sample_app(4);
        app.selected = 2;
        let buffer = draw(&app, 120, 40);
        let screen = text(&buffer);
        assert!(screen.contains("▶ Axis 3 · sd"), "{screen}");
        assert!(!screen.contains("▶ Axis 1"));
        assert!(screen.contains("Command → axis 3"));
        assert!(screen.contains("Velocity · axis 3"));
        // The selected panel's border is thick and in the accent colour.
        let row = screen.lines().nth(1).expect("panel row");
        let x = row.chars().position(|c| c == '▶').expect("marker") as u16;
        let corner = (0..x).rev().find(|x| buffer[(*x, 1)].symbol() == "┏");
        let corner = corner.expect("a thick corner before the title");
        assert_eq!(buffer[(corner, 1)].fg, ACCENT);
        let plain = screen.lines().nth(1).expect("row").find("┌");
        assert!(plain.is_some(), "other panels keep a plain border");
    }

    #[test]
    fn the_help_line_names_every_key() {
        let app = sample_app(2);
        let screen = text(&draw(&app, 120, 40));
        assert!(screen.contains(INPUT_RULE), "the rule fits in 120 columns");
        for key in [
            "Tab/1-8 select axis",
            "s stop",
            "x emergency stop",
            "←/→ hold: jog",
            "+/- jog speed",
            "q quit",
            "Enter submit",
            "g move all axes together",
            "Esc clear",
        ] {
            assert!(screen.contains(key), "{key} in the help:\n{screen}");
        }
    }

    #[test]
    fn eight_axes_fit_at_120_by_40_and_a_small_screen_keeps_the_selected_one() {
        let app = sample_app(8);
        let screen = text(&draw(&app, 120, 40));
        assert_eq!(screen.matches("Current Position:").count(), 8, "{screen}");
        assert!(screen.contains("Enter steps:"));
        let small = text(&draw(&app, 80, 24));
        assert_eq!(small.matches("Current Position:").count(), 1, "{small}");
        assert!(small.contains("▶ Axis 1"));
        assert!(small.contains("Enter steps:"));
    }

    #[test]
    fn the_prompt_shows_both_questions_and_the_finish_hint() {
        let mut app = sample_app(2);
        app.prompt.stage = Stage::Speed { steps: -2_000 };
        app.prompt.field = "150".into();
        let screen = text(&draw(&app, 120, 40));
        assert!(
            screen.contains("Enter steps: -2000   Enter speed: 150"),
            "{screen}"
        );

        let mut app = sample_app(2);
        let mut stopped = readout(18_002, 0, Mode::STOP_LATCHED.bits(), 0);
        stopped.status.stop_pin_high = false;
        stopped.figures.dropped_steps = Some(21_998);
        app.axes[0].last_command = Some(LastCommand::Move {
            steps: 40_000,
            speed: 20_000,
        });
        app.apply(Instant::now(), vec![Ok(stopped), Ok(stopped)], None);
        let screen = text(&draw(&app, 120, 40));
        assert!(
            screen.contains("type 21998 at Enter steps: to finish"),
            "{screen}"
        );
        assert_eq!(
            value_of(&screen, "Dropped steps:", 1).as_deref(),
            Some("21998")
        );
        assert_eq!(value_of(&screen, "Stop pin:", 1).as_deref(), Some("LOW"));
        assert_eq!(value_of(&screen, "Mode:", 1).as_deref(), Some("100000"));
        assert!(screen.contains("stopped by stop pin"));
    }

    #[test]
    fn a_homings_unused_travel_is_not_shown_as_dropped_steps() {
        let mut app = sample_app(2);
        let mut homed = readout(-52, 0, 0, 0);
        homed.figures.dropped_steps = Some(499_948);
        app.axes[0].last_command = Some(LastCommand::Home);
        app.apply(Instant::now(), vec![Ok(homed), Ok(homed)], None);
        let screen = text(&draw(&app, 120, 40));
        assert_eq!(
            value_of(&screen, "Homing travel unused:", 1).as_deref(),
            Some("499948"),
            "{screen}"
        );
        // Axis 2, which did not home, still counts dropped steps.
        assert_eq!(screen.matches("Dropped steps:").count(), 1, "{screen}");
        // The next move counts dropped steps again.
        app.axes[0].last_command = Some(LastCommand::Move {
            steps: 100,
            speed: 1_000,
        });
        let screen = text(&draw(&app, 120, 40));
        assert_eq!(screen.matches("Dropped steps:").count(), 2, "{screen}");
        assert!(!screen.contains("Homing travel unused:"));
    }

    #[test]
    fn faults_and_missing_capabilities_are_shown() {
        let mut app = sample_app(1);
        app.info.capabilities = Capabilities {
            stop_pin: Some("not supported by this board (a pin)".into()),
            jog: None,
            emergency_stop: None,
        };
        app.fault = Some("board reset mid-move".into());
        app.axes[0].error = Some("fault: board reset mid-move".into());
        let screen = text(&draw(&app, 120, 40));
        assert!(screen.contains("FAULT: board reset mid-move"), "{screen}");
        assert!(
            screen.contains(" fault: board reset mid-move "),
            "on the panel"
        );
        assert!(screen.contains("stop: not supported by this board (a pin)"));
    }

    #[test]
    fn the_velocity_axis_ends_on_round_numbers() {
        assert_eq!(velocity_bounds(&[(0.0, 20_000.0)]), [0.0, 25_000.0]);
        assert_eq!(velocity_bounds(&[(0.0, 8_000.0)]), [0.0, 10_000.0]);
        assert_eq!(velocity_bounds(&[(0.0, -5_000.0)]), [-6_000.0, 0.0]);
        assert_eq!(velocity_bounds(&[]), [0.0, 1_000.0]);
    }

    #[test]
    fn any_screen_size_renders_without_panicking() {
        let app = sample_app(8);
        for (width, height) in [(1, 1), (10, 3), (20, 5), (40, 12), (80, 24), (200, 60)] {
            let screen = text(&draw(&app, width, height));
            assert_eq!(screen.lines().count(), usize::from(height));
        }
    }

    /// The header's row as drawn `width` columns wide.
    fn header_row(app: &App, width: u16) -> String {
        let screen = text(&draw(app, width, 40));
        screen.lines().next().unwrap_or_default().to_string()
    }

    #[test]
    fn the_header_never_runs_its_items_into_each_other() {
        for title in [
            "emulated P2 hub · 4 cogs · 200 MHz · real time · recording /dev/shm/a-rather-long-session-name.vcd",
            "serial /dev/pts/3 @ 115200 · [cogstep 0.1.0 protocol 1 · 4 axes · lm3s6965evb]",
            "x",
        ] {
            let mut app = sample_app(1);
            app.info.title = title.into();
            let right = format!("jog speed 5000 steps/s · {} fps", app.fps);
            let right = right.as_str();
            let full = format!(" cogstep  P2 stepper demo · {title}");
            for width in 1..=200 {
                let row = header_row(&app, width);
                let row = row.trim_end();
                let left = match row.strip_suffix(right) {
                    // Apart from the left by at least one blank.
                    Some(left) => {
                        assert!(left.is_empty() || left.ends_with(' '), "{width}: {row:?}");
                        left.trim_end()
                    }
                    None => row,
                };
                // The left in full, or cut with an ellipsis, never mixed with the right.
                let shown = left.strip_suffix('…').unwrap_or(left);
                assert!(full.starts_with(shown), "{width}: {row:?}");
                assert!(
                    left == full || left.ends_with('…') || left.is_empty(),
                    "{width} columns, cut without an ellipsis: {row:?}"
                );
                // The right ends with a blank of its own.
                if usize::from(width) >= full.chars().count() + 2 + right.chars().count() {
                    assert!(row.starts_with(&full) && row.ends_with(right), "{width}: {row:?}");
                }
            }
        }
    }

    #[test]
    fn bars_fill_in_eighths() {
        assert_eq!(bar(0.0, 4), "");
        assert_eq!(bar(1.0, 4), "████");
        assert_eq!(bar(0.5, 4), "██");
        assert_eq!(bar(0.56, 4), "██▎");
    }
}
