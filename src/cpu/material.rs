//! Scattering by the material rules of MODEL.md ("Materials", steps 2 and 3), as
//! shaders/common/material.wgsl does it.

use super::rng::Rng;
use super::sampling::{normalize_or, random_unit_vector};
use super::scene::Material;
use glam::Vec3A;

pub struct Scatter {
    pub dir: Vec3A,
    pub attenuation: Vec3A,
    /// The path ends here (a bounce below the surface).
    pub absorbed: bool,
}

/// Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", 1994.
fn schlick(cosine: f32, ratio: f32) -> f32 {
    let r0 = (1.0 - ratio) / (1.0 + ratio);
    let r0 = r0 * r0;
    let x = 1.0 - cosine;
    let x2 = x * x;
    r0 + (1.0 - r0) * (x2 * x2 * x)
}

pub(super) fn reflect(d: Vec3A, n: Vec3A) -> Vec3A {
    d - 2.0 * d.dot(n) * n
}

/// Snell's law in the lecture's form (r_perp, r_par), `n` facing the incoming `d`.
pub(super) fn refract_dir(d: Vec3A, n: Vec3A, cos_theta: f32, ratio: f32) -> Vec3A {
    let r_perp = ratio * (d + cos_theta * n);
    let r_par = -(1.0 - r_perp.dot(r_perp)).abs().sqrt() * n;
    r_perp + r_par
}

/// A dielectric: reflect by total internal reflection or with Schlick's probability, else
/// refract; an index-matched interface (ratio exactly 1) lets the ray through unchanged.
pub fn scatter_dielectric(m: &Material, d: Vec3A, n_out: Vec3A, rng: &mut Rng) -> Scatter {
    let front = d.dot(n_out) < 0.0;
    let n = if front { n_out } else { -n_out };
    let ratio = if front { 1.0 / m.ior } else { m.ior };
    let cos_theta = (-d).dot(n).min(1.0);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let mut dir = d;
    if ratio != 1.0 {
        let u = rng.rand();
        dir = if ratio * sin_theta > 1.0 || schlick(cos_theta, ratio) > u {
            reflect(d, n).normalize()
        } else {
            refract_dir(d, n, cos_theta, ratio).normalize()
        };
    }
    if m.absorption > 0.0 {
        dir = normalize_or(dir + m.absorption * random_unit_vector(rng), dir);
    }
    Scatter {
        dir,
        attenuation: m.color,
        absorbed: false,
    }
}

/// Lambertian, smoothness blend, fuzz and the specular-probability lobe of the lecture; the
/// caller picks the lobe (`is_spec`) so that light sampling can come between. `n`: the
/// (shading) normal on the side `d` comes from.
#[inline(always)]
pub fn scatter_surface(m: &Material, d: Vec3A, n: Vec3A, is_spec: bool, rng: &mut Rng) -> Scatter {
    let diffuse = normalize_or(n + random_unit_vector(rng), n);
    let mut dir = diffuse;
    let mut tint = m.color;
    if is_spec {
        let mut mirror = reflect(d, n);
        if m.absorption > 0.0 {
            mirror = normalize_or(mirror + m.absorption * random_unit_vector(rng), n);
        }
        dir = normalize_or(diffuse.lerp(mirror, m.smoothness), n);
        tint = m.specular_color;
    }
    Scatter {
        dir,
        attenuation: tint,
        absorbed: dir.dot(n) <= 0.0,
    }
}
