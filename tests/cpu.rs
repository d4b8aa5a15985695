//! The native CPU tracer against the GPU's: every shipped scene converges to the same image
//! (the bias check of `converge`, tile by tile), its sums are as exact as the GPU's whatever
//! the rounds, and `--adapter cpu-native` picks it. (The known-answer and the
//! BVH/specialization tests run on both backends too: `on_both` in tests/common.)

mod common;
use common::*;
use termtrace::output::LinearImage;
use termtrace::render::{Backend, RenderOptions, Renderer, Snapshot};
use termtrace::scene::{BUILTIN_SCENES, Scene};

fn render_on(backend: Backend, scene: &Scene, seed: u32, spp: u32) -> Snapshot {
    let s = termtrace::common::FrameSettings {
        seed,
        ..settings(32, 24, scene.render.max_bounces.min(12))
    };
    snapshot_on(backend, scene, s, spp, RenderOptions::default())
}

/// Each of `names` (a built-in scene or a file) through `common::cpu_converges_to_gpu`.
fn converge_alike(names: &[String]) {
    let scenes: Vec<Scene> = names.iter().map(|n| Scene::load(n).unwrap()).collect();
    let named: Vec<(&str, &Scene)> = names.iter().map(|n| n.as_str()).zip(&scenes).collect();
    cpu_converges_to_gpu(&named);
}

#[test]
fn every_shipped_scene_converges_to_the_gpu_image_on_the_cpu() {
    // tests/nee.rs shows the same check finding a light 5 % too bright.
    let names: Vec<String> = BUILTIN_SCENES.iter().map(|(n, _)| n.to_string()).collect();
    converge_alike(&names);
}

#[test]
fn every_committed_model_converges_to_the_gpu_image_on_the_cpu() {
    // The same check on every committed glTF and OBJ asset (glTF's BRDF, textures, normal
    // maps, smooth shading, cut-outs, MTL materials) and the README's outdoor dog under the
    // sunny map.
    let mut files = vec!["docs/outdoor-dog.toml".to_string()];
    for dir in ["tests/gltf", "tests/assets/obj"] {
        for e in std::fs::read_dir(dir).unwrap() {
            let d = e.unwrap().path();
            if d.ends_with("fuzz") || !d.is_dir() {
                continue;
            }
            for f in std::fs::read_dir(&d).unwrap() {
                let f = f.unwrap().path();
                if termtrace::scene::is_model(&f) {
                    files.push(f.display().to_string());
                }
            }
        }
    }
    files.sort();
    assert!(files.len() >= 7, "{files:?}");
    converge_alike(&files);
}

/// The share of pixels whose colours agree to a relative 10⁻³.
fn agreeing(a: &LinearImage, b: &LinearImage) -> f64 {
    agreeing_within(a, b, 1e-3)
}

#[test]
fn both_tracers_draw_the_same_numbers() {
    // The same seed on both backends: showcase takes every kind of draw (jitter, lens, lobe,
    // light choice and point, direction, fuzz, glass, roulette) and more than the stratified
    // ten, so if rng.wgsl and cpu::rng differed in any draw, pixels would differ by the
    // noise nearly everywhere (another seed agrees on 17 %: sky). They trace the same paths
    // (all 768 pixels agree today), up to the rare path that float rounding (GPU sin/cos
    // against the CPU's polynomial) sends the other way at an edge or a roulette threshold.
    let scene = Scene::load("showcase").unwrap();
    let gpu = render_on(Backend::Gpu(ctx()), &scene, 5, 4).image();
    let cpu = render_on(Backend::Cpu, &scene, 5, 4).image();
    let share = agreeing(&gpu, &cpu);
    eprintln!("pixels equal to 1e-3: {:.1} %", 100.0 * share);
    assert!(share > 0.95, "only {:.1} % of pixels agree", 100.0 * share);
    // And a different seed does not agree: the comparison can fail.
    let other = render_on(Backend::Cpu, &scene, 6, 4).image();
    let chance = agreeing(&cpu, &other);
    eprintln!("with another seed: {:.1} %", 100.0 * chance);
    assert!(
        chance < 0.5,
        "{:.1} % of pixels agree by chance",
        100.0 * chance
    );
}

#[test]
fn the_cpu_sums_are_exact_whatever_the_rounds() {
    // Fixed-point sums: 7 samples in one go, or in rounds and submissions of any size (the
    // first look included), give the same words bit for bit.
    let scene = Scene::load("showcase").unwrap();
    let s = settings(24, 16, 6);
    let whole = {
        let mut r = Renderer::new(Backend::Cpu, &scene, s, RenderOptions::default());
        r.render_spp(7);
        r.snapshot()
    };
    let pieces = {
        let options = RenderOptions {
            first_look: true,
            submission: std::time::Duration::from_micros(1),
            ..Default::default()
        };
        let mut r = Renderer::new(Backend::Cpu, &scene, s, options);
        while r.submit(7).is_some() {
            r.wait(0);
        }
        r.snapshot()
    };
    assert_eq!(whole.samples, 7);
    assert_eq!(pieces.samples, 7);
    assert_eq!(whole.data.even, pieces.data.even);
    assert_eq!(whole.data.odd, pieces.data.odd);
    assert!(whole.data.segments > 0 && whole.data.segments == pieces.data.segments);
}

#[test]
fn cpu_native_is_an_adapter_name() {
    let b = Backend::open(Some("cpu-native")).unwrap();
    assert!(matches!(b, Backend::Cpu));
    assert!(b.describe().contains("CPU"));
    // Anything else still names a wgpu adapter.
    assert!(Backend::open(Some("no-such-adapter-anywhere")).is_err());
}
