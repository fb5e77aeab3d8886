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
}

impl Dialect {
    /// The name on command lines: `cogstep` or `p2demo`.
    pub fn as_str(self) -> &'static str {
        match self {
            Dialect::Cogstep => "cogstep",
            Dialect::P2Demo => "p2demo",
        }
    }
}

/// `cogstep` or `p2demo`.
impl fmt::Display for Dialect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A dialect name that is neither `cogstep` nor `p2demo` (a command-line
/// parser shows the name given beside this message).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown dialect (expected cogstep or p2demo)")]
pub struct UnknownDialect;

/// Reads `cogstep` or `p2demo` (any case, surrounding blanks ignored).
impl FromStr for Dialect {
    type Err = UnknownDialect;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        let name = name.trim();
        if name.eq_ignore_ascii_case("cogstep") {
            Ok(Dialect::Cogstep)
        } else if name.eq_ignore_ascii_case("p2demo") {
            Ok(Dialect::P2Demo)
        } else {
            Err(UnknownDialect)
        }
    }
}
