//! From pin edges to steps: what a driver chip does with `sd` and `cc`
//! outputs.

/// Which of a driver's inputs an edge is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StepLine {
    /// `sd`: the step input; a rising edge is one step.
    Step,
    /// `sd`: the direction input; high = negative steps.
    Dir,
    /// `cc`: the clockwise input; a rising edge is one positive step.
    Cw,
    /// `cc`: the counter-clockwise input; a rising edge is one negative step.
    Ccw,
}

/// Turns the edges on a driver's inputs into steps, as a driver chip does:
/// the direction input's level is latched, and a step input's rising edge
/// moves the field one step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepDecoder {
    dir_high: bool,
}

impl StepDecoder {
    /// A decoder with the direction input low (positive steps).
    pub fn new() -> Self {
        Self::default()
    }

    /// An edge: `Some(forward)` when it makes a step.
    pub fn edge(&mut self, line: StepLine, level: bool) -> Option<bool> {
        match (line, level) {
            (StepLine::Dir, _) => {
                self.dir_high = level;
                None
            }
            (StepLine::Step, true) => Some(!self.dir_high),
            (StepLine::Cw, true) => Some(true),
            (StepLine::Ccw, true) => Some(false),
            (_, false) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sd_latches_the_direction_and_cc_names_it() {
        let mut sd = StepDecoder::new();
        assert_eq!(sd.edge(StepLine::Step, true), Some(true));
        assert_eq!(sd.edge(StepLine::Step, false), None);
        assert_eq!(sd.edge(StepLine::Dir, true), None);
        assert_eq!(sd.edge(StepLine::Step, true), Some(false));
        let mut cc = StepDecoder::new();
        assert_eq!(cc.edge(StepLine::Ccw, true), Some(false));
        assert_eq!(cc.edge(StepLine::Cw, true), Some(true));
        assert_eq!(cc.edge(StepLine::Cw, false), None);
    }
}
