//! `spreadsheet-export`: the command-line shell over the library (see the
//! crate docs in `lib.rs`): parse, run, one line per error, exit code.

use std::io::ErrorKind;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::error::ErrorKind as ClapErrorKind;
use clap::Parser;
use spreadsheet_export::cli::{Cli, Command};
use spreadsheet_export::{compare, run, ExportError};

fn main() -> ExitCode {
    let stdout_open = stdout_is_open();
    // An interrupted export leaves no temporary file behind.
    if let Err(error) = spreadsheet_export::output::remove_temporaries_on_signals() {
        eprintln!("spreadsheet-export: cannot watch for signals: {error}");
        return ExitCode::from(2);
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error)
            if matches!(
                error.kind(),
                ClapErrorKind::DisplayHelp | ClapErrorKind::DisplayVersion
            ) =>
        {
            // --help and --version print as clap formats them.
            let _ = error.print();
            return ExitCode::SUCCESS;
        }
        Err(error) => return fail(&ExportError::Usage(one_line(&error.to_string()))),
    };
    if let Some(Command::Compare(args)) = cli.command {
        if !stdout_open {
            return fail(&ExportError::StdoutClosed);
        }
        let result = args.into_request().and_then(|(request, fastest)| {
            compare::run(&request, fastest, std::io::stdout().lock())
        });
        return match result {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) if broken_pipe(&error) => ExitCode::SUCCESS,
            Err(error) => fail(&error),
        };
    }
    if let Some(Command::Gcode(args)) = cli.command {
        return run_gcode(args, stdout_open);
    }
    if let Some(request) = cli.together_request() {
        if cli.output.is_none() && !stdout_open {
            return fail(&ExportError::StdoutClosed);
        }
        return match request.and_then(|request| run_together(&request, cli.output.as_deref())) {
            Ok(summary) => {
                eprintln!("spreadsheet-export: {}", summary.line());
                ExitCode::SUCCESS
            }
            Err(error) if broken_pipe(&error) => ExitCode::SUCCESS,
            Err(error) => fail(&error),
        };
    }
    let request = match cli.into_request() {
        Ok(request) => request,
        Err(error) => return fail(&error),
    };
    // --vcd alone writes nothing to stdout.
    if request.output.is_none() && request.vcd.is_none() && !stdout_open {
        return fail(&ExportError::StdoutClosed);
    }
    match run(&request, std::io::stdout().lock()) {
        Ok(outcome) => {
            if let Some(line) = outcome.motor_summary() {
                eprintln!("spreadsheet-export: {line}");
            }
            if let Some(line) = outcome.dynamics_summary() {
                eprintln!("spreadsheet-export: {line}");
            }
            ExitCode::from(outcome.exit_code() as u8)
        }
        Err(error) if broken_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => fail(&error),
    }
}

/// `gcode`: `--check` lists every error; a run writes its table and the
/// summary line.
fn run_gcode(args: spreadsheet_export::cli::GcodeArgs, stdout_open: bool) -> ExitCode {
    use spreadsheet_export::gcode;
    if args.check {
        let program = args.file.clone();
        let result =
            gcode::load_machine(&args.machine).and_then(|spec| gcode::check(&program, &spec));
        return match result {
            Ok(errors) if errors.is_empty() => {
                eprintln!("spreadsheet-export: {}: no errors", program.display());
                ExitCode::SUCCESS
            }
            Ok(errors) => {
                for error in &errors {
                    eprintln!("spreadsheet-export: {}: {error}", program.display());
                }
                fail(&ExportError::GcodeCheck {
                    path: program,
                    count: errors.len(),
                })
            }
            Err(error) => fail(&error),
        };
    }
    let request = match args.into_request() {
        Ok(request) => request,
        Err(error) => return fail(&error),
    };
    let table_on_stdout =
        request.output.is_none() && request.vcd.is_none() && request.plot.is_none();
    if table_on_stdout && !stdout_open {
        return fail(&ExportError::StdoutClosed);
    }
    match gcode::run(&request, std::io::stdout().lock()) {
        Ok(summary) => {
            eprintln!("spreadsheet-export: {}", summary.line());
            ExitCode::SUCCESS
        }
        Err(error) if broken_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => fail(&error),
    }
}

/// `--together`: the table to the -o file (whole or not at all) or stdout.
fn run_together(
    request: &spreadsheet_export::together::TogetherRequest,
    output: Option<&std::path::Path>,
) -> Result<spreadsheet_export::together::TogetherSummary, ExportError> {
    use spreadsheet_export::output::PendingFile;
    use spreadsheet_export::together;
    match output {
        None => together::run(request, std::io::BufWriter::new(std::io::stdout().lock())),
        Some(path) => {
            let mut pending = PendingFile::create(path)?;
            let summary = together::run(request, std::io::BufWriter::new(pending.file())).map_err(
                |error| match error {
                    ExportError::Write { source, .. } => ExportError::Write {
                        path: path.to_path_buf(),
                        source,
                    },
                    other => other,
                },
            )?;
            pending.commit()?;
            Ok(summary)
        }
    }
}

/// Whether file descriptor 1 was open when the process started. Rust's
/// runtime, before `main`, opens `/dev/null` on a closed fd 0, 1 or 2, so
/// `main` sees a stdout that takes every write: a table to it would
/// "succeed" having written nothing. This looks first, from the ELF
/// initialiser list, which runs before the runtime's set-up.
static STDOUT_OPEN_AT_START: AtomicBool = AtomicBool::new(true);

#[cfg(any(target_os = "linux", target_os = "android", target_os = "freebsd"))]
#[used]
#[link_section = ".init_array"]
static LOOK_AT_STDOUT: extern "C" fn() = {
    extern "C" fn look_at_stdout() {
        use std::os::fd::AsFd;
        // A duplicate of a closed descriptor fails with EBADF.
        let open = std::io::stdout().as_fd().try_clone_to_owned().is_ok();
        // Relaxed: one thread, before `main` exists to read it.
        STDOUT_OPEN_AT_START.store(open, Ordering::Relaxed);
    }
    look_at_stdout
};

fn stdout_is_open() -> bool {
    STDOUT_OPEN_AT_START.load(Ordering::Relaxed)
}

/// The reader of stdout went away (`| head`): nothing to report.
fn broken_pipe(error: &ExportError) -> bool {
    matches!(error, ExportError::Write { path, source }
        if path.as_os_str() == "-" && source.kind() == ErrorKind::BrokenPipe)
}

fn fail(error: &ExportError) -> ExitCode {
    eprintln!("spreadsheet-export: {error}");
    ExitCode::from(error.exit_code() as u8)
}

/// clap's message on one line: its lines up to the usage, joined, without
/// the leading "error: ".
fn one_line(message: &str) -> String {
    let text = message
        .lines()
        .map(str::trim)
        .take_while(|line| !line.starts_with("Usage:") && !line.starts_with("For more information"))
        .filter(|line| !line.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    let text = text.trim_start_matches("error: ");
    if text.is_empty() {
        "invalid command line (see --help)".to_string()
    } else {
        format!("{text} (see --help)")
    }
}
