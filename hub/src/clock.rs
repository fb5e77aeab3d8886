//! The system counter (CT): virtual or real.
//!
//! - [`ClockMode::Virtual`]: CT only moves when the hub is told to advance
//!   ([`Hub::advance`](crate::Hub::advance), [`Hub::run_until_idle`](crate::Hub::run_until_idle)).
//!   Deterministic: the same commands at the same CT give the same edges.
//! - [`ClockMode::Real`]: CT follows the monotonic clock at clkfreq ticks per
//!   second from the hub's creation; cogs wait for their step times (at
//!   `SCHED_FIFO` priority 1 where the process may: [`ask_for_realtime_priority`]).
//!
//! The virtual clock's handshake between the hub and its cogs is [`Epochs`]
//! and [`EpochDone`], model-checked with loom.

use std::time::{Duration, Instant};

use crate::sync::{AtomicU64, Ordering};

/// Where the system counter's time comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ClockMode {
    /// Deterministic emulated time (tests, exports, benchmarks).
    #[default]
    Virtual,
    /// Wall-clock time (the terminal demo, a board simulator).
    Real,
}

/// The monotonic clock seen as a counter at clkfreq.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RealClock {
    start: Instant,
    clkfreq: u32,
}

impl RealClock {
    pub fn new(clkfreq: u32) -> Self {
        Self {
            start: Instant::now(),
            clkfreq,
        }
    }

    /// CT now.
    pub fn now(&self) -> u64 {
        let elapsed = self.start.elapsed();
        let ticks = elapsed.as_nanos() * u128::from(self.clkfreq) / 1_000_000_000;
        u64::try_from(ticks).unwrap_or(u64::MAX)
    }

    /// The wall time from now until CT `ct` (zero if past).
    pub fn until(&self, ct: u64) -> Duration {
        let now = self.now();
        let ticks = ct.saturating_sub(now);
        Duration::from_nanos(
            u64::try_from(u128::from(ticks) * 1_000_000_000 / u128::from(self.clkfreq.max(1)))
                .unwrap_or(u64::MAX),
        )
    }
}

