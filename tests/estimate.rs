//! The error estimate against the true error (issue 45): on every shipped scene, the caustic
//! one included, on both tracers, at 16, 64 and 256 samples per pixel, the mean over runs of
//! estimated ÷ true relative RMSE must be within 0.8–1.25, for the raw image (the status
//! line's noise figure, `render`'s and `converge`'s estimate) and for the image the preview
//! shows (per tile raw or denoised, `denoise::Denoised::shown_sums`).
//!
//! The true error is measured against committed references of `REFERENCE_SPP` (2²⁰) samples
//! per pixel, `tests/estimate/SCENE.exr`, rendered on an H200 by the ignored test
//! `write_the_references` (the two tracers converge to the same image: the bias checks of
//! `tests/cpu.rs`). A reference of 4096 samples, rendered here, held up to half of its own
//! noise on the caustic scenes and read their ratios low; at 2²⁰ a reference's noise is
//! 1/4096 of a 256-spp run's. Each reference is checked against the runs' own mean, so one
//! left stale by a change of the images fails the test by name.
//!
//! Where sampling makes fireflies the mean ratio is not yet within the bounds everywhere:
//! those cells, measured, are in `OPEN` (issue 45 stays open for them) and are printed but
//! not held to the bounds. Every other cell is. A run's figure is not the whole story on a
//! firefly scene: it is usually low where the run missed the bright paths and high where it
//! found them, so each cell also prints the estimate in expectation (the mean estimated
//! relative MSE over the mean true one), and the raw estimate's must be at least
//! `EXPECTED_FLOOR` on every scene, the open ones included: it must not undercount fireflies.
//!
//! Eight runs say little of a firefly scene: its ratios are heavy-tailed, and eight runs of
//! `outdoor` read its shown estimate 0.51–0.62 where 96 read it 2.2–2.7 (and 9 in
//! expectation: one candidate's firefly counted for another's image, `denoise::cross_fitted`).
//! So the CPU tracer runs the `FIREFLY` scenes `FIREFLY_RUNS` times, and the light-tailed ones
//! eight; the GPU tracer (lavapipe, slower) runs every scene four times and holds only the
//! light-tailed ones to the bounds and to `EXPECTED_FLOOR` (its estimator is the host's:
//! tests/denoise.rs, held on the firefly scenes by the CPU tracer's runs). A few runs'
//! expectation on a firefly scene is one run's firefly: four runs read `glass`'s raw estimate
//! at 64 spp 0.65 of the truth once its rough balls were drawn by their facets, twelve read
//! `outdoor`'s at 256 spp 0.61, where the CPU tracer's 96 runs read 1.06 and 1.27.
mod common;

use common::{ctx, settings, snapshot_on};
use termtrace::common::FrameSettings;
use termtrace::converge::metrics::errors;
use termtrace::denoise::denoise;
use termtrace::output::LinearImage;
use termtrace::render::{Backend, RenderOptions, Renderer, Snapshot};
use termtrace::scene::{BUILTIN_SCENES, Scene};

const SPPS: [u32; 3] = [16, 64, 256];
/// Samples per pixel of the committed references.
const REFERENCE_SPP: u32 = 1 << 20;
/// Where the references are (`TERMTRACE_REFERENCE_DIR` overrides it for
/// `write_the_references`).
const REFERENCES: &str = "tests/estimate";
/// Large enough for 4 × 3 of the denoiser's 16-pixel tiles.
const SIZE: (u32, u32) = (64, 36);

/// The shipped scenes whose sampling makes fireflies: a caustic, or a glossy lobe or a mirror
/// finding a small bright light.
const FIREFLY: &[&str] = &["outdoor", "outdoor-caustics", "pbr", "glass"];
/// Runs of each `FIREFLY` scene on the CPU tracer (about 50 s in all here).
const FIREFLY_RUNS: u32 = 96;

