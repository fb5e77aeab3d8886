//! Reading a reply line back, host side ([`Reply::parse`]).

use super::StatusLine;

/// One reply line as a host reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reply<'a> {
    /// `ok`: the command was carried out.
    Ok,
    /// `error:<code> <text>`: the command was refused; nothing changed.
    Error {
        /// The code number (see [`ErrorCode::from_number`](super::ErrorCode::from_number)).
        code: u8,
        /// The text after the code.
        text: &'a str,
    },
    /// `[...]`: information, the brackets removed.
    Info(&'a str),
    /// `<...>`: an axis's status.
    Status(StatusLine),
}

impl<'a> Reply<'a> {
    /// Reads one reply line (its line end, if any, is ignored). `None` for a
    /// line the protocol does not define.
    pub fn parse(line: &'a str) -> Option<Self> {
        let line = line.trim_end_matches(['\r', '\n']);
        if line == "ok" {
            return Some(Reply::Ok);
        }
        if let Some(rest) = line.strip_prefix("error:") {
            let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
            return Some(Reply::Error {
                code: code.parse().ok()?,
                text,
            });
        }
        if let Some(info) = line.strip_prefix('[') {
            return info.strip_suffix(']').map(Reply::Info);
        }
        if line.starts_with('<') {
            return StatusLine::parse(line).map(Reply::Status);
        }
        None
    }

    /// Whether this line ends the reply to a command (`ok` or `error:`).
    pub fn is_final(&self) -> bool {
        matches!(self, Reply::Ok | Reply::Error { .. })
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    #[test]
    fn replies_are_read_back() {
        assert_eq!(Reply::parse("ok\n"), Some(Reply::Ok));
        assert_eq!(
            Reply::parse("error:7 not idle"),
            Some(Reply::Error {
                code: 7,
                text: "not idle"
            })
        );
        assert_eq!(
            Reply::parse("[cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000]\n"),
            Some(Reply::Info(
                "cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000"
            ))
        );
        assert!(matches!(
            Reply::parse("<1|Idle|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>"),
            Some(Reply::Status(StatusLine { axis: 1, .. }))
        ));
        assert_eq!(Reply::parse("okay"), None);
        assert_eq!(Reply::parse("error:x y"), None);
        assert!(Reply::Ok.is_final());
        assert!(!Reply::Info("").is_final());
    }
}
