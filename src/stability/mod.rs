//! Numerical stability: the tracer's single-ray operations against a double-precision
//! reference, the white furnace on the extreme scenes, and `check --stress`.

pub mod chi2;
pub mod meshes;
pub mod probe;
pub mod reference;

use crate::common::FrameSettings;
use crate::common::arrays::sphere_anchor;
use crate::common::layout::{GpuQuad, GpuSphere};
use crate::gpu::GpuContext;
use crate::render::{RenderOptions, Renderer};
use crate::scene::generate::SplitMix64;
use crate::scene::gltf::DIELECTRIC_F0;
use crate::scene::{Material, MaterialModel, Scene, Shape, Sky};
use glam::{DVec3, Vec3};
use probe::{GpuProbeInput, GpuProbeOutput, PROBE_QUAD, PROBE_SCATTER, PROBE_SPHERE, ProbePass};
use std::sync::Arc;

/// What the double-precision reference says an input should give.
#[derive(Clone, Copy, Debug)]
enum Expected {
    Hit {
        t: f64,
    },
    Scatter {
        reflected: DVec3,
        refracted: Option<DVec3>,
        schlick: f64,
    },
}

/// A family of probe inputs and the largest relative error it tolerates.
pub struct Category {
    pub name: String,
    /// Largest relative error that passes (see `categories` for why each is what it is).
    pub threshold: f64,
    inputs: Vec<GpuProbeInput>,
    expected: Vec<Expected>,
}

/// The outcome of one category.
#[derive(Clone, Debug)]
pub struct ProbeResult {
    pub name: String,
    pub count: usize,
    /// Worst relative error over every result of the category.
    pub worst: f64,
    /// Inputs where the GPU missed a hit the reference found, or the opposite.
    pub mismatches: usize,
    pub threshold: f64,
}

impl ProbeResult {
    /// No probe: a row of `check --stress` that renders only.
    pub fn none() -> ProbeResult {
        ProbeResult {
            name: String::new(),
            count: 0,
            worst: 0.0,
            mismatches: 0,
            threshold: 0.0,
        }
    }

    pub fn pass(&self) -> bool {
        self.mismatches == 0 && self.worst <= self.threshold
    }
}

