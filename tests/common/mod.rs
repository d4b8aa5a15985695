//! Shared by the tracer tests: one device per test binary (the software adapter in CI, or the
//! one TERMTRACE_ADAPTER names), the native CPU tracer beside it (`on_both`), and small
//! helpers to render scenes written inline.
#![allow(dead_code)]

use glam::DVec3;
use std::cell::RefCell;
use std::sync::{Arc, OnceLock};
use termtrace::common::{FrameSettings, arrays, layout::SceneUniforms};
use termtrace::gpu::GpuContext;
use termtrace::output::LinearImage;
use termtrace::render::{Backend, RenderOptions, Renderer, Snapshot};
use termtrace::scene::Scene;

pub mod textured;

pub fn ctx() -> Arc<GpuContext> {
    static CTX: OnceLock<Arc<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| {
        let sel = std::env::var("TERMTRACE_ADAPTER").ok();
        let c = GpuContext::new(sel.as_deref()).expect("a GPU adapter for the tests");
        eprintln!("tests run on {}", c.adapter_name());
        Arc::new(c)
    })
    .clone()
}

thread_local! {
    /// The backend `snapshot_with` renders on (the GPU device when unset).
    static BACKEND: RefCell<Option<Backend>> = const { RefCell::new(None) };
}

/// The backend the helpers render on now.
pub fn backend() -> Backend {
    BACKEND
        .with(|b| b.borrow().clone())
        .unwrap_or_else(|| Backend::Gpu(ctx()))
}

/// Runs `check` with the helpers rendering on the GPU device, then on the native CPU
/// tracer: the same known answers hold on both.
pub fn on_both(check: impl Fn()) {
    for b in [Backend::Gpu(ctx()), Backend::Cpu] {
        eprintln!("checking on {}", b.describe());
        BACKEND.with(|c| *c.borrow_mut() = Some(b));
        check();
    }
    BACKEND.with(|c| *c.borrow_mut() = None);
}

pub fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

pub fn settings(w: u32, h: u32, max_bounces: u32) -> FrameSettings {
    FrameSettings::new(w, h, max_bounces, 1)
}

/// Renders `spp` samples per pixel on `b` and returns the accumulation.
pub fn snapshot_on(
    b: Backend,
    scene: &Scene,
    s: FrameSettings,
    spp: u32,
    options: RenderOptions,
) -> Snapshot {
    let mut r = Renderer::new(b, scene, s, options);
    r.render_spp(spp);
    let snap = r.snapshot();
    if snap.min_samples() != spp as u64 || snap.max_samples() != spp as u64 {
        // Say enough to tell a discarded sample (NaN) from a cut invocation (llvmpipe's loop
        // limit, `render::schedule`): which pixels miss how many samples, and the pipeline of
        // the last submission.
        let off: Vec<(u32, u32, u64)> = (snap.sample_counts().enumerate())
            .filter(|(_, n)| *n != spp as u64)
            .map(|(i, n)| (i as u32 % s.width, i as u32 / s.width, n))
            .collect();
        panic!(
            "{} to {} of {spp} samples per pixel; {} pixels off (x, y, samples; the first 8: \
             {:?}), {} invalid samples, last pipeline {:?}",
            snap.min_samples(),
            snap.max_samples(),
            off.len(),
            &off[..off.len().min(8)],
            snap.invalid_samples(),
            r.last_pipeline().map(|f| f.summary())
        );
    }
    snap
}

/// Renders `spp` samples per pixel on the current backend and returns the accumulation.
pub fn snapshot_with(
    scene: &Scene,
    s: FrameSettings,
    spp: u32,
    options: RenderOptions,
) -> Snapshot {
    snapshot_on(backend(), scene, s, spp, options)
}

/// `snapshot` on the native CPU tracer: for long references and tests of the estimators
/// rather than of a backend (many times faster than the software adapter).
pub fn cpu_snapshot(scene: &Scene, s: FrameSettings, spp: u32) -> Snapshot {
    snapshot_on(Backend::Cpu, scene, s, spp, RenderOptions::default())
}

pub fn snapshot(scene: &Scene, s: FrameSettings, spp: u32) -> Snapshot {
    snapshot_with(scene, s, spp, RenderOptions::default())
}

pub fn render(toml: &str, w: u32, h: u32, spp: u32, max_bounces: u32) -> LinearImage {
    let snap = snapshot(&scene(toml), settings(w, h, max_bounces), spp);
    assert_eq!(snap.invalid_samples(), 0, "invalid samples");
    snap.image()
}

/// The camera frame the tracer uses, for host-side geometry.
pub fn camera_frame(scene: &Scene, w: u32, h: u32) -> SceneUniforms {
    let mut u = SceneUniforms::default();
    arrays::camera_uniforms(&scene.camera, w as f64 / h as f64, DVec3::ZERO, &mut u);
    u
}

/// Direction of the pinhole ray through image point (x, y) in pixel units (f64).
pub fn pinhole_dir(u: &SceneUniforms, w: u32, h: u32, x: f64, y: f64) -> DVec3 {
    let v = |a: [f32; 3]| DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    (v(u.cam_to_corner) + (x / w as f64) * v(u.cam_horizontal) - (y / h as f64) * v(u.cam_vertical))
        .normalize()
}

