//! The denoiser's cost per frame (`denoise::denoise`: both halves filtered, the estimate and
//! the tile choice) on real frames: a scene traced at the preview's size for 120×40 cells in
//! half blocks (120×76 pixels) and at the widest graphics image (960×608), on the default
//! backend, then denoised on the host's threads (`--threads`-like: RAYON_NUM_THREADS).
//!
//! `cargo bench --bench denoise [-- SCENE]` (default: showcase).

use std::time::Instant;
use termtrace::common::FrameSettings;
use termtrace::denoise::denoise;
use termtrace::output::LinearImage;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

/// True relative RMSE (pbrt's relMSE, reference² + 0.01) of `img` against `reference`.
fn true_error(img: &[[f32; 3]], reference: &LinearImage) -> f64 {
    let mut s = 0.0;
    for (p, r) in img.iter().zip(&reference.pixels) {
        for c in 0..3 {
            s += (p[c] as f64 - r[c] as f64).powi(2) / ((r[c] as f64).powi(2) + 0.01);
        }
    }
    (s / (3 * img.len()) as f64).sqrt()
}

/// At 120×76: the raw and denoised images' true errors against a reference of 4096 spp (on
/// the CPU tracer), and their estimates, at 4 to 256 spp.
fn quality(scene: &Scene, backend: &Backend) {
    let settings = FrameSettings::new(120, 76, scene.render.max_bounces, 1);
    let reference_settings = FrameSettings::new(120, 76, scene.render.max_bounces, 7);
    let mut r = Renderer::new(
        Backend::Cpu,
        scene,
        reference_settings,
        RenderOptions::default(),
    );
    r.render_spp(4096);
    let reference = r.snapshot().image();
    println!(
        "120×76 against 4096 spp: spp, raw true / estimated, denoised true / estimated (relative RMSE)"
    );
    let mut r = Renderer::new(backend.clone(), scene, settings, RenderOptions::default());
    for spp in [4, 16, 64, 256] {
        r.render_spp(spp);
        let snap = r.snapshot();
        let guides = r.guides().clone();
        let d = denoise(&snap.data.even, &snap.data.odd, &guides);
        println!(
            "  {spp:>4} spp   raw {:>6.2} % / {:>6.2} %   denoised {:>6.2} % / {:>6.2} %   shown {:>6.2} % / {:>6.2} % ({} of {} tiles)",
            100.0 * true_error(&d.raw, &reference),
            100.0 * d.rel_rmse(d.raw_sums()),
            100.0 * true_error(&d.denoised, &reference),
            100.0 * d.rel_rmse(d.denoised_sums()),
            100.0 * true_error(&d.shown(), &reference),
            100.0 * d.rel_rmse(d.shown_sums()),
            d.tiles.iter().filter(|&&t| t).count(),
            d.tiles.len()
        );
    }
}

fn main() {
    let name = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .unwrap_or_else(|| "showcase".into());
    let scene = Scene::load(&name).unwrap_or_else(|e| panic!("{e}"));
    let backend = Backend::open(std::env::var("TERMTRACE_ADAPTER").ok().as_deref())
        .unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{name} on {}, {} threads",
        backend.describe(),
        rayon::current_num_threads()
    );
    quality(&scene, &backend);
    for (w, h) in [(120, 76), (960, 608)] {
        let settings = FrameSettings::new(w, h, scene.render.max_bounces, 1);
        let mut r = Renderer::new(backend.clone(), &scene, settings, RenderOptions::default());
        r.render_spp(4);
        let t = Instant::now();
        let guides = r.guides().clone();
        let guide_ms = t.elapsed().as_secs_f64() * 1e3;
        let snap = r.snapshot();
        let mut best = f64::INFINITY;
        let mut out = None;
        for _ in 0..5 {
            let t = Instant::now();
            out = Some(denoise(&snap.data.even, &snap.data.odd, &guides));
            best = best.min(t.elapsed().as_secs_f64());
        }
        let d = out.expect("denoised");
        // The WGSL pass on a GPU: the filter, the estimate and the small image's readback
        // (the first run compiles its pipelines and is left out).
        // Also with the output averaged 8×8 (a 64th of the readback), which leaves mostly the
        // filter's own time.
        let gpu_ms = backend.gpu().map(|ctx| {
            let mut pass = termtrace::gpu::denoise::DenoisePass::new(ctx);
            let (accum, guides) = (r.accumulation().unwrap(), r.guide_buffer().unwrap());
            let mut best = [f64::INFINITY; 2];
            // Half a second of runs first: a GPU idle for a moment has lowered its clock
            // (an H200 idles at 555 of its 1980 MHz), and the preview's denoiser runs
            // between the tracer's submissions, on a busy GPU.
            let warm = Instant::now();
            while warm.elapsed().as_secs_f64() < 0.5 {
                pass.run(ctx, accum, guides, (w, h), 8);
            }
            for (k, factor) in [1, 8].into_iter().enumerate() {
                pass.run(ctx, accum, guides, (w, h), factor);
                for _ in 0..10 {
                    let t = Instant::now();
                    pass.run(ctx, accum, guides, (w, h), factor);
                    best[k] = best[k].min(t.elapsed().as_secs_f64());
                }
            }
            // The dispatches alone on the GPU (timestamps, where the adapter has them): what
            // the filter costs without the submission, the wait and the readback.
            pass.enable_profile(ctx);
            let mut fastest: Option<Vec<f64>> = None;
            for _ in 0..10 {
                pass.run(ctx, accum, guides, (w, h), 8);
                let ms = pass.profile(ctx);
                let total =
                    |m: &Option<Vec<f64>>| m.as_ref().map_or(f64::INFINITY, |m| m.iter().sum());
                if total(&ms) < total(&fastest) {
                    fastest = ms;
                }
            }
            if let Some(ms) = fastest {
                let names = [
                    "prepare", "settle", "atrous", "atrous", "atrous", "atrous", "atrous",
                    "regress", "finish", "compose",
                ];
                let parts: Vec<String> = names
                    .iter()
                    .zip(&ms)
                    .map(|(n, t)| format!("{n} {t:.3}"))
                    .collect();
                println!(
                    "{w:>4}×{h:<4} GPU dispatches {:.3} ms in all (the fastest of 10 runs): {} ms",
                    ms.iter().sum::<f64>(),
                    parts.join(", ")
                );
            }
            // The GPU's frame against the host's: the same filters, so about one estimate.
            let g = pass.run(ctx, accum, guides, (w, h), 1);
            let frame = termtrace::denoise::from_tiles(g, (w, h), 1);
            println!(
                "{w:>4}×{h:<4} estimated error of the shown image at 4 spp: GPU {:?}, host {:.2}%",
                frame.denoised.map(|e| e.text()),
                100.0 * d.rel_rmse(d.shown_sums())
            );
            (best[0] * 1e3, best[1] * 1e3)
        });
        println!(
            "{w:>4}×{h:<4} denoise on the host {:>7.2} ms (best of 5){}   guides ({} samples) {guide_ms:>7.2} ms   \
             estimated error at 4 spp: raw {:.2} %, denoised {:.2} %",
            best * 1e3,
            gpu_ms.map_or(String::new(), |(g, g8)| format!(
                ", on the GPU {g:.3} ms (best of 10, with the readback; \
                 {g8:.3} ms with the output averaged 8×8)"
            )),
            termtrace::common::guides::GUIDE_SAMPLES,
            100.0 * d.rel_rmse(d.raw_sums()),
            100.0 * d.rel_rmse(d.shown_sums())
        );
    }
}
