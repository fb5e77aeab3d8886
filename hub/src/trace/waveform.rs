//! Edges as a VCD (value change dump) file, written as they come.
//!
//! A [`VcdStream`] declares every pin it is given (with its role name, such
//! as `axis1_step`, and its level at the file's time 0), then takes edges in
//! batches in any order and writes those older than a horizon in time
//! order, so a recording of any length runs in bounded memory. Time 0 of the
//! file is the CT the stream started at; the time unit follows the clock
//! exactly ([`Timebase`]): at 200 MHz one CT tick is 5 ns, written as
//! multiples of 1 ns.
//!
//! An edge that arrives after the file has passed its time (a real-time
//! drain later than the horizon allowed for) is still written, at the
//! file's current time, counted ([`VcdStream::late_edges`]) and noted in the
//! file: never dropped in silence.
//!
//! The files open in GTKWave and in PulseView (sigrok): only 1-bit wires,
//! and comments only in the header and after the last time, because
//! sigrok's VCD reader stops at a `$comment` among the value changes.

use std::io::{self, BufWriter, Write};

use vcd::{IdCode, SimulationCommand, TimescaleUnit, Value};

use crate::pins::{Edge, Outputs, PIN_COUNT};

/// A pin as a waveform declares it.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Signal {
    /// The pin, 0–63; 64–255 are free for wires that are no pin (the
    /// [`Recorder`](super::Recorder)'s `recording_edges_lost` marker).
    pub pin: u8,
    /// Its role name: `axis1_step`, `axis1_dir`, `axis1_stop`, `axis2_cw`,
    /// `axis2_ccw`, … (axis N is cog N − 1), or `pin<N>` for a pin no axis
    /// owns.
    pub name: String,
    /// Whether the pin is an input (a stop pin) rather than an output.
    pub input: bool,
    /// Its level at the waveform's time 0.
    pub level: bool,
}

impl Signal {
    /// The three pins of the axis on cog `cog` (axis `cog + 1`), low.
    pub fn of_axis(cog: usize, stop_pin: u8, outputs: Outputs) -> [Signal; 3] {
        let (a, b) = match outputs {
            Outputs::StepDir { .. } => ("step", "dir"),
            Outputs::CwCcw { .. } => ("cw", "ccw"),
        };
        let [pin_a, pin_b] = outputs.pins();
        [
            (stop_pin, "stop", true),
            (pin_a, a, false),
            (pin_b, b, false),
        ]
        .map(|(pin, role, input)| Signal {
            pin,
            name: format!("axis{}_{role}", cog + 1),
            input,
            level: false,
        })
    }
}

/// Why a VCD could not be written.
#[derive(Debug, thiserror::Error)]
pub enum VcdError {
    /// The hub was built without `trace_edges`: it has no edges to write.
    #[error(
        "the hub records no edges: build it with `HubConfig {{ trace_edges: true, .. }}` to write a VCD"
    )]
    TracingOff,
    /// Writing failed.
    #[error("cannot write the VCD: {0}")]
    Io(#[from] io::Error),
}

/// How CT ticks become VCD times: exact multiples of 1 ns, 1 ps or 1 fs
/// when one tick is a whole number of them (any clock of the form
/// 2^a · 5^b Hz up to 10^15: 200 MHz, 250 MHz, 160 MHz, 20 MHz, …);
/// otherwise (180 MHz, 300 MHz: a tick is not a whole number of any unit)
/// picoseconds rounded to the nearest, which keeps every tick distinct and
/// in order, and the file says so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timebase {
    clkfreq: u32,
    unit: TimescaleUnit,
    /// VCD units per second.
    units_per_s: u64,
    /// VCD units per tick, when that is a whole number.
    units_per_tick: Option<u64>,
}

impl Timebase {
    /// The time base for a clock of `clkfreq` Hz (0 is taken as 1).
    pub fn new(clkfreq: u32) -> Self {
        let clkfreq = clkfreq.max(1);
        let exact = [
            (TimescaleUnit::NS, 1_000_000_000u64),
            (TimescaleUnit::PS, 1_000_000_000_000),
            (TimescaleUnit::FS, 1_000_000_000_000_000),
        ]
        .into_iter()
        .find(|(_, per_s)| per_s % u64::from(clkfreq) == 0);
        match exact {
            Some((unit, units_per_s)) => Self {
                clkfreq,
                unit,
                units_per_s,
                units_per_tick: Some(units_per_s / u64::from(clkfreq)),
            },
            None => Self {
                clkfreq,
                unit: TimescaleUnit::PS,
                units_per_s: 1_000_000_000_000,
                units_per_tick: None,
            },
        }
    }

