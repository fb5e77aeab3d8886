//! What the interpreter refuses: a kind, at a line and column.

/// A G-code error: the line (as the caller numbered it), the 1-based
/// column (in characters) of the offending word, and what is wrong.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("line {line}, column {column}: {kind}")]
pub struct GcodeError {
    /// The line, as given to [`crate::Interpreter::interpret_line`]
    /// (1-based in [`crate::check`]).
    pub line: u32,
    /// The column of the offending word's letter (1-based, in characters);
    /// for an error of the line as a whole (a missing word), the column of
    /// the word that asked for it, or 1.
    pub column: u32,
    /// What is wrong.
    pub kind: GcodeErrorKind,
}

/// What is wrong with a line.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum GcodeErrorKind {
    /// Not a word: a character that is no letter, a letter without a
    /// number, a number in a form G-code does not have, an unclosed `(`.
    #[error("malformed word")]
    Malformed,
    /// A word outside the supported subset (for example `M3`, `S1000`,
    /// `G38.2`, `G18`).
    #[error("unsupported word {0}{1}")]
    UnsupportedWord(char, f64),
    /// An axis letter (upper case, as on the line) the machine does not
    /// have.
    #[error("the machine has no axis {0}")]
    UnknownAxis(char),
    /// The same letter twice on one line.
    #[error("{0} appears twice on the line")]
    RepeatedWord(char),
    /// Two of G0, G1, G2, G3 on one line.
    #[error("two motion words on one line")]
    TwoMotionWordsOnOneLine,
    /// Two words of one modal group (`G90 G91`, `G20 G21`, `G61 G64`, two
    /// of `G4 G28 G92`, two of `M0 M2 M30`), or `G28`/`G92` with a motion
    /// word (both would take the axis words).
    #[error("two words of one modal group on one line")]
    ModalGroupConflict,
    /// A word nothing on the line uses: `P` without `G4`, `I`, `J` or `R`
    /// without an arc.
    #[error("{0} is not used by anything on the line")]
    UnusedWord(char),
    /// A feed move (G1, G2, G3) before any `F`.
    #[error("a feed move needs a feed rate (F) first")]
    MissingFeed,
    /// `G4` without `P`.
    #[error("G4 needs a dwell time (P, seconds)")]
    MissingDwellTime,
    /// `G92` without an axis word.
    #[error("G92 needs at least one axis word")]
    MissingAxisWord,
    /// An arc without `I`/`J` or `R`.
    #[error("an arc needs I and J (the centre) or R (the radius)")]
    MissingArcParameter,
    /// An arc with both `R` and `I`/`J`.
    #[error("an arc takes either I and J or R, not both")]
    ArcFormsMixed,
    /// The arc's end is not on its circle: with I/J the end's radius
    /// differs from the start's by more than 0.5 mm, or by more than
    /// 0.005 mm and 0.1 % (grbl's tolerance); with R the end is more than
    /// that beyond the diameter.
    #[error("the arc's end is not on its circle")]
    ArcRadiusMismatch,
    /// An arc of radius 0 (`I0 J0`, `R0`).
    #[error("an arc's radius must be above 0")]
    ArcZeroRadius,
    /// An R arc that ends where it starts (a full circle needs I and J).
    #[error("an R arc cannot end where it starts (use I and J for a full circle)")]
    ArcEndIsStart,
    /// A number out of its range: `F` ≤ 0, `P` < 0, a position beyond the
    /// steps' range, a move of more than 2³¹ − 1 steps on an axis.
    #[error("number out of range")]
    NumberOutOfRange,
    /// A move that would end beyond a soft limit of the axis (the
    /// axis letter, lower case).
    #[error("the move would end beyond axis {axis}'s soft limit")]
    BeyondSoftLimit {
        /// The axis letter, lower case.
        axis: char,
    },
    /// G28 names an axis that has no home switch in the machine file (the
    /// axis letter, lower case).
    #[error("G28: axis {0} has no home switch")]
    NoHomeSwitch(char),
}
