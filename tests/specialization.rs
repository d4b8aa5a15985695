//! Two ways to the same image: the BVH against testing every primitive, and the pipeline
//! specialized for a scene against the generic one. Both evaluate the same arithmetic on the
//! same random numbers, so the images must agree bit for bit, on the GPU adapter and on the
//! native CPU tracer (`on_both`).

mod common;
use common::*;
use termtrace::render::RenderOptions;
use termtrace::scene::generate::SplitMix64;
use termtrace::scene::{BUILTIN_SCENES, Scene};

/// Many primitives of every kind, with every material kind, so that paths bounce around.
fn crowded_scene() -> String {
    let mut rng = SplitMix64::new(5);
    let mut s = String::from(
        "[camera]\nlook_from = [0, 3, 9]\nlook_at = [0, 0.5, 0]\nvfov = 45\n\
         [[sphere]]\ncenter = [0, -1000, 0]\nradius = 1000\ncolor = [0.5, 0.5, 0.5]\n\
         [[mesh]]\nfile = \"meshes/torus.obj\"\ntranslate = [0, 1, 0]\nrotation = [60, 0, 0]\ncolor = [0.9, 0.6, 0.2]\nsmoothness = 0.7\n",
    );
    let material = |rng: &mut SplitMix64| match rng.next_u64() % 4 {
        0 => format!(
            "color = [{:.3}, {:.3}, {:.3}]\n",
            rng.f64(),
            rng.f64(),
            rng.f64()
        ),
        1 => format!("smoothness = 1\nabsorption = {:.3}\n", rng.range(0.0, 0.4)),
        2 => "smoothness = -1\nior = 1.5\n".to_string(),
        _ => format!("color = [1, 1, 1]\nlight = {:.2}\n", rng.range(0.5, 3.0)),
    };
    for _ in 0..200 {
        s += &format!(
            "[[sphere]]\ncenter = [{:.3}, {:.3}, {:.3}]\nradius = {:.3}\n{}",
            rng.range(-6.0, 6.0),
            rng.range(0.0, 3.0),
            rng.range(-6.0, 6.0),
            rng.range(0.05, 0.4),
            material(&mut rng)
        );
    }
    for _ in 0..40 {
        s += &format!(
            "[[quad]]\nq = [{:.3}, {:.3}, {:.3}]\nu = [{:.3}, 0, {:.3}]\nv = [0, {:.3}, {:.3}]\n{}",
            rng.range(-6.0, 6.0),
            rng.range(0.0, 2.0),
            rng.range(-6.0, 6.0),
            rng.range(0.2, 1.0),
            rng.range(-0.5, 0.5),
            rng.range(0.2, 1.0),
            rng.range(-0.5, 0.5),
            material(&mut rng)
        );
    }
    for _ in 0..40 {
        s += &format!(
            "[[box]]\ncenter = [{:.3}, {:.3}, {:.3}]\nhalf_extents = [{:.3}, {:.3}, {:.3}]\nrotation = [{:.1}, {:.1}, {:.1}]\n{}",
            rng.range(-6.0, 6.0),
            rng.range(0.0, 2.0),
            rng.range(-6.0, 6.0),
            rng.range(0.1, 0.4),
            rng.range(0.1, 0.4),
            rng.range(0.1, 0.4),
            rng.range(0.0, 90.0),
            rng.range(0.0, 90.0),
            rng.range(0.0, 90.0),
            material(&mut rng)
        );
    }
    s
}

#[test]
fn the_bvh_finds_the_same_hits_as_testing_every_primitive() {
    on_both(|| {
        let text = crowded_scene();
        // The mesh path is relative to the built-in scenes' folder.
        let scene = Scene::from_toml(&text, "builtin:test").unwrap();
        let n = scene.counts();
        assert!(n.spheres > 200 && n.quads == 40 && n.boxes == 40 && n.triangles > 2000);
        let s = settings(48, 32, 8);
        let with = snapshot_with(&scene, s, 4, RenderOptions::default()).image();
        let without = snapshot_with(
            &scene,
            s,
            4,
            RenderOptions {
                no_bvh: true,
                ..Default::default()
            },
        )
        .image();
        let (differ, worst, first) = image_diff(&with, &without);
        assert_eq!(
            differ, 0,
            "{differ} pixels differ (by up to {worst:e}, first at {first:?})"
        );
        // And the image is not trivially uniform: the test sees geometry.
        let distinct: std::collections::HashSet<_> =
            with.pixels.iter().map(|p| p.map(f32::to_bits)).collect();
        assert!(
            distinct.len() > 500,
            "only {} distinct pixels",
            distinct.len()
        );
    });
}

#[test]
fn specialized_and_generic_pipelines_give_the_same_image() {
    on_both(|| {
        for (name, _) in BUILTIN_SCENES {
            let scene = Scene::load(name).unwrap();
            let s = settings(32, 18, scene.render.max_bounces.min(8));
            // The specialized pipeline itself, not whichever of the two the tuner prefers.
            let special = snapshot_with(
                &scene,
                s,
                2,
                RenderOptions {
                    no_tune: true,
                    ..Default::default()
                },
            )
            .image();
            let generic = snapshot_with(
                &scene,
                s,
                2,
                RenderOptions {
                    generic: true,
                    ..Default::default()
                },
            )
            .image();
            let (differ, worst, first) = image_diff(&special, &generic);
            assert_eq!(
                differ, 0,
                "{name}: {differ} pixels differ (by up to {worst:e}, first at {first:?})"
            );
        }
    });
}

