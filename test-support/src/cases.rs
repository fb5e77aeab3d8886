//! Case counts for property tests.

/// How many random cases a property runs: `default`, or the number in
/// `COGSTEP_MODEL_CASES` (the long `--ignored` runs set it).
pub fn cases(default: u32) -> u32 {
    std::env::var("COGSTEP_MODEL_CASES")
        .ok()
        .and_then(|cases| cases.parse().ok())
        .unwrap_or(default)
}
