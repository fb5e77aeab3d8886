//! The run-ahead handshake (`cogstep_handoff::AheadSlot`) model-checked
//! with loom: the owner (core 0) and the helper (core 1) each a thread,
//! in every interleaving loom explores. Loom's cells fail the run on any
//! read of a cell while the other side may write it; the checks below add
//! that every answer the owner reads is the one computed from the request
//! it is read with, and that every post is served.
//!
//!     RUSTFLAGS="--cfg loom" CARGO_TARGET_DIR=target/loom \
//!         cargo test --manifest-path firmware/Cargo.toml -p cogstep-handoff --release --test ahead_loom
#![cfg(loom)]

use cogstep_handoff::AheadSlot;
use loom::sync::Arc;
use loom::thread;

/// The helper's work: the answer to request `n` (odd requests are of no use).
fn work(from: &u32, ahead: &mut Option<u32>) -> bool {
    *ahead = Some(from * 10 + 1);
    from % 2 == 0
}

#[test]
fn answers_match_their_requests_and_no_cell_is_shared() {
    loom::model(|| {
        let slot = Arc::new(AheadSlot::<u32>::new());
        let helper = {
            let slot = slot.clone();
            thread::spawn(move || {
                let mut served = 0;
                // Bounded, as loom needs: enough turns to serve every post.
                for _ in 0..3 {
                    if slot.serve(work) {
                        served += 1;
                    } else {
                        thread::yield_now();
                    }
                }
                served
            })
        };
        let mut posted = 0u32;
        let mut answers = 0;
        for request in 0..3u32 {
            if let Some((from, ahead)) = slot.answer(|from, ahead| (*from, *ahead)) {
                assert_eq!(ahead, from * 10 + 1, "an answer read with another request");
                assert_eq!(from % 2, 0, "an answer of no use read");
                answers += 1;
            }
            if slot.post(|from| {
                *from = Some(request);
                true
            }) {
                posted += 1;
            }
            thread::yield_now();
        }
        assert_eq!(slot.posts(), posted);
        let served = helper.join().unwrap();
        assert!(served <= posted);
        assert!(answers <= posted);
        // Whatever the helper served last is the last request posted.
        if slot.idle() && served > 0 {
            if let Some((from, ahead)) = slot.answer(|from, ahead| (*from, *ahead)) {
                assert_eq!(ahead, from * 10 + 1);
            }
        }
    });
}

/// A post refused while the helper holds the slot changes nothing: the
/// request it holds is the one it answers.
#[test]
fn a_post_while_the_helper_holds_the_slot_is_refused() {
    loom::model(|| {
        let slot = Arc::new(AheadSlot::<u32>::new());
        assert!(slot.post(|from| {
            *from = Some(4);
            true
        }));
        let helper = {
            let slot = slot.clone();
            thread::spawn(move || slot.serve(work))
        };
        let second = slot.post(|from| {
            *from = Some(6);
            true
        });
        let served = helper.join().unwrap();
        assert!(served);
        if !second {
            // Refused: the helper answered request 4.
            assert_eq!(slot.answer(|from, ahead| (*from, *ahead)), Some((4, 41)));
        } else {
            // Taken after the helper served 4: 6 waits for its turn.
            assert!(!slot.idle());
        }
    });
}
