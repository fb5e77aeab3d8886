//! VCD files of hub runs, read back with an independent reader (the `vcd`
//! crate's parser): every axis pin declared by role with its level at time
//! 0, and the same edges at the same times as the hub's trace.

use std::collections::BTreeMap;
use std::io::Write;
use std::sync::{Arc, Mutex};

use cogstep_test_support::hub::{start_axis, Wiring};
use driver::trace::{Recorder, RecorderOptions, Timebase, VcdError, VcdStream, LOST_MARKER_NAME};
use driver::{ClockMode, Edge, Hub, HubConfig};
use proptest::prelude::*;

/// A VCD as a reader sees it.
#[derive(Debug, Default)]
struct Waveform {
    timescale: Option<(u32, vcd::TimescaleUnit)>,
    comments: Vec<String>,
    /// Wire name → id.
    names: BTreeMap<String, vcd::IdCode>,
    /// Level at time 0, by name.
    initial: BTreeMap<String, bool>,
    /// Changes after the initial dump: (time, name, level).
    changes: Vec<(u64, String, bool)>,
}

fn read(bytes: &[u8]) -> Waveform {
    let mut parser = vcd::Parser::new(bytes);
    let header = parser.parse_header().expect("header");
    let mut wave = Waveform {
        timescale: header.timescale,
        ..Waveform::default()
    };
    let scope = header.find_scope(&["cogstep"]).expect("scope cogstep");
    let mut by_id = BTreeMap::new();
    for item in &scope.items {
        match item {
            vcd::ScopeItem::Var(var) => {
                assert_eq!(var.size, 1);
                wave.names.insert(var.reference.clone(), var.code);
                by_id.insert(var.code, var.reference.clone());
            }
            vcd::ScopeItem::Comment(text) => wave.comments.push(text.clone()),
            _ => {}
        }
    }
    for item in &header.items {
        if let vcd::ScopeItem::Comment(text) = item {
            wave.comments.push(text.clone());
        }
    }
    let (mut time, mut in_dump) = (0u64, false);
    for command in parser {
        match command.expect("command") {
            vcd::Command::Timestamp(t) => {
                assert!(t >= time, "time goes forward");
                time = t;
            }
            vcd::Command::Begin(vcd::SimulationCommand::Dumpvars) => in_dump = true,
            vcd::Command::End(_) => in_dump = false,
            vcd::Command::ChangeScalar(id, value) => {
                let name = by_id[&id].clone();
                let level = match value {
                    vcd::Value::V1 => true,
                    vcd::Value::V0 => false,
                    other => panic!("{other:?} on {name}"),
                };
                if in_dump {
                    wave.initial.insert(name, level);
                } else {
                    wave.changes.push((time, name, level));
                }
            }
            vcd::Command::Comment(text) => wave.comments.push(text),
            other => panic!("unexpected {other:?}"),
        }
    }
    wave
}

/// The trace's edges as the file should hold them (time from CT, names
/// from the pin map).
fn expected(trace: &[Edge], names: &BTreeMap<u8, &str>, clkfreq: u32) -> Vec<(u64, String, bool)> {
    let timebase = Timebase::new(clkfreq);
    trace
        .iter()
        .map(|edge| {
            (
                timebase.time(edge.ct),
                names[&edge.pin].to_string(),
                edge.level,
            )
        })
        .collect()
}

#[derive(Clone, Debug)]
enum Action {
    Move { axis: usize, speed: u32, steps: i32 },
    StopPin { axis: usize, high: bool },
    Advance { ticks: u64 },
}

fn action() -> impl Strategy<Value = Action> {
    prop_oneof![
        3 => (0..2usize, 500u32..40_000, -3_000i32..3_000)
            .prop_map(|(axis, speed, steps)| Action::Move { axis, speed, steps }),
        1 => (0..2usize, any::<bool>()).prop_map(|(axis, high)| Action::StopPin { axis, high }),
        3 => (0u64..30_000_000).prop_map(|ticks| Action::Advance { ticks }),
    ]
}

