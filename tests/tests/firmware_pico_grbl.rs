//! grbl 1.1 on the Raspberry Pi Pico firmware (`firmware/run-pico-sim
//! --dialect grbl`, under the rp2040py emulator): the same board-side
//! engine and path motion as `board-sim --dialect grbl` and the LM3S6965
//! under QEMU (`firmware_qemu_grbl.rs`), byte for byte over its UART0's
//! pseudo-terminal, and driven by the host's `SerialBoard`. Every end
//! position is checked exactly.
//!
//! The emulator runs about 25 times slower than the chip, so the moves
//! are a millimetre or two. Ignored: it needs Debian's Rust toolchain and
//! the emulator's virtual environment; `.ci/run` runs it with
//! `cargo test -p cogstep-tests --test firmware_pico_grbl -- --ignored`.
#![cfg(unix)]

use std::time::{Duration, Instant};

use cogstep_test_support::pico::read_vcd;
use cogstep_test_support::script::DeviceScript;
use cogstep_test_support::serial::RawPort;
use driver::serial::host::{SerialBoard, SerialConfig, StreamState};
use driver::serial::Dialect;
use driver::AxisContract;

/// The longest any wait here may take before it fails.
const PATIENCE: Duration = Duration::from_secs(120);
const WELCOME: &str = "Grbl 1.1h ['$' for help]";
/// 250 steps/mm (grbl's default), 10 mm/s, 1,000 mm/s²: short moves in
/// little simulated time.
const QUICK: [&str; 6] = [
    "$110=600",
    "$111=600",
    "$112=600",
    "$120=1000",
    "$121=1000",
    "$122=1000",
];

/// The firmware under the emulator, speaking grbl
/// (`firmware/run-pico-sim --dialect grbl`); taken down (SIGTERM) when
/// dropped.
fn pico() -> DeviceScript {
    DeviceScript::start("firmware/run-pico-sim", &["--dialect", "grbl"], true)
}

/// A grbl line from the raw port: grbl ends every line with CR LF.
fn line(port: &mut RawPort) -> String {
    let line = port.line();
    assert!(line.ends_with('\r'), "grbl ends lines with CRLF: {line:?}");
    line.trim_end().to_string()
}

/// Sends `text` and returns the lines up to its `ok` or `error:N`.
fn command(port: &mut RawPort, text: &str) -> Vec<String> {
    port.send(format!("{text}\n").as_bytes());
    let mut reply = Vec::new();
    loop {
        let line = line(port);
        let last = line == "ok" || line.starts_with("error:");
        reply.push(line);
        if last {
            return reply;
        }
    }
}

/// A status report (`?`), once one comes.
fn report(port: &mut RawPort) -> String {
    port.send(b"?");
    loop {
        let line = line(port);
        if line.starts_with('<') {
            return line;
        }
    }
}

