//! The status line (`<...>`, [`StatusLine`]): written by the board from
//! an axis's status, read back by a host.

use core::fmt;

use cogstep_motion::axis::{AxisState, AxisStatus, Mode};

/// One status line: `<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusLine {
    /// The axis, 0-based.
    pub axis: usize,
    /// `Idle`, `Run`, `Jog`, `Hold` or `Alarm`.
    pub state: AxisState,
    /// Steps from the origin.
    pub position: i64,
    /// The reference's STM: the signed steps of a command not yet taken
    /// (0 once the axis has it, which is always so when a board replies).
    pub stm: i32,
    /// Steps still to make; 0 exactly when the axis is idle.
    pub steps_to_go: u64,
    /// The reference driver's 6 mode bits (bits 0–5).
    pub mode_bits: u8,
    /// The velocity of the last step, steps/s.
    pub velocity_steps_per_s: u32,
    /// Whether the stop pin is high.
    pub stop_pin_high: bool,
}

impl StatusLine {
    /// The status line of one axis.
    pub fn new(axis: usize, status: &AxisStatus) -> Self {
        StatusLine {
            axis,
            state: status.state(),
            position: status.position,
            stm: status.stm,
            steps_to_go: status.steps_to_go,
            // bits() keeps 6 bits, so the cast is exact.
            mode_bits: status.mode.reference_bits() as u8,
            velocity_steps_per_s: status.velocity_steps_per_s,
            stop_pin_high: status.stop_pin_high,
        }
    }

    /// Reads a status line back (host side). The line end, if any, is
    /// ignored; anything else out of shape gives `None`.
    pub fn parse(line: &str) -> Option<Self> {
        let inner = line
            .trim_end_matches(['\r', '\n'])
            .strip_prefix('<')?
            .strip_suffix('>')?;
        let mut fields = inner.split('|');
        let axis = fields.next()?.parse().ok()?;
        let state = match fields.next()? {
            "Idle" => AxisState::Idle,
            "Run" => AxisState::Run,
            "Jog" => AxisState::Jog,
            "Hold" => AxisState::Hold,
            "Alarm" => AxisState::Alarm,
            _ => return None,
        };
        let position = fields.next()?.strip_prefix("pos:")?.parse().ok()?;
        let stm = fields.next()?.strip_prefix("stm:")?.parse().ok()?;
        let steps_to_go = fields.next()?.strip_prefix("togo:")?.parse().ok()?;
        let mode = fields.next()?.strip_prefix("mode:")?;
        if mode.len() != 6 || !mode.bytes().all(|b| b == b'0' || b == b'1') {
            return None;
        }
        let mode_bits = u8::from_str_radix(mode, 2).ok()?;
        let velocity_steps_per_s = fields.next()?.strip_prefix("vel:")?.parse().ok()?;
        let stop_pin_high = match fields.next()?.strip_prefix("stop:")? {
            "high" => true,
            "low" => false,
            _ => return None,
        };
        if fields.next().is_some() {
            return None;
        }
        Some(StatusLine {
            axis,
            state,
            position,
            stm,
            steps_to_go,
            mode_bits,
            velocity_steps_per_s,
            stop_pin_high,
        })
    }
}

/// The status line without its line end.
impl fmt::Display for StatusLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mode = Mode(u32::from(self.mode_bits)).binary();
        write!(
            f,
            "<{}|{}|pos:{}|stm:{}|togo:{}|mode:",
            self.axis,
            self.state.as_str(),
            self.position,
            self.stm,
            self.steps_to_go
        )?;
        for digit in mode {
            fmt::Write::write_char(f, char::from(digit))?;
        }
        let stop = if self.stop_pin_high { "high" } else { "low" };
        write!(f, "|vel:{}|stop:{stop}>", self.velocity_steps_per_s)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    #[test]
    fn the_status_line_format_is_exact() {
        let status = AxisStatus {
            position: 1200,
            stm: 0,
            steps_to_go: 800,
            mode: Mode(0b001011),
            velocity_steps_per_s: 20_000,
            stop_pin_high: true,
        };
        let line = StatusLine::new(0, &status);
        assert_eq!(
            std::format!("{line}"),
            "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>"
        );
        assert_eq!(
            StatusLine::parse(
                "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>\r\n"
            ),
            Some(line)
        );

        let alarm = AxisStatus {
            position: -5,
            stm: 0,
            steps_to_go: 0,
            mode: Mode::ESTOP | Mode::STOP_LATCHED | Mode::REVERSE,
            velocity_steps_per_s: 0,
            stop_pin_high: false,
        };
        assert_eq!(
            std::format!("{}", StatusLine::new(7, &alarm)),
            "<7|Alarm|pos:-5|stm:0|togo:0|mode:110000|vel:0|stop:low>"
        );
    }

    #[test]
    fn status_lines_out_of_shape_are_not_read() {
        for line in [
            "<0|Run|pos:1|stm:0|togo:1|mode:00101|vel:1|stop:high>",
            "<0|Walk|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high|x>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001021|vel:1|stop:high>",
            "<0|Run|pos:1|stm:-1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:up>",
            "0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high>",
            "<0|Run|pos:1|stm:0|togo:1|mode:001011|vel:1|stop:high",
        ] {
            assert_eq!(StatusLine::parse(line), None, "{line}");
        }
    }
}
