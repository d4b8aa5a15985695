//! The frame clock (src/ui/flow.rs) seen from the far terminal: the real binary in a
//! pseudo-terminal whose emulator holds back its answers to the status queries on demand.
//! Without answers no frame beyond the unanswered limit is written, whatever changes;
//! one late answer releases exactly one frame, and it shows the latest state (an edit made
//! while waiting, with what has accumulated since), not an older one.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;
use termtrace::cli::preview_bench::{PreviewBench, Probe};

/// Frames the far screen has received once they stop coming (none for `quiet`).
fn settled_frames(p: &Probe<'_>, quiet: Duration) -> u64 {
    let mut last = p.screen().frames;
    for _ in 0..40 {
        std::thread::sleep(quiet);
        let now = p.screen().frames;
        if now == last {
            return now;
        }
        last = now;
    }
    panic!("frames kept coming without answers: {last}");
}

#[test]
fn without_answers_frames_stop_and_a_late_answer_releases_the_latest_state() {
    let gate = Arc::new(AtomicI64::new(i64::MAX / 2));
    let b = PreviewBench {
        exe: env!("CARGO_BIN_EXE_termtrace").into(),
        scene: "basic".into(),
        cols: 60,
        rows: 16,
        presses: 0,
        settle: Duration::ZERO,
        timeout: Duration::from_secs(60),
        window: Duration::ZERO,
        args: vec!["--max-spp".into(), "1000000".into()],
        link: None,
        command: None,
        answer_gate: Some(gate.clone()),
    };
    b.run_with(|p| {
        // Answered frames until the image has a few samples.
        p.wait_for(Duration::from_secs(120), |s| s.spp.is_some_and(|n| n >= 3))
            .expect("the preview draws");
        // From now on no answers: at most two more frames, then none.
        gate.store(0, Ordering::SeqCst);
        let quiet = Duration::from_millis(1500);
        let stalled = settled_frames(p, quiet);
        let before = p.screen();
        assert_eq!(stalled, settled_frames(p, quiet));
        // An edit while waiting changes the state, but writes nothing.
        p.type_key(b"+");
        std::thread::sleep(quiet);
        assert_eq!(
            p.screen().frames,
            stalled,
            "a frame was written without an answer"
        );
        // One late answer: exactly one frame, and it is of the latest state: the edit, with
        // the samples the new state has gathered meanwhile (no frame of the states between).
        gate.store(1, Ordering::SeqCst);
        let after = p
            .wait_for(Duration::from_secs(60), |s| s.frames > stalled)
            .expect("the answer releases a frame");
        assert_eq!(
            settled_frames(p, quiet),
            stalled + 1,
            "one answer, one frame"
        );
        let shown = p.screen();
        assert_ne!(
            shown.params, before.params,
            "the released frame shows the edit"
        );
        assert!(shown.spp.is_some(), "{before:?} → {shown:?} ({after:?})");
        // Answers again: frames flow.
        gate.store(i64::MAX / 2, Ordering::SeqCst);
        p.wait_for(Duration::from_secs(60), |s| s.frames > stalled + 3)
            .expect("frames flow again");
    })
    .expect("the preview runs in a pseudo-terminal");
}
