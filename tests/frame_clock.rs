//! The frame clock (src/ui/flow.rs) seen from the far terminal: the real binary in a
//! pseudo-terminal whose emulator holds back its answers to the status queries on demand.
//! Without answers no frame beyond the unanswered limit is written, whatever changes;
//! one late answer releases exactly one frame, and it shows the latest state (an edit made
//! while waiting, with what has accumulated since), not an older one.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;
use termtrace::measure::preview::{PreviewBench, Probe};

mod common;

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
        args: vec!["--max-spp".into(), "1000000".into()],
        answer_gate: Some(gate.clone()),
        ..PreviewBench::new(env!("CARGO_BIN_EXE_termtrace"), "basic", 60, 16)
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

#[test]
fn once_the_accumulation_stops_the_far_screen_is_a_direct_render() {
    // 60×16 cells: 14 rows of half blocks (60×28 pixels) above the two status rows; the
    // pseudo-terminal's 10×20-pixel cells make square pixels, as a direct render has.
    let (cols, rows, spp) = (60u16, 16u16, 8u32);
    let b = PreviewBench {
        args: vec!["--max-spp".into(), spp.to_string()],
        ..PreviewBench::new(env!("CARGO_BIN_EXE_termtrace"), "basic", cols, rows)
    };
    let far = b
        .run_with(|p| {
            p.wait_for(Duration::from_secs(120), |s| s.spp == Some(spp as u64))
                .expect("the preview reaches --max-spp");
            // The final frame and any rest of it have been answered and drawn.
            std::thread::sleep(Duration::from_secs(2));
            p.cells(0..rows - 2)
        })
        .expect("the preview runs in a pseudo-terminal");

    let scene = termtrace::scene::Scene::load("basic").unwrap();
    let s = termtrace::common::FrameSettings::new(
        cols as u32,
        2 * (rows as u32 - 2),
        scene.render.max_bounces,
        scene.render.seed,
    );
    let mut r = termtrace::render::Renderer::new(
        common::ctx(),
        &scene,
        s,
        termtrace::render::RenderOptions::default(),
    );
    r.render_spp(spp);
    let direct = termtrace::output::cells::encode(
        &r.snapshot().image(),
        termtrace::output::cells::CellMode::Half,
        termtrace::output::cells::ColorMode::Truecolor,
    );
    let rgb = |c: termtrace::output::cells::CellColor| match c {
        termtrace::output::cells::CellColor::Rgb(v) => Some(v),
        _ => None,
    };
    let mut worst = 0u8;
    for (row, far_row) in far.iter().enumerate() {
        for (col, f) in far_row.iter().enumerate() {
            let d = direct[row * cols as usize + col];
            assert_eq!(f.glyph, d.glyph.to_string(), "cell {col},{row}");
            for (a, b) in [(f.fg, rgb(d.fg)), (f.bg, rgb(d.bg))] {
                let (a, b) = (a.expect("a 24-bit colour"), b.expect("a 24-bit colour"));
                for c in 0..3 {
                    worst = worst.max(a[c].abs_diff(b[c]));
                }
            }
        }
    }
    // The GPU's resolve and the host's image round the same sums to f32 in two orders: a
    // channel may land one 8-bit step apart, never more.
    assert!(
        worst <= 1,
        "the far screen differs from a direct render by up to {worst}"
    );
}
