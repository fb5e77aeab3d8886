//! A stop pin that goes low while a group move is being admitted, from
//! another thread, with the real clock: the group either is refused
//! (`StopPinLow`) or stops on its line; it never runs all its steps with
//! the pin low. (Before the fix, a pin dropped 0–300 µs into
//! `move_together` let 162 to 1,235 of about 1,480 Ok'd groups run every
//! step.)

use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

use driver::{AxisError, ClockMode, Hub, HubConfig};

#[test]
fn a_stop_pin_dropped_during_admission_never_lets_the_whole_group_run() {
    let hub = Arc::new(
        Hub::new(HubConfig {
            clock: ClockMode::Real,
            realtime_priority: false,
            ..HubConfig::default()
        })
        .unwrap(),
    );
    let x = hub.start_sd(0, 1, 2).unwrap();
    let y = hub.start_sd(3, 4, 5).unwrap();
    let (mut refused, mut stopped) = (0, 0);
    for cycle in 0..300u64 {
        hub.set_input(0, true).unwrap();
        hub.set_input(3, true).unwrap();
        let (x0, y0) = (x.position(), y.position());
        // Each cycle drops y's stop pin at another moment, 0–150 µs after
        // both threads leave the barrier (a spin, not a sleep, so the
        // moment falls inside the admission).
        let delay = Duration::from_nanos((cycle * 7_919_111) % 150_000);
        let barrier = Arc::new(Barrier::new(2));
        let dropper = {
            let hub = Arc::clone(&hub);
            let barrier = Arc::clone(&barrier);
            std::thread::spawn(move || {
                barrier.wait();
                let start = Instant::now();
                while start.elapsed() < delay {
                    std::hint::spin_loop();
                }
                hub.set_input(3, false).unwrap();
            })
        };
        barrier.wait();
        let result = hub.move_together(&[(&x, 2_000), (&y, 2_000)], 20_000);
        dropper.join().unwrap();
        hub.run_until_idle();
        match result {
            Err(AxisError::StopPinLow) => {
                refused += 1;
                assert_eq!(
                    (x.position(), y.position()),
                    (x0, y0),
                    "a refused group moved"
                );
            }
            Ok(()) => {
                stopped += 1;
                assert!(
                    y.position() - y0 < 2_000,
                    "cycle {cycle}: the whole group ran with y's stop pin low"
                );
                assert!(x.position() - x0 < 2_000, "cycle {cycle}: x left the line");
                assert!(((x.position() - x0) - (y.position() - y0)).abs() <= 1);
            }
            Err(other) => panic!("cycle {cycle}: {other}"),
        }
    }
    eprintln!("{refused} refused, {stopped} stopped on the line");
}