fn f3(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

/// f64 value of what the GPU actually received (inputs are rounded to f32 on the way).
fn d3(v: [f32; 3]) -> DVec3 {
    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
}

fn random_unit(rng: &mut SplitMix64) -> DVec3 {
    let z = rng.range(-1.0, 1.0);
    let phi = rng.range(0.0, std::f64::consts::TAU);
    let r = (1.0 - z * z).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A perpendicular unit vector to `n`.
fn perpendicular(n: DVec3) -> DVec3 {
    let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    n.cross(a).normalize()
}

impl Category {
    fn new(name: impl Into<String>, threshold: f64) -> Category {
        Category {
            name: name.into(),
            threshold,
            inputs: Vec::new(),
            expected: Vec::new(),
        }
    }

    /// A ray from `origin` through the point at perpendicular distance `off` (a fraction of
    /// the radius) from a sphere's centre, against the sphere as the tracer stores it (anchor
    /// toward `toward`).
    fn sphere_ray(
        &mut self,
        origin: DVec3,
        center: DVec3,
        radius: f64,
        off: f64,
        toward: DVec3,
        rng: &mut SplitMix64,
    ) {
        let to = center - origin;
        let side = perpendicular(to.normalize());
        let spin =
            glam::DQuat::from_axis_angle(to.normalize(), rng.range(0.0, std::f64::consts::TAU));
        let side = spin * side;
        let dir = (to + side * off * radius).normalize();
        let (a, n) = sphere_anchor(center, radius, toward);
        let sphere = GpuSphere {
            anchor: f3(a),
            radius: radius as f32,
            anchor_normal: f3(n),
            material: 0,
        };
        let input = GpuProbeInput {
            origin: f3(origin),
            kind: PROBE_SPHERE,
            dir: f3(dir),
            sphere,
            ..Default::default()
        };
        self.push_sphere(input);
    }

    /// Adds a sphere probe, with the reference computed in f64 on exactly the sphere and ray
    /// the GPU receives (its f32 anchor A, normal N and radius r describe the sphere of centre
    /// A - rN through A), so that the comparison measures the arithmetic, not the rounding of
    /// the inputs to f32.
    fn push_sphere(&mut self, input: GpuProbeInput) {
        let s = &input.sphere;
        let n = d3(s.anchor_normal);
        let r = (s.radius as f64).abs();
        let center = d3(s.anchor) - r * n;
        let t = reference::sphere_hit(d3(input.origin), d3(input.dir), center, r * n.length());
        if let Some(t) = t {
            self.inputs.push(input);
            self.expected.push(Expected::Hit { t });
        }
    }

    /// A ray to a random point of a quad, unless it sees the quad more than `max_angle` from
    /// its normal (grazing views are ill-conditioned: ∂t/∂dir grows as 1/cos).
    fn quad_ray(
        &mut self,
        origin: DVec3,
        q: DVec3,
        u: DVec3,
        v: DVec3,
        max_angle: f64,
        rng: &mut SplitMix64,
    ) {
        let target = q + rng.range(0.05, 0.95) * u + rng.range(0.05, 0.95) * v;
        let dir = (target - origin).normalize();
        if dir.dot(u.cross(v).normalize()).abs() < max_angle.cos() {
            return;
        }
        let n = u.cross(v);
        let quad = GpuQuad {
            q: f3(q),
            u: f3(u),
            v: f3(v),
            normal: f3(n.normalize()),
            w: f3(n / n.dot(n)),
            ..Default::default()
        };
        let input = GpuProbeInput {
            origin: f3(origin),
            kind: PROBE_QUAD,
            dir: f3(dir),
            quad,
            ..Default::default()
        };
        // The reference on the quad as the GPU stores it: its plane is (q, normal) in f32.
        let g = &input.quad;
        let (o, d) = (d3(input.origin), d3(input.dir));
        let (qn, nn) = (d3(g.q), d3(g.normal));
        let t = nn.dot(qn - o) / nn.dot(d);
        if reference::quad_hit(o, d, q, u, v).is_some() && t > 0.0 {
            self.inputs.push(input);
            self.expected.push(Expected::Hit { t });
        }
    }

    fn scatter(&mut self, d: DVec3, n: DVec3, ratio: f64) {
        let input = GpuProbeInput {
            kind: PROBE_SCATTER,
            dir: f3(d),
            normal: f3(n),
            ratio: ratio as f32,
            ..Default::default()
        };
        let (d, n, ratio) = (d3(input.dir), d3(input.normal), input.ratio as f64);
        let cos = (-d.dot(n)).min(1.0);
        // 1 - |r_perp|², under the square root of r_par: it vanishes at the critical angle,
        // where refraction is ill-conditioned by nature; those within 1e-3 of it are not
        // compared (their reflection and Schlick still are).
        let under_root = 1.0 - ratio * ratio * (1.0 - cos * cos);
        self.inputs.push(input);
        self.expected.push(Expected::Scatter {
            reflected: reference::reflect(d, n),
            refracted: (under_root > 1e-3).then(|| reference::refract(d, n, ratio)),
            schlick: reference::schlick(cos, ratio),
        });
    }
}

const PER_CATEGORY: usize = 2048;

/// The probe families: ordinary inputs and each extreme of the stability issue. Thresholds:
/// f32 has a relative precision of 6e-8; an operation of a few dozen roundings stays under
/// 1e-5 unless it is ill-conditioned. Grazing hits are: the distance to a silhouette changes
/// by ∂t/∂d ∝ 1/√(1 - (d/r)²), so a ray 1e-6 of the radius from the edge amplifies the
/// direction's rounding (6e-8) a thousandfold; their threshold is 1e-3.
pub fn categories(seed: u64) -> Vec<Category> {
    let mut rng = SplitMix64::new(seed);
    let mut out = Vec::new();

    let mut c = Category::new("sphere: random", 1e-5);
    for _ in 0..PER_CATEGORY {
        let center = DVec3::new(
            rng.range(-10.0, 10.0),
            rng.range(-10.0, 10.0),
            rng.range(-10.0, 10.0),
        );
        let radius = rng.range(0.1, 5.0) * if rng.f64() < 0.2 { -1.0 } else { 1.0 };
        let origin = center + random_unit(&mut rng) * radius.abs() * rng.range(1.5, 40.0);
        c.sphere_ray(
            origin,
            center,
            radius,
            rng.range(0.0, 0.95),
            origin,
            &mut rng,
        );
    }
    out.push(c);

    for r in [1e3, 1e5, 1e6] {
        let mut c = Category::new(
            format!("sphere: radius {r:.0e}, origin 1e-3 to 10 above it"),
            1e-5,
        );
        let center = DVec3::new(0.0, -r, 0.0);
        for _ in 0..PER_CATEGORY {
            let origin = DVec3::new(
                rng.range(-2.0, 2.0),
                10f64.powf(rng.range(-3.0, 1.0)),
                rng.range(-2.0, 2.0),
            );
            // Toward the ground at least 10° below the horizon (nearer the horizon the hit
            // becomes tangent, ill-conditioned like the grazing category below).
            let down = loop {
                let d = DVec3::new(
                    rng.range(-1.0, 1.0),
                    -rng.range(0.1, 1.0),
                    rng.range(-1.0, 1.0),
                )
                .normalize();
                if -d.y >= 10f64.to_radians().sin() {
                    break d;
                }
            };
            let (a, n) = sphere_anchor(center, r, DVec3::ZERO);
            let input = GpuProbeInput {
                origin: f3(origin),
                kind: PROBE_SPHERE,
                dir: f3(down),
                sphere: GpuSphere {
                    anchor: f3(a),
                    radius: r as f32,
                    anchor_normal: f3(n),
                    material: 0,
                },
                ..Default::default()
            };
            c.push_sphere(input);
        }
        out.push(c);
    }

    let mut c = Category::new("sphere: radius 1e-4 at 1e-3", 1e-5);
    for _ in 0..PER_CATEGORY {
        let center = DVec3::new(0.0, 0.0, -1e-3) + random_unit(&mut rng) * 2e-4;
        c.sphere_ray(
            DVec3::ZERO,
            center,
            1e-4,
            rng.range(0.0, 0.95),
            DVec3::ZERO,
            &mut rng,
        );
    }
    out.push(c);

    let mut c = Category::new("sphere: origin 1e4 away", 1e-5);
    for _ in 0..PER_CATEGORY {
        let center = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let origin = center + random_unit(&mut rng) * 1e4;
        c.sphere_ray(
            origin,
            center,
            rng.range(0.2, 1.0),
            rng.range(0.0, 0.95),
            center,
            &mut rng,
        );
    }
    out.push(c);

    let mut c = Category::new("sphere: scene translated by 1e4", 1e-5);
    for _ in 0..PER_CATEGORY {
        let base = DVec3::splat(1e4);
        let center = base
            + DVec3::new(
                rng.range(-5.0, 5.0),
                rng.range(-5.0, 5.0),
                rng.range(-5.0, 5.0),
            );
        let origin = center + random_unit(&mut rng) * rng.range(2.0, 20.0);
        c.sphere_ray(
            origin,
            center,
            rng.range(0.2, 1.0),
            rng.range(0.0, 0.95),
            origin,
            &mut rng,
        );
    }
    out.push(c);

    let mut c = Category::new(
        "sphere: grazing, 1e-6 to 1e-2 of the radius inside the edge",
        1e-3,
    );
    for _ in 0..PER_CATEGORY {
        let center = DVec3::new(
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
        );
        let origin = center + random_unit(&mut rng) * rng.range(3.0, 30.0);
        let off = 1.0 - 10f64.powf(rng.range(-6.0, -2.0));
        c.sphere_ray(origin, center, 1.0, off, origin, &mut rng);
    }
    out.push(c);

    let mut c = Category::new("quad: random, within 84° of the normal", 1e-5);
    for _ in 0..PER_CATEGORY {
        let q = DVec3::new(
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
        );
        let (u, v) = (
            random_unit(&mut rng) * rng.range(0.5, 3.0),
            random_unit(&mut rng) * rng.range(0.5, 3.0),
        );
        let origin = q + random_unit(&mut rng) * rng.range(2.0, 50.0);
        c.quad_ray(origin, q, u, v, 84f64.to_radians(), &mut rng);
    }
    out.push(c);

    let mut c = Category::new("quad: seen 1e-3 to 1e-1 rad off edge-on", 1e-4);
    for _ in 0..PER_CATEGORY {
        let (u, v) = (DVec3::new(2.0, 0.0, 0.0), DVec3::new(0.0, 0.0, -2.0));
        let q = DVec3::new(-1.0, 0.0, 1.0);
        let angle = 10f64.powf(rng.range(-3.0, -1.0));
        let dist = rng.range(2.0, 10.0);
        let origin = DVec3::new(rng.range(-0.5, 0.5), dist * angle.sin(), dist * angle.cos());
        c.quad_ray(origin, q, u, v, std::f64::consts::FRAC_PI_2, &mut rng);
    }
    out.push(c);

    for (name, ratio) in [
        ("1/1.5", 1.0 / 1.5),
        ("1.5", 1.5),
        ("1/2.4", 1.0 / 2.4),
        ("2.4", 2.4),
        ("1/10", 0.1),
        ("1.0001", 1.0001),
    ] {
        let mut c = Category::new(
            format!("scatter, ratio {name}: reflect, refract (rel.), Schlick (abs.)"),
            1e-5,
        );
        for _ in 0..PER_CATEGORY {
            let n = random_unit(&mut rng);
            let mut d = random_unit(&mut rng);
            if d.dot(n) > 0.0 {
                d = -d;
            }
            c.scatter(d, n, ratio);
        }
        out.push(c);
    }
    out
}

/// Relative error of a vector result.
fn vec_error(got: [f32; 3], want: DVec3) -> f64 {
    (d3(got) - want).length() / want.length().max(1e-30)
}

/// Runs every category on the GPU and compares with the reference.
pub fn run_probes(ctx: &GpuContext, cats: &[Category]) -> Vec<ProbeResult> {
    let pass = ProbePass::new(&ctx.device);
    cats.iter()
        .map(|c| {
            let out: Vec<GpuProbeOutput> = pass.run(ctx, &c.inputs);
            let (mut worst, mut mismatches) = (0.0f64, 0usize);
            for (o, e) in out.iter().zip(&c.expected) {
                match *e {
                    Expected::Hit { t } => {
                        if o.t > 0.0 {
                            worst = worst.max((o.t as f64 - t).abs() / t);
                        } else {
                            mismatches += 1;
                        }
                    }
                    Expected::Scatter {
                        reflected,
                        refracted,
                        schlick,
                    } => {
                        worst = worst.max(vec_error(o.reflected, reflected));
                        if let Some(r) = refracted {
                            worst = worst.max(vec_error(o.refracted, r));
                        }
                        // Schlick's value is a probability compared with a uniform random
                        // number: an absolute error e flips a decision with probability e.
                        worst = worst.max((o.schlick as f64 - schlick).abs());
                    }
                }
            }
            ProbeResult {
                name: c.name.clone(),
                count: c.inputs.len(),
                worst,
                mismatches,
                threshold: c.threshold,
            }
        })
        .collect()
}

/// Probe rays from a scene's camera to every sphere and quad it holds (the scene's own
/// geometry and anchors).
pub fn scene_category(scene: &Scene, seed: u64) -> Category {
    let mut rng = SplitMix64::new(seed);
    let mut c = Category::new(format!("{} rays", scene.short_name()), 1e-5);
    let origin = scene.camera.look_from;
    for o in &scene.objects {
        for _ in 0..64 {
            match &o.shape {
                // Spheres around the camera are seen from inside: not this family's case.
                Shape::Sphere { center, radius } if (*center - origin).length() > radius.abs() => {
                    c.sphere_ray(
                        origin,
                        *center,
                        *radius,
                        rng.range(0.0, 0.9),
                        scene.camera.look_at,
                        &mut rng,
                    );
                }
                Shape::Quad { q, u, v } => {
                    c.quad_ray(origin, *q, *u, *v, std::f64::consts::FRAC_PI_2, &mut rng)
                }
                _ => {}
            }
        }
    }
    c
}

/// The scene with every material made white and lossless, and emitters dark, under a
/// uniform sky of radiance `l`: every path that escapes carries exactly `l` (throughput
/// multiplies by 1), so the image must be exactly `l` however the geometry sends the rays.
/// A ray that slips under a surface and stays trapped shows as a darker pixel. Fuzz is
/// removed: MODEL.md absorbs a fuzzed bounce below the surface, which would lose energy.
pub fn white_furnace(scene: &Scene, l: f32) -> Scene {
    let mut s = scene.clone();
    s.sky = Sky::Uniform(Vec3::splat(l));
    for o in &mut s.objects {
        let m = o.material.clone();
        o.material = if m.is_emitter() {
            Material {
                color: Vec3::ONE,
                ..Material::default()
            }
        } else if m.is_pbr() {
            // glTF's BRDF is not lossless (single scattering; `fresnel_mix` as the
            // specification writes it): a pbr surface becomes the lecture's white one, a
            // Lambertian and a mirror lobe in glTF's shares, its maps (a normal map's
            // shading normals) kept.
            Material {
                color: Vec3::ONE,
                model: MaterialModel::Lecture,
                smoothness: 1.0,
                specular: m.metallic + (1.0 - m.metallic) * DIELECTRIC_F0,
                specular_color: None,
                absorption: 0.0,
                light: 0.0,
                ..m
            }
        } else {
            Material {
                color: Vec3::ONE,
                specular_color: None,
                absorption: 0.0,
                light: 0.0,
                ..m
            }
        };
    }
    s
}

/// One row of `check --stress`.
#[derive(Clone, Debug)]
pub struct StressRow {
    pub case: String,
    pub invalid: u64,
    /// Worst relative deviation from the white furnace's exact value, where defined.
    pub furnace: Option<f64>,
    pub probe: ProbeResult,
}

impl StressRow {
    pub fn pass(&self) -> bool {
        self.invalid == 0
            && self.furnace.is_none_or(|e| e <= FURNACE_TOLERANCE)
            && self.probe.pass()
    }
}

/// A white furnace pixel is a sum of identical samples divided by their count: exact up to a
/// few ulps.
pub const FURNACE_TOLERANCE: f64 = 4.0 * f32::EPSILON as f64;
/// Radiance of the furnace's sky: not a power of two, so rounding would show.
pub const FURNACE_SKY: f32 = 0.7;
/// Bounces allowed in the furnace: paths in open scenes escape long before.
pub const FURNACE_BOUNCES: u32 = 1000;

/// Scenes whose every path must escape to the sky. Not: the closed sphere; the
/// total-internal-reflection trap, where a lossless slab keeps some light for ever (as a real
/// one would, until its edge); coincident surfaces, where a ray refracted into a glass sphere
/// is inside the diffuse sphere occupying the same place. Those paths rightly end at
/// max_bounces; what these scenes must show is no invalid sample.
pub fn furnace_applies(name: &str) -> bool {
    !["inside_diffuse", "tir_trap", "coincident"]
        .iter()
        .any(|n| name.ends_with(n))
}

/// Renders `scene` at `settings` for `spp`: (invalid samples, the image).
pub fn render_counting(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    settings: FrameSettings,
    spp: u32,
) -> (u64, crate::output::LinearImage) {
    let mut r = Renderer::new(ctx.clone(), scene, settings, RenderOptions::default());
    r.render_spp(spp);
    let snap = r.snapshot();
    (snap.invalid_samples(), snap.image())
}

/// Worst relative deviation of an image from a constant.
pub fn furnace_error(img: &crate::output::LinearImage, expected: f32) -> f64 {
    img.pixels
        .iter()
        .flat_map(|p| p.iter())
        .map(|v| (*v as f64 - expected as f64).abs() / expected as f64)
        .fold(0.0, f64::max)
}

/// Accumulation after many frames of a furnace sphere filling a 4×4 image.
pub struct Drift {
    pub invalid: u64,
    /// Worst relative deviation of a pixel's mean from the exact per-sample value.
    pub error: f64,
}

/// A sphere of albedo 0.3 under a uniform sky 0.7 fills the view: every sample is exactly
/// 0.3f × 0.7f, so after `spp` frames the mean must still be that value. A plain f32 running
/// sum drifts well past 1e-5 by a million frames (see tests/stability.rs); the two-sum pair
/// does not.
pub fn accumulation_drift(ctx: &Arc<GpuContext>, spp: u32) -> Drift {
    let scene = Scene::from_toml(
        "[camera]\nlook_from = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 10\n[sky]\nuniform = [0.7, 0.7, 0.7]\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\ncolor = [0.3, 0.3, 0.3]\n",
        "drift",
    )
    .expect("the drift scene is valid");
    let mut r = Renderer::new(
        ctx.clone(),
        &scene,
        FrameSettings::new(4, 4, 1, 1),
        RenderOptions::default(),
    );
    r.render_spp(spp);
    let snap = r.snapshot();
    Drift {
        invalid: snap.invalid_samples(),
        error: furnace_error(&snap.image(), 0.3f32 * 0.7f32),
    }
}
