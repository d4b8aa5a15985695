//! Deterministic scene generators: the `weekend` and `spheres` files in `scenes/`
//! (`cargo run --example gen_scenes`) and random sphere fields for benchmarks.

use super::*;
use glam::{DVec3, Vec3};

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, well-mixed generator so that generated
/// scenes are the same on every machine and toolchain.
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
}

/// Rounds to 4 decimals so generated files stay readable.
fn r4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

fn r4v(v: Vec3) -> Vec3 {
    Vec3::new(
        r4(v.x as f64) as f32,
        r4(v.y as f64) as f32,
        r4(v.z as f64) as f32,
    )
}

fn sphere(center: DVec3, radius: f64, material: Material, name: Option<&str>) -> Object {
    Object {
        name: name.map(str::to_string),
        shape: Shape::Sphere {
            center: DVec3::new(r4(center.x), r4(center.y), r4(center.z)),
            radius,
        },
        material,
        material_name: None,
        gltf: None,
    }
}

fn lambertian(c: Vec3) -> Material {
    Material {
        color: r4v(c),
        ..Material::default()
    }
}

fn metal(c: Vec3, fuzz: f64) -> Material {
    Material {
        color: r4v(c),
        smoothness: 1.0,
        absorption: r4(fuzz) as f32,
        ..Material::default()
    }
}

fn glass(ior: f32) -> Material {
    Material {
        color: Vec3::ONE,
        smoothness: -1.0,
        ior,
        ..Material::default()
    }
}

/// The final scene of Ray Tracing in One Weekend (Shirley, §14 "Where Next?"): a large
/// ground sphere, small spheres on a jittered 22 × 22 grid (80 % Lambertian, 15 % fuzzy metal,
/// 5 % glass), three large spheres, camera from (13,2,3) to the origin, vfov 20, a 0.6°
/// defocus angle at focus distance 10.
pub fn weekend(seed: u64) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut objects = vec![sphere(
        DVec3::new(0.0, -1000.0, 0.0),
        1000.0,
        lambertian(Vec3::splat(0.5)),
        Some("ground"),
    )];
    for a in -11..11 {
        for b in -11..11 {
            let choose = rng.f64();
            let center = DVec3::new(a as f64 + 0.9 * rng.f64(), 0.2, b as f64 + 0.9 * rng.f64());
            if (center - DVec3::new(4.0, 0.2, 0.0)).length() <= 0.9 {
                continue;
            }
            let mut rv = || Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32);
            let m = if choose < 0.8 {
                lambertian(rv() * rv())
            } else if choose < 0.95 {
                let c = Vec3::splat(0.5) + 0.5 * rv();
                metal(c, rng.range(0.0, 0.5))
            } else {
                glass(1.5)
            };
            objects.push(sphere(center, 0.2, m, None));
        }
    }
    objects.push(sphere(
        DVec3::new(0.0, 1.0, 0.0),
        1.0,
        glass(1.5),
        Some("glass"),
    ));
    objects.push(sphere(
        DVec3::new(-4.0, 1.0, 0.0),
        1.0,
        lambertian(Vec3::new(0.4, 0.2, 0.1)),
        Some("brown"),
    ));
    objects.push(sphere(
        DVec3::new(4.0, 1.0, 0.0),
        1.0,
        metal(Vec3::new(0.7, 0.6, 0.5), 0.0),
        Some("bronze mirror"),
    ));
    let focus = 10.0;
    let defocus_angle: f64 = 0.6;
    Scene {
        origin: "termtrace::scene::generate::weekend".into(),
        camera: Camera {
            look_from: DVec3::new(13.0, 2.0, 3.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov: 20.0,
            // The book's defocus_radius = focus * tan(angle / 2); aperture is the diameter.
            aperture: r4(2.0 * focus * (defocus_angle.to_radians() / 2.0).tan()),
            focus_distance: Some(focus),
        },
        render: RenderSettings {
            width: 1280,
            height: 720,
            spp: 500,
            max_bounces: 50,
            seed: 1,
        },
        sky: Sky::default(),
        environment: None,
        materials: Vec::new(),
        objects,
        gltf: Vec::new(),
    }
}

