//! The interpreter's and the machine file's tests.

mod arcs;
mod lines;
mod machine_file;
mod model;

use std::vec::Vec;

use crate::{Block, GcodeError, Interpreter, MachineSpec};

/// Two axes at 80 steps/mm, no limits (the shipped plotter's form).
pub(crate) fn plotter() -> MachineSpec {
    MachineSpec::from_toml_str(include_str!(
        "../../spreadsheet-export/machines/plotter.toml"
    ))
    .unwrap()
}

/// The shipped 3-axis CNC: soft limits, home switches, Z at 400 steps/mm.
pub(crate) fn cnc() -> MachineSpec {
    MachineSpec::from_toml_str(include_str!(
        "../../spreadsheet-export/machines/xyz-cnc.toml"
    ))
    .unwrap()
}

/// The blocks of `lines` (numbered from 1), or the first error.
pub(crate) fn run(interpreter: &mut Interpreter, lines: &[&str]) -> Result<Vec<Block>, GcodeError> {
    let mut blocks = Vec::new();
    for (index, text) in lines.iter().enumerate() {
        interpreter.interpret_line(index as u32 + 1, text, &mut |block| blocks.push(block))?;
    }
    Ok(blocks)
}

/// Proptest cases per property: 64, or `COGSTEP_MODEL_CASES`.
pub(crate) fn cases() -> u32 {
    std::env::var("COGSTEP_MODEL_CASES")
        .ok()
        .and_then(|cases| cases.parse().ok())
        .unwrap_or(64)
}
