//! Scene files (TOML) through the parser and the native CPU tracer: every input must be
//! refused with a message or parsed into a scene that the tracer prepares (its tree, lights,
//! maps) and traces, never panic. The origin is a built-in one, so that a scene reads built-in
//! maps and meshes alone and never the file system. The trace is 8 × 6 pixels, 2 samples and
//! at most 12 bounces, whatever the scene asks, so that one input costs milliseconds.
//! Seeds: `fuzz/corpus/scene/` (the shipped and extreme scenes); dictionary:
//! `fuzz/scene.dict`. Run: `cargo fuzz run scene -- -dict=scene.dict` (README, "Fuzzing").
#![no_main]

use libfuzzer_sys::fuzz_target;
use termtrace::common::FrameSettings;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(scene) = Scene::from_toml(text, "builtin:fuzz.toml") else {
        return;
    };
    let settings = FrameSettings::new(8, 6, scene.render.max_bounces.min(12), 1);
    let mut r = Renderer::new(Backend::Cpu, &scene, settings, RenderOptions::default());
    r.render_spp(2);
    let snap = r.snapshot();
    let _ = snap.image();
    let _ = snap.noise_estimate();
});
