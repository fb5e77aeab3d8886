//! Per-step export of a move (being built: see the project's open issues).

fn main() {
    eprintln!("spreadsheet-export: not built yet");
    std::process::exit(1);
}
