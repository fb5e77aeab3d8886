//! `spreadsheet-export`: the command-line shell over the library (see the
//! crate docs in `lib.rs`): parse, run, one line per error, exit code.

use std::io::ErrorKind;
use std::process::ExitCode;

use clap::error::ErrorKind as ClapErrorKind;
use clap::Parser;
use spreadsheet_export::cli::{Cli, Command};
use spreadsheet_export::{compare, run, ExportError};

fn main() -> ExitCode {
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
        let result = args.into_request().and_then(|(request, fastest)| {
            compare::run(&request, fastest, std::io::stdout().lock())
        });
        return match result {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) if broken_pipe(&error) => ExitCode::SUCCESS,
            Err(error) => fail(&error),
        };
    }
    if let Some(request) = cli.together_request() {
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
