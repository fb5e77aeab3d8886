//! The TOML machine file (feature `std`):
//!
//! ```toml
//! [axes.x]
//! steps_per_mm = 80.0
//! max_speed_mm_s = 200.0
//! max_accel_mm_s2 = 2000.0
//! # optional: soft_min_mm, soft_max_mm, home = "min" | "max", home_speed_mm_s
//! [planner]
//! junction_deviation_mm = 0.01
//! arc_tolerance_mm = 0.002
//! # optional: queue_len (default 32)
//! ```
//!
//! The axes keep the file's order. Integers are taken where numbers are
//! asked (`steps_per_mm = 80`). Every error names its key.

use std::string::{String, ToString};

use toml::{Table, Value};

use crate::machine::{
    AxisSpec, HomeEnd, Key, MachineError, MachineSpec, PlannerSpec, AXIS_LETTERS, DEFAULT_QUEUE_LEN,
};

const AXIS_KEYS: [&str; 7] = [
    "steps_per_mm",
    "max_speed_mm_s",
    "max_accel_mm_s2",
    "soft_min_mm",
    "soft_max_mm",
    "home",
    "home_speed_mm_s",
];
const PLANNER_KEYS: [&str; 3] = ["junction_deviation_mm", "arc_tolerance_mm", "queue_len"];

impl MachineSpec {
    /// Reads a machine file (see [`crate::machine_file`]); the axes in the
    /// file's order, checked as [`MachineSpec::new`] checks.
    pub fn from_toml_str(text: &str) -> Result<MachineSpec, MachineError> {
        let table: Table = text.parse().map_err(|error: toml::de::Error| {
            let line = error
                .span()
                .map_or(0, |span| text[..span.start].matches('\n').count() + 1);
            MachineError::Toml {
                line,
                message: error.message().trim().to_string(),
            }
        })?;
        for key in table.keys() {
            if key != "axes" && key != "planner" {
                return Err(MachineError::UnknownKey(key.clone()));
            }
        }
        let axes_table = sub_table(&table, "axes", Key::Table("axes"))?;
        let mut axes = [AxisSpec::new('x', 1.0, 1.0, 1.0); 8];
        let mut count = 0;
        for (name, value) in axes_table {
            let letter = axis_letter(name)?;
            let Value::Table(axis_table) = value else {
                return Err(MachineError::WrongType {
                    key: Key::AxisTable(letter),
                    expected: "a table",
                });
            };
            if count == axes.len() {
                return Err(MachineError::AxisCount(axes_table.len()));
            }
            axes[count] = read_axis(letter, axis_table)?;
            count += 1;
        }
        let planner_table = sub_table(&table, "planner", Key::Table("planner"))?;
        let planner = read_planner(planner_table)?;
        MachineSpec::new(&axes[..count], planner)
    }
}

fn sub_table<'t>(table: &'t Table, name: &str, key: Key) -> Result<&'t Table, MachineError> {
    match table.get(name) {
        None => Err(MachineError::Missing(key)),
        Some(Value::Table(inner)) => Ok(inner),
        Some(_) => Err(MachineError::WrongType {
            key,
            expected: "a table",
        }),
    }
}

fn axis_letter(name: &str) -> Result<char, MachineError> {
    let mut chars = name.chars();
    match (chars.next(), chars.next()) {
        (Some(letter), None) if AXIS_LETTERS.contains(&letter) => Ok(letter),
        _ => Err(MachineError::UnknownAxis(name.to_string())),
    }
}

fn read_axis(letter: char, table: &Table) -> Result<AxisSpec, MachineError> {
    for key in table.keys() {
        if !AXIS_KEYS.contains(&key.as_str()) {
            return Err(MachineError::UnknownKey(
                String::from("axes.") + &letter.to_string() + "." + key,
            ));
        }
    }
    let key = |name: &'static str| Key::Axis(letter, name);
    let home = match table.get("home") {
        None => None,
        Some(Value::String(end)) if end == "min" => Some(HomeEnd::Min),
        Some(Value::String(end)) if end == "max" => Some(HomeEnd::Max),
        Some(_) => return Err(MachineError::Home(letter)),
    };
    Ok(AxisSpec {
        letter,
        steps_per_mm: required(table, key("steps_per_mm"))?,
        max_speed_mm_s: required(table, key("max_speed_mm_s"))?,
        max_accel_mm_s2: required(table, key("max_accel_mm_s2"))?,
        soft_min_mm: optional(table, key("soft_min_mm"))?,
        soft_max_mm: optional(table, key("soft_max_mm"))?,
        home,
        home_speed_mm_s: optional(table, key("home_speed_mm_s"))?,
    })
}

fn read_planner(table: &Table) -> Result<PlannerSpec, MachineError> {
    for key in table.keys() {
        if !PLANNER_KEYS.contains(&key.as_str()) {
            return Err(MachineError::UnknownKey(String::from("planner.") + key));
        }
    }
    let queue_len = match table.get("queue_len") {
        None => DEFAULT_QUEUE_LEN,
        Some(Value::Integer(len)) => usize::try_from(*len)
            .ok()
            .filter(|&len| len > 0)
            .ok_or(MachineError::QueueLen)?,
        Some(_) => return Err(MachineError::QueueLen),
    };
    Ok(PlannerSpec {
        junction_deviation_mm: required(table, Key::Planner("junction_deviation_mm"))?,
        arc_tolerance_mm: required(table, Key::Planner("arc_tolerance_mm"))?,
        queue_len,
    })
}

fn key_name(key: Key) -> &'static str {
    match key {
        Key::Table(name) | Key::Axis(_, name) | Key::Planner(name) => name,
        Key::AxisTable(_) => "",
    }
}

fn optional(table: &Table, key: Key) -> Result<Option<f64>, MachineError> {
    match table.get(key_name(key)) {
        None => Ok(None),
        Some(Value::Float(value)) => Ok(Some(*value)),
        // Machine files say `steps_per_mm = 80` as often as `80.0`.
        #[allow(clippy::cast_precision_loss)]
        Some(Value::Integer(value)) => Ok(Some(*value as f64)),
        Some(_) => Err(MachineError::WrongType {
            key,
            expected: "a number",
        }),
    }
}

fn required(table: &Table, key: Key) -> Result<f64, MachineError> {
    optional(table, key)?.ok_or(MachineError::Missing(key))
}
