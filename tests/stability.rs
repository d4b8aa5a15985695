//! Numerical stability (docs/STABILITY.md): the extreme scenes never produce an invalid
//! sample, the white furnace is exact on every open one, the albedo furnace holds on huge
//! spheres, a million frames accumulate exactly, translation changes nothing, and the GPU's
//! single-ray operations agree with a double-precision reference.

mod common;
use common::*;
use glam::DVec3;
use termtrace::common::FrameSettings;
use termtrace::scene::{EXTREME_SCENES, Scene, Shape};
use termtrace::stability::{self, FURNACE_BOUNCES, FURNACE_SKY, FURNACE_TOLERANCE};

fn extreme(name: &str, text: &str) -> Scene {
    Scene::from_toml(text, &format!("builtin:{name}")).unwrap()
}

#[test]
fn every_extreme_scene_renders_without_an_invalid_sample() {
    for (name, text) in EXTREME_SCENES {
        let s = extreme(name, text);
        let (invalid, img) = stability::render_counting(
            &ctx(),
            &s,
            FrameSettings::new(32, 18, s.render.max_bounces, 1),
            8,
        );
        assert_eq!(invalid, 0, "{name}: {invalid} invalid samples");
        assert!(
            img.pixels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0),
            "{name}"
        );
    }
}

#[test]
fn the_white_furnace_is_exact_on_every_open_extreme_scene() {
    let mut checked = 0;
    for (name, text) in EXTREME_SCENES {
        if !stability::furnace_applies(name) {
            continue;
        }
        let s = stability::white_furnace(&extreme(name, text), FURNACE_SKY);
        let (_, img) = stability::render_counting(
            &ctx(),
            &s,
            FrameSettings::new(32, 18, FURNACE_BOUNCES, 1),
            8,
        );
        let e = stability::furnace_error(&img, FURNACE_SKY);
        assert!(e <= FURNACE_TOLERANCE, "{name}: white furnace off by {e:e}");
        checked += 1;
    }
    assert!(checked >= 14, "only {checked} scenes checked");
}

#[test]
fn a_lambertian_ground_of_any_radius_is_exactly_half_the_sky() {
    // The camera 1 unit above a ground sphere looks down at 45° with a 30° field of view:
    // every ray hits it, every bounce escapes, so every pixel is 0.5 × L, at radius 1e3, 1e5
    // and 1e6 alike (a self-hit would darken a pixel by another 0.5).
    for r in [1e3, 1e5, 1e6] {
        let toml = format!(
            "[camera]\nlook_from = [0, 1, 0]\nlook_at = [0, 0, -1]\nvfov = 30\n\
             [sky]\nuniform = [0.8, 0.8, 0.8]\n\
             [[sphere]]\ncenter = [0, {}, 0]\nradius = {r}\ncolor = [0.5, 0.5, 0.5]\n",
            -r
        );
        let img = render(&toml, 32, 32, 8, 8);
        let e = stability::furnace_error(&img, 0.5 * 0.8);
        assert!(e <= FURNACE_TOLERANCE, "radius {r}: off by {e:e}");
    }
}

#[test]
fn a_million_frames_accumulate_exactly() {
    // What a plain f32 running sum does with the same samples: drift far past 1e-5.
    let v = 0.3f32 * 0.7f32;
    let mut naive = 0.0f32;
    for _ in 0..500_000 {
        naive += v;
    }
    let naive_error = (naive as f64 / 500_000.0 - v as f64).abs() / v as f64;
    assert!(
        naive_error > 1e-4,
        "the test would not tell: {naive_error:e}"
    );
    let d = stability::accumulation_drift(&ctx(), 1_000_000);
    eprintln!(
        "after 1e6 frames: {:e} (a plain f32 sum: {naive_error:e})",
        d.error
    );
    assert_eq!(d.invalid, 0);
    assert!(d.error <= 1e-5, "drift {:e}", d.error);
}

/// The scene moved by `t`, camera included.
fn translated(s: &Scene, t: DVec3) -> Scene {
    let mut s = s.clone();
    s.camera.look_from += t;
    s.camera.look_at += t;
    for o in &mut s.objects {
        match &mut o.shape {
            Shape::Sphere { center, .. } | Shape::Box { center, .. } => *center += t,
            Shape::Quad { q, .. } => *q += t,
            Shape::Mesh { translate, .. } => *translate += t,
        }
    }
    s
}

#[test]
fn moving_the_whole_scene_far_away_changes_no_pixel() {
    // Positions reach the GPU relative to a floating origin subtracted in f64, so a scene
    // moved by an exactly representable offset gives the same f32 inputs, hence the same
    // image: at 1e4 from the origin as at it.
    for name in ["basic", "cornell", "dielectric"] {
        let s = Scene::load(name).unwrap();
        let fs = settings(32, 18, 6);
        let here = snapshot(&s, fs, 4).image();
        let there = snapshot(&translated(&s, DVec3::new(1e4, -2048.0, 3072.5)), fs, 4).image();
        let (differ, worst, _) = image_diff(&here, &there);
        assert_eq!(
            differ, 0,
            "{name}: {differ} pixels differ by up to {worst:e}"
        );
    }
}

#[test]
fn the_gpu_agrees_with_the_double_precision_reference() {
    let results = stability::run_probes(&ctx(), &stability::categories(3));
    for r in &results {
        eprintln!(
            "{:<70} {:>6} rays, worst {:.2e} (allowed {:.0e})",
            r.name, r.count, r.worst, r.threshold
        );
        assert!(r.count > 1000, "{}: only {} rays", r.name, r.count);
        assert!(
            r.pass(),
            "{}: worst relative error {:e}, {} mismatched hits",
            r.name,
            r.worst,
            r.mismatches
        );
    }
}

#[test]
fn the_mesh_stress_cases_are_seen_valid_and_exact_in_the_furnace_on_both_tracers() {
    // Meshes as people make them (`stability::meshes`): each must be in view (a twentieth of
    // the pixels or more differ from the sky alone), render without an invalid sample, and keep
    // its white furnace exact (a leak into a closed shell or a self-hit would trap a path).
    let cases = stability::meshes::cases();
    assert_eq!(cases.len(), 7);
    on_both(|| {
        for (name, s) in &cases {
            let st = FrameSettings::new(32, 18, 12, 1);
            let snap = snapshot(s, st, 4);
            assert_eq!(snap.invalid_samples(), 0, "{name}");
            let mut sky = s.clone();
            sky.objects.clear();
            let (img, bare) = (snap.image(), snapshot(&sky, st, 4).image());
            let seen = img
                .pixels
                .iter()
                .zip(&bare.pixels)
                .filter(|(a, b)| a != b)
                .count();
            eprintln!("{name}: {seen} of {} pixels see the mesh", img.pixels.len());
            assert!(
                seen * 20 >= img.pixels.len(),
                "{name}: only {seen} of {} pixels see the mesh",
                img.pixels.len()
            );
            let f = stability::white_furnace(s, FURNACE_SKY);
            let img = snapshot(&f, FrameSettings::new(32, 18, FURNACE_BOUNCES, 1), 4).image();
            let e = stability::furnace_error(&img, FURNACE_SKY);
            assert!(e <= FURNACE_TOLERANCE, "{name}: white furnace off by {e:e}");
        }
    });
}
