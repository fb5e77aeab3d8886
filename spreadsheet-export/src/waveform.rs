//! `--vcd`: the move run by an emulated cog, every pin edge to a VCD file.
//!
//! The table is computed from the profile alone; this runs the same move
//! (profile, arithmetic, clock, offset, divisor) through the hub in virtual
//! time, so the file shows what a cog's pins do: the step pulses (1,000
//! ticks wide), the direction pin and its set-up time, and the stop pin,
//! held high from time 0. The axis is axis 1 on pins 0 (stop), 1 and 2
//! (step and dir for `sd`, cw and ccw for `cc`). The pins are idle at
//! time 0 and the move starts one direction set-up time (1,000 ticks)
//! later, so no edge shares time 0 with the initial levels: every reader
//! (sigrok's VCD input among them) sees the first step as an edge.
//!
//! The hub advances in slices and each slice's edges are written before
//! the next: memory stays bounded however long the move. A slice is sized
//! to hold a few tens of thousands of edges, so a slow move does not take
//! billions of slices either.

use std::path::Path;

use driver::profile::scurve::Arithmetic;
use driver::trace::VcdStream;
use driver::{ClockMode, Direction, Hub, HubConfig};

use crate::cli::{OutputsArg, ProfileKind, Request};
use crate::error::ExportError;
use crate::output::PendingFile;

/// What went into the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VcdSummary {
    /// Edges written.
    pub edges: u64,
    /// Rising edges on the pulse pin (one per step).
    pub steps: u64,
    /// CT at the end of the file.
    pub end_ct: u64,
}

/// Edges a slice aims at (a slice's time doubles or halves towards it).
const SLICE_EDGES: u64 = 50_000;

/// Runs the request's move on a virtual hub and writes its VCD to
/// `destination` (not committed: the caller commits it with the rest).
pub fn write(
    request: &Request,
    destination: &Path,
    outputs: OutputsArg,
) -> Result<(PendingFile, VcdSummary), ExportError> {
    let refused = |reason: String| ExportError::VcdMove(reason);
    let arithmetic = match request.profile {
        ProfileKind::P2Exact => Arithmetic::P2Exact,
        _ => Arithmetic::Smooth,
    };
    // Checked by the command line: an S-curve speed (whole) and an i32 step count.
    let speed = request.speed_steps_per_s as u32;
    let magnitude = i32::try_from(request.steps).map_err(|_| refused("too many steps".into()))?;
    let steps = if request.direction < 0.0 {
        -magnitude
    } else {
        magnitude
    };
    let hub = Hub::new(HubConfig {
        clkfreq: request.clkfreq,
        clock: ClockMode::Virtual,
        offset_deg: request.offset_deg,
        accel_div: request.accel_div,
        arithmetic,
        trace_edges: true,
        max_cogs: 1,
        ..HubConfig::default()
    })
    .map_err(|error| refused(error.to_string()))?;
    let axis = match outputs {
        OutputsArg::Sd => hub.start_sd(0, 1, 2),
        OutputsArg::Cc => hub.start_cc(0, 1, 2),
    }
    .map_err(|error| refused(error.to_string()))?;
    hub.set_input(0, true)
        .map_err(|error| refused(error.to_string()))?;
    // The stop pin's rise is in the levels at time 0.
    drop(hub.take_trace());
    let pulse_pin = axis.outputs().pulse_pin(if steps < 0 {
        Direction::Reverse
    } else {
        Direction::Forward
    });
    let setup_ticks = u64::from(hub.config().dir_setup_ticks);

    let mut pending = PendingFile::create(destination)?;
    let write_error = |source| ExportError::Write {
        path: destination.to_path_buf(),
        source,
    };
    let mut stream =
        VcdStream::new(pending.file(), request.clkfreq, 0, &hub.signals()).map_err(write_error)?;
    // Idle levels first: with the first edge at time 0, the instant of the
    // levels, a reader such as sigrok takes the pin as already high and
    // loses the first step. The move is sent one set-up time later.
    hub.advance(setup_ticks.max(1));
    axis.move_steps(speed, steps)
        .map_err(|error| refused(error.to_string()))?;
    let mut slice_ticks = u64::from(request.clkfreq / 1_000).max(1);
    while hub.rising_edges(pulse_pin) < u64::from(request.steps) {
        let before = hub.rising_edges(pulse_pin);
        let ct = hub.advance(slice_ticks);
        let edges = hub.take_trace();
        let count = edges.len() as u64;
        stream.push(edges);
        // A later slice's first step may set the direction up to
        // `setup_ticks` before its CT: write only what is older.
        stream
            .write_before(ct.saturating_sub(setup_ticks))
            .map_err(write_error)?;
        if count < SLICE_EDGES / 2 {
            slice_ticks = slice_ticks.saturating_mul(2);
        } else if count > SLICE_EDGES * 2 {
            slice_ticks = (slice_ticks / 2).max(1);
        }
        if hub.rising_edges(pulse_pin) == before && slice_ticks == u64::MAX {
            return Err(refused("the cog made no step".into()));
        }
    }
    hub.run_until_idle();
    stream.push(hub.take_trace());
    // The file ends with the move: the last step's delay run out (the
    // slices may have run the clock further).
    let end_ct = axis.last_step_ct() + u64::from(axis.delay_ticks());
    let edges = stream.edges_written() + stream.edges_waiting() as u64;
    stream.finish(end_ct).map_err(write_error)?;
    let summary = VcdSummary {
        edges,
        steps: hub.rising_edges(pulse_pin),
        end_ct,
    };
    hub.shutdown();
    Ok((pending, summary))
}
