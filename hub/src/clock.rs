//! The system counter (CT): virtual or real.
//!
//! - [`ClockMode::Virtual`]: CT only moves when the hub is told to advance
//!   ([`Hub::advance`](crate::Hub::advance), [`Hub::run_until_idle`](crate::Hub::run_until_idle)).
//!   Deterministic: the same commands at the same CT give the same edges.
//! - [`ClockMode::Real`]: CT follows the monotonic clock at clkfreq ticks per
//!   second from the hub's creation; cogs wait for their step times.

use std::time::{Duration, Instant};

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