/// An sd axis (stop 0, step 1, dir 2) and a cc axis (stop 3, cw 4, ccw 5).
const NAMES: [(u8, &str); 6] = [
    (0, "axis1_stop"),
    (1, "axis1_step"),
    (2, "axis1_dir"),
    (3, "axis2_stop"),
    (4, "axis2_cw"),
    (5, "axis2_ccw"),
];

/// Runs the actions on a virtual hub at `clkfreq`; `each_advance` sees the
/// hub after every advance (for streaming).
fn run(clkfreq: u32, actions: &[Action], mut each_advance: impl FnMut(&Hub, u64)) -> Hub {
    let hub = Hub::new(HubConfig {
        clkfreq,
        trace_edges: true,
        ..HubConfig::default()
    })
    .expect("hub");
    let axes = [
        hub.start_sd(0, 1, 2).expect("sd"),
        hub.start_cc(3, 4, 5).expect("cc"),
    ];
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    for action in actions {
        match *action {
            Action::Move { axis, speed, steps } => {
                let _ = axes[axis].move_steps(speed, steps);
            }
            Action::StopPin { axis, high } => axes[axis].set_stop_pin(high).expect("pin"),
            Action::Advance { ticks } => {
                let ct = hub.advance(ticks);
                each_advance(&hub, ct);
            }
        }
    }
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    hub.run_until_idle();
    hub
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    /// `Hub::write_vcd` read back: the same edges, at the same times, on
    /// pins named by role, every pin low at time 0.
    #[test]
    fn write_vcd_round_trips_through_a_reader(
        actions in prop::collection::vec(action(), 1..12),
        clock in prop::sample::select(vec![200_000_000u32, 180_000_000, 160_000_000]),
    ) {
        let hub = run(clock, &actions, |_, _| {});
        let mut bytes = Vec::new();
        hub.write_vcd(&mut bytes).expect("vcd");
        let wave = read(&bytes);
        let names: BTreeMap<u8, &str> = NAMES.into_iter().collect();
        let declared: Vec<&str> = wave.names.keys().map(String::as_str).collect();
        let mut want: Vec<&str> = names.values().copied().collect();
        want.sort_unstable();
        prop_assert_eq!(declared, want);
        prop_assert!(wave.initial.values().all(|level| !level));
        prop_assert_eq!(wave.initial.len(), 6);
        let trace = hub.trace();
        prop_assert_eq!(&wave.changes, &expected(&trace, &names, clock));
        // Times map back to the very CT of each edge.
        let timebase = Timebase::new(clock);
        for ((time, _, _), edge) in wave.changes.iter().zip(&trace) {
            prop_assert_eq!(timebase.ticks(*time), edge.ct);
        }
    }

    /// Streamed in pieces after each advance (bounded memory), the file is
    /// byte for byte the one written whole.
    #[test]
    fn streaming_by_advances_writes_the_same_file(actions in prop::collection::vec(action(), 1..12)) {
        let streamed = RefBuffer::default();
        let mut stream: Option<VcdStream<RefBuffer>> = None;
        let hub = run(200_000_000, &actions, |hub, ct| {
            let stream = stream.get_or_insert_with(|| {
                VcdStream::new(streamed.clone(), 200_000_000, 0, &low(hub)).expect("header")
            });
            stream.push(hub.take_trace());
            stream.write_before(ct.saturating_sub(u64::from(hub.config().dir_setup_ticks))).expect("write");
        });
        let mut stream = match stream {
            Some(stream) => stream,
            None => VcdStream::new(streamed.clone(), 200_000_000, 0, &low(&hub)).expect("header"),
        };
        stream.push(hub.take_trace());
        stream.finish(hub.now()).expect("finish");
        let wave = read(&streamed.bytes());
        let names: BTreeMap<u8, &str> = NAMES.into_iter().collect();
        // Re-run for the whole trace (virtual time repeats bit for bit).
        let again = run(200_000_000, &actions, |_, _| {});
        prop_assert_eq!(&wave.changes, &expected(&again.trace(), &names, 200_000_000));
        let mut whole = Vec::new();
        again.write_vcd(&mut whole).expect("vcd");
        prop_assert_eq!(String::from_utf8(streamed.bytes()).unwrap(), String::from_utf8(whole).unwrap());
    }
}

