//! The reference demo's two questions, `Enter steps:` then `Enter speed:`,
//! and the answers they accept. A refused answer comes back as a short
//! reason for the prompt line; nothing is sent.

/// The longest answer a prompt takes, in characters.
pub const FIELD_MAX: usize = 12;

/// Which question the prompt asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// `Enter steps:` (signed: the sign is the direction).
    Steps,
    /// `Enter speed:` (steps/s), for a move of `steps` steps.
    Speed {
        /// The answer to `Enter steps:`.
        steps: i32,
    },
    /// `Group steps:` (`g`): one signed step count per axis, axis 1 first,
    /// separated by spaces, for a coordinated move.
    GroupSteps,
    /// `Enter speed:` for the group move whose steps the prompt holds.
    GroupSpeed,
}

/// The longest answer to `Group steps:`, in characters (eight axes).
pub const GROUP_FIELD_MAX: usize = 8 * FIELD_MAX;

/// Reads an answer to `Group steps:`: one signed step count per axis
/// (0 allowed: that axis stays still), separated by spaces, at most `axes`
/// of them and at least one not 0.
pub fn parse_group_steps(field: &str, axes: usize) -> Result<Vec<i32>, String> {
    let words: Vec<&str> = field.split_whitespace().collect();
    if words.is_empty() {
        return Err("type one number of steps per axis, axis 1 first (e.g. 2000 -500 0)".into());
    }
    if words.len() > axes {
        return Err(format!(
            "{} numbers for {axes} ax{}: one per axis",
            words.len(),
            if axes == 1 { "is" } else { "es" }
        ));
    }
    let steps = words
        .iter()
        .map(|word| match parse_steps(word) {
            Ok(steps) => Ok(steps),
            Err(_)
                if word.trim_start_matches('-').bytes().all(|b| b == b'0')
                    && !word.trim_start_matches('-').is_empty() =>
            {
                Ok(0)
            }
            Err(reason) => Err(reason),
        })
        .collect::<Result<Vec<i32>, String>>()?;
    if steps.iter().all(|steps| *steps == 0) {
        return Err("every axis has 0 steps: nothing to move".into());
    }
    Ok(steps)
}

/// Reads an answer to `Enter steps:`: a signed, non-zero step count.
pub fn parse_steps(field: &str) -> Result<i32, String> {
    let digits = field.strip_prefix('-').unwrap_or(field);
    if field.is_empty() {
        return Err("type a number of steps first (e.g. 2000, or -2000 to go back)".into());
    }
    if digits.is_empty() {
        return Err("type the digits after '-'".into());
    }
    if !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("'{field}' is not a whole number of steps"));
    }
    let steps: i64 = field
        .parse()
        .map_err(|_| format!("'{field}' is too large: at most {} steps", i32::MAX))?;
    let steps = i32::try_from(steps)
        .map_err(|_| format!("{steps} is too large: at most {} steps per move", i32::MAX))?;
    if steps == 0 {
        return Err("0 steps: nothing to move".into());
    }
    Ok(steps)
}

/// Reads an answer to `Enter speed:`: steps/s, at least 1, at most `max`
/// when the backend knows its limit. An empty answer takes `default` (the
/// last speed used) when there is one.
pub fn parse_speed(field: &str, default: Option<u32>, max: Option<u32>) -> Result<u32, String> {
    let speed = if field.is_empty() {
        default.ok_or_else(|| "type a speed in steps/s (e.g. 20000)".to_string())?
    } else {
        if !field.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!(
                "'{field}' is not a speed: type steps/s, digits only"
            ));
        }
        let speed: u64 = field
            .parse()
            .map_err(|_| format!("'{field}' is too fast"))?;
        u32::try_from(speed).map_err(|_| format!("{speed} steps/s is too fast"))?
    };
    if speed == 0 {
        return Err("speed must be at least 1 step/s".into());
    }
    if let Some(max) = max {
        if speed > max {
            return Err(format!(
                "{speed} steps/s is too fast: at most {max} steps/s here"
            ));
        }
    }
    Ok(speed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_signed_non_zero_whole_numbers() {
        assert_eq!(parse_steps("2000"), Ok(2000));
        assert_eq!(parse_steps("-2000"), Ok(-2000));
        assert_eq!(parse_steps("007"), Ok(7));
        assert_eq!(parse_steps(&i32::MAX.to_string()), Ok(i32::MAX));
        for bad in [
            "",
            "-",
            "0",
            "-0",
            "--5",
            "1-2",
            "2147483648",
            "99999999999999999999",
        ] {
            let reason = parse_steps(bad).expect_err(bad);
            assert!(!reason.is_empty());
        }
        assert_eq!(
            parse_steps("0").unwrap_err(),
            "0 steps: nothing to move".to_string()
        );
    }

    #[test]
    fn group_steps_are_one_number_per_axis() {
        assert_eq!(parse_group_steps("2000 -500 0", 3), Ok(vec![2000, -500, 0]));
        assert_eq!(parse_group_steps("  7   0 ", 4), Ok(vec![7, 0]));
        assert_eq!(parse_group_steps("-0 5", 2), Ok(vec![0, 5]));
        for (bad, axes) in [
            ("", 3),
            ("1 2 3 4", 3),
            ("0 0", 2),
            ("1 x", 2),
            ("1 -", 2),
            ("2147483648", 1),
        ] {
            let reason = parse_group_steps(bad, axes).expect_err(bad);
            assert!(!reason.is_empty());
        }
    }

    #[test]
    fn speed_is_positive_bounded_and_defaults_to_the_last_one() {
        assert_eq!(parse_speed("20000", None, Some(199_600)), Ok(20_000));
        assert_eq!(parse_speed("", Some(5_000), None), Ok(5_000));
        assert!(parse_speed("", None, None).is_err());
        assert!(parse_speed("0", None, None).is_err());
        assert!(parse_speed("-5", None, None).is_err());
        assert!(parse_speed("199601", None, Some(199_600)).is_err());
        assert!(parse_speed("99999999999", None, None).is_err());
    }
}