/// A grid of `cols × rows` spheres with random materials of every kind the lecture teaches.
pub fn sphere_grid(cols: u32, rows: u32, seed: u64) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let mut objects = vec![sphere(
        DVec3::new(0.0, -1000.0, 0.0),
        1000.0,
        lambertian(Vec3::new(0.45, 0.45, 0.42)),
        Some("ground"),
    )];
    for j in 0..rows {
        for i in 0..cols {
            let x = (i as f64 - (cols - 1) as f64 / 2.0) * 0.9 + rng.range(-0.1, 0.1);
            let z = -(j as f64) * 0.9 + rng.range(-0.1, 0.1);
            let radius = r4(rng.range(0.25, 0.38));
            let hue = Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32);
            let m = match rng.next_u64() % 5 {
                0 => lambertian(hue * 0.9),
                1 => metal(Vec3::splat(0.6) + 0.4 * hue, rng.range(0.0, 0.3)),
                2 => Material {
                    color: r4v(hue * 0.9),
                    smoothness: r4(rng.range(0.2, 0.9)) as f32,
                    ..Material::default()
                },
                3 => Material {
                    color: r4v(hue * 0.9),
                    smoothness: 0.95,
                    specular: r4(rng.range(0.05, 0.3)) as f32,
                    specular_color: Some(Vec3::ONE),
                    ..Material::default()
                },
                _ => glass(r4(rng.range(1.3, 1.8)) as f32),
            };
            objects.push(sphere(DVec3::new(x, radius, z), radius, m, None));
        }
    }
    Scene {
        origin: "termtrace::scene::generate::sphere_grid".into(),
        camera: Camera {
            look_from: DVec3::new(0.0, 2.2, 3.0),
            look_at: DVec3::new(0.0, 0.0, -(rows as f64) * 0.35),
            up: DVec3::Y,
            vfov: 45.0,
            aperture: 0.0,
            focus_distance: None,
        },
        render: RenderSettings {
            width: 800,
            height: 450,
            spp: 256,
            max_bounces: 12,
            seed: 1,
        },
        sky: Sky::default(),
        environment: None,
        materials: Vec::new(),
        objects,
        gltf: Vec::new(),
    }
}

/// `n` small spheres of the weekend scene's three materials on a jittered square grid of
/// unit spacing around the weekend's three large spheres, on a ground quad: the same view as
/// `weekend` at any number of spheres (benchmarks: `termtrace bench --spheres N`).
pub fn sphere_field(n: usize, seed: u64) -> Scene {
    let mut scene = weekend(seed);
    let big = scene.objects.split_off(scene.objects.len() - 3);
    let mut rng = SplitMix64::new(seed);
    let side = (n as f64).sqrt().ceil() as i64;
    let half = side as f64 / 2.0;
    let mut objects = vec![Object {
        name: Some("ground".into()),
        shape: Shape::Quad {
            q: DVec3::new(-4.0 * half - 10.0, 0.0, 4.0 * half + 10.0),
            u: DVec3::new(8.0 * half + 20.0, 0.0, 0.0),
            v: DVec3::new(0.0, 0.0, -(8.0 * half + 20.0)),
        },
        material: lambertian(Vec3::splat(0.5)),
        material_name: None,
        gltf: None,
    }];
    'grid: for a in 0..side {
        for b in 0..side {
            if objects.len() > n {
                break 'grid;
            }
            let center = DVec3::new(
                a as f64 - half + 0.9 * rng.f64(),
                0.2,
                b as f64 - half + 0.9 * rng.f64(),
            );
            let choose = rng.f64();
            let mut rv = || Vec3::new(rng.f64() as f32, rng.f64() as f32, rng.f64() as f32);
            let m = if choose < 0.8 {
                lambertian(rv() * rv())
            } else if choose < 0.95 {
                metal(Vec3::splat(0.5) + 0.5 * rv(), 0.25)
            } else {
                glass(1.5)
            };
            objects.push(sphere(center, 0.2, m, None));
        }
    }
    objects.extend(big);
    scene.objects = objects;
    scene.origin = format!("termtrace::scene::generate::sphere_field({n})");
    scene.camera.aperture = 0.0;
    scene
}
