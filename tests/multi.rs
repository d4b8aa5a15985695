//! A render on several devices at once (`--adapter all`, `--adapter 0,1`) is the render one
//! device makes, bit for bit, where the devices compute alike: two devices opened on the
//! software adapter, two native CPU tracers. Devices that do not compute alike (the CPU
//! tracer beside the software adapter) still give exactly the sum of what each traced: the
//! samples it claimed, traced alone on it, add up to the team's image word for word.

mod common;
use common::*;
use std::path::Path;
use std::process::Command;
use std::sync::Arc;
use termtrace::common::accum::Sums;
use termtrace::gpu::GpuContext;
use termtrace::render::team::Team;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

/// A second device on the tests' adapter: its own queue, buffers and pipelines.
fn second_device() -> Backend {
    let sel = std::env::var("TERMTRACE_ADAPTER").ok();
    Backend::Gpu(Arc::new(
        GpuContext::new(sel.as_deref()).expect("a second device on the tests' adapter"),
    ))
}

/// Samples `range` of every pixel traced by one renderer on `b`: its exact sums.
fn alone(b: Backend, scene: &Scene, range: std::ops::Range<u32>) -> Sums {
    let options = RenderOptions {
        first_sample: range.start,
        ..Default::default()
    };
    let mut r = Renderer::new(b, scene, settings(24, 16, 6), options);
    r.render_spp(range.end - range.start);
    r.exact_sums()
}

fn team(backends: &[Backend], scene: &Scene, range: std::ops::Range<u32>) -> Team {
    let t = Team::new(
        backends,
        scene,
        settings(24, 16, 6),
        RenderOptions::default(),
        range,
    );
    t.run(std::time::Duration::from_millis(50), None, |_| true);
    t
}

#[test]
fn two_devices_alike_make_one_devices_image_bit_for_bit() {
    // Showcase has glass, a light and light sampling. Two devices on the software adapter,
    // then two CPU tracers; a whole render and a shard's range (samples 5..18).
    let scene = Scene::load("showcase").unwrap();
    for pair in [
        [Backend::Gpu(ctx()), second_device()],
        [Backend::Cpu, Backend::Cpu],
    ] {
        for range in [0..16, 5..18] {
            let one = alone(pair[0].clone(), &scene, range.clone());
            assert!(one.even.iter().any(|w| *w != 0));
            let t = team(&pair, &scene, range.clone());
            let shares = t.shares();
            let claimed: u64 = shares.iter().map(|s| s.samples).sum();
            assert_eq!(claimed, (range.end - range.start) as u64);
            // Both devices of the software adapter trace (a round there takes milliseconds,
            // one sample a claim until both are measured); two CPU tracers on a 2-core
            // machine may well leave one sample-sized round to just one of them.
            if matches!(pair[0], Backend::Gpu(_)) {
                assert!(
                    shares.iter().all(|s| s.samples > 0),
                    "both devices traced: {shares:?}"
                );
            }
            let both = t.exact_sums();
            assert_eq!(both, one, "{} on {range:?}", t.describe());
        }
    }
}

#[test]
fn unlike_devices_add_up_to_what_each_traced_alone() {
    // The CPU tracer and the software adapter round some paths differently, so their team's
    // image is not either one's; it is exactly the sum of the ranges each claimed, each
    // traced alone on its device.
    let scene = Scene::load("showcase").unwrap();
    let backends = [Backend::Gpu(ctx()), Backend::Cpu];
    let t = team(&backends, &scene, 0..20);
    let mut total = Sums {
        even: vec![0u32; 24 * 16 * 10],
        odd: vec![0u32; 24 * 16 * 10],
        invalid: 0,
    };
    let mut covered = Vec::new();
    for (b, share) in backends.iter().zip(t.shares()) {
        for range in share.ranges {
            covered.push(range.clone());
            total.add(&alone(b.clone(), &scene, range));
        }
    }
    covered.sort_by_key(|r| r.start);
    let tiled: Vec<u32> = covered.iter().flat_map(|r| [r.start, r.end]).collect();
    let mut expect = vec![0];
    for r in &covered[..covered.len() - 1] {
        expect.extend([r.end, r.end]);
    }
    expect.push(20);
    assert_eq!(tiled, expect, "the claims tile 0..20 once");
    assert_eq!(t.exact_sums(), total);
}

fn termtrace(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_termtrace"));
    c.current_dir(dir).env_remove("TERMTRACE_ADAPTER");
    c
}

#[test]
fn the_command_line_takes_a_list_and_all() {
    // `--adapter cpu-native,cpu-native` writes the very snapshot of `--adapter cpu-native`;
    // `--adapter all` on a machine without a hardware GPU renders on the default backend;
    // `converge` measures two devices sharing each run; `Backend::open`, which opens one
    // device, refuses a list by name (the preview shares one: ui::worker's tests).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let render = |adapter: &str, out: &str| {
        let o = termtrace(d)
            .args(["render", "cornell", "--width", "24", "--height", "16"])
            .args(["--spp", "12", "-q", "--adapter", adapter, "-o", out])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "--adapter {adapter}: {err}");
        err
    };
    render("cpu-native", "one.tta");
    let err = render("cpu-native, cpu-native", "two.tta");
    assert!(
        err.contains("% of the samples"),
        "each device's share: {err}"
    );
    assert_eq!(
        std::fs::read(d.join("one.tta")).unwrap(),
        std::fs::read(d.join("two.tta")).unwrap()
    );
    render("all", "all.png");
    assert!(d.join("all.png").exists());
    let o = termtrace(d)
        .args([
            "converge", "cornell", "--out", "c", "--width", "24", "--height", "16",
        ])
        .args(["--time", "0.3", "--reference-spp", "64", "--no-cache"])
        .args(["--adapter", "cpu-native,cpu-native"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("native CPU tracer (") && err.contains(" + "),
        "{err}"
    );
    let csv = std::fs::read_to_string(d.join("c/convergence.csv")).unwrap();
    assert!(csv.lines().count() > 2, "{csv}");
    let e = Backend::open(Some("0,1")).err().expect("a list refused");
    assert!(
        e.to_string()
            .contains("adapter `0,1` names several devices"),
        "{e}"
    );
}