/// Waits for a report whose state starts with `state`; returns it.
fn wait_state(port: &mut RawPort, state: &str) -> String {
    let start = Instant::now();
    loop {
        let report = report(port);
        if report[1..].starts_with(state) {
            return report;
        }
        assert!(start.elapsed() < PATIENCE, "never {state}: {report}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn mpos(report: &str) -> &str {
    let at = report.find("MPos:").expect("MPos") + 5;
    let end = report[at..]
        .find('|')
        .map_or(report.len() - 1, |end| at + end);
    &report[at..end]
}

/// The board reset at rest (its welcome read), with the QUICK settings.
fn fresh(pico: &DeviceScript) -> RawPort {
    let mut port = RawPort::open(&pico.path, PATIENCE);
    port.send(b"\x18");
    while line(&mut port) != WELCOME {}
    for setting in QUICK {
        assert_eq!(command(&mut port, setting), ["ok"], "{setting}");
    }
    port
}

#[test]
#[ignore = "needs the firmware toolchain and the emulator's venv: .ci/run runs it"]
fn the_pico_speaks_grbl_and_ends_lines_arcs_and_a_hold_exactly() {
    let pico = pico();
    let mut port = fresh(&pico);
    let info = command(&mut port, "$I");
    assert_eq!(
        info,
        [
            format!("[VER:1.1h.cogstep-{}:]", env!("CARGO_PKG_VERSION")),
            "[OPT:,31,128]".to_string(),
            "ok".to_string()
        ]
    );
    // A line and a half circle (r 0.5 mm): the end is exact.
    assert_eq!(command(&mut port, "G21 G90 G1 X1 F600"), ["ok"]);
    assert_eq!(command(&mut port, "G2 X2 Y0 I0.5 J0"), ["ok"]);
    assert_eq!(mpos(&wait_state(&mut port, "Idle")), "2.000,0.000,0.000");
    // A malformed line moves nothing.
    assert!(command(&mut port, "G1 X5 Q7")[0].starts_with("error:"));
    // A feed hold comes to rest on the path; resume ends exactly.
    assert_eq!(command(&mut port, "G1 X0 F300"), ["ok"]);
    wait_state(&mut port, "Run");
    port.send(b"!");
    let held = mpos(&wait_state(&mut port, "Hold:0")).to_string();
    assert_ne!(held, "0.000,0.000,0.000", "held before the end");
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(mpos(&report(&mut port)), held, "held means still");
    port.send(b"~");
    assert_eq!(mpos(&wait_state(&mut port, "Idle")), "0.000,0.000,0.000");
}

#[test]
#[ignore = "needs the firmware toolchain and the emulator's venv: .ci/run runs it"]
fn the_host_streams_a_program_to_the_pico_and_it_ends_exactly() {
    let pico = pico();
    drop(fresh(&pico));
    let mut config = SerialConfig::new(&pico.path);
    config.dialect = Dialect::Grbl;
    // The emulator answers slowly.
    config.timeout = Duration::from_secs(5);
    config.poll_interval = Duration::from_millis(100);
    let host = SerialBoard::open(config).expect("the host opens the Pico");
    assert_eq!(host.identity(), WELCOME);
    let program: Vec<String> = [
        "G21 G90",
        "G1 X0.5 Y0.5 F600",
        "G1 X1 Y0 ; a corner",
        "G0 X0.2",
    ]
    .iter()
    .map(|line| line.to_string())
    .collect();
    let stream = host.stream_gcode(&program).expect("it streams");
    let start = Instant::now();
    while !stream.progress().state.is_over() {
        assert!(start.elapsed() < PATIENCE, "{:?}", stream.progress());
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(stream.progress().state, StreamState::Done);
    host.refresh().expect("a report");
    let position = |index: usize| {
        host.axis(index)
            .expect("an axis")
            .status()
            .expect("status")
            .position
    };
    assert_eq!([position(0), position(1), position(2)], [50, 0, 0]);
    host.close();
}

/// A line faster than the M0+ can time its steps (5,000 steps/s on X: the
/// path's `f64` in software): every step reaches the pin, and late steps
/// keep their periods. The edges a command's catch-up drove together used
/// to share one CT, where a step's fall cancelled its rise: grbl reported
/// `MPos:8.000` with 1,931 of the 2,000 pulses on the pin. Now each edge
/// keeps its own CT (`Hardware::drive_pin`), and one that comes late goes
/// out one lag behind, its axis's next ones as late (no burst).
#[test]
#[ignore = "needs the firmware toolchain and the emulator's venv: .ci/run runs it"]
fn a_line_faster_than_the_core_keeps_up_with_puts_every_step_on_the_pin() {
    let vcd =
        std::env::temp_dir().join(format!("cogstep-pico-grbl-fast-{}.vcd", std::process::id()));
    let vcd_arg = vcd.to_str().expect("a UTF-8 path");
    let pico = DeviceScript::start(
        "firmware/run-pico-sim",
        &["--dialect", "grbl", "--vcd", vcd_arg],
        true,
    );
    let mut port = fresh(&pico);
    for setting in ["$110=4800", "$120=2000", "G1 X8 F1200"] {
        assert_eq!(command(&mut port, setting), ["ok"], "{setting}");
    }
    assert_eq!(mpos(&wait_state(&mut port, "Idle")), "8.000,0.000,0.000");
    drop(port);
    pico.stop();
    let changes = read_vcd(&vcd);
    let _ = std::fs::remove_file(&vcd);
    let rises: Vec<i64> = changes["axis1_step"]
        .iter()
        .filter(|&&(_, high)| high)
        .map(|&(ns, _)| ns)
        .collect();
    assert_eq!(rises.len(), 2_000, "pulses on axis1_step");
    // 5,000 steps/s is a period of 200 µs: none a quarter of that.
    let shortest = rises
        .windows(2)
        .map(|pair| pair[1] - pair[0])
        .min()
        .unwrap();
    assert!(shortest >= 50_000, "two steps {shortest} ns apart");
}