/// Cells (scene, image, spp) whose mean ratio over the CPU tracer's `FIREFLY_RUNS` runs is
/// outside 0.8–1.25, or within 0.01 of a bound (BENCHMARKS.md, "An estimate that counts
/// fireflies", "The filtered images' estimate", "Light samples for the glossy lobe", "The
/// sun in a mirror ball, seen", "The sun in a glass ball, seen", "A glossy lobe mixed
/// with the diffuse one", "Light samples through rough glass" and "Light samples through
/// glTF's glass balls" have their figures):
/// - the raw estimate on `outdoor-caustics` and `pbr` at 16 spp (1.34, 1.25): high. On
///   `outdoor` at 256 spp (0.81): low in most runs, high in expectation (1.27). In
///   expectation every firefly scene's raw estimate reads 0.91–1.83 of the truth: a run's
///   error there is mostly one pixel's rare bright samples (the sun seen at a glossy lobe's
///   rim, the sun through `glass`'s frosted ball after three scatterings), and the proxy,
///   which a spike in one half does not lift by the other half, counts them rather than
///   dividing them away; the runs without them read low;
/// - the shown image's on `glass` at 16, 64 and 256 spp (0.77, 0.75, 0.75), and on
///   `outdoor-caustics` and `outdoor` at 256 spp (0.79, 0.78). Measured on `outdoor` and
///   `glass` (96 runs, the à-trous image shown everywhere so that no choice enters): with the
///   exact reference as the weight it read 0.57–0.85; with each filter's own noise-variance
///   map as well (from each half's squared luminances, so that D(A) is independent of B and
///   the estimator unbiased), 0.63–0.90. What is left is the error of the bright paths a run
///   did not find: the filters average the noise the run holds away, not the light it
///   missed, so that part of the error grows in the shown image's share, and only the runs
///   that found those paths see it. On `glass` at 16 spp, since its polished ball is sampled
///   through, a third of the shown image's error is one tile's, the frosted (0.35) ball's
///   lower edge: paths of three scatterings through it find the sun as fireflies (the
///   largest of 6 000 samples of one pixel 63, its mean 0.32), the denoised image there
///   reads 0.6–0.7 of the reference, and its estimate counts 0.49 of that tile's error.
const OPEN: &[(&str, &str, u32)] = &[
    ("outdoor-caustics", "raw", 16),
    ("pbr", "raw", 16),
    ("outdoor", "raw", 256),
    ("outdoor", "shown", 256),
    ("outdoor-caustics", "shown", 256),
    ("glass", "shown", 16),
    ("glass", "shown", 64),
    ("glass", "shown", 256),
];

/// The least the raw estimate may count of the true relative MSE in expectation (`summary`'s
/// second figure), on every scene and checkpoint, none left open: the estimate must not
/// undercount fireflies. The proxy before this one (the halves' 3×3 means, the pixel's own
/// firefly in them) read 0.23–0.36 on `pbr`, `outdoor` and `glass`; this one reads at least
/// 0.91.
const EXPECTED_FLOOR: f64 = 0.75;

/// One run at one checkpoint: the estimated and the true relative RMSE of the raw image and
/// of the shown one.
#[derive(Clone, Copy, Debug)]
struct Ratios {
    raw: (f64, f64),
    shown: (f64, f64),
}

/// Over runs of (estimated, true): the mean of the runs' estimated ÷ true (the issue's
/// figure), and √(mean estimated relMSE ÷ mean true relMSE), whether the estimate counts the
/// error in expectation. On a firefly scene the two differ: a run's figure is usually low
/// when it missed the bright paths and high when it found them, while the expectation is
/// dominated by the runs that found them.
fn summary(runs: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    let v: Vec<(f64, f64)> = runs.collect();
    let ratio = mean(v.iter().map(|(e, t)| e / t));
    let expected = (mean(v.iter().map(|(e, _)| e * e)) / mean(v.iter().map(|(_, t)| t * t))).sqrt();
    (ratio, expected)
}

/// The committed reference of `name`.
fn reference(name: &str) -> LinearImage {
    let path = format!("{REFERENCES}/{name}.exr");
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{path}: {e} (write it with `write_the_references`)"))
        .to_rgb32f();
    assert_eq!(img.dimensions(), SIZE, "{path}");
    LinearImage {
        width: SIZE.0,
        height: SIZE.1,
        pixels: img.pixels().map(|p| p.0).collect(),
    }
}

/// The frame settings of the references and the runs.
fn frame_settings(scene: &Scene) -> FrameSettings {
    settings(SIZE.0, SIZE.1, scene.render.max_bounces.min(8))
}

