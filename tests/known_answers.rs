//! Known-answer renders: scenes whose every path has the same value, so the image is exact
//! up to float rounding. Each test states what it checks and how many pixels it checked, and
//! runs on the GPU adapter and on the native CPU tracer (`on_both`).

mod common;
use common::*;
use glam::DVec3;

const W: u32 = 48;
const H: u32 = 48;
const SPP: u32 = 8;

/// A sphere in front of the camera, `material` spliced in, under a uniform sky `sky`.
fn sphere_scene(material: &str, sky: &str) -> String {
    format!(
        "[camera]\nlook_from = [0, 0, 0]\nlook_at = [0, 0, -3]\nvfov = 40\n\
         [sky]\n{sky}\n\
         [[sphere]]\ncenter = [0.2, -0.1, -3]\nradius = 0.8\n{material}\n"
    )
}

/// Checks every pixel the sphere covers equals `inside` and every pixel it misses equals
/// `outside`, within `tol` relative; returns how many pixels were checked.
fn check_coverage(toml: &str, inside: [f32; 3], outside: [f32; 3], tol: f64) -> (usize, usize) {
    let s = scene(toml);
    let img = render(toml, W, H, SPP, 10);
    let frame = camera_frame(&s, W, H);
    let (mut n_in, mut n_out) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let v = img.get(x, y);
            match sphere_coverage(&frame, W, H, (x, y), DVec3::new(0.2, -0.1, -3.0), 0.8) {
                Some(true) => {
                    assert!(
                        rel_err(v, inside) <= tol,
                        "pixel ({x},{y}) inside: {v:?} != {inside:?}"
                    );
                    n_in += 1;
                }
                Some(false) => {
                    assert!(
                        rel_err(v, outside) <= tol,
                        "pixel ({x},{y}) outside: {v:?} != {outside:?}"
                    );
                    n_out += 1;
                }
                None => {}
            }
        }
    }
    assert!(
        n_in > 400 && n_out > 400,
        "too few pixels checked: {n_in} inside, {n_out} outside"
    );
    (n_in, n_out)
}

