//! The preview benchmark's harness (`bench --preview`) checked for what it sees, not for how
//! fast: the real binary in a pseudo-terminal, read by a terminal emulator; after each key
//! the screen must show the edited value and a restarted sample count, and the frames and
//! bytes it counts while converging must be there.

use std::time::Duration;
use termtrace::measure::preview::PreviewBench;

#[test]
fn the_harness_sees_each_edit_with_a_restarted_sample_count() {
    let b = PreviewBench {
        presses: 2,
        settle: Duration::from_millis(300),
        // Generous: this checks what is shown, not how fast (CI's software adapter is slow).
        timeout: Duration::from_secs(60),
        window: Duration::from_millis(800),
        args: vec!["--max-spp".into(), "1000000".into()],
        ..PreviewBench::new(env!("CARGO_BIN_EXE_termtrace"), "basic", 80, 16)
    };
    let r = b.run().expect("the preview runs in a pseudo-terminal");
    assert_eq!(r.misses, 0, "{r:?}");
    assert_eq!(r.latencies.len(), 2, "{r:?}");
    for &(before, after) in &r.restarts {
        assert!(before >= 2 && after < before, "no restart seen: {r:?}");
    }
    // `+` then `-`: the first parameter went up a fine step, then back.
    let (first_before, first_after) = &r.edits[0];
    let (second_before, second_after) = &r.edits[1];
    assert_ne!(first_before, first_after);
    assert_eq!(first_after, second_before);
    assert_eq!(second_after, first_before, "{r:?}");
    assert!(first_before.starts_with('▸'), "{first_before}");
    // The traced size of an 80×16 terminal in half blocks: 80 × (16 - 2 status rows) × 2.
    assert_eq!(r.size, "80×28");
    assert!(r.fps > 0.0 && r.bytes_per_second > 0.0, "{r:?}");
}
