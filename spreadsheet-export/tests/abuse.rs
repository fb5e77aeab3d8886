//! The programs under abuse (issue 27): the binary run as a user would,
//! fed what a careless or hostile caller feeds it. Each run is bounded in
//! time and memory (`ulimit` in a shell in front of the binary, a reader
//! that stops early, a few thousand steps).
#![cfg(unix)]

use std::io::Read;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");
const MOTORS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/motors");

fn export(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs the binary through `sh -c '<limits>; exec BIN "$@"'`.
fn limited(limits: &str, args: &[&str]) -> Command {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(format!("{limits}; exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(args);
    command
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Exit code 2 and exactly one line on stderr containing `expected`.
fn assert_one_line_error(output: &Output, expected: &str) {
    let message = stderr(output);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    assert_eq!(message.lines().count(), 1, "{message}");
    assert!(message.starts_with("spreadsheet-export: "), "{message}");
    assert!(message.contains(expected), "{message}");
}

fn entries(directory: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(directory)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn path_str(path: &Path) -> &str {
    path.to_str().unwrap()
}

// --- 3. Memory, input sizes, a full disk ---------------------------------

/// The group move of 2,147,483,647 steps streams: 20 MB of its table come
/// out under a 128 MiB address-space limit (it used to collect every edge
/// first, 67 bytes a step, and abort before writing a row).
#[test]
fn together_streams_in_bounded_memory() {
    let mut child = limited(
        "ulimit -v 131072",
        &["--together", "2147483647,-1000000,5", "--speed", "100000"],
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let wanted = 20_000_000;
    let mut table = Vec::with_capacity(wanted);
    child
        .stdout
        .take()
        .unwrap()
        .take(wanted as u64)
        .read_to_end(&mut table)
        .unwrap();
    // The reader goes away: the export ends on the broken pipe.
    let output = child.wait_with_output().unwrap();
    assert_eq!(table.len(), wanted, "{}", stderr(&output));
    let text = String::from_utf8_lossy(&table[..200]);
    assert!(
        text.starts_with(
            "time_s,ct_ticks,progress,axis0_position,axis1_position,axis2_position,deviation_steps\n0,0,0,0,0,0,0\n"
        ),
        "{text}"
    );
}

/// An endless motor file is refused at 1 MiB, by the export and by
/// `compare` (it used to be read until memory ran out).
#[test]
fn an_endless_motor_file_is_refused() {
    let export_args = ["--steps", "200", "--speed", "2000", "--motor", "/dev/zero"];
    let compare_args = [
        "compare",
        "--steps",
        "200",
        "--speed",
        "2000",
        "--motor",
        "/dev/zero",
    ];
    for args in [&export_args[..], &compare_args[..]] {
        let output = limited("ulimit -v 262144", args).output().unwrap();
        assert_one_line_error(&output, "motor file /dev/zero: larger than 1 MiB");
        assert!(output.stdout.is_empty());
    }
    let directory = tempfile::tempdir().unwrap();
    let big = directory.path().join("big.toml");
    let mut text = std::fs::read_to_string(format!("{MOTORS}/type-100.toml")).unwrap();
    text.push_str(&"# padding\n".repeat(120_000));
    std::fs::write(&big, text).unwrap();
    let output = export(&[
        "--steps",
        "200",
        "--speed",
        "2000",
        "--motor",
        path_str(&big),
    ]);
    assert_one_line_error(&output, "larger than 1 MiB");
}

/// A file-size limit stands in for a full disk (the same failed write):
/// the export stops with the write error and leaves no file behind, CSV
/// and XLSX (whose writer panics on it inside) alike.
#[test]
fn a_full_disk_stops_the_export_and_leaves_nothing() {
    for (name, steps) in [("big.csv", "-2147483648"), ("big.xlsx", "-1000000")] {
        let directory = tempfile::tempdir().unwrap();
        let destination = directory.path().join(name);
        // 1 MiB with 512-byte blocks, 2 MiB with 1 KiB ones.
        let output = limited(
            "ulimit -f 2048",
            &[
                "--steps",
                steps,
                "--speed",
                "40000",
                "-o",
                path_str(&destination),
            ],
        )
        .output()
        .unwrap();
        assert_one_line_error(&output, "File too large");
        assert!(stderr(&output).contains(name), "{}", stderr(&output));
        assert!(
            entries(directory.path()).is_empty(),
            "{name}: {:?}",
            entries(directory.path())
        );
    }
}

// --- 4. Outputs that name one file ---------------------------------------

#[test]
fn outputs_that_name_one_file_are_refused_before_writing() {
    let directory = tempfile::tempdir().unwrap();
    let dir = directory.path();
    std::fs::write(dir.join("real.csv"), "kept\n").unwrap();
    std::fs::hard_link(dir.join("real.csv"), dir.join("hard.vcd")).unwrap();
    std::os::unix::fs::symlink("real.csv", dir.join("soft.csv")).unwrap();
    std::os::unix::fs::symlink("new.vcd", dir.join("dangling.csv")).unwrap();
    std::fs::create_dir(dir.join("sub")).unwrap();
    let before = entries(dir);
    let at = |name: &str| path_str(&dir.join(name)).to_string();
    let cases: [(&[String], &str); 7] = [
        (
            &["-o".into(), at("v.vcd"), "--vcd".into(), at("v.vcd")],
            "-o and --vcd",
        ),
        (
            &["-o".into(), at("p.svg"), "--plot".into(), at("p.svg")],
            "-o and --plot",
        ),
        (
            &[
                "-o".into(),
                at("same.xlsx"),
                "--vcd".into(),
                at("same.xlsx"),
            ],
            "-o and --vcd",
        ),
        (
            &[
                "--vcd".into(),
                at("sub/../w.svg"),
                "--plot".into(),
                at("w.svg"),
            ],
            "--vcd and --plot",
        ),
        (
            &["-o".into(), at("soft.csv"), "--vcd".into(), at("real.csv")],
            "-o and --vcd",
        ),
        (
            &["-o".into(), at("real.csv"), "--vcd".into(), at("hard.vcd")],
            "-o and --vcd",
        ),
        (
            &[
                "-o".into(),
                at("dangling.csv"),
                "--vcd".into(),
                at("new.vcd"),
            ],
            "-o and --vcd",
        ),
    ];
    for (outputs, flags) in cases {
        let mut args = vec!["--steps", "200", "--speed", "2000"];
        args.extend(outputs.iter().map(String::as_str));
        let output = export(&args);
        assert_one_line_error(&output, &format!("{flags} name the same file"));
        assert_eq!(entries(dir), before, "{outputs:?}: nothing written");
    }
    assert_eq!(
        std::fs::read_to_string(dir.join("real.csv")).unwrap(),
        "kept\n"
    );
    // Distinct names still work, and /dev/null takes any number of outputs.
    let output = export(&[
        "--steps",
        "200",
        "--speed",
        "2000",
        "-o",
        &at("t.csv"),
        "--vcd",
        &at("t.vcd"),
        "--plot",
        &at("t.svg"),
    ]);
    assert!(output.status.success(), "{output:?}");
    let output = export(&[
        "--steps",
        "200",
        "--speed",
        "2000",
        "-o",
        "/dev/null",
        "--vcd",
        "/dev/null",
    ]);
    assert!(output.status.success(), "{output:?}");
}

// --- 8. Errors: TOML lines, non-finite figures, one line, closed stdout ---

#[test]
fn a_toml_error_in_column_one_names_its_own_line() {
    let directory = tempfile::tempdir().unwrap();
    let motor = directory.path().join("m.toml");
    std::fs::write(
        &motor,
        "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\nbogus = 1\n",
    )
    .unwrap();
    let output = export(&["--steps", "9", "--speed", "9", "--motor", path_str(&motor)]);
    assert_one_line_error(&output, "unknown field `bogus`");
    assert!(
        stderr(&output).trim_end().ends_with("(line 4)"),
        "{}",
        stderr(&output)
    );
}

/// `damping_nm_s_per_rad = 1e30` made the rotor model's lag NaN (or 1e57
/// steps): refused with the reason, by the export and by `compare`.
#[test]
fn damping_the_rotor_model_cannot_follow_is_refused() {
    let directory = tempfile::tempdir().unwrap();
    let motor = directory.path().join("heavy.toml");
    let text = std::fs::read_to_string(format!("{MOTORS}/type-100.toml")).unwrap();
    let text: String = text
        .lines()
        .map(|line| match line.starts_with("damping_nm_s_per_rad") {
            true => "damping_nm_s_per_rad = 1e30\n".to_string(),
            false => format!("{line}\n"),
        })
        .collect();
    std::fs::write(&motor, text).unwrap();
    let motor = path_str(&motor);
    let output = export(&[
        "--steps",
        "200",
        "--speed",
        "2000",
        "--motor",
        motor,
        "--dynamics",
    ]);
    assert_one_line_error(&output, "damping_nm_s_per_rad = 1e30 gives a damping ratio");
    assert!(output.stdout.is_empty(), "no rows");
    let output = export(&[
        "compare", "--steps", "200", "--speed", "2000", "--motor", motor,
    ]);
    assert_one_line_error(&output, "damping ratio");
    assert!(!String::from_utf8_lossy(&output.stdout).contains("NaN"));
}

/// Only the real error, once (the zip writer's drop message came first).
#[cfg(target_os = "linux")]
#[test]
fn an_xlsx_to_a_full_device_is_one_error_line() {
    for format in ["xlsx", "csv"] {
        let output = export(&[
            "--steps",
            "2000",
            "--speed",
            "4000",
            "-o",
            "/dev/full",
            "--format",
            format,
        ]);
        assert_one_line_error(
            &output,
            "cannot write /dev/full: No space left on device (os error 28)",
        );
    }
}

/// A table to a closed stdout fails: Rust's runtime puts /dev/null on a
/// closed fd 1, where the table used to vanish with exit 0. (The binary
/// looks at fd 1 before that on ELF systems only.)
#[cfg(any(target_os = "linux", target_os = "android", target_os = "freebsd"))]
#[test]
fn a_table_to_a_closed_stdout_fails() {
    let motor = format!("{MOTORS}/type-100.toml");
    let cases: [&[&str]; 3] = [
        &["--steps", "200", "--speed", "2000"],
        &["--together", "200,-50", "--speed", "2000"],
        &[
            "compare", "--steps", "200", "--speed", "2000", "--motor", &motor,
        ],
    ];
    for args in cases {
        let output = limited("exec >&-", args).output().unwrap();
        assert_one_line_error(&output, "standard output is closed");
    }
    // A table to a file needs no stdout.
    let directory = tempfile::tempdir().unwrap();
    let table = directory.path().join("t.csv");
    let output = limited(
        "exec >&-",
        &["--steps", "200", "--speed", "2000", "-o", path_str(&table)],
    )
    .output()
    .unwrap();
    assert!(output.status.success(), "{output:?}");
    assert_eq!(
        std::fs::read_to_string(&table).unwrap().lines().count(),
        201
    );
}

/// Starts a long export into a fresh directory, waits for its temporary
/// file, sends `signal`: the process dies of it (a shell sees 128 + the
/// signal) and leaves nothing behind.
fn interrupt(signal: Signal) {
    let directory = tempfile::tempdir().unwrap();
    let destination = directory.path().join("big.csv");
    let mut child = Command::new(BIN)
        .args(["--steps", "2000000000", "--speed", "40000", "-o"])
        .arg(&destination)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !entries(directory.path())
        .iter()
        .any(|name| name.starts_with(".spreadsheet-export-"))
    {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no temporary file"
        );
        assert!(child.try_wait().unwrap().is_none(), "ended early");
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(100));
    kill(Pid::from_raw(child.id() as i32), signal).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(
        status.signal(),
        Some(signal as i32),
        "{signal:?}: {status:?}"
    );
    assert!(
        entries(directory.path()).is_empty(),
        "{signal:?}: {:?}",
        entries(directory.path())
    );
}

#[test]
fn sigusr1_and_other_stopping_signals_remove_the_temporary_file() {
    for signal in [
        Signal::SIGUSR1,
        Signal::SIGUSR2,
        Signal::SIGHUP,
        Signal::SIGALRM,
    ] {
        interrupt(signal);
    }
}

// --- 5. The VCD's first step, as sigrok reads it --------------------------

/// Rising edges of `channel` in a VCD: changes to 1 from 0, the levels at
/// the first time being the start (not edges).
fn rises(vcd: &str, channel: &str) -> u64 {
    let id = vcd
        .lines()
        .filter_map(|line| {
            let words: Vec<&str> = line.split_whitespace().collect();
            match words.as_slice() {
                ["$var", "wire", "1", id, name, "$end"] if *name == channel => Some(id.to_string()),
                _ => None,
            }
        })
        .next()
        .unwrap_or_else(|| panic!("no wire {channel}"));
    let body = &vcd[vcd.find("$enddefinitions").expect("a VCD")..];
    let (mut level, mut count, mut started) = (None, 0, false);
    for word in body.split_whitespace() {
        if let Some(time) = word.strip_prefix('#') {
            // The first time's values are the initial levels.
            started |= time != "0";
            continue;
        }
        let (value, word_id) = word.split_at(1);
        if word_id != id || !matches!(value, "0" | "1") {
            continue;
        }
        let high = value == "1";
        if high && level == Some(false) && started {
            count += 1;
        }
        level = Some(high);
    }
    count
}

/// sigrok (PulseView's engine) counts every step of a forward `sd` move,
/// a reverse `cc` move and a P2Exact move: the first edge comes after the
/// levels at time 0. Without `sigrok-cli` (Debian: `apt-get install
/// sigrok-cli`) it says it skipped sigrok and checks the file itself: no
/// value changes at time 0 but the initial levels, the pulse pins low.
#[test]
fn every_step_of_the_vcd_is_an_edge_sigrok_counts() {
    let sigrok = Command::new("sigrok-cli").arg("--version").output().is_ok();
    if !sigrok {
        assert!(
            std::env::var_os("COGSTEP_REQUIRE_SIGROK").is_none(),
            "COGSTEP_REQUIRE_SIGROK is set but sigrok-cli is not installed"
        );
        eprintln!("sigrok-cli is not installed: skipped sigrok, checking the VCD text only");
    }
    let directory = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str, u64); 3] = [
        (&["--steps", "2000", "--outputs", "sd"], "axis1_step", 2_000),
        (&["--steps", "-1500", "--outputs", "cc"], "axis1_ccw", 1_500),
        (
            &["--steps", "777", "--outputs", "sd", "--profile", "p2-exact"],
            "axis1_step",
            777,
        ),
    ];
    for (i, (args, pulse, steps)) in cases.into_iter().enumerate() {
        let path: PathBuf = directory.path().join(format!("m{i}.vcd"));
        let mut full = vec!["--speed", "4000", "--vcd", path_str(&path)];
        full.extend_from_slice(args);
        let output = export(&full);
        assert!(output.status.success(), "{output:?}");
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(rises(&text, pulse), steps, "{args:?}: the file itself");
        // Time 0 holds the $dumpvars levels and nothing else; pulse pins low.
        let after_definitions = &text[text.find("$enddefinitions").unwrap()..];
        let dump = &after_definitions[after_definitions.find("$dumpvars").unwrap()..];
        let (levels, rest) = dump.split_once("$end").unwrap();
        let first_word = rest.split_whitespace().next().unwrap();
        assert!(
            first_word.starts_with('#') && first_word != "#0",
            "{args:?}: a change at time 0: {first_word}"
        );
        assert!(levels.contains('0'), "{levels}");
        if sigrok {
            let output = Command::new("sigrok-cli")
                .args(["-I", "vcd:downsample=100", "-i"])
                .arg(&path)
                .args(["-O", "vcd"])
                .output()
                .expect("sigrok-cli runs");
            assert!(output.status.success(), "{output:?}");
            let resampled = String::from_utf8(output.stdout).unwrap();
            assert_eq!(
                rises(&resampled, pulse),
                steps,
                "{args:?}: as sigrok reads it"
            );
        }
    }
}