/// The estimated and the true relative RMSE of the image the preview shows (per tile raw or
/// denoised) from `r`'s samples so far, `snap` their snapshot.
fn shown_errors(r: &mut Renderer, snap: &Snapshot, reference: &LinearImage) -> (f64, f64) {
    let d = denoise(&snap.data.even, &snap.data.odd, r.guides());
    let shown = LinearImage {
        width: SIZE.0,
        height: SIZE.1,
        pixels: d.shown(),
    };
    (
        d.rel_rmse(d.shown_sums()),
        errors(&shown, reference).rel_rmse(),
    )
}

/// Per checkpoint of `SPPS`, the ratios of each of `runs` independent runs of `name` on `b`.
fn ratios(b: &Backend, name: &str, runs: u32) -> Vec<Vec<Ratios>> {
    let scene = Scene::load(name).unwrap();
    let mut fs = frame_settings(&scene);
    let ref_image = reference(name);
    // The mean of each run's last image, against the reference's.
    let mut run_means = Vec::new();
    let truth = |img: &termtrace::output::LinearImage| errors(img, &ref_image).rel_rmse();
    let mut out = vec![Vec::new(); SPPS.len()];
    for run in 0..runs {
        fs.seed = 1 + run;
        let mut r = Renderer::new(b.clone(), &scene, fs, RenderOptions::default());
        for (i, &spp) in SPPS.iter().enumerate() {
            r.render_spp(spp);
            let snap: Snapshot = r.snapshot();
            let raw = (snap.noise_estimate().unwrap(), truth(&snap.image()));
            let shown = shown_errors(&mut r, &snap, &ref_image);
            out[i].push(Ratios { raw, shown });
            if i + 1 == SPPS.len() {
                run_means.push(image_mean(&snap.image()));
            }
        }
    }
    // A stale reference (the images changed since it was written) fails by name: the runs'
    // mean must be within 5 standard errors of its mean (their spread: 8 or 4 runs), or
    // 0.2 % of it. Not from the GPU tracer's 4 runs of a firefly scene: their spread says
    // nothing of the bright paths none of them found (4 runs of `outdoor-caustics` read its
    // mean 2.1 % low, "29.6 standard errors"); the CPU tracer's 96 runs check those references,
    // and the two tracers converge to the same image (tests/cpu.rs).
    if FIREFLY.contains(&name) && runs < 8 {
        return out;
    }
    let m = mean(run_means.iter().copied());
    let n = run_means.len() as f64;
    let se = (run_means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    let r = image_mean(&ref_image);
    assert!(
        (m - r).abs() <= 5.0 * se + 2e-3 * r,
        "{name}: the runs' mean {m} is {:.1} standard errors from {REFERENCES}/{name}.exr's {r}: \
         is the reference stale? (write_the_references)",
        (m - r).abs() / se
    );
    out
}

/// The mean of an image's channels.
fn image_mean(img: &LinearImage) -> f64 {
    mean(img.pixels.iter().flatten().map(|&c| c as f64))
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.collect();
    v.iter().sum::<f64>() / v.len() as f64
}

/// Prints the table per scene and checkpoint on `b` (a Markdown table, for BENCHMARKS.md):
/// each cell the mean of the runs' estimated ÷ true, and in brackets the same in expectation
/// (`summary`); returns the cells whose mean ratio is outside 0.8–1.25 and not `OPEN`, and
/// those whose raw estimate counts less than `EXPECTED_FLOOR` in expectation. The firefly
/// scenes run `firefly_runs` times and are held to both; without it, as many as the others,
/// held to neither.
fn check_all(b: Backend, runs: u32, firefly_runs: Option<u32>) -> Vec<String> {
    eprintln!(
        "\n{} runs on {} ({} of each firefly scene)",
        runs,
        b.describe(),
        firefly_runs.map_or("as many, held to neither bound nor floor,".into(), |n| n
            .to_string())
    );
    eprintln!("| scene | raw 16 | raw 64 | raw 256 | shown 16 | shown 64 | shown 256 |");
    eprintln!("|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for (name, _) in BUILTIN_SCENES {
        let firefly = FIREFLY.contains(name);
        let held = !firefly || firefly_runs.is_some();
        let r = ratios(
            &b,
            name,
            if firefly {
                firefly_runs.unwrap_or(runs)
            } else {
                runs
            },
        );
        let raw: Vec<(f64, f64)> = r.iter().map(|c| summary(c.iter().map(|x| x.raw))).collect();
        let shown: Vec<(f64, f64)> = r
            .iter()
            .map(|c| summary(c.iter().map(|x| x.shown)))
            .collect();
        let cells: Vec<String> = raw
            .iter()
            .chain(&shown)
            .map(|(v, e)| format!("{v:.2} ({e:.2})"))
            .collect();
        eprintln!("| {name} | {} |", cells.join(" | "));
        for (i, spp) in SPPS.iter().enumerate() {
            if held && raw[i].1 < EXPECTED_FLOOR {
                failures.push(format!(
                    "{name} at {spp} spp, raw: the estimate counts {:.3} of the true relative \
                     MSE's root in expectation",
                    raw[i].1
                ));
            }
            for (what, (v, _)) in [("raw", raw[i]), ("shown", shown[i])] {
                if !(0.8..=1.25).contains(&v) && held && !OPEN.contains(&(name, what, *spp)) {
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
    let failures = check_all(Backend::Cpu, 8, Some(FIREFLY_RUNS));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_estimate_tracks_the_true_error_on_every_shipped_scene_on_the_gpu_tracer() {
    let failures = check_all(Backend::Gpu(ctx()), 4, None);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Writes the references `tests/estimate/SCENE.exr`: each shipped scene at `SIZE`, max 8
/// bounces, `REFERENCE_SPP` samples per pixel on the test adapter, the reference seed. Run on
/// a fast GPU: `TERMTRACE_REFERENCE_DIR=DIR cargo test --release --test estimate --
/// --ignored write_the_references` (BENCHMARKS.md, "An honest error estimate", has the
/// machine and the time).
#[test]
#[ignore = "renders 2^20 samples per pixel of every shipped scene: minutes on a fast GPU"]
fn write_the_references() {
    let dir = std::env::var("TERMTRACE_REFERENCE_DIR").unwrap_or(REFERENCES.into());
    std::fs::create_dir_all(&dir).unwrap();
    // TERMTRACE_REFERENCE_SCENES: a comma-separated subset (all when unset).
    let only = std::env::var("TERMTRACE_REFERENCE_SCENES").ok();
    for (name, _) in BUILTIN_SCENES {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|n| n == *name))
        {
            continue;
        }
        let scene = Scene::load(name).unwrap();
        let mut fs = frame_settings(&scene);
        fs.seed = termtrace::converge::reference::REFERENCE_SEED;
        let t = std::time::Instant::now();
        let snap = snapshot_on(
            Backend::Gpu(ctx()),
            &scene,
            fs,
            REFERENCE_SPP,
            RenderOptions::default(),
        );
        assert_eq!(snap.invalid_samples(), 0, "{name}");
        let path = std::path::Path::new(&dir).join(format!("{name}.exr"));
        termtrace::output::write_exr(&path, &snap.image()).unwrap();
        eprintln!(
            "{name}: {REFERENCE_SPP} spp in {:.1} s, estimate {:.2e}",
            t.elapsed().as_secs_f64(),
            snap.noise_estimate().unwrap_or(f64::NAN)
        );
    }
}

/// What the estimate could be with a perfect proxy: the raw estimate with each pixel's
/// squared error divided by its true reference² (+ ε) instead of the proxy's, on the CPU
/// tracer, 16 runs, printed as `check_all`'s cells (BENCHMARKS.md, "An estimate that counts
/// fireflies"). Its expectation is right on every scene (the halves' (A − B)² is unbiased);
/// its mean ratio on the firefly scenes is what a run's figure can reach at best. Run with
/// `cargo test --release --test estimate -- --ignored the_reference_as_the_proxy --nocapture`.
#[test]
#[ignore = "a measurement for BENCHMARKS.md: it prints, and holds nothing"]
fn the_reference_as_the_proxy() {
    use termtrace::common::estimate::REL_MSE_EPSILON;
    eprintln!("\n| scene | raw 16 | raw 64 | raw 256 |");
    eprintln!("|---|---|---|---|");
    for (name, _) in BUILTIN_SCENES {
        let scene = Scene::load(name).unwrap();
        let reference = reference(name);
        // 1 / (reference² + ε): the weights of a perfect proxy.
        let exact: Vec<[f32; 3]> = reference
            .pixels
            .iter()
            .map(|t| t.map(|v| (1.0 / (v as f64 * v as f64 + REL_MSE_EPSILON)) as f32))
            .collect();
        let mut fs = frame_settings(&scene);
        let mut per = vec![Vec::new(); SPPS.len()];
        for run in 0..16 {
            fs.seed = 1 + run;
            let mut r = Renderer::new(Backend::Cpu, &scene, fs, RenderOptions::default());
            for (i, &spp) in SPPS.iter().enumerate() {
                r.render_spp(spp);
                let snap = r.snapshot();
                let estimate = snap.error_estimate_weighted(&exact).unwrap().rel_rmse;
                per[i].push((estimate, errors(&snap.image(), &reference).rel_rmse()));
            }
        }
        let cells: Vec<String> = per
            .iter()
            .map(|c| {
                let (v, e) = summary(c.iter().copied());
                format!("{v:.2} ({e:.2})")
            })
            .collect();
        eprintln!("| {name} | {} |", cells.join(" | "));
    }
}

/// The target error the stop aims at on each shipped scene: 5 %, or on the two caustic scenes
/// the least round figure each reaches within `STOP_MAX` samples on every seed, so that the
/// test measures where the stop lands rather than that it runs out of samples. At 5 % `glass`
/// reached it in none of 4 runs: its true error at 4096 spp is 10–16 % (the sun's caustics
/// through its frosted balls, which only scattered paths find), and its estimate said so, so
/// every run traced all 4096 samples (true ÷ target 1.9–3.3 there, the error of 4096 spp, not
/// a stop). `outdoor-caustics` reached 5 % in 3209–4096 spp, or in 3 of 8 runs not at all,
/// and landed at 1.01–1.34 (mean 1.26). Measured (seeds 1–8, true ÷ target at the stop): `glass`
/// at 20 % 0.83–1.23 (mean 0.99), 46–4096 spp; `outdoor-caustics` at 7 % 0.94–1.15 (mean 1.01),
/// 1682–3016 spp (BENCHMARKS.md, "The stop at a target on the caustic scenes").
fn stop_target(name: &str) -> f64 {
    match name {
        "glass" => 0.20,
        "outdoor-caustics" => 0.07,
        _ => 0.05,
    }
}

/// The most samples per pixel a run of the stop test traces.
const STOP_MAX: u32 = 4096;

/// The stop at a target error (`render --target-error`, the preview's `--target-error`: both
/// claim their samples through `render::stages`), against the committed references: on every
/// shipped scene the true relative RMSE where it stops, over the target (`stop_target`),
/// averaged over 4 seeds, must be within 0.75–1.25 (issue 45); and a run that traces every
/// sample allowed without its estimate reaching the target must indeed be short of it (true
/// error at least 0.75 of the target): it did not trace on for nothing.
#[test]
fn the_stop_at_a_target_error_lands_near_it_on_every_shipped_scene() {
    use termtrace::render::stages::{Next, first_end, next};
    let mut failures = Vec::new();
    eprintln!("\n| scene | target | true ÷ target at the stop, seeds 1–4 | spp |");
    eprintln!("|---|---|---|---|");
    for (name, _) in BUILTIN_SCENES {
        let scene = Scene::load(name).unwrap();
        let reference = reference(name);
        let target = stop_target(name);
        let mut fs = frame_settings(&scene);
        let (mut ratios, mut spps) = (Vec::new(), Vec::new());
        for seed in 1..=4 {
            fs.seed = seed;
            let mut r = Renderer::new(Backend::Cpu, &scene, fs, RenderOptions::default());
            let mut end = first_end(Some(target), STOP_MAX);
            let reached = loop {
                r.render_spp(end);
                match next(end, r.snapshot().noise_estimate(), target, STOP_MAX) {
                    Next::Reached => break true,
                    Next::Exhausted => break false,
                    Next::To(e) => end = e,
                }
            };
            let snap = r.snapshot();
            let ratio = errors(&snap.image(), &reference).rel_rmse() / target;
            if !reached && ratio < 0.75 {
                failures.push(format!(
                    "{name}, seed {seed}: traced all {STOP_MAX} spp, its true error {ratio:.3} \
                     of the target"
                ));
            }
            ratios.push(ratio);
            // `*`: every sample allowed traced, the estimate still above the target.
            spps.push(format!("{end}{}", if reached { "" } else { "*" }));
        }
        let m = mean(ratios.iter().copied());
        let cells: Vec<String> = ratios.iter().map(|x| format!("{x:.2}")).collect();
        eprintln!(
            "| {name} | {:.0} % | {} (mean {m:.2}) | {} |",
            100.0 * target,
            cells.join(" "),
            spps.join(" ")
        );
        if !(0.75..=1.25).contains(&m) {
            failures.push(format!(
                "{name}: true ÷ target {m:.3} at {} spp",
                spps.join(" ")
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The status line's doubt (`common::resolved::Doubt`: "fireflies" or "few samples" beside a
/// rounded figure) against how far its figure is from the truth, on every shipped scene at 64
/// and 256 spp, 8 runs on the CPU tracer (issue 45: the status line says when its estimate is
/// unreliable). Where a run's raw figure is off by more than 2× either way, at least 90 % of
/// such runs must be doubted (measured: 16 of 17, all on the firefly scenes); where the
/// denoised image's figure (the shown image's, which the same doubt marks rough) is, at least
/// 80 % (measured: 18 of 22, all on the firefly scenes); and on the light-tailed scenes at
/// 256 spp, at most one run in 8 of each (no crying wolf).
#[test]
fn the_status_line_doubts_where_its_figure_is_off() {
    use termtrace::common::Resolved;
    eprintln!("\n| scene | 64 spp: doubted runs, estimate ÷ true (`?` doubted) | 256 spp |");
    eprintln!("|---|---|---|");
    let (mut off, mut off_doubted) = (0, 0);
    let (mut shown_off, mut shown_off_doubted) = (0, 0);
    let mut wolf = Vec::new();
    for (name, _) in BUILTIN_SCENES {
        let scene = Scene::load(name).unwrap();
        let reference = reference(name);
        let mut fs = frame_settings(&scene);
        // Per checkpoint, each run's (doubted, estimate ÷ true).
        let mut per = vec![Vec::new(); 2];
        for seed in 1..=8 {
            fs.seed = seed;
            let mut r = Renderer::new(Backend::Cpu, &scene, fs, RenderOptions::default());
            for (i, spp) in [64u32, 256].into_iter().enumerate() {
                r.render_spp(spp);
                // The status line's frame, as the CPU tracer's preview makes it.
                let sums = r.exact_sums();
                let frame = Resolved::from_sums(&sums.even, &sums.odd, SIZE, 1, 0);
                let truth = errors(&frame.image, &reference).rel_rmse();
                let ratio = frame.noise.unwrap_or(f64::NAN) / truth;
                per[i].push((frame.doubt.is_some(), ratio));
                // The denoised image shown, whose figure follows the raw one's on the line.
                let snap = r.snapshot();
                let (estimate, truth) = shown_errors(&mut r, &snap, &reference);
                let x = estimate / truth;
                if !(0.5..=2.0).contains(&x) {
                    shown_off += 1;
                    shown_off_doubted += frame.doubt.is_some() as usize;
                }
            }
        }
        let mut cells = Vec::new();
        for runs in &per {
            let doubted = runs.iter().filter(|(d, _)| *d).count();
            let ratios: Vec<String> = runs
                .iter()
                .map(|(d, x)| format!("{x:.2}{}", if *d { "?" } else { "" }))
                .collect();
            cells.push(format!("{doubted}/8: {}", ratios.join(" ")));
            for &(d, x) in runs {
                if !(0.5..=2.0).contains(&x) {
                    off += 1;
                    off_doubted += d as usize;
                }
            }
        }
        let light_tailed = !FIREFLY.contains(name);
        let doubted_256 = per[1].iter().filter(|(d, _)| *d).count();
        if light_tailed && doubted_256 > 1 {
            wolf.push(format!(
                "{name}: {doubted_256} of 8 runs doubted at 256 spp"
            ));
        }
        eprintln!("| {name} | {} |", cells.join(" | "));
    }
    eprintln!("{off_doubted} of {off} runs off by more than 2× were doubted");
    eprintln!("{shown_off_doubted} of {shown_off} runs whose shown figure was off were doubted");
    assert!(
        shown_off > 0,
        "no shown figure was off by 2×: the test tests nothing"
    );
    assert!(
        shown_off_doubted as f64 >= 0.8 * shown_off as f64,
        "only {shown_off_doubted} of {shown_off} runs whose shown figure was off by more than 2× \
         were doubted"
    );
    assert!(off > 0, "no run was off by 2×: the test tests nothing");
    assert!(
        off_doubted as f64 >= 0.9 * off as f64,
        "only {off_doubted} of {off} runs off by more than 2× were doubted"
    );
    assert!(wolf.is_empty(), "{}", wolf.join("\n"));
}
