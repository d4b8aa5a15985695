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
pub(super) fn schlick(cosine: f32, ratio: f32) -> f32 {
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

/// How far below 0 `gloss_pdf`'s discriminant may round for a direction the lobe draws.
pub(super) const DISC_ROUNDING: f32 = 1e-6;

/// The density, in solid angle, with which the lecture's glossy lobe (`scatter_surface`'s
/// specular lobe at smoothness `s` in (0, 1), without fuzz) draws `w`, about the shading
/// normal `n` with the mirror direction `r`: what light sampling weighs its samples by.
///
/// The lobe draws d from the cosine lobe (density d·n / π) and returns w = normalize(x), x =
/// s·r + (1 − s)·d: a point of the sphere of radius 1 − s about s·r, seen from the origin.
/// The points of that sphere on the ray through w are at distances λ with |λw − s·r| = 1 − s,
/// the roots of λ² − 2λ s (w·r) + s² − (1 − s)² = 0: one positive root below s = ½, and for
/// s above it none or two (w within asin((1 − s) / s) of r). Each root's d = (λw − s·r) /
/// (1 − s) adds its density times the projection's Jacobian dω_d / dω_w = λ² / ((1 − s)²
/// |d·w|), and |d·w| = √disc / (1 − s), disc the quadratic's reduced discriminant (Pharr,
/// Jakob and Humphreys, PBRT 4th ed., §4.2.2, for the solid angle of a projected area
/// element). So the density is Σ (d·n) λ² / (π (1 − s) √disc) over the roots with d·n > 0
/// (material.wgsl: gloss_pdf).
pub fn gloss_pdf(w: Vec3A, n: Vec3A, r: Vec3A, s: f32) -> f32 {
    let t = 1.0 - s;
    let c = w.dot(r);
    // 1 − c² as |w × r|², which keeps its digits where w is near r.
    let disc = t * t - s * s * w.cross(r).length_squared();
    // At the cone's edge the density is infinite, and a drawn direction's disc may round to
    // just below 0 there: it keeps a large density (not 0, which would leave the lobe's
    // sample unweighed against light sampling).
    if disc.is_nan() || disc <= -DISC_ROUNDING {
        return 0.0;
    }
    let q = disc.max(DISC_ROUNDING * DISC_ROUNDING).sqrt();
    let mut sum = 0.0;
    for lambda in [s * c + q, s * c - q] {
        if lambda > 0.0 {
            let cos_d = (lambda * w - s * r).dot(n) / t;
            if cos_d > 0.0 {
                sum += cos_d * lambda * lambda;
            }
        }
    }
    sum / (std::f32::consts::PI * t * q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::sampling::basis;

    fn glossy(smoothness: f32) -> Material {
        Material {
            color: Vec3A::splat(0.5),
            specular_color: Vec3A::ONE,
            smoothness,
            absorption: 0.0,
            specular: 1.0,
            light: 0.0,
            ior: 1.5,
            light_slot: 0,
            metallic: 0.0,
            roughness: 0.0,
            pbr: false,
            transmission: 0.0,
            thin: false,
            attenuation: Vec3A::ZERO,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
        }
    }

    /// `gloss_pdf` is the density of `scatter_surface`'s glossy lobe: over directions w drawn
    /// by the lobe itself, the mean of 1[w in a cap] / pdf(w) is the cap's solid angle (the
    /// change of variables; where two draws map to one w, the density sums both). Caps about
    /// the mirror direction and off it, at normal and grazing incidence, smoothness below,
    /// at and above ½ (where each w within the lobe's cone has two preimages), within five
    /// standard errors of 200 000 draws (and 0.1 %, the grid's measure of the cap's part the
    /// lobe reaches). A density off by its Jacobian (λ² left out) or
    /// missing the second root fails it.
    #[test]
    fn the_glossy_density_is_the_lobes() {
        let n = Vec3A::Z;
        let cases = [
            (0.3, 0.0f32),
            (0.5, 0.6),
            (0.7, 0.0),
            (0.7, 1.1),
            (0.6, 1.4),
            (0.95, 0.5),
            (0.9, 1.4),
        ];
        for (s, incidence) in cases {
            let d = Vec3A::new(incidence.sin(), 0.0, -incidence.cos());
            let r = reflect(d, n);
            let m = glossy(s);
            // The lobe's cone about r (where s > ½), a cap about r inside it, and one off r
            // by a third of its width.
            let cone = if s > 0.5 { ((1.0 - s) / s).asin() } else { 0.6 };
            let [t, _, _] = basis(r);
            for (axis, half) in [
                (r, cone),
                (r, 0.5 * cone),
                ((r + 0.3 * cone * t).normalize(), 0.3 * cone),
            ] {
                // The cap's solid angle where the lobe reaches (at grazing incidence the
                // directions whose preimages all lie below the surface it does not): on a
                // 400 × 400 grid even in solid angle.
                let [a, b, _] = basis(axis);
                let k = 400;
                let reached = (0..k * k)
                    .filter(|i| {
                        let z = 1.0 - (i / k) as f32 / k as f32 * (1.0 - half.cos());
                        let phi = 2.0 * std::f32::consts::PI * (i % k) as f32 / k as f32;
                        let w = axis * z
                            + (1.0 - z * z).max(0.0).sqrt() * (a * phi.cos() + b * phi.sin());
                        gloss_pdf(w, n, r, s) > 0.0
                    })
                    .count();
                let want =
                    2.0 * std::f64::consts::PI * (1.0 - (half as f64).cos()) * reached as f64
                        / (k * k) as f64;
                let (mut sum, mut sum2) = (0.0f64, 0.0f64);
                let draws = 200_000;
                for i in 0..draws {
                    let sc = scatter_surface(&m, d, n, true, &mut Rng::new(7, i, 3));
                    if sc.dir.dot(axis) >= half.cos() {
                        let v = 1.0 / gloss_pdf(sc.dir, n, r, s) as f64;
                        sum += v;
                        sum2 += v * v;
                    }
                }
                let mean = sum / draws as f64;
                let se = ((sum2 / draws as f64 - mean * mean) / draws as f64).sqrt();
                assert!(
                    (mean - want).abs() < 5.0 * se + 1e-3 * want,
                    "s {s}, incidence {incidence}, cap {half}: {mean} against {want} (± {se})"
                );
            }
        }
    }
}
