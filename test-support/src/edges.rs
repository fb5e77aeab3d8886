//! Steps read back from a trace's pin edges alone.

use cogstep_motion::axis_core::{Edge, Outputs};

/// The CTs of the rising edges on `pin`, in order.
pub fn rising(edges: &[Edge], pin: u8) -> Vec<u64> {
    edges
        .iter()
        .filter(|edge| edge.pin == pin && edge.level)
        .map(|edge| edge.ct)
        .collect()
}

/// Every step an axis wired to `outputs` made, from the trace: the CT of
/// the step's rising edge and the signed step count after it, counted from
/// 0 (sd: step pulses, negative while the direction pin is high; cc: cw
/// pulses minus ccw pulses).
pub fn signed_steps(outputs: Outputs, trace: &[Edge]) -> Vec<(u64, i64)> {
    let mut reverse = false;
    let mut count = 0i64;
    let mut steps = Vec::new();
    for edge in trace {
        match outputs {
            Outputs::StepDir { step, dir } => {
                if edge.pin == dir {
                    reverse = edge.level;
                } else if edge.pin == step && edge.level {
                    count += if reverse { -1 } else { 1 };
                    steps.push((edge.ct, count));
                }
            }
            Outputs::CwCcw { cw, ccw } => {
                if edge.level && (edge.pin == cw || edge.pin == ccw) {
                    count += if edge.pin == cw { 1 } else { -1 };
                    steps.push((edge.ct, count));
                }
            }
        }
    }
    steps
}

/// The signed step count of an axis wired to `outputs`, from the trace.
pub fn position_from_edges(outputs: Outputs, trace: &[Edge]) -> i64 {
    signed_steps(outputs, trace)
        .last()
        .map_or(0, |&(_, count)| count)
}
