//! Directions and points drawn from the random streams (shaders/common/sampling.wgsl).

use super::rng::Rng;
use glam::{Vec2, Vec3A};

pub const PI: f32 = std::f32::consts::PI;

pub use crate::scene::trig::sin_cos_turns;

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
