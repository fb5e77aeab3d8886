//! `spreadsheet-export --vcd`: the move on an emulated cog, read back with
//! an independent VCD reader (the `vcd` crate's parser).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

use driver::profile::scurve::{SCurve, ScurveConfig};
use proptest::prelude::*;

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");

fn export(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A VCD as a reader sees it: names, time-0 levels, changes and timescale.
struct Waveform {
    timescale: (u32, vcd::TimescaleUnit),
    initial: BTreeMap<String, bool>,
    changes: Vec<(u64, String, bool)>,
    /// The last time in the file.
    end: u64,
}

impl Waveform {
    fn read(path: &Path) -> Self {
        let bytes = std::fs::read(path).expect("the VCD exists");
        let mut parser = vcd::Parser::new(&bytes[..]);
        let header = parser.parse_header().expect("a VCD header");
        let scope = header.find_scope(&["cogstep"]).expect("scope cogstep");
        let names: BTreeMap<vcd::IdCode, String> = scope
            .items
            .iter()
            .filter_map(|item| match item {
                vcd::ScopeItem::Var(var) => Some((var.code, var.reference.clone())),
                _ => None,
            })
            .collect();
        let mut wave = Waveform {
            timescale: header.timescale.expect("a timescale"),
            initial: BTreeMap::new(),
            changes: Vec::new(),
            end: 0,
        };
        let (mut time, mut in_dump) = (0, false);
        for command in parser {
            match command.expect("a VCD command") {
                vcd::Command::Timestamp(t) => {
                    time = t;
                    wave.end = t;
                }
                vcd::Command::Begin(_) => in_dump = true,
                vcd::Command::End(_) => in_dump = false,
                vcd::Command::ChangeScalar(id, value) => {
                    let name = names[&id].clone();
                    let level = value == vcd::Value::V1;
                    if in_dump {
                        wave.initial.insert(name, level);
                    } else {
                        wave.changes.push((time, name, level));
                    }
                }
                _ => {}
            }
        }
        wave
    }

    fn rises(&self, name: &str) -> Vec<u64> {
        self.changes
            .iter()
            .filter(|(_, n, level)| n == name && *level)
            .map(|(t, _, _)| *t)
            .collect()
    }

    /// The level of `name` just before `time`.
    fn level_before(&self, name: &str, time: u64) -> bool {
        self.changes
            .iter()
            .rfind(|(t, n, _)| n == name && *t < time)
            .map_or(self.initial[name], |(_, _, level)| *level)
    }
}

#[test]
fn vcd_alone_writes_only_the_vcd_with_every_pin() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("move.vcd");
    let output = export(&[
        "--steps",
        "3000",
        "--speed",
        "20000",
        "--vcd",
        path.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{output:?}");
    assert!(output.stdout.is_empty(), "no table without -o");
    assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
    let wave = Waveform::read(&path);
    assert_eq!(wave.timescale, (1, vcd::TimescaleUnit::NS));
    let names: Vec<&str> = wave.initial.keys().map(String::as_str).collect();
    assert_eq!(names, ["axis1_dir", "axis1_step", "axis1_stop"]);
    assert!(
        wave.initial["axis1_stop"],
        "the stop pin is high from time 0"
    );
    let rises = wave.rises("axis1_step");
    assert_eq!(rises.len(), 3_000);
    assert!(
        !wave.level_before("axis1_dir", rises[0]),
        "forward: dir low"
    );
    // The intervals are the profile's delays, 5 ns a tick.
    let delays: Vec<u64> = SCurve::new(ScurveConfig::default(), 20_000, 3_000)
        .unwrap()
        .map(|step| u64::from(step.delay_ticks) * 5)
        .collect();
    for (i, pair) in rises.windows(2).enumerate() {
        assert_eq!(pair[1] - pair[0], delays[i], "after step {i}");
    }
    assert_eq!(wave.end, rises[2_999] + delays[2_999], "ends with the move");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("one CT tick = 5 ns"), "{text:.600}");
}

#[test]
fn vcd_with_a_table_writes_both() {
    let directory = tempfile::tempdir().unwrap();
    let vcd_path = directory.path().join("m.vcd");
    let csv_path = directory.path().join("m.csv");
    let output = export(&[
        "--steps",
        "-500",
        "--speed",
        "8000",
        "--profile",
        "p2-exact",
        "--outputs",
        "cc",
        "--vcd",
        vcd_path.to_str().unwrap(),
        "-o",
        csv_path.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{output:?}");
    let table = std::fs::read_to_string(&csv_path).unwrap();
    assert_eq!(table.lines().count(), 501);
    let wave = Waveform::read(&vcd_path);
    let names: Vec<&str> = wave.initial.keys().map(String::as_str).collect();
    assert_eq!(names, ["axis1_ccw", "axis1_cw", "axis1_stop"]);
    assert_eq!(wave.rises("axis1_ccw").len(), 500);
    assert!(wave.rises("axis1_cw").is_empty());
    // The same move: the intervals between pulses are the table's periods
    // (rising edge to rising edge: for p2-exact, delay + pulse + overhead).
    let column = table
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|name| name == "period_ticks")
        .expect("a period_ticks column");
    let delays: Vec<u64> = table
        .lines()
        .skip(1)
        .map(|line| line.split(',').nth(column).unwrap().parse().unwrap())
        .collect();
    let rises = wave.rises("axis1_ccw");
    for (i, pair) in rises.windows(2).enumerate() {
        assert_eq!(pair[1] - pair[0], delays[i] * 5, "after step {i}");
    }
}

#[test]
fn vcd_refusals_are_one_line_and_leave_nothing() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("m.vcd");
    let vcd = path.to_str().unwrap();
    for (args, reason) in [
        (
            vec![
                "--steps",
                "10",
                "--speed",
                "100",
                "--profile",
                "leib",
                "--accel",
                "9",
            ],
            "use --profile p2 or p2-exact",
        ),
        (
            vec!["--steps", "3000000000", "--speed", "100"],
            "at most 2147483647 steps",
        ),
        (
            vec!["--steps", "10", "--speed", "1000000"],
            "cannot run this move",
        ),
    ] {
        let mut all = args.clone();
        all.extend(["--vcd", vcd]);
        let output = export(&all);
        let message = String::from_utf8(output.stderr.clone()).unwrap();
        assert_eq!(output.status.code(), Some(2), "{all:?}: {message}");
        assert!(message.contains(reason), "{message}");
        assert_eq!(message.lines().count(), 1, "{message}");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Any move: exactly |steps| rising edges on the pulse pin, the
    /// direction pin at the move's level (set up in time) before the first.
    #[test]
    fn the_vcd_has_one_rise_per_step_and_the_direction_first(
        steps in prop_oneof![-3_000i32..=-1, 1i32..=3_000],
        speed in 200u32..60_000,
        exact in any::<bool>(),
        cc in any::<bool>(),
    ) {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("m.vcd");
        let (steps_arg, speed_arg) = (steps.to_string(), speed.to_string());
        let profile = if exact { "p2-exact" } else { "p2" };
        let outputs = if cc { "cc" } else { "sd" };
        let output = export(&[
            "--steps", &steps_arg, "--speed", &speed_arg, "--profile", profile,
            "--outputs", outputs, "--vcd", path.to_str().unwrap(),
        ]);
        prop_assert!(output.status.success(), "{:?}", output);
        let wave = Waveform::read(&path);
        let magnitude = steps.unsigned_abs() as usize;
        if cc {
            let (on, off) = if steps > 0 { ("axis1_cw", "axis1_ccw") } else { ("axis1_ccw", "axis1_cw") };
            prop_assert_eq!(wave.rises(on).len(), magnitude);
            prop_assert!(wave.rises(off).is_empty());
        } else {
            let rises = wave.rises("axis1_step");
            prop_assert_eq!(rises.len(), magnitude);
            let reverse = steps < 0;
            prop_assert_eq!(wave.level_before("axis1_dir", rises[0]), reverse);
            if reverse {
                // Set up 1,000 ticks (5 µs) before the first step.
                prop_assert!(rises[0] >= 5_000);
                prop_assert!(wave.level_before("axis1_dir", rises[0] - 4_999));
            }
            prop_assert!(wave.changes.iter().filter(|c| c.1 == "axis1_dir").count() <= 1);
        }
        // Every pulse ends: the pulse pins end low (dir keeps its level).
        for name in ["axis1_step", "axis1_cw", "axis1_ccw"].into_iter().filter(|n| wave.initial.contains_key(*n)) {
            prop_assert!(!wave.level_before(name, u64::MAX));
        }
    }
}

/// sigrok, PulseView's engine, reads the file and counts the steps. Runs
/// where `sigrok-cli` is installed (Debian: `apt-get install sigrok-cli`);
/// elsewhere it says it was skipped, unless `COGSTEP_REQUIRE_SIGROK=1`
/// makes the absence a failure (CI with the package).
#[test]
fn sigrok_reads_the_vcd_and_counts_every_step() {
    if Command::new("sigrok-cli")
        .arg("--version")
        .output()
        .is_err()
    {
        assert!(
            std::env::var_os("COGSTEP_REQUIRE_SIGROK").is_none(),
            "COGSTEP_REQUIRE_SIGROK is set but sigrok-cli is not installed"
        );
        eprintln!("sigrok-cli is not installed: skipped");
        return;
    }
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("m.vcd");
    // A short ramp (--accel-div 100) keeps the capture small: ~60 ms.
    let output = export(&[
        "--steps",
        "-1000",
        "--speed",
        "20000",
        "--accel-div",
        "100",
        "--vcd",
        path.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{output:?}");
    let count = |channel: &str| {
        // One sample per CT tick (5 ns): exact, and 5 times fewer samples.
        let decoder = format!("counter:data={channel}:data_edge=rising");
        let output = Command::new("sigrok-cli")
            .arg("-i")
            .arg(&path)
            .args(["-I", "vcd:downsample=5", "-P", &decoder])
            .output()
            .expect("sigrok-cli runs");
        assert!(output.status.success(), "{output:?}");
        let text = String::from_utf8(output.stdout).unwrap();
        text.lines().last().unwrap_or_default().to_string()
    };
    assert_eq!(count("axis1_step"), "counter-1: 1000");
}
