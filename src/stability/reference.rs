//! Double-precision references for the tracer's single-ray operations (the same formulas as
//! the WGSL, evaluated in f64), to measure the float error of the GPU's results.

use glam::DVec3;

/// Nearest positive hit distance of a unit-direction ray with a sphere, in f64 with the
/// stable forms of Ray Tracing Gems ch. 7 (exact to f64 precision).
pub fn sphere_hit(origin: DVec3, dir: DVec3, center: DVec3, radius: f64) -> Option<f64> {
    let r = radius.abs();
    let f = origin - center;
    let b = f.dot(dir);
    let l = f - b * dir;
    let disc = (r - l.length()) * (r + l.length());
    if disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - r * r;
    let q = -b - disc.sqrt().copysign(b);
    if q == 0.0 {
        return None;
    }
    let (t0, t1) = (c / q, q);
    let (near, far) = (t0.min(t1), t0.max(t1));
    [near, far].into_iter().find(|t| *t > 0.0)
}

/// Ray/parallelogram: the hit distance if the plane hit lies inside.
pub fn quad_hit(origin: DVec3, dir: DVec3, q: DVec3, u: DVec3, v: DVec3) -> Option<f64> {
    let n = u.cross(v);
    let denom = n.dot(dir);
    if denom == 0.0 {
        return None;
    }
    let t = n.dot(q - origin) / denom;
    if t <= 0.0 {
        return None;
    }
    let p = origin + t * dir - q;
    let w = n / n.dot(n);
    let (a, b) = (w.dot(p.cross(v)), w.dot(u.cross(p)));
    ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
}

pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// MODEL.md's refraction (n facing d): r_perp = ratio·(d + cos·n), r_par = -√|1 - |r_perp|²|·n.
pub fn refract(d: DVec3, n: DVec3, ratio: f64) -> DVec3 {
    let cos = (-d.dot(n)).min(1.0);
    let perp = ratio * (d + cos * n);
    perp - (1.0 - perp.length_squared()).abs().sqrt() * n
}

/// Schlick's reflectance with r0 = ((1 - ratio)/(1 + ratio))².
pub fn schlick(cos: f64, ratio: f64) -> f64 {
    let r0 = ((1.0 - ratio) / (1.0 + ratio)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos).powi(5)
}