/// Whether a pixel's whole footprint sees the sphere (`Some(true)`), misses it entirely
/// (`Some(false)`), or straddles its silhouette (`None`). Angles on the unit sphere obey the
/// triangle inequality, so the pixel centre's angle to the sphere's centre ± the largest angle
/// from the centre ray to a corner ray bounds every ray of the pixel.
pub fn sphere_coverage(
    u: &SceneUniforms,
    w: u32,
    h: u32,
    px: (u32, u32),
    center: DVec3,
    radius: f64,
) -> Option<bool> {
    let origin = DVec3::new(
        u.cam_origin[0] as f64,
        u.cam_origin[1] as f64,
        u.cam_origin[2] as f64,
    );
    let to_c = center - origin;
    let beta = (radius / to_c.length()).asin();
    let (x, y) = (px.0 as f64, px.1 as f64);
    let c = pinhole_dir(u, w, h, x + 0.5, y + 0.5);
    let alpha = c.angle_between(to_c);
    let gamma = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .map(|(dx, dy)| c.angle_between(pinhole_dir(u, w, h, x + dx, y + dy)))
        .fold(0.0, f64::max);
    let margin = 1e-4;
    if alpha + gamma < beta - margin {
        Some(true)
    } else if alpha - gamma > beta + margin {
        Some(false)
    } else {
        None
    }
}

/// The jittered camera ray of every pixel's first sample (seed 1, sample 0), replayed on the
/// host with the tracer's random stream: `(x, y, direction)` in row order.
pub fn first_sample_dirs(u: &SceneUniforms, w: u32, h: u32) -> Vec<(u32, u32, DVec3)> {
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut rng = HostRng::new(y * w + x, 0, 1);
            let (jx, jy) = rng.rand2();
            out.push((
                x,
                y,
                pinhole_dir(u, w, h, x as f64 + jx as f64, y as f64 + jy as f64),
            ));
        }
    }
    out
}

/// The share of pixels whose colours agree to a relative `tol`.
pub fn agreeing_within(a: &LinearImage, b: &LinearImage, tol: f64) -> f64 {
    let same = (a.pixels.iter().zip(&b.pixels))
        .filter(|(p, q)| rel_err(**p, **q) < tol)
        .count();
    same as f64 / a.pixels.len() as f64
}

/// Largest relative difference between two colours.
pub fn rel_err(a: [f32; 3], b: [f32; 3]) -> f64 {
    (0..3)
        .map(|c| (a[c] as f64 - b[c] as f64).abs() / (b[c] as f64).abs().max(1e-30))
        .fold(0.0, f64::max)
}

/// The tracer's random stream on the host: the CPU tracer's, bit for bit the WGSL one
/// (shaders/common/rng.wgsl).
pub use termtrace::cpu::rng::Rng as HostRng;

/// (pixels that differ, largest channel difference, first differing pixel) of two images.
pub fn image_diff(a: &LinearImage, b: &LinearImage) -> (usize, f32, Option<(u32, u32)>) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut n = 0;
    let mut worst = 0.0f32;
    let mut first = None;
    for (i, (p, q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        let d = (0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0f32, f32::max);
        if p != q {
            n += 1;
            first.get_or_insert((i as u32 % a.width, i as u32 / a.width));
        }
        worst = worst.max(d);
    }
    (n, worst, first)
}

/// The CPU tracer against the GPU's on each named scene: 32×24, the scene's bounces (at most
/// 12), 48 spp, independent samples (seed 1 on the GPU, 2 on the CPU) so that the test's
/// variance is right. No 8×8 tile may differ, Bonferroni-corrected over all tiles of all the
/// scenes at α = 0.01, and neither tracer may have an invalid sample.
pub fn cpu_converges_to_gpu(scenes: &[(&str, &Scene)]) {
    let mut tally = BiasTally::default();
    for &(name, scene) in scenes {
        let render = |b: Backend, seed| {
            let s = FrameSettings {
                seed,
                ..settings(32, 24, scene.render.max_bounces.min(12))
            };
            snapshot_on(b, scene, s, 48, RenderOptions::default())
        };
        let gpu = render(Backend::Gpu(ctx()), 1);
        let cpu = render(Backend::Cpu, 2);
        assert_eq!(
            cpu.invalid_samples(),
            0,
            "{name}: invalid samples on the CPU"
        );
        assert_eq!(
            gpu.invalid_samples(),
            0,
            "{name}: invalid samples on the GPU"
        );
        tally.check(name, &cpu, &gpu, 0.01 / scenes.len() as f64);
    }
    tally.assert_none_differ(12 * scenes.len());
}

/// The bias check of `converge` over several scenes (8×8 tiles, Welch t-tests): the tiles
/// tested and those that differ, each named by its scene.
#[derive(Default)]
pub struct BiasTally {
    tiles: usize,
    failures: Vec<String>,
}

impl BiasTally {
    /// Tests `img` against `reference` at significance `alpha` per tile (Bonferroni over the
    /// scene's tiles inside; the caller divides by the number of scenes).
    pub fn check(&mut self, name: &str, img: &Snapshot, reference: &Snapshot, alpha: f64) {
        let r = termtrace::converge::metrics::bias_check(img, reference, false, 8, alpha);
        self.tiles += r.tiles;
        eprintln!("{name}: {} tiles, smallest p {:.3e}", r.tiles, r.min_p);
        if !r.significant.is_empty() {
            self.failures.push(format!("{name}: {:?}", r.significant));
        }
    }

    /// Fails unless at least `min_tiles` tiles were tested and none differed.
    pub fn assert_none_differ(self, min_tiles: usize) {
        let tiles = self.tiles;
        assert!(tiles >= min_tiles, "only {tiles} tiles tested");
        assert!(
            self.failures.is_empty(),
            "tiles differ: {:#?}",
            self.failures
        );
    }
}

/// `path`'s GLB with its JSON chunk changed by `edit`.
pub fn glb_edited(path: &str, edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let glb = std::fs::read(path).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    edit(&mut doc);
    let mut text = serde_json::to_vec(&doc).unwrap();
    text.resize(text.len().next_multiple_of(4), b' ');
    let rest = &glb[20 + json_len..];
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((20 + text.len() + rest.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(rest);
    out
}