#[test]
fn a_pipeline_compiled_in_the_background_changes_nothing_in_the_image() {
    // The preview's path: a diffuse scene, then an edit that makes a sphere glass (a new
    // feature set). The renderer traces with the generic pipeline until the new one is
    // compiled, then switches; the accumulated image must be what a fresh render gives.
    let diffuse = scene(
        "[[sphere]]\ncenter = [0, -100.5, -1]\nradius = 100\n[[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\n",
    );
    let mut glass = diffuse.clone();
    glass.objects[1].material.smoothness = -1.0;
    glass.objects[1].material.color = glam::Vec3::ONE;
    let s = settings(40, 30, 8);
    let options = RenderOptions {
        compile_in_background: true,
        ..Default::default()
    };
    let mut r = termtrace::render::Renderer::new(ctx(), &diffuse, s, options);
    r.render_spp(2);
    r.set_scene(&glass, s);
    r.render_spp(12);
    let switched = r.snapshot().image();
    let fresh = snapshot(&glass, s, 12).image();
    let (differ, worst, _) = image_diff(&switched, &fresh);
    assert_eq!(differ, 0, "{differ} pixels differ by up to {worst:e}");
}

#[test]
fn samples_traced_on_several_lanes_sum_to_the_same_accumulation() {
    // A pixel's samples spread over lanes whose fixed-point sums the reduce pass adds: the
    // sums must be the same words as one lane's, halves and counters included. `lamp` has
    // light sampling and Russian roulette (random path lengths).
    for name in ["lamp", "dielectric"] {
        let scene = Scene::load(name).unwrap();
        let s = settings(24, 16, 8);
        let one = snapshot_with(
            &scene,
            s,
            13,
            RenderOptions {
                lanes: Some(1),
                ..Default::default()
            },
        );
        // Lanes, and the preview's first look (even rows, then odd ones, for the first sample).
        for (lanes, first_look) in [(2, false), (5, true), (64, false), (1, true)] {
            let many = snapshot_with(
                &scene,
                s,
                13,
                RenderOptions {
                    lanes: Some(lanes),
                    first_look,
                    ..Default::default()
                },
            );
            let bits = |v: &Vec<[f32; 4]>| -> Vec<[u32; 4]> {
                v.iter().map(|p| p.map(f32::to_bits)).collect()
            };
            assert!(
                bits(&one.data.even) == bits(&many.data.even)
                    && bits(&one.data.odd) == bits(&many.data.odd),
                "{name}: {lanes} lanes (first look {first_look}) give other sums than one"
            );
            assert_eq!(one.data.invalid, many.data.invalid);
        }
    }
}

#[test]
fn the_tuner_times_whole_rounds_taken_in_several_submissions() {
    use std::collections::BTreeMap;
    use termtrace::render::{Backend, Renderer};
    // Submissions of a few rows each (a 1 µs target: each takes the fewest paths one may,
    // 16 of 64 rows here), as a large image on a slow adapter has them: every submission of
    // a round must use the round's pipeline, both pipelines must be timed, and a choice come.
    let scene = Scene::load("basic").unwrap();
    let options = RenderOptions {
        submission: std::time::Duration::from_micros(1),
        tune_on_software: true,
        ..Default::default()
    };
    let mut r = Renderer::new(Backend::Gpu(ctx()), &scene, settings(256, 64, 8), options);
    // The pipelines of each round's submissions, by the samples done before the round.
    let mut rounds: BTreeMap<u32, Vec<_>> = BTreeMap::new();
    while r.tuned().is_none() && rounds.len() < 100 {
        let before = r.samples();
        r.submit(u32::MAX).expect("samples left");
        rounds
            .entry(before)
            .or_default()
            .push(r.last_pipeline().unwrap());
        r.wait(0);
    }
    let (chosen, (special, generic)) = r.tuned().expect("a choice within 100 rounds");
    assert!(special > 0.0 && special.is_finite(), "{special}");
    assert!(generic > 0.0 && generic.is_finite(), "{generic}");
    for (samples, pipelines) in &rounds {
        assert!(
            pipelines.len() > 1,
            "round at {samples} spp: one submission"
        );
        assert!(
            pipelines.iter().all(|p| *p == pipelines[0]),
            "round at {samples} spp mixes pipelines"
        );
    }
    let timed: Vec<_> = rounds.values().map(|p| p[0]).collect();
    assert!(timed.contains(&r.features()) && timed.iter().any(|p| *p != r.features()));
    assert!(chosen == r.features() || timed.contains(&chosen));
}

#[test]
fn a_software_adapter_traces_with_the_scene_s_own_pipeline_and_times_none() {
    use termtrace::render::{Backend, Renderer};
    // On lavapipe the generic pipeline's first dispatch compiles for minutes (BENCHMARKS.md,
    // "Shaders compiled once on lavapipe"): unless asked (`tune_on_software`, the test above),
    // a software adapter never times it against the scene's own.
    let ctx = ctx();
    assert!(ctx.is_software(), "the tests' adapter is a software one");
    let scene = Scene::load("basic").unwrap();
    let options = RenderOptions {
        submission: std::time::Duration::from_micros(1),
        ..Default::default()
    };
    let mut r = Renderer::new(Backend::Gpu(ctx), &scene, settings(256, 64, 8), options);
    for _ in 0..12 {
        r.submit(u32::MAX).expect("samples left");
        assert_eq!(
            r.last_pipeline(),
            Some(r.features()),
            "only the scene's own pipeline"
        );
        r.wait(0);
    }
    assert!(
        !r.tuning() && r.tuned().is_none(),
        "no tuner on a software adapter"
    );
}
