//! Prints the demo's screen as text, captured from a real run in a
//! pseudo-terminal (the README's screenshot comes from here):
//!
//! ```text
//! cargo build -p demo-tui && cargo run -p demo-tui --example screen_capture
//! ```
//!
//! It answers the prompts on axis 1 (20,000 steps at 20,000 steps/s),
//! starts axis 2 backwards, and captures the screen mid-move. Pass the
//! binary's path as the first argument to use another build, and the
//! demo's own arguments after it (`--axes 8`, ...).

#[path = "../tests/pty/mod.rs"]
mod pty;

use std::path::PathBuf;
use std::time::Duration;

fn main() {
    let binary = std::env::args_os().nth(1).map_or_else(
        || {
            // target/<profile>/examples/screen_capture → target/<profile>/demo-tui
            let mut path = std::env::current_exe().expect("own path");
            path.pop();
            path.pop();
            path.push("demo-tui");
            path
        },
        PathBuf::from,
    );
    let wait = Duration::from_secs(20);
    let demo_args: Vec<String> = std::env::args().skip(2).collect();
    let demo_args: Vec<&str> = demo_args.iter().map(String::as_str).collect();
    let demo = pty::Demo::spawn(&binary, &demo_args, pty::Keyboard::Legacy);
    demo.wait_text("Enter steps:", wait);
    demo.send(b"\t");
    demo.wait_text("▶ Axis 2", wait);
    demo.send(b"-6000\r");
    demo.wait_text("Enter speed:", wait);
    demo.send(b"8000\r");
    demo.wait_for("the prompt back", wait, |s| !s.contains("Enter speed:"));
    demo.send(b"\x1b[Z"); // Shift-Tab: back to axis 1
    demo.wait_text("▶ Axis 1", wait);
    demo.send(b"20000\r");
    demo.wait_text("Enter speed:", wait);
    demo.send(b"20000\r");
    let screen = demo.wait_for("axis 1 past 15000", wait, |s| {
        pty::number(s, "Current Position:", 1).is_some_and(|p| p > 15_500)
    });
    for line in screen.lines() {
        println!("{}", line.trim_end());
    }
    demo.send(b"q");
}
