//! Which language a board speaks on its serial line.

use core::fmt;
use core::str::FromStr;

/// What the board speaks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Dialect {
    /// The cogstep line protocol (`docs/protocol.md`).
    #[default]
    Cogstep,
    /// The P2 reference driver's demo screens and prompts ([`crate::p2demo`]).
    P2Demo,
    /// grbl 1.1's serial interface, for G-code senders ([`crate::grbl`]).
    Grbl,
}

impl Dialect {
    /// The name on command lines: `cogstep`, `p2demo` or `grbl`.
    pub fn as_str(self) -> &'static str {
        match self {
            Dialect::Cogstep => "cogstep",
            Dialect::P2Demo => "p2demo",
            Dialect::Grbl => "grbl",
        }
    }
}

/// `cogstep`, `p2demo` or `grbl`.
impl fmt::Display for Dialect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A dialect name that is not `cogstep`, `p2demo` or `grbl` (a
/// command-line parser shows the name given beside this message).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown dialect (expected cogstep, p2demo or grbl)")]
pub struct UnknownDialect;

/// Reads `cogstep`, `p2demo` or `grbl` (any case, surrounding blanks ignored).
impl FromStr for Dialect {
    type Err = UnknownDialect;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        let name = name.trim();
        if name.eq_ignore_ascii_case("cogstep") {
            Ok(Dialect::Cogstep)
        } else if name.eq_ignore_ascii_case("p2demo") {
            Ok(Dialect::P2Demo)
        } else if name.eq_ignore_ascii_case("grbl") {
            Ok(Dialect::Grbl)
        } else {
            Err(UnknownDialect)
        }
    }
}
