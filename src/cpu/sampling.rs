//! Directions and points drawn from the random streams (shaders/common/sampling.wgsl).

use super::rng::Rng;
use glam::{Vec2, Vec3A};

pub const PI: f32 = std::f32::consts::PI;

/// Uniform on the unit sphere (Archimedes: z uniform in [-1, 1], azimuth uniform).
#[inline(always)]
pub fn random_unit_vector(rng: &mut Rng) -> Vec3A {
    let (u, v) = rng.rand2();
    let z = 1.0 - 2.0 * u;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = sin_cos_turns(v);
    Vec3A::new(r * c, r * s, z)
}

/// Uniform in the unit disk (polar mapping, r = sqrt(u)).
#[inline]
pub fn random_in_disk(rng: &mut Rng) -> Vec2 {
    let (u, v) = rng.rand2();
    let r = u.sqrt();
    let (s, c) = sin_cos_turns(v);
    Vec2::new(r * c, r * s)
}

/// (sin 2πt, cos 2πt) for t in [0, 1], branch-free: the quadrant by rounding 4t, then
/// Taylor polynomials on [-π/4, π/4] (truncation below 3·10⁻⁸), rotated into the quadrant.
/// libm's `sin_cos` took 5–7 % of the tracer's time.
#[inline(always)]
pub fn sin_cos_turns(t: f32) -> (f32, f32) {
    // Rounding by truncation (t ≥ 0): `round` is a libm call below SSE4.1.
    let q = (4.0 * t + 0.5) as i32 as f32;
    let x = 2.0 * PI * (t - 0.25 * q);
    let x2 = x * x;
    let s =
        x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 / 362880.0))));
    let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0))));
    // Quadrant k: (sin, cos) is (s, c), (c, −s), (−s, −c) or (−c, s).
    let k = q as u32;
    let (a, b) = if k & 1 == 0 { (s, c) } else { (c, s) };
    (
        f32::from_bits(a.to_bits() ^ (k & 2) << 30),
        f32::from_bits(b.to_bits() ^ (k.wrapping_add(1) & 2) << 30),
    )
}

/// normalize(v), or `fallback` when v is too short to have a direction.
#[inline]
pub fn normalize_or(v: Vec3A, fallback: Vec3A) -> Vec3A {
    let l2 = v.dot(v);
    if l2 < 1e-12 {
        return fallback;
    }
    v / l2.sqrt()
}

/// An orthonormal basis around a unit vector, as columns (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 6(1), 2017).
#[inline]
pub fn basis(n: Vec3A) -> [Vec3A; 3] {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    [
        Vec3A::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3A::new(b, s + n.y * n.y * a, -n.y),
        n,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_turns_matches_libm() {
        let mut worst = 0.0f64;
        for k in 0..=1_000_000u32 {
            let t = k as f32 / 1_000_000.0;
            let (s, c) = sin_cos_turns(t);
            let phi = std::f64::consts::TAU * t as f64;
            worst = worst.max(
                (s as f64 - phi.sin())
                    .abs()
                    .max((c as f64 - phi.cos()).abs()),
            );
        }
        assert!(worst < 3e-7, "worst error {worst:e}");
    }
}
