//! Hubs and axes as the tests set them up.

use cogstep_hub::{Axis, Hub, HubConfig};
use cogstep_motion::axis_core::Outputs;

/// Which output variant an axis is started with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wiring {
    /// Step and direction (`start_sd`).
    Sd,
    /// Clockwise and counter-clockwise (`start_cc`).
    Cc,
}

impl Wiring {
    /// [`Wiring::Sd`] when `sd`, else [`Wiring::Cc`].
    pub fn sd_if(sd: bool) -> Wiring {
        if sd {
            Wiring::Sd
        } else {
            Wiring::Cc
        }
    }

    /// The output pins of axis `index` started by [`start_axis`]: 3·index + 1
    /// (step or cw) and 3·index + 2 (dir or ccw).
    pub fn outputs(self, index: usize) -> Outputs {
        let first = u8::try_from(3 * index + 1).expect("a pin number");
        match self {
            Wiring::Sd => Outputs::StepDir {
                step: first,
                dir: first + 1,
            },
            Wiring::Cc => Outputs::CwCcw {
                cw: first,
                ccw: first + 1,
            },
        }
    }
}

/// A hub with `config`, its edge trace on.
pub fn tracing_hub(config: HubConfig) -> Hub {
    Hub::new(HubConfig {
        trace_edges: true,
        ..config
    })
    .expect("hub")
}

/// Starts axis `index` as `wiring` on stop pin 3·index and output pins
/// 3·index + 1 (step or cw) and 3·index + 2 (dir or ccw), and sets its
/// stop pin high so that it may move.
pub fn start_axis(hub: &Hub, index: usize, wiring: Wiring) -> Axis {
    let stop = u8::try_from(3 * index).expect("a pin number");
    let axis = match wiring {
        Wiring::Sd => hub.start_sd(stop, stop + 1, stop + 2),
        Wiring::Cc => hub.start_cc(stop, stop + 1, stop + 2),
    }
    .expect("axis");
    hub.set_input(stop, true).expect("stop pin");
    axis
}
