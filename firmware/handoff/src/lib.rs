//! Work computed ahead on another core: the handshake of one slot.
//!
//! The Pico has two cores. Core 0 runs everything (the host's session, the
//! axes' cores, the edges); core 1 computes each axis's next ramp run
//! while core 0 yields the armed one, from a prediction of the state the
//! axis will be in when that run is used up (the motion crate's
//! `SCurve::run_ahead_from`). Core 0 takes the answer only if the
//! prediction came true (`SCurve::adopt_run_ahead`):
//! the steps are then bit for bit the ones it would have computed, and a
//! late or wrong answer costs only the time core 0 takes to compute the
//! run itself, as it does without core 1.
//!
//! An [`AheadSlot`] holds one request (`from`) and its answer (`ahead`).
//! One owner (core 0) posts requests and reads answers; one helper (core 1)
//! serves them. Each of the two counts has one writer:
//!
//! - the owner writes `from` only while the helper holds nothing
//!   (`served == posted`), then counts the post (release);
//! - the helper, seeing a post it has not served (acquire), reads `from`,
//!   writes `ahead` and whether it is of use, then counts it served
//!   (release);
//! - the owner reads `ahead` only once `served == posted` (acquire).
//!
//! Only loads and stores: the M0+ has no compare-and-swap. `tests/ahead_loom.rs`
//! model-checks this very code with loom (`RUSTFLAGS="--cfg loom"`), the
//! owner and the helper each a thread: no cell is read while written, and
//! every answer read is the one computed from the request it is read with.

#![no_std]

#[cfg(loom)]
use loom::cell::UnsafeCell;
#[cfg(loom)]
use loom::sync::atomic::{AtomicBool, AtomicU32, Ordering};

#[cfg(not(loom))]
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// `core`'s cell behind loom's interface (loom's checks each access).
#[cfg(not(loom))]
#[derive(Debug)]
struct UnsafeCell<T>(core::cell::UnsafeCell<T>);

#[cfg(not(loom))]
impl<T> UnsafeCell<T> {
    const fn new(value: T) -> Self {
        Self(core::cell::UnsafeCell::new(value))
    }

    fn with<R>(&self, f: impl FnOnce(*const T) -> R) -> R {
        f(self.0.get())
    }

    fn with_mut<R>(&self, f: impl FnOnce(*mut T) -> R) -> R {
        f(self.0.get())
    }
}

/// One request handed from an owner to a helper and its answer (see the
/// module docs). The owner's methods ([`AheadSlot::post`],
/// [`AheadSlot::answer`], [`AheadSlot::idle`]) are called from one context
/// only, the helper's ([`AheadSlot::serve`]) from one other.
#[derive(Debug)]
pub struct AheadSlot<T> {
    /// Requests posted: the owner's count (wrapping).
    posted: AtomicU32,
    /// Requests served: the helper's count (wrapping); equal to `posted`
    /// when the helper holds nothing.
    served: AtomicU32,
    /// Whether the last answer is of use: the helper's word, stored
    /// before `served`.
    useful: AtomicBool,
    from: UnsafeCell<Option<T>>,
    ahead: UnsafeCell<Option<T>>,
}

// SAFETY: the cells are reached only under the handshake in the module
// docs: each by one side at a time, handed over by a release store and an
// acquire load of a count.
unsafe impl<T: Send> Sync for AheadSlot<T> {}

impl<T> AheadSlot<T> {
    /// No request.
    #[cfg(not(loom))]
    pub const fn new() -> Self {
        Self {
            posted: AtomicU32::new(0),
            served: AtomicU32::new(0),
            useful: AtomicBool::new(false),
            from: UnsafeCell::new(None),
            ahead: UnsafeCell::new(None),
        }
    }

    /// No request.
    #[cfg(loom)]
    pub fn new() -> Self {
        Self {
            posted: AtomicU32::new(0),
            served: AtomicU32::new(0),
            useful: AtomicBool::new(false),
            from: UnsafeCell::new(None),
            ahead: UnsafeCell::new(None),
        }
    }

    /// The owner's: whether the helper holds nothing (its last request
    /// served, or none posted).
    #[inline]
    pub fn idle(&self) -> bool {
        self.served.load(Ordering::Acquire) == self.posted.load(Ordering::Relaxed)
    }

    /// The owner's: requests posted so far (wrapping): a board rings the
    /// helper's doorbell when this moves.
    #[inline]
    pub fn posts(&self) -> u32 {
        self.posted.load(Ordering::Relaxed)
    }

    /// The owner's: when the helper holds nothing, writes a request with
    /// `write` (given the last one, `None` at first) and posts it if
    /// `write` returns `true`. Returns whether it posted.
    pub fn post(&self, write: impl FnOnce(&mut Option<T>) -> bool) -> bool {
        if !self.idle() {
            return false;
        }
        // SAFETY: the helper has served every post (acquire in `idle`) and
        // reads `from` only after the next.
        let posted = self.from.with_mut(|from| write(unsafe { &mut *from }));
        if posted {
            let count = self.posted.load(Ordering::Relaxed).wrapping_add(1);
            self.posted.store(count, Ordering::Release);
        }
        posted
    }

    /// The owner's: when the helper holds nothing and its last answer is
    /// of use, `read(request, answer)`.
    pub fn answer<R>(&self, read: impl FnOnce(&T, &T) -> R) -> Option<R> {
        if !self.idle() || !self.useful.load(Ordering::Relaxed) {
            return None;
        }
        // SAFETY: the helper wrote both before its release of `served`,
        // which `idle` acquired, and writes neither before the next post.
        self.from.with(|from| {
            self.ahead.with(|ahead| {
                let (from, ahead) = unsafe { (&*from, &*ahead) };
                Some(read(from.as_ref()?, ahead.as_ref()?))
            })
        })
    }

    /// The helper's: serves the request posted since the last call, if
    /// any: `work(request, answer)` writes the answer (given the last one,
    /// `None` at first) and says whether it is of use. Returns whether it
    /// served one.
    pub fn serve(&self, work: impl FnOnce(&T, &mut Option<T>) -> bool) -> bool {
        let posted = self.posted.load(Ordering::Acquire);
        if posted == self.served.load(Ordering::Relaxed) {
            return false;
        }
        // SAFETY: the owner wrote `from` before its release of `posted`,
        // acquired above, and touches neither cell until `served` is
        // stored below.
        let useful = self.from.with(|from| {
            self.ahead.with_mut(|ahead| {
                let (from, ahead) = unsafe { (&*from, &mut *ahead) };
                from.as_ref().is_some_and(|from| work(from, ahead))
            })
        });
        self.useful.store(useful, Ordering::Relaxed);
        self.served.store(posted, Ordering::Release);
        true
    }
}

#[cfg(not(loom))]
impl<T> Default for AheadSlot<T> {
    fn default() -> Self {
        Self::new()
    }
}
