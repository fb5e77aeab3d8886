//! Dropping a hub stops every cog, wherever its last reference goes: with
//! the real clock and `trace_edges`, the trace drainer's temporary handle
//! can be the last one, and the hub then drops on the drainer's own thread
//! (issue 23: it joined itself, panicked, and left the cogs running). The
//! deterministic case, the drainer made to hold the last reference, is
//! `hub::tests::the_hub_dropped_on_its_drainer_stops_every_cog` in
//! cogstep-hub; this runs the race as a user meets it.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use driver::{ClockMode, Hub, HubConfig};

/// The threads of this process whose name starts with `prefix` (Linux).
fn threads_named(prefix: &str) -> usize {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return 0;
    };
    tasks
        .filter_map(Result::ok)
        .filter_map(|task| std::fs::read_to_string(task.path().join("comm")).ok())
        .filter(|name| name.starts_with(prefix))
        .count()
}

#[test]
fn create_move_drop_cycles_leave_no_thread_and_no_panic() {
    let panics = Arc::new(AtomicUsize::new(0));
    let counted = Arc::clone(&panics);
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        counted.fetch_add(1, Ordering::SeqCst);
        report(info);
    }));
    const CYCLES: usize = 1_000;
    for cycle in 0..CYCLES {
        let hub = Hub::new(HubConfig {
            clock: ClockMode::Real,
            trace_edges: true,
            ..HubConfig::default()
        })
        .expect("hub");
        let x = hub.start_sd(0, 1, 2).expect("x");
        hub.set_input(0, true).expect("stop pin");
        x.move_steps(40_000, 20 + (cycle % 7) as i32).expect("move");
        // Drop while the drainer is busy at varying points of its period.
        std::thread::sleep(Duration::from_micros(100 * (cycle % 13) as u64));
        drop(x);
        drop(hub);
    }
    // A hub dropped on its drainer stops its cogs from there, a moment later.
    let deadline = Instant::now() + Duration::from_secs(20);
    while threads_named("cog") + threads_named("hub-drain") > 0 {
        assert!(
            Instant::now() < deadline,
            "{} cog and {} drainer threads still run after {CYCLES} hubs were dropped",
            threads_named("cog"),
            threads_named("hub-drain")
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    assert_eq!(panics.load(Ordering::SeqCst), 0, "a thread panicked");
}