    /// The VCD time unit (the file's `$timescale` is 1 of it).
    pub fn unit(&self) -> TimescaleUnit {
        self.unit
    }

    /// VCD units per tick when every tick is a whole number of them.
    pub fn units_per_tick(&self) -> Option<u64> {
        self.units_per_tick
    }

    /// The VCD time of `ticks` after the start (saturating).
    pub fn time(&self, ticks: u64) -> u64 {
        match self.units_per_tick {
            Some(per_tick) => ticks.saturating_mul(per_tick),
            None => {
                let clkfreq = u128::from(self.clkfreq);
                let scaled =
                    (u128::from(ticks) * u128::from(self.units_per_s) + clkfreq / 2) / clkfreq;
                u64::try_from(scaled).unwrap_or(u64::MAX)
            }
        }
    }

    /// The ticks after the start that a VCD time stands for (the inverse
    /// of [`Timebase::time`], exact for every time it produces).
    pub fn ticks(&self, time: u64) -> u64 {
        match self.units_per_tick {
            Some(per_tick) => time / per_tick,
            None => {
                let units = u128::from(self.units_per_s);
                let ticks = (u128::from(time) * u128::from(self.clkfreq) + units / 2) / units;
                u64::try_from(ticks).unwrap_or(u64::MAX)
            }
        }
    }

    /// One line for the file: the clock and what a tick is in VCD time.
    pub fn describe(&self) -> String {
        let unit = self.unit;
        match self.units_per_tick {
            Some(per_tick) => format!(
                "clkfreq {} Hz: one CT tick = {per_tick} {unit}, exactly",
                self.clkfreq
            ),
            None => format!(
                "clkfreq {} Hz: one CT tick = 1/{} s, not a whole number of any VCD unit; \
                 times are rounded to the nearest 1 {unit} (every tick stays distinct)",
                self.clkfreq, self.clkfreq
            ),
        }
    }
}

/// A VCD being written as edges come (see the module docs).
pub struct VcdStream<W: Write> {
    writer: vcd::Writer<BufWriter<W>>,
    ids: [Option<IdCode>; 256],
    notes: Vec<String>,
    timebase: Timebase,
    start_ct: u64,
    /// The CT of the file's current time.
    written_ct: u64,
    pending: Vec<Edge>,
    late: u64,
    written: u64,
}

impl<W: Write> VcdStream<W> {
    /// Writes the header: the clock, time 0 = `start_ct`, a wire per
    /// signal under the scope `cogstep`, and every signal's level at time 0.
    pub fn new(out: W, clkfreq: u32, start_ct: u64, signals: &[Signal]) -> io::Result<Self> {
        let timebase = Timebase::new(clkfreq);
        let mut writer = vcd::Writer::new(BufWriter::with_capacity(1 << 16, out));
        writer.version(concat!("cogstep ", env!("CARGO_PKG_VERSION")))?;
        writer.comment(&timebase.describe())?;
        writer.comment(&format!("time 0 = CT {start_ct}"))?;
        writer.timescale(1, timebase.unit())?;
        writer.add_module("cogstep")?;
        let mut ids = [None; 256];
        for signal in signals {
            if let Some(slot) = ids.get_mut(usize::from(signal.pin)) {
                if slot.is_none() {
                    *slot = Some(writer.add_wire(1, &signal.name)?);
                }
            }
        }
        writer.upscope()?;
        writer.enddefinitions()?;
        writer.timestamp(0)?;
        writer.begin(SimulationCommand::Dumpvars)?;
        for signal in signals {
            if let Some(Some(id)) = ids.get(usize::from(signal.pin)) {
                writer.change_scalar(*id, value(signal.level))?;
            }
        }
        writer.end()?;
        Ok(Self {
            writer,
            ids,
            notes: Vec::new(),
            timebase,
            start_ct,
            written_ct: start_ct,
            pending: Vec::new(),
            late: 0,
            written: 0,
        })
    }