/// Asks the kernel to run the calling thread (a real-clock cog) with the
/// lowest real-time priority, `SCHED_FIFO` 1: when its steps are due it
/// preempts every ordinary thread (a compiler, a browser) at once instead
/// of waiting behind them for milliseconds. Only where the process may
/// (root, `CAP_SYS_NICE`, or an `rtprio` limit above 0 in
/// `/etc/security/limits.conf`); otherwise the thread stays as it was.
/// A cog sleeps between batches and needs a few microseconds of CPU each
/// time, and the kernel keeps 5% of every second for ordinary threads
/// whatever real-time threads do. Returns whether the kernel took it.
pub(crate) fn ask_for_realtime_priority() -> bool {
    #[cfg(target_os = "linux")]
    {
        use thread_priority::unix::{
            set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
            ThreadSchedulePolicy,
        };
        set_thread_priority_and_policy(
            thread_native_id(),
            thread_priority::ThreadPriority::Min,
            ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
        )
        .is_ok()
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}

/// The virtual clock's epochs: how the hub tells its cogs to run to a CT
/// and learns that they have.
///
/// ```text
/// hub                                        cog (each)
/// target ◄─store(Relaxed)─ T
/// epoch ◄─fetch_add(AcqRel)─ E               load(Acquire) == E (≠ the last it ran)
///   wake the cogs                            read target (Relaxed): T
///                                            run every event up to T
///                                            ct ◄─store(Relaxed)─ its CT
/// load(Acquire) ≥ E, for every cog ◄──────── done ◄─store(Release)─ E
/// read each cog's ct (Relaxed); now ◄─store(Release)─ T (or the last ct)
/// ```
///
/// - The target is written before the epoch's number with `Release` (the
///   `AcqRel` increment), and the cog that loads the number with `Acquire`
///   reads that target: never the last epoch's, and never the next one's,
///   since the hub opens no epoch before every cog has finished this one.
/// - `done` is stored with `Release` after the cog's CT, its pins and its
///   status: a hub that sees the epoch done with `Acquire` sees them all.
/// - `now` is stored with `Release` once the epoch is over: a cog idle
///   between epochs that reads it with `Acquire` starts commands there.
///
/// Model-checked with loom (`clock::loom_tests`) through these very types.
#[derive(Debug, Default)]
pub(crate) struct Epochs {
    /// Virtual CT: every cog has processed all events up to here.
    now: AtomicU64,
    /// The CT the current epoch runs to (u64::MAX: until quiescent).
    target: AtomicU64,
    /// How many epochs were opened.
    epoch: AtomicU64,
}

impl Epochs {
    /// CT now (between epochs: the end of the last).
    pub fn now(&self) -> u64 {
        self.now.load(Ordering::Acquire)
    }

    /// The hub's side, once an epoch is over: CT is now `ct`.
    pub fn set_now(&self, ct: u64) {
        self.now.store(ct, Ordering::Release);
    }

    /// The hub's side: opens an epoch that runs to `target`; returns its
    /// number, for [`EpochDone::is_done`]. One epoch at a time (the hub
    /// holds a lock), opened only once every cog finished the last.
    pub fn open(&self, target: u64) -> u64 {
        self.target.store(target, Ordering::Relaxed);
        // Release: a cog that sees the new number sees its target.
        self.epoch.fetch_add(1, Ordering::AcqRel) + 1
    }

    /// The number of the last epoch opened (a new cog starts from it).
    pub fn opened(&self) -> u64 {
        self.epoch.load(Ordering::Acquire)
    }

    /// The cog's side: the epoch opened since `seen` and its target, if any.
    #[inline]
    pub fn opened_since(&self, seen: u64) -> Option<(u64, u64)> {
        // Acquire: pairs with `open`'s Release; the target read after is its own.
        let epoch = self.epoch.load(Ordering::Acquire);
        (epoch != seen).then(|| (epoch, self.target.load(Ordering::Relaxed)))
    }
}

/// A cog's side of the epochs: the last epoch it finished and its CT then.
#[derive(Debug, Default)]
pub(crate) struct EpochDone {
    done: AtomicU64,
    ct: AtomicU64,
}

impl EpochDone {
    /// The cog ran every event of `epoch`; its CT is `ct` (Release: what
    /// it did, pins and status included, is seen with the number).
    pub fn finish(&self, epoch: u64, ct: u64) {
        self.ct.store(ct, Ordering::Relaxed);
        self.done.store(epoch, Ordering::Release);
    }

    /// Whether `epoch` is finished (Acquire: pairs with [`EpochDone::finish`]).
    pub fn is_done(&self, epoch: u64) -> bool {
        self.done.load(Ordering::Acquire) >= epoch
    }

    /// The cog's CT at the end of its last finished epoch (read after
    /// [`EpochDone::is_done`] said so).
    pub fn ct(&self) -> u64 {
        self.ct.load(Ordering::Relaxed)
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;
    use loom::thread;

    /// `cogs` cogs run the epochs to `targets` opened one after another:
    /// each cog runs each epoch exactly once, to that epoch's own target;
    /// the hub, once it sees every cog done, reads the CT and the work each
    /// did in it; a cog idle between epochs reads the CT the hub set.
    fn epochs_model(cogs: u64, targets: &'static [u64], preemptions: usize) {
        let mut model = loom::model::Builder::new();
        // Spin loops: bounded preemptions, as loom advises.
        model.preemption_bound = Some(preemptions);
        model.max_branches = 20_000;
        model.check(move || {
            let epochs = Arc::new(Epochs::default());
            let cogs: Vec<_> = (0..cogs)
                .map(|id| {
                    let epochs = Arc::clone(&epochs);
                    let done = Arc::new(EpochDone::default());
                    // What the cog did in the epoch (its pins, its status).
                    let work = Arc::new(AtomicU64::new(0));
                    let thread = {
                        let (done, work) = (Arc::clone(&done), Arc::clone(&work));
                        thread::spawn(move || {
                            let mut seen = 0;
                            while seen < targets.len() as u64 {
                                match epochs.opened_since(seen) {
                                    Some((epoch, target)) => {
                                        assert_eq!(epoch, seen + 1, "no epoch skipped");
                                        assert_eq!(
                                            target, targets[seen as usize],
                                            "its own target"
                                        );
                                        if seen > 0 {
                                            // Idle between epochs: CT is where the hub set it.
                                            assert_eq!(epochs.now(), targets[seen as usize - 1]);
                                        }
                                        work.store(target + id, Ordering::Relaxed);
                                        done.finish(epoch, target);
                                        seen = epoch;
                                    }
                                    None => thread::yield_now(),
                                }
                            }
                        })
                    };
                    (done, work, thread)
                })
                .collect();
            for &target in targets {
                let epoch = epochs.open(target);
                for (done, _, _) in &cogs {
                    while !done.is_done(epoch) {
                        thread::yield_now();
                    }
                }
                for (id, (done, work, _)) in cogs.iter().enumerate() {
                    assert_eq!(done.ct(), target);
                    assert_eq!(work.load(Ordering::Relaxed), target + id as u64);
                }
                epochs.set_now(target);
            }
            for (_, _, thread) in cogs {
                thread.join().unwrap();
            }
        });
    }

    /// One cog, epochs back to back: never a stale or a skipped target.
    #[test]
    fn a_cog_runs_each_epoch_to_its_own_target() {
        epochs_model(1, &[100, 200, 300], 2);
    }

    /// Two cogs: the hub sees an epoch done only when both have run it,
    /// and then sees what each did. (Three spinning threads: one preemption,
    /// or the model runs for many minutes.)
    #[test]
    fn the_hub_sees_every_cog_done_and_what_it_did() {
        epochs_model(2, &[100], 1);
    }
}
