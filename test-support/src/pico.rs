//! Checking the Pico firmware's pins edge by edge (`tests/tests/firmware_pico.rs`
//! for the timer build, `firmware_pico_pio.rs` for the PIO build): the
//! axis cores replayed on the host from the CT each command acted at
//! ([`Replay`]), the VCD file `firmware/run-pico-sim --vcd` writes
//! ([`read_vcd`], wires named by [`pin_names`]), waiting on the
//! board's status lines over a [`RawPort`], and the emulator started one
//! way for all of them ([`start_pico_sim`]).

use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

use cogstep_motion::profile::scurve::{Arithmetic, ScurveConfig};
use cogstep_motion::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs};

use crate::script::DeviceScript;
use crate::serial::RawPort;

/// `firmware/run-pico-sim` with `axes` axes in `arithmetic`, the PIO
/// build when `pio`, with a VCD file of every pin's changes when `vcd`
/// is given; control lines on its standard input, SIGTERM when dropped.
pub fn start_pico_sim(
    axes: usize,
    arithmetic: Arithmetic,
    pio: bool,
    vcd: Option<&Path>,
) -> DeviceScript {
    let axes = axes.to_string();
    let mut args = vec!["--axes", &axes, "--arithmetic", arithmetic_flag(arithmetic)];
    if pio {
        args.push("--pio");
    }
    let vcd = vcd.map(|vcd| vcd.to_str().expect("a UTF-8 path"));
    if let Some(vcd) = vcd {
        args.extend(["--vcd", vcd]);
    }
    DeviceScript::start("firmware/run-pico-sim", &args, true)
}

/// `run-pico-sim --arithmetic`'s word for `arithmetic`.
pub fn arithmetic_flag(arithmetic: Arithmetic) -> &'static str {
    match arithmetic {
        Arithmetic::Smooth => "smooth",
        Arithmetic::P2Exact => "p2exact",
    }
}

/// The firmware's axis core settings at `clkfreq` in `arithmetic`, as
/// `cogstep_firmware::core_config` makes them: step/dir on even axes,
/// cw/ccw on odd ones, 5 µs pulses and direction set-up, a jog's 150 ms
/// heartbeat.
pub fn firmware_core_config(index: usize, clkfreq: u32, arithmetic: Arithmetic) -> AxisCoreConfig {
    let outputs = if index.is_multiple_of(2) {
        Outputs::StepDir { step: 0, dir: 1 }
    } else {
        Outputs::CwCcw { cw: 0, ccw: 1 }
    };
    let micros = |us: u64| u64::from(clkfreq) * us / 1_000_000;
    AxisCoreConfig {
        scurve: ScurveConfig {
            clkfreq,
            arithmetic,
            ..ScurveConfig::default()
        },
        outputs,
        pulse_ticks: u32::try_from(micros(5)).expect("a pulse in range"),
        dir_setup_ticks: u32::try_from(micros(5)).expect("a set-up in range"),
        jog_timeout_ticks: micros(150_000),
        math_ticks: 0,
        limit_estop: false,
        // `core_config`'s; the Pico sets its own for homing (twice its
        // lead), which no replayed scenario reaches.
        input_latency_ticks: 0,
    }
}

/// What a line did to the axes, for the replay.
#[derive(Clone, Copy, Debug)]
pub enum Action {
    /// A command to axis `.0`.
    Command(usize, CoreCommand),
    /// Axis `.0`'s stop "pin" (`S` low, `R` high).
    StopPin(usize, bool),
    /// Axis `.0`'s part of a group move stopped on its line
    /// (`AxisCore::stop_group_after`): what the firmware does to every
    /// member when one's stop pin goes low.
    StopGroup(usize),
}

/// The axis cores of the replay, with every edge they decide.
pub struct Replay {
    cores: Vec<AxisCore>,
    /// Each axis's edges, in order.
    pub edges: Vec<Vec<Edge>>,
    /// The firmware's look-ahead (the direction set-up): a command
    /// arriving at CT `ct` acts on its core at `ct + setup`.
    setup: u64,
}

impl Replay {
    /// `axes` cores at `clkfreq` in `arithmetic`, their stop pins high.
    pub fn new(axes: usize, clkfreq: u32, arithmetic: Arithmetic) -> Replay {
        let configs: Vec<_> = (0..axes)
            .map(|index| firmware_core_config(index, clkfreq, arithmetic))
            .collect();
        Replay {
            setup: u64::from(configs.first().map_or(0, |config| config.dir_setup_ticks)),
            cores: configs
                .into_iter()
                .map(|config| {
                    let mut core = AxisCore::new(config, 0);
                    core.set_stop_pin(0, true);
                    core
                })
                .collect(),
            edges: vec![Vec::new(); axes],
        }
    }

