//! The `L` reply's limit and homing lines ([`LimitLine`]): written by the
//! board, read back by a host.

use core::fmt;

use cogstep_motion::axis::{AxisError, Direction, HomeReport, LimitStatus, LimitTrip};

use super::LINE_END;

/// The `L` reply's three information lines: an axis's limit and homing
/// state (three lines, so that each stays within
/// [`REPLY_LINE_MAX`](crate::REPLY_LINE_MAX) whatever the numbers).
///
/// ```text
/// [limits 0 soft:-1000,50000 min:11/1 max:-]
/// [fault 0 max,51234,51234,120]
/// [home 0 ok,-1783,-3217,-3217,-3217,12]
/// ```
///
/// - `soft:` `<min>,<max>` or `none`; `min:`, `max:` the hard limit
///   inputs, `<pin>/<active level>` or `-`;
/// - `fault` `none`, or `<min|max>,<position>,<physical>,<stopping steps>`
///   of the trip;
/// - `home` `none` (never homed), `homing`, `ok,<seek position>,<seek
///   physical>,<latch position>,<latch physical>,<position>`, or
///   `error,<notfound|stuck|aborted|limit-min|limit-max|range|failed>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimitLine {
    /// The axis, 0-based.
    pub axis: usize,
    /// Its limit and homing state.
    pub status: LimitStatus,
}

fn side_word(side: Direction) -> &'static str {
    match side {
        Direction::Forward => "max",
        Direction::Reverse => "min",
    }
}

const HOME_ERRORS: [(&str, AxisError); 6] = [
    ("notfound", AxisError::HomeSwitchNotFound),
    ("stuck", AxisError::HomeSwitchStuck),
    ("aborted", AxisError::HomingAborted),
    ("limit-min", AxisError::IntoLimit(Direction::Reverse)),
    ("limit-max", AxisError::IntoLimit(Direction::Forward)),
    ("range", AxisError::PositionOutOfRange),
];

