//! The hub: shared memory, the system counter, 64 pins, and the cogs.
//!
//! ```
//! use cogstep_hub::{ClockMode, Hub, HubConfig};
//! let hub = Hub::new(HubConfig { clkfreq: 200_000_000, clock: ClockMode::Virtual, ..Default::default() })?;
//! let x = hub.start_sd(0, 1, 2)?;          // stop pin 0, step pin 1, dir pin 2
//! hub.set_input(0, true);                  // the stop pin must be high to run
//! x.move_steps(20_000, -5_000)?;           // 20,000 steps/s, 5,000 steps back
//! let ct = hub.run_until_idle();
//! assert_eq!(x.position(), -5_000);
//! assert_eq!(x.stm(), 0);
//! assert_eq!(hub.rising_edges(1), 5_000);
//! assert!(ct > 0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! With [`ClockMode::Virtual`] time moves only in [`Hub::advance`] and
//! [`Hub::run_until_idle`]; commands and inputs given between those calls
//! take effect at the CT [`Hub::now`] shows, so the same calls give the same
//! edges bit for bit, however the threads are scheduled. (A command given by
//! another thread *while* the hub advances takes effect at whatever CT its
//! cog has reached then.) With [`ClockMode::Real`] the counter follows the
//! monotonic clock and the cogs run on their own.
//!
//! The hub by concern, one file each:
//!
//! | file | what |
//! |---|---|
//! | `config` | [`HubConfig`], [`HubError`], what each cog's axis core runs with |
//! | `lifecycle` | [`Hub::new`], starting cogs on pins, [`Hub::shutdown`], releasing an axis, the drop |
//! | `inputs` | input pins, simulated switches, output pins, emergency stops |
//! | `time` | the system counter: [`Hub::advance`], [`Hub::run_until_idle`], virtual epochs |
//! | `traces` | the edge trace, its drainer, VCD files, the signals by role |
//! | `groups` | coordinated moves ([`Hub::move_together`]) |

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;

use crate::cog::{CogShared, HubShared};
use crate::pins::Edge;
use crate::sync::AtomicBool;
use crate::trace::Signal;

mod config;
mod groups;
mod inputs;
mod lifecycle;
mod time;
mod traces;

pub use config::{HubConfig, HubError};
pub(crate) use inputs::{request_estop, wait_for_estop};

struct CogSlot {
    shared: Arc<CogShared>,
    thread: Option<JoinHandle<()>>,
}

pub(crate) struct HubInner {
    pub(crate) config: HubConfig,
    pub(crate) shared: Arc<HubShared>,
    cogs: Mutex<Vec<CogSlot>>,
    /// Pins claimed by running cogs and their switches (bit per pin).
    claimed: Mutex<u64>,
    /// Pins driven by simulated switches (bit per pin; also in `claimed`).
    switch_pins: Mutex<u64>,
    /// Serialises advancing the virtual clock; holds the list of cogs an
    /// epoch runs, kept so that epochs allocate nothing.
    advancing: Mutex<Vec<Arc<CogShared>>>,
    trace: Mutex<Vec<Edge>>,
    /// Every started axis's pins, by role (for VCD files).
    pin_names: Mutex<BTreeMap<u8, Signal>>,
    next_id: Mutex<usize>,
    /// Serialises group moves' admission, so that two callers never hold
    /// half of each other's axes.
    pub(crate) grouping: Mutex<()>,
    /// The look-ahead paths of this hub (virtual clock: the hub runs them
    /// between slices of its epochs).
    pub(crate) paths: Mutex<Vec<std::sync::Weak<crate::path::PathShared>>>,
    /// Clock ticks of CORDIC work per ramp step (QROTATE then QDIV in a cog's slot).
    math_ticks: u64,
    drainer_stop: Arc<AtomicBool>,
    drainer: Mutex<Option<JoinHandle<()>>>,
    /// Lets a test hold the drainer while it has the hub upgraded.
    #[cfg(all(test, not(loom)))]
    drainer_probe: Arc<tests::DrainerProbe>,
}

/// The hub: start cogs on pins, drive inputs, watch outputs, run the clock.
/// Cheap to clone: clones share one hub. The cogs stop when the last clone
/// (and every [`Axis`](crate::Axis)) is dropped, or with [`Hub::shutdown`].
#[derive(Clone)]
pub struct Hub {
    pub(crate) inner: Arc<HubInner>,
}

pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicking cog must not take the hub down with it.
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;
    use crate::clock::ClockMode;
    use std::sync::atomic::AtomicBool as StdAtomicBool;
    use std::sync::Weak;
    use std::time::Duration;
    use std::time::Instant;

    /// A gate in the drainer's loop: a test closes it, the drainer stops
    /// there with its upgraded hub in hand, and goes on when it opens.
    #[derive(Debug, Default)]
    pub(super) struct DrainerProbe {
        closed: StdAtomicBool,
        waiting: StdAtomicBool,
        ended: StdAtomicBool,
    }

    impl DrainerProbe {
        pub(super) fn hold_here(&self) {
            while self.closed.load(std::sync::atomic::Ordering::SeqCst) {
                self.waiting
                    .store(true, std::sync::atomic::Ordering::SeqCst);
                std::thread::sleep(Duration::from_micros(100));
            }
        }

        pub(super) fn ended(&self) {
            self.ended.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }

    fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while !done() {
            assert!(Instant::now() < deadline, "timed out waiting: {what}");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// The drainer made to hold the last reference: the hub drops on the
    /// drainer's thread, which must not join itself, and every cog's
    /// thread still ends.
    #[test]
    fn the_hub_dropped_on_its_drainer_stops_every_cog() {
        use std::sync::atomic::Ordering::SeqCst;
        let hub = Hub::new(HubConfig {
            clock: ClockMode::Real,
            trace_edges: true,
            ..HubConfig::default()
        })
        .expect("hub");
        let x = hub.start_sd(0, 1, 2).expect("x");
        let y = hub.start_cc(3, 4, 5).expect("y");
        hub.set_input(0, true).expect("stop pin");
        x.move_steps(20_000, 200).expect("move");
        hub.run_until_idle();
        let probe = Arc::clone(&hub.inner.drainer_probe);
        let cogs: Vec<Weak<CogShared>> = [&x, &y]
            .iter()
            .map(|axis| Arc::downgrade(&axis.shared))
            .collect();
        let inner = Arc::downgrade(&hub.inner);
        probe.closed.store(true, SeqCst);
        probe.waiting.store(false, SeqCst);
        wait_for("the drainer at the gate", || probe.waiting.load(SeqCst));
        // The drainer holds a handle now: ours are not the last.
        drop((x, y, hub));
        assert!(inner.upgrade().is_some(), "the drainer holds the hub");
        probe.closed.store(false, SeqCst);
        wait_for("the hub dropped", || inner.upgrade().is_none());
        wait_for("every cog thread ended", || {
            cogs.iter().all(|cog| cog.upgrade().is_none())
        });
        // Not a panic: the drainer's loop ran to its end.
        wait_for("the drainer ended", || probe.ended.load(SeqCst));
    }
}