fn mul(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

/// Float rounding allowed on an exact answer: a few ulps of f32.
const EXACT: f64 = 4.0 * f32::EPSILON as f64;

#[test]
fn lambertian_sphere_under_uniform_sky_is_albedo_times_sky() {
    on_both(|| {
        let albedo = [0.3, 0.5, 0.7];
        let sky = [0.9, 0.8, 1.2];
        let (i, o) = check_coverage(
            &sphere_scene("color = [0.3, 0.5, 0.7]", "uniform = [0.9, 0.8, 1.2]"),
            mul(albedo, sky),
            sky,
            EXACT,
        );
        eprintln!("furnace: {i} covered pixels = albedo x sky, {o} sky pixels = sky");
    });
}

#[test]
fn white_mirror_under_uniform_sky_is_the_sky() {
    on_both(|| {
        let sky = [0.6, 0.7, 0.8];
        check_coverage(
            &sphere_scene(
                "color = [1, 1, 1]\nsmoothness = 1\nabsorption = 0",
                "uniform = [0.6, 0.7, 0.8]",
            ),
            sky,
            sky,
            EXACT,
        );
    });
}

#[test]
fn white_fuzzy_specular_sphere_under_uniform_sky_is_the_sky() {
    on_both(|| {
        // Any mix of lobes of a white, non-absorbing surface returns the sky whenever it escapes;
        // on a convex sphere every bounce escapes unless it is aimed below the surface, which only
        // fuzz can do: absorption 0.3 with smoothness 0.5 never reaches below (the blend keeps
        // half of a diffuse direction), so the furnace stays exact.
        let sky = [0.5, 0.5, 0.5];
        check_coverage(
            &sphere_scene(
                "color = [1, 1, 1]\nsmoothness = 0.5\nabsorption = 0.3\nspecular = 0.5",
                "uniform = [0.5, 0.5, 0.5]",
            ),
            sky,
            sky,
            EXACT,
        );
    });
}

#[test]
fn emitter_seen_directly_is_color_times_light() {
    on_both(|| {
        let c = [0.9f32, 0.6, 0.3];
        let expected = c.map(|x| x * 5.0);
        check_coverage(
            &sphere_scene("color = [0.9, 0.6, 0.3]\nlight = 5", "uniform = [0, 0, 0]"),
            expected,
            [0.0; 3],
            EXACT,
        );
    });
}

#[test]
fn lambertian_plane_under_uniform_sky_is_half_the_sky() {
    on_both(|| {
        // Albedo 0.5: every camera ray hits the plane, every bounce leaves it for the sky.
        let toml = "[camera]\nlook_from = [0, 1, 0]\nlook_at = [0, 0, -0.5]\nvfov = 40\n\
                    [sky]\nuniform = [0.8, 1.0, 0.6]\n\
                    [[quad]]\nq = [-1000, 0, 1000]\nu = [2000, 0, 0]\nv = [0, 0, -2000]\ncolor = [0.5, 0.5, 0.5]\n";
        let img = render(toml, W, H, SPP, 4);
        let expected = [0.4f32, 0.5, 0.3];
        for (i, p) in img.pixels.iter().enumerate() {
            assert!(rel_err(*p, expected) <= EXACT, "pixel {i}: {p:?}");
        }
    });
}

#[test]
fn glass_of_ior_one_vanishes() {
    on_both(|| {
        // An index-matched interface neither reflects nor bends: the image is the empty scene's,
        // bit for bit, under a gradient sky with a sun.
        let sky = "bottom = [1.0, 0.9, 0.8]\ntop = [0.2, 0.4, 1.0]\n\
                   sun = { direction = [0.3, 0.2, 1], color = [1, 1, 1], intensity = 3, size = 20 }";
        let empty = format!("[camera]\nlook_at = [0, 0, -3]\nvfov = 40\n[sky]\n{sky}\n");
        let glass = format!(
            "{empty}[[sphere]]\ncenter = [0.2, -0.1, -3]\nradius = 0.8\nsmoothness = -1\nior = 1.0\n"
        );
        let a = render(&empty, W, H, SPP, 10);
        let b = render(&glass, W, H, SPP, 10);
        let (n, worst, first) = image_diff(&a, &b);
        assert_eq!(
            n, 0,
            "a glass sphere of ior 1.0 changed {n} pixels, by up to {worst:e}, first at {first:?}"
        );
    });
}

#[test]
fn glass_of_ior_one_over_a_ground_vanishes_to_rounding() {
    on_both(|| {
        // Over a diffuse ground the path through the sphere reaches the ground from a slightly
        // different origin (float rounding of the hit points), so equality holds to rounding only.
        let base = "[camera]\nlook_from = [0, 0.5, 1]\nlook_at = [0, 0, -3]\nvfov = 40\n\
                    [[sphere]]\ncenter = [0, -100.5, -3]\nradius = 100\ncolor = [0.5, 0.6, 0.4]\n";
        let glass = format!(
            "{base}[[sphere]]\ncenter = [0, 0, -3]\nradius = 0.5\nsmoothness = -1\nior = 1.0\n"
        );
        let a = render(base, W, H, SPP, 10);
        let b = render(&glass, W, H, SPP, 10);
        let (_, worst, _) = image_diff(&a, &b);
        eprintln!("glass ior 1.0 over ground: worst pixel difference {worst:e}");
        assert!(worst <= 1e-4, "worst pixel difference {worst}");
    });
}

#[test]
fn total_internal_reflection_is_exact() {
    on_both(|| {
        // Seen from inside the glass (below a quad whose normal points up) at 55° to 65° from the
        // normal, ior 1.5 · sin θ > 1: every ray reflects, back down into the sky below, whose
        // radiance t = 0.5 (dir.y + 1) with dir.y = -d.y. One sample per pixel, each camera ray
        // reproduced on the host with the tracer's random stream.
        let toml = "[camera]\nlook_from = [0, -5, 8.660254037844386]\nlook_at = [0, 0, 0]\nvfov = 10\n\
                    [sky]\nbottom = [0, 0, 0]\ntop = [1, 1, 1]\n\
                    [[quad]]\nq = [-10, 0, -10]\nu = [0, 0, 20]\nv = [20, 0, 0]\nsmoothness = -1\nior = 1.5\n";
        let s = scene(toml);
        let (w, h) = (24u32, 24u32);
        let img = render(toml, w, h, 1, 1);
        let frame = camera_frame(&s, w, h);
        let mut worst = 0.0f64;
        for (x, y, d) in first_sample_dirs(&frame, w, h) {
            assert!(
                1.5 * (1.0 - d.y * d.y).sqrt() > 1.0,
                "test geometry: no TIR at ({x},{y})"
            );
            let expected = [(0.5 * (1.0 - d.y)) as f32; 3];
            let e = rel_err(img.get(x, y), expected);
            worst = worst.max(e);
            assert!(
                e < 2e-5,
                "pixel ({x},{y}): {:?} vs {expected:?}",
                img.get(x, y)
            );
        }
        eprintln!("total internal reflection: worst relative error {worst:e}");
    });
}

#[test]
fn unobstructed_pixels_see_exactly_the_sky_formula() {
    on_both(|| {
        // One sample per pixel: reproduce each sample's jittered camera ray on the host with the
        // tracer's random stream, and evaluate MODEL.md's sky formula there.
        let toml = "[camera]\nlook_from = [0, 0, 0]\nlook_at = [0, 0.3, -1]\nvfov = 70\n\
                    [sky]\nbottom = [1.0, 0.9, 0.8]\ntop = [0.2, 0.4, 1.0]\n\
                    sun = { direction = [0.2, 0.5, -1], color = [1, 0.8, 0.6], intensity = 2, size = 8 }\n";
        let s = scene(toml);
        let (w, h) = (40u32, 30u32);
        let img = render(toml, w, h, 1, 4);
        let frame = camera_frame(&s, w, h);
        let mut worst = 0.0f64;
        for (x, y, dir) in first_sample_dirs(&frame, w, h) {
            let expected = s.sky.radiance(dir).as_vec3().to_array();
            let e = rel_err(img.get(x, y), expected);
            worst = worst.max(e);
            assert!(
                e < 2e-5,
                "pixel ({x},{y}): {:?} vs {expected:?}",
                img.get(x, y)
            );
        }
        eprintln!(
            "sky formula: worst relative error {worst:e} over {} pixels",
            w * h
        );
    });
}

#[test]
fn max_bounces_zero_shows_only_what_camera_rays_see() {
    on_both(|| {
        // B = 0: a diffuse surface seen directly is black (no scattering allowed), an emitter
        // seen directly is its emission, the sky is the sky.
        let toml = sphere_scene("color = [0.5, 0.5, 0.5]", "uniform = [0.7, 0.7, 0.7]");
        let s = scene(&toml);
        let img = render(&toml, W, H, 4, 0);
        let frame = camera_frame(&s, W, H);
        let mut n = 0;
        for y in 0..H {
            for x in 0..W {
                if let Some(hit) =
                    sphere_coverage(&frame, W, H, (x, y), DVec3::new(0.2, -0.1, -3.0), 0.8)
                {
                    let expected = if hit { [0.0; 3] } else { [0.7; 3] };
                    assert_eq!(img.get(x, y), expected, "pixel ({x},{y})");
                    n += 1;
                }
            }
        }
        assert!(n > 1000);
    });
}

#[test]
fn a_seed_makes_a_render_reproducible() {
    on_both(|| {
        let toml = "[[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\n\
                    [[sphere]]\ncenter = [0, -100.5, -1]\nradius = 100\nsmoothness = 0.5\nabsorption = 0.2\n";
        let s = scene(toml);
        let a = snapshot(&s, settings(32, 24, 8), 6).image();
        let b = snapshot(&s, settings(32, 24, 8), 6).image();
        assert_eq!(
            image_diff(&a, &b).0,
            0,
            "same seed, same adapter, different image"
        );
        let mut other = settings(32, 24, 8);
        other.seed = 2;
        let c = snapshot(&s, other, 6).image();
        assert!(
            image_diff(&a, &c).0 > 0,
            "a different seed gave the same image"
        );
    });
}
