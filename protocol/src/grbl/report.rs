//! grbl's report formats: positions, the status report's fields, `$G`, `$#`.

use core::fmt;

use super::motion::{Offsets, ParserState};
use super::GRBL_AXES;

/// Millimetres per inch.
const MM_PER_INCH: f64 = 25.4;

/// A length as grbl prints it: mm with 3 decimals, or inches with 4.
pub fn format_mm(mm: f64, inches: bool, out: &mut impl fmt::Write) -> fmt::Result {
    // -0.000 reads as a move to a sender; grbl prints 0.000.
    if inches {
        let value = mm / MM_PER_INCH;
        let value = if value.abs() < 0.000_05 { 0.0 } else { value };
        write!(out, "{value:.4}")
    } else {
        let value = if mm.abs() < 0.000_5 { 0.0 } else { mm };
        write!(out, "{value:.3}")
    }
}

/// `x,y,z`, each with [`format_mm`].
pub fn write_axes_mm(
    values_mm: &[f64; GRBL_AXES],
    inches: bool,
    out: &mut impl fmt::Write,
) -> fmt::Result {
    for (axis, &value) in values_mm.iter().enumerate() {
        if axis > 0 {
            out.write_char(',')?;
        }
        format_mm(value, inches, out)?;
    }
    Ok(())
}

/// A machine position in mm: steps divided by steps/mm, per axis.
pub fn steps_to_mm(steps: &[i64; GRBL_AXES], steps_per_mm: &[f64; GRBL_AXES]) -> [f64; GRBL_AXES] {
    let mut mm = [0.0; GRBL_AXES];
    for axis in 0..GRBL_AXES {
        mm[axis] = steps[axis] as f64 / steps_per_mm[axis];
    }
    mm
}

/// `$G`'s line: `[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`.
pub fn write_parser_state(state: &ParserState, out: &mut impl fmt::Write) -> fmt::Result {
    write!(
        out,
        "[GC:G{} G{} G{} G{} G{} G{} M5 M9 T0 F{} S0]\r\n",
        state.motion_mode,
        state.coordinate_system,
        state.plane,
        state.units,
        state.distance,
        state.feed_rate_mode,
        Rounded(state.feed),
    )
}

/// A feed as grbl prints it (no decimals in mm).
struct Rounded(f64);

impl fmt::Display for Rounded {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.0}", self.0)
    }
}

/// `$#`'s lines: G54–G59, G28, G30, G92, TLO, PRB.
pub fn write_offsets(offsets: &Offsets, inches: bool, out: &mut impl fmt::Write) -> fmt::Result {
    let zero = [0.0; GRBL_AXES];
    for system in 54..=59 {
        write!(out, "[G{system}:")?;
        let values = if system == 54 { &offsets.g54 } else { &zero };
        write_axes_mm(values, inches, out)?;
        out.write_str("]\r\n")?;
    }
    for (name, values) in [("G28", &zero), ("G30", &zero), ("G92", &offsets.g92)] {
        write!(out, "[{name}:")?;
        write_axes_mm(values, inches, out)?;
        out.write_str("]\r\n")?;
    }
    out.write_str("[TLO:")?;
    format_mm(0.0, inches, out)?;
    out.write_str("]\r\n[PRB:")?;
    write_axes_mm(&zero, inches, out)?;
    out.write_str(":0]\r\n")
}