/// The hub's signals with the levels of CT 0 (everything low).
fn low(hub: &Hub) -> Vec<driver::trace::Signal> {
    hub.signals()
        .into_iter()
        .map(|mut signal| {
            signal.level = false;
            signal
        })
        .collect()
}

/// A writer whose bytes the test can read while the recorder owns it.
#[derive(Clone, Default)]
struct RefBuffer(Arc<Mutex<Vec<u8>>>);

impl RefBuffer {
    fn bytes(&self) -> Vec<u8> {
        self.0.lock().unwrap().clone()
    }
}

impl Write for RefBuffer {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_forward_move_declares_the_direction_pin_and_the_input() {
    let hub = run(
        200_000_000,
        &[Action::Move {
            axis: 0,
            speed: 20_000,
            steps: 2_000,
        }],
        |_, _| {},
    );
    let mut bytes = Vec::new();
    hub.write_vcd(&mut bytes).unwrap();
    let text = String::from_utf8(bytes.clone()).unwrap();
    assert!(text.contains("$timescale 1 ns $end"), "{text:.400}");
    let wave = read(&bytes);
    assert_eq!(wave.timescale, Some((1, vcd::TimescaleUnit::NS)));
    assert!(wave
        .comments
        .iter()
        .any(|c| c.contains("one CT tick = 5 ns")));
    for name in [
        "axis1_step",
        "axis1_dir",
        "axis1_stop",
        "axis2_cw",
        "axis2_ccw",
        "axis2_stop",
    ] {
        assert!(wave.names.contains_key(name), "{name} declared");
    }
    let rises = wave
        .changes
        .iter()
        .filter(|(_, name, level)| name == "axis1_step" && *level)
        .count();
    assert_eq!(rises, 2_000);
    assert!(!wave.changes.iter().any(|(_, name, _)| name == "axis1_dir"));
    // The stop pin goes high at time 0, as set_input made it.
    assert_eq!(wave.changes[0], (0, "axis1_stop".to_string(), true));
}

#[test]
fn a_hub_without_tracing_refuses_to_write_a_vcd() {
    let hub = Hub::new(HubConfig::default()).unwrap();
    let x = start_axis(&hub, 0, Wiring::Sd);
    x.move_steps(20_000, 100).unwrap();
    hub.run_until_idle();
    let mut bytes = Vec::new();
    let error = hub.write_vcd(&mut bytes).unwrap_err();
    assert!(matches!(error, VcdError::TracingOff), "{error}");
    assert!(error.to_string().contains("trace_edges"));
    assert!(bytes.is_empty(), "nothing written");
    assert!(matches!(
        Recorder::start(&hub, Vec::new(), RecorderOptions::default()),
        Err(VcdError::TracingOff)
    ));
}

#[test]
fn an_input_pulse_at_one_ct_keeps_its_order() {
    let hub = Hub::new(HubConfig {
        trace_edges: true,
        ..HubConfig::default()
    })
    .unwrap();
    let _x = start_axis(&hub, 0, Wiring::Sd);
    hub.advance(1_000);
    hub.set_input(0, false).unwrap();
    hub.set_input(0, true).unwrap();
    hub.set_input(0, true).unwrap(); // no change: no edge
    let mut bytes = Vec::new();
    hub.write_vcd(&mut bytes).unwrap();
    let wave = read(&bytes);
    let stop: Vec<_> = wave
        .changes
        .iter()
        .filter(|c| c.1 == "axis1_stop")
        .cloned()
        .collect();
    assert_eq!(
        stop,
        [
            (0, "axis1_stop".to_string(), true),
            (5_000, "axis1_stop".to_string(), false),
            (5_000, "axis1_stop".to_string(), true),
        ]
    );
}

#[test]
fn timebase_follows_the_clock() {
    let at_200 = Timebase::new(200_000_000);
    assert_eq!(at_200.units_per_tick(), Some(5));
    assert_eq!(at_200.time(1_000), 5_000);
    let at_1k = Timebase::new(1_000);
    assert_eq!(at_1k.units_per_tick(), Some(1_000_000));
    let odd = Timebase::new(180_000_000);
    assert_eq!(odd.units_per_tick(), None);
    assert!(odd.describe().contains("rounded"));
    let mut last = None;
    for ct in (0..200_000u64).chain([u64::from(u32::MAX) * 1_000]) {
        let time = odd.time(ct);
        assert_eq!(odd.ticks(time), ct);
        assert!(last < Some(time));
        last = Some(time);
    }
}

/// A real-time hub recorded while it runs: the file has every step edge at
/// its exact CT, and nothing lost.
#[test]
fn a_recorder_streams_a_real_time_move() {
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Real,
        trace_edges: true,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_sd(0, 1, 2).unwrap();
    let y = hub.start_cc(3, 4, 5).unwrap();
    hub.set_input(0, true).unwrap();
    let out = RefBuffer::default();
    let recorder = Recorder::start(&hub, out.clone(), RecorderOptions::default()).unwrap();
    hub.set_input(3, true).unwrap();
    x.move_steps(20_000, -2_000).unwrap();
    y.move_steps(10_000, 500).unwrap();
    hub.run_until_idle();
    let summary = recorder.finish().unwrap();
    assert_eq!((summary.lost, summary.late), (0, 0));
    let wave = read(&out.bytes());
    assert!(wave.initial["axis1_stop"], "high before the recording");
    assert!(!wave.initial["axis2_stop"]);
    let count = |name: &str, level: bool| {
        wave.changes
            .iter()
            .filter(|c| c.1 == name && c.2 == level)
            .count()
    };
    assert_eq!(count("axis1_step", true), 2_000);
    assert_eq!(count("axis1_dir", true), 1);
    assert_eq!(count("axis2_cw", true), 500);
    assert_eq!(count("axis2_stop", true), 1);
    assert_eq!(summary.edges, wave.changes.len() as u64);
    assert!(wave.comments.iter().any(|c| c.contains("recording ended")));
}

/// Rings too small for the step rate: the loss is counted and noted in
/// the file, and what was written plus what was lost is every edge.
#[test]
fn a_recorder_reports_ring_overflows_in_the_file() {
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Real,
        trace_edges: true,
        trace_ring: 16,
        ..HubConfig::default()
    })
    .unwrap();
    let x = start_axis(&hub, 0, Wiring::Sd);
    let out = RefBuffer::default();
    let recorder = Recorder::start(&hub, out.clone(), RecorderOptions::default()).unwrap();
    x.move_steps(150_000, 30_000).unwrap();
    hub.run_until_idle();
    let lost_seen = recorder.lost_edges();
    let summary = recorder.finish().unwrap();
    assert!(
        summary.lost > 0,
        "a 16-edge ring overflows at 150,000 steps/s"
    );
    assert!(summary.lost >= lost_seen);
    assert_eq!(summary.edges + summary.lost, 60_000, "{summary:?}");
    let wave = read(&out.bytes());
    let lost_note = format!("{} lost", summary.lost);
    assert!(
        wave.comments.iter().any(|c| c.contains(&lost_note)),
        "{:?}",
        wave.comments
    );
    // The marker wire is high over the intervals where edges were lost.
    let marks: Vec<_> = wave
        .changes
        .iter()
        .filter(|c| c.1 == LOST_MARKER_NAME)
        .collect();
    assert!(!marks.is_empty());
    assert!(marks.first().unwrap().2 && !marks.last().unwrap().2);
    let step_pin = wave.changes.iter().filter(|c| c.1 == "axis1_step").count() as u64;
    assert_eq!(step_pin + summary.lost, 60_000);
}
