//! The README's "library in a minute" runs, and is the README's.
#![cfg(feature = "std")]

mod minute {
    include!("readme/minute.rs");

    pub fn run() -> Result<(), Box<dyn std::error::Error>> {
        main()
    }
}

#[test]
fn the_library_in_a_minute_runs() {
    minute::run().unwrap();
}

#[test]
fn the_readme_shows_this_very_code() {
    let readme = include_str!("../../README.md");
    let code = include_str!("readme/minute.rs");
    assert!(readme.contains(&format!("```rust\n{code}```\n")));
}

mod gcode {
    include!("readme/gcode.rs");

    pub fn run() -> Result<(), Box<dyn std::error::Error>> {
        main()
    }
}

#[test]
fn the_gcode_example_runs() {
    gcode::run().unwrap();
}

#[test]
fn the_readme_shows_the_gcode_example() {
    let readme = include_str!("../../README.md");
    let code = include_str!("readme/gcode.rs");
    assert!(readme.contains(&format!("```rust\n{code}```\n")));
}