    fn run_to(&mut self, index: usize, ct: u64) {
        let (core, edges) = (&mut self.cores[index], &mut self.edges[index]);
        while let Some(t) = core.next_event().filter(|&t| t <= ct) {
            core.run_event(t, &mut |edge| edges.push(edge));
        }
    }

    /// `action` at firmware CT `ct` (the core's `ct` + the set-up).
    pub fn apply(&mut self, ct: u64, action: Action) {
        let core_ct = ct + self.setup;
        match action {
            Action::Command(index, command) => {
                self.run_to(index, core_ct);
                let _ = self.cores[index].command(core_ct, command);
            }
            Action::StopPin(index, high) => {
                self.run_to(index, core_ct);
                self.cores[index].set_stop_pin(core_ct, high);
            }
            Action::StopGroup(index) => {
                self.run_to(index, core_ct);
                self.cores[index].stop_group_after(core_ct);
            }
        }
    }

    /// Runs every core to its end.
    pub fn finish(&mut self) {
        for index in 0..self.cores.len() {
            self.run_to(index, u64::MAX);
        }
    }
}

/// The PIO model's counts (the control line `pio`): name → value.
pub fn pio_counts(pico: &mut DeviceScript) -> HashMap<String, String> {
    let reply = pico.control("pio");
    let words: Vec<&str> = reply
        .strip_prefix("ok pio ")
        .unwrap_or_else(|| panic!("pio: {reply}"))
        .split_whitespace()
        .collect();
    words
        .chunks(2)
        .map(|pair| (pair[0].to_string(), pair.get(1).unwrap_or(&"").to_string()))
        .collect()
}

/// The VCD's changes of each wire: (ns, level), the initial values left out.
pub fn read_vcd(path: &Path) -> HashMap<String, Vec<(i64, bool)>> {
    let text = std::fs::read_to_string(path).expect("the VCD file");
    let mut names = HashMap::new();
    let mut changes: HashMap<String, Vec<(i64, bool)>> = HashMap::new();
    let mut now = 0i64;
    let mut in_dumpvars = false;
    for line in text.lines() {
        let line = line.trim();
        if let Some(var) = line.strip_prefix("$var wire 1 ") {
            let mut words = var.split_whitespace();
            let (id, name) = (words.next().unwrap(), words.next().unwrap());
            names.insert(id.to_string(), name.to_string());
        } else if line == "$dumpvars" {
            in_dumpvars = true;
        } else if line == "$end" && in_dumpvars {
            in_dumpvars = false;
        } else if let Some(time) = line.strip_prefix('#') {
            now = time.parse().unwrap();
        } else if let (Some(level @ ('0' | '1')), false) = (line.chars().next(), in_dumpvars) {
            if let Some(name) = names.get(&line[1..]) {
                changes
                    .entry(name.clone())
                    .or_default()
                    .push((now, level == '1'));
            }
        }
    }
    changes
}

/// The pins' names of axis `index` (0-based), as the VCD has them.
pub fn pin_names(index: usize) -> [String; 2] {
    let number = index + 1;
    if index.is_multiple_of(2) {
        [format!("axis{number}_step"), format!("axis{number}_dir")]
    } else {
        [format!("axis{number}_cw"), format!("axis{number}_ccw")]
    }
}

/// The axis's position from its status line.
pub fn position_of(line: &str) -> i64 {
    let start = line.find("pos:").expect("a status line") + 4;
    line[start..]
        .split('|')
        .next()
        .unwrap()
        .parse()
        .expect("a position")
}

/// Waits (in simulated time) until axis `index`'s position passes `past`
/// (in the direction of its sign); fails after `patience`.
pub fn wait_position(raw: &mut RawPort, axes: usize, index: usize, past: i64, patience: Duration) {
    let start = Instant::now();
    loop {
        let lines = raw.status(axes);
        let position = position_of(&lines[index]);
        if (past >= 0 && position >= past) || (past < 0 && position <= past) {
            return;
        }
        assert!(start.elapsed() < patience, "axis {index}: {lines:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Waits until every axis has nothing left to make; fails after `patience`.
pub fn wait_idle(raw: &mut RawPort, axes: usize, patience: Duration) {
    let start = Instant::now();
    loop {
        let lines = raw.status(axes);
        if lines.iter().all(|line| {
            line.contains("|togo:0|") && !line.contains("|Run|") && !line.contains("|Jog|")
        }) {
            return;
        }
        assert!(start.elapsed() < patience, "{lines:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
}
