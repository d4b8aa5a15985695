//! The preview's resolve pass per frame (`gpu::resolve::ResolvePass`: the cells' image, the
//! noise estimate's terms and their squares, read back) and its host twin
//! (`Resolved::from_sums`, the CPU tracer's frames): a scene traced at the preview's size for
//! 240×70 cells in half blocks (240×136 pixels), once as traced and once supersampled 2×2.
//!
//! `cargo bench --bench resolve [-- SCENE]` (default: weekend), on the default backend
//! (TERMTRACE_ADAPTER picks one); the resolve pass where it is a GPU.

use std::time::Instant;
use termtrace::common::{FrameSettings, Resolved};
use termtrace::gpu::resolve::ResolvePass;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

fn main() {
    let name = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .unwrap_or_else(|| "weekend".into());
    let scene = Scene::load(&name).unwrap_or_else(|e| panic!("{e}"));
    let backend = Backend::open(std::env::var("TERMTRACE_ADAPTER").ok().as_deref())
        .unwrap_or_else(|e| panic!("{e}"));
    println!("{name} on {}", backend.describe());
    for factor in [1u32, 2] {
        let (w, h) = (240 * factor, 136 * factor);
        let settings = FrameSettings::new(w, h, scene.render.max_bounces, 1);
        let mut r = Renderer::new(backend.clone(), &scene, settings, RenderOptions::default());
        r.render_spp(16);
        // The host's frame of the exact sums (what the CPU tracer's preview makes).
        let sums = r.exact_sums();
        let mut host_best = f64::INFINITY;
        for _ in 0..10 {
            let t = Instant::now();
            let f = Resolved::from_sums(&sums.even, &sums.odd, (w, h), factor, 0);
            host_best = host_best.min(t.elapsed().as_secs_f64());
            assert!(f.noise.is_some());
        }
        let gpu = backend.gpu().map(|ctx| {
            let accum = r.accumulation().expect("a GPU accumulation");
            let mut pass = ResolvePass::new(ctx);
            let frame = |pass: &mut ResolvePass| {
                let slot = pass
                    .request(ctx, accum, (w, h), factor)
                    .expect("a free slot");
                loop {
                    ctx.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("poll");
                    if pass.ready(slot) {
                        break pass.take(slot).expect("the readback maps");
                    }
                }
            };
            // Half a second first: an idle GPU has lowered its clock.
            let warm = Instant::now();
            while warm.elapsed().as_secs_f64() < 0.5 {
                frame(&mut pass);
            }
            let mut best = f64::INFINITY;
            for _ in 0..50 {
                let t = Instant::now();
                frame(&mut pass);
                best = best.min(t.elapsed().as_secs_f64());
            }
            best
        });
        println!(
            "{w}×{h} traced, factor {factor}: host frame {:.2} ms (best of 10){}",
            host_best * 1e3,
            gpu.map_or(String::new(), |g| format!(
                ", GPU resolve pass with its readback {:.3} ms (best of 50)",
                g * 1e3
            ))
        );
    }
}
