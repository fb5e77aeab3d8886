//! `Axis::status()` is one instant's fields (issue 23: it read about
//! twenty independent atomics, so a status could mix two steps). While a
//! single move of N steps runs from 0, every step the cog publishes has
//! position + steps to go = N; a status that mixed two steps would not.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use driver::{ClockMode, Hub, HubConfig};

#[test]
fn a_status_never_mixes_two_steps() {
    const STEPS: i32 = 60_000;
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Virtual,
        ..HubConfig::default()
    })
    .expect("hub");
    // cc: no trace, no switch, so steps are published one by one only
    // while ramping; the slew runs in batches, each published whole too.
    let x = hub.start_cc(0, 1, 2).expect("x");
    hub.set_input(0, true).unwrap();
    x.move_steps(50_000, STEPS).unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let reader = {
        let x = x.clone();
        let done = Arc::clone(&done);
        std::thread::spawn(move || {
            let mut reads = 0u64;
            let mut last = 0;
            while !done.load(Ordering::Acquire) {
                let status = x.status();
                let sum = status.position + status.steps_to_go as i64;
                assert_eq!(
                    sum,
                    i64::from(STEPS),
                    "a status of two steps: {status:?} after {reads} reads"
                );
                assert!(status.position >= last, "a status went back: {status:?}");
                last = status.position;
                reads += 1;
            }
            reads
        })
    };
    // Advance in small slices, so the cog publishes while the reader reads.
    while x.steps_to_go() > 0 {
        hub.advance(20_000);
    }
    done.store(true, Ordering::Release);
    let reads = reader.join().expect("no torn status");
    assert!(reads > 0);
    assert_eq!(x.position(), i64::from(STEPS));
}