    /// Takes edges, in any order; edges on pins not declared are ignored.
    pub fn push(&mut self, edges: impl IntoIterator<Item = Edge>) {
        let ids = &self.ids;
        self.pending.extend(
            edges
                .into_iter()
                .filter(|edge| matches!(ids.get(usize::from(edge.pin)), Some(Some(_)))),
        );
    }

    /// Writes, in time order, the edges taken so far that happened before
    /// `horizon_ct`; later ones wait for a later horizon.
    pub fn write_before(&mut self, horizon_ct: u64) -> io::Result<()> {
        // Stable by (CT, pin): one pin's edges at one CT keep their order.
        self.pending.sort_by_key(|edge| (edge.ct, edge.pin));
        let ready = self.pending.partition_point(|edge| edge.ct < horizon_ct);
        let mut pending = std::mem::take(&mut self.pending);
        let result = pending
            .drain(..ready)
            .try_for_each(|edge| self.write_edge(edge));
        self.pending = pending;
        result
    }

    fn write_edge(&mut self, edge: Edge) -> io::Result<()> {
        let Some(Some(id)) = self.ids.get(usize::from(edge.pin)).copied() else {
            return Ok(());
        };
        if edge.ct > self.written_ct {
            self.written_ct = edge.ct;
            self.writer
                .timestamp(self.timebase.time(edge.ct - self.start_ct))?;
        } else if edge.ct < self.written_ct {
            self.late += 1;
        }
        self.written += 1;
        self.writer.change_scalar(id, value(edge.level))
    }

    /// Adds a comment for the end of the file (after the last time, where
    /// every reader takes it).
    pub fn note(&mut self, text: impl Into<String>) {
        self.notes.push(text.into());
    }

    /// Pushes what is written so far to the underlying writer.
    pub fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }

    /// Edges written after the file had passed their time (written at the
    /// file's time then).
    pub fn late_edges(&self) -> u64 {
        self.late
    }

    /// Edges written so far.
    pub fn edges_written(&self) -> u64 {
        self.written
    }

    /// Edges taken but not yet written.
    pub fn edges_waiting(&self) -> usize {
        self.pending.len()
    }

    /// The CT of the file's current time.
    pub fn current_ct(&self) -> u64 {
        self.written_ct
    }

    /// Writes every edge still waiting, ends the file at `end_ct` (or its
    /// last edge, if later), writes the notes (and one on late edges, if
    /// there were any) and flushes.
    pub fn finish(mut self, end_ct: u64) -> io::Result<()> {
        self.write_before(u64::MAX)?;
        if end_ct > self.written_ct {
            self.writer
                .timestamp(self.timebase.time(end_ct - self.start_ct))?;
        }
        if self.late > 0 {
            self.notes.push(format!(
                "cogstep: {} edges arrived after the file had passed their time and are \
                 written late (at the time the file had reached)",
                self.late
            ));
        }
        for note in &self.notes {
            self.writer.comment(note)?;
        }
        self.writer.flush()
    }
}

fn value(level: bool) -> Value {
    if level {
        Value::V1
    } else {
        Value::V0
    }
}

/// Writes a whole trace as a VCD: `signals` declared with their levels at
/// time 0 (= CT 0), plus a `pin<N>` input for any other pin with an edge,
/// the edges in time order, the file ending at `end_ct`.
pub fn write_vcd<W: Write>(
    out: W,
    edges: &[Edge],
    clkfreq: u32,
    signals: &[Signal],
    end_ct: u64,
) -> io::Result<()> {
    let mut all = signals.to_vec();
    let mut declared = signals.iter().fold(0u64, |mask, s| mask | bit(s.pin));
    for edge in edges {
        if edge.pin < PIN_COUNT && declared & bit(edge.pin) == 0 {
            declared |= bit(edge.pin);
            all.push(Signal {
                pin: edge.pin,
                name: format!("pin{}", edge.pin),
                input: true,
                level: false,
            });
        }
    }
    let mut stream = VcdStream::new(out, clkfreq, 0, &all)?;
    stream.push(edges.iter().copied());
    stream.finish(end_ct)
}

fn bit(pin: u8) -> u64 {
    1u64.checked_shl(u32::from(pin)).unwrap_or(0)
}