impl LimitLine {
    /// Writes the three lines, each with its line end.
    pub fn write_lines<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        let status = &self.status;
        write!(out, "[limits {} soft:", self.axis)?;
        match status.soft_limits {
            Some((min, max)) => write!(out, "{min},{max}")?,
            None => out.write_str("none")?,
        }
        out.write_str(" min:")?;
        crate::command::write_limit_pin(out, status.limit_pins[0])?;
        out.write_str(" max:")?;
        crate::command::write_limit_pin(out, status.limit_pins[1])?;
        write!(out, "]{LINE_END}[fault {} ", self.axis)?;
        match status.trip {
            Some(trip) => write!(
                out,
                "{},{},{},{}",
                side_word(trip.side),
                trip.position,
                trip.physical,
                trip.stopping_steps
            )?,
            None => out.write_str("none")?,
        }
        write!(out, "]{LINE_END}[home {} ", self.axis)?;
        match (status.homing, status.home_outcome) {
            (true, _) => out.write_str("homing")?,
            (false, None) => out.write_str("none")?,
            (false, Some(Ok(report))) => write!(
                out,
                "ok,{},{},{},{},{}",
                report.seek_position,
                report.seek_physical,
                report.latch_position,
                report.latch_physical,
                report.position
            )?,
            (false, Some(Err(error))) => {
                let word = HOME_ERRORS
                    .iter()
                    .find(|(_, known)| *known == error)
                    .map_or("failed", |(word, _)| word);
                write!(out, "error,{word}")?
            }
        }
        write!(out, "]{LINE_END}")
    }

    /// Reads one of the three lines (host side; with or without brackets
    /// and line end) into `status`, and returns its axis; `None` for a
    /// line that is none of them or is out of shape (`status` unchanged).
    pub fn parse_into(line: &str, status: &mut LimitStatus) -> Option<usize> {
        let inner = line.trim_end_matches(['\r', '\n']);
        let inner = inner.strip_prefix('[').unwrap_or(inner);
        let inner = inner.strip_suffix(']').unwrap_or(inner);
        let mut words = inner.split(' ');
        let kind = words.next()?;
        let axis = words.next()?.parse().ok()?;
        let mut read = *status;
        match kind {
            "limits" => {
                read.soft_limits = match words.next()?.strip_prefix("soft:")? {
                    "none" => None,
                    pair => {
                        let (min, max) = pair.split_once(',')?;
                        Some((min.parse().ok()?, max.parse().ok()?))
                    }
                };
                let pin = |word: &str| crate::command::parse_limit_pin(word.as_bytes()).ok();
                read.limit_pins = [
                    pin(words.next()?.strip_prefix("min:")?)?,
                    pin(words.next()?.strip_prefix("max:")?)?,
                ];
            }
            "fault" => {
                read.trip = match words.next()? {
                    "none" => None,
                    fault => {
                        let mut parts = fault.split(',');
                        let side = match parts.next()? {
                            "max" => Direction::Forward,
                            "min" => Direction::Reverse,
                            _ => return None,
                        };
                        let trip = LimitTrip {
                            side,
                            position: parts.next()?.parse().ok()?,
                            physical: parts.next()?.parse().ok()?,
                            stopping_steps: parts.next()?.parse().ok()?,
                        };
                        if parts.next().is_some() {
                            return None;
                        }
                        Some(trip)
                    }
                };
            }
            "home" => {
                (read.homing, read.home_outcome) = match words.next()? {
                    "none" => (false, None),
                    "homing" => (true, None),
                    home => {
                        let mut parts = home.split(',');
                        let outcome = match parts.next()? {
                            "ok" => {
                                let mut number = || parts.next()?.parse::<i64>().ok();
                                Ok(HomeReport {
                                    seek_position: number()?,
                                    seek_physical: number()?,
                                    latch_position: number()?,
                                    latch_physical: number()?,
                                    position: number()?,
                                })
                            }
                            "error" => {
                                let word = parts.next()?;
                                Err(HOME_ERRORS
                                    .iter()
                                    .find(|(known, _)| *known == word)
                                    .map_or(AxisError::Fault("homing failed"), |(_, e)| *e))
                            }
                            _ => return None,
                        };
                        if parts.next().is_some() {
                            return None;
                        }
                        (false, Some(outcome))
                    }
                };
            }
            _ => return None,
        }
        if words.next().is_some() {
            return None;
        }
        *status = read;
        Some(axis)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::String;

    use super::*;

    fn limit_lines(line: &LimitLine) -> String {
        let mut out = String::new();
        line.write_lines(&mut out).unwrap();
        out
    }

    #[test]
    fn limit_lines_read_back_and_fit_a_reply_line() {
        let report = HomeReport {
            seek_position: -1_783,
            seek_physical: -3_217,
            latch_position: -3_217,
            latch_physical: -3_217,
            position: 12,
        };
        let shown = LimitLine {
            axis: 0,
            status: LimitStatus {
                soft_limits: Some((-1_000, 50_000)),
                limit_pins: [Some((11, true)), None],
                trip: Some(LimitTrip {
                    side: Direction::Forward,
                    position: 51_234,
                    physical: 51_234,
                    stopping_steps: 120,
                }),
                homing: false,
                home_outcome: Some(Ok(report)),
            },
        };
        let text = limit_lines(&shown);
        assert_eq!(
            text,
            "[limits 0 soft:-1000,50000 min:11/1 max:-]\n\
             [fault 0 max,51234,51234,120]\n\
             [home 0 ok,-1783,-3217,-3217,-3217,12]\n"
        );
        let mut read = LimitStatus::default();
        for line in text.lines() {
            assert_eq!(LimitLine::parse_into(line, &mut read), Some(0));
        }
        assert_eq!(read, shown.status);
        let extreme = LimitLine {
            axis: 63,
            status: LimitStatus {
                soft_limits: Some((i64::MIN, i64::MAX)),
                limit_pins: [Some((63, false)), Some((62, true))],
                trip: Some(LimitTrip {
                    side: Direction::Reverse,
                    position: i64::MIN,
                    physical: i64::MIN,
                    stopping_steps: u64::MAX,
                }),
                homing: false,
                home_outcome: Some(Ok(HomeReport {
                    seek_position: i64::MIN,
                    seek_physical: i64::MIN,
                    latch_position: i64::MIN,
                    latch_physical: i64::MIN,
                    position: i64::MIN,
                })),
            },
        };
        let text = limit_lines(&extreme);
        let mut read = LimitStatus::default();
        for line in text.split_inclusive('\n') {
            assert!(line.len() <= crate::REPLY_LINE_MAX, "{line}");
            assert_eq!(LimitLine::parse_into(line, &mut read), Some(63));
        }
        assert_eq!(read, extreme.status);
        for error in HOME_ERRORS.map(|(_, error)| error) {
            let failed = LimitLine {
                axis: 1,
                status: LimitStatus {
                    home_outcome: Some(Err(error)),
                    ..LimitStatus::default()
                },
            };
            let mut read = LimitStatus::default();
            for line in limit_lines(&failed).lines() {
                LimitLine::parse_into(line, &mut read).unwrap();
            }
            assert_eq!(read, failed.status);
        }
        for bad in [
            "[home 0 ok,1,2]",
            "[fault 0 up,1,2,3]",
            "[limits x soft:none min:- max:-]",
        ] {
            let mut read = LimitStatus::default();
            assert_eq!(LimitLine::parse_into(bad, &mut read), None, "{bad}");
            assert_eq!(read, LimitStatus::default());
        }
    }
}
