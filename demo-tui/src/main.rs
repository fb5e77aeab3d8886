//! The cogstep terminal demo (being built: see the project's open issues).

fn main() {
    eprintln!(
        "demo-tui: the terminal demo is not built yet; the motion core is in the `driver` crate"
    );
    std::process::exit(1);
}
