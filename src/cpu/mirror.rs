//! The map's light as a perfect mirror sphere reflects it onto a point (next-event estimation
//! through a mirror ball, docs/MODEL-NOTES.md "The map in a mirror ball"): where on the
//! sphere a point sees a direction's light reflected, and how much the sphere spreads it.
//! Twin: shaders/common/mirror.wgsl (tests/twins.rs keeps their functions paired).
//!
//! The reflection point is the specular vertex that manifold next-event estimation solves for
//! (Hanika, Droske & Fascione, "Manifold Next Event Estimation", EGSR 2015); on a sphere it
//! lies in the plane of the centre, the point and the direction, one unknown angle, found by
//! safeguarded Newton steps. The spread is the reflected ray tube's, from Coddington's
//! focal lengths of a convex mirror (Born & Wolf, "Principles of Optics", §4.6; Kravtsov &
//! Orlov, "Caustics, Catastrophes and Wave Fields", §2.2): a distant source's image seen at
//! distance d from the mirror subtends `spread` times its own solid angle.

use super::sampling::basis;
use crate::scene::trig::{FRAC_1_TAU, acos_over_pi, atan2_turns, sin_cos_turns};
use glam::Vec3A;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// The most Newton steps of `point`: a step the bracket refuses halves it instead, and near
/// the root the steps converge quadratically; it stops at a step under 10⁻⁶ radians.
const STEPS: u32 = 8;

/// Where a point sees light from a direction reflected by a mirror sphere.
#[derive(Clone, Copy, Debug)]
pub struct Reflection {
    /// Unit direction from the point to the reflection point.
    pub dir: Vec3A,
    /// Distance from the point to the reflection point.
    pub dist: f32,
    /// The sphere's outward normal at the reflection point.
    pub normal: Vec3A,
    /// Cosine of the angle of incidence (the normal against the light's direction).
    pub cos_i: f32,
}

/// The point of the mirror sphere (centre `c`, radius `r` > 0) at which `p` sees light that
/// arrives from direction `w` (unit, towards the light) reflected, or None where there is
/// none: `p` inside the sphere, or the light behind it as `p` sees it.
///
/// The normal n at the point bisects w and the direction v from the point to p. In the plane
/// of e1 (from the centre to p, at distance D) and w (at angle α from e1), n = (cos φ, sin φ),
/// and the law of reflection is h(φ) = sin(α − φ) − D sin φ / L(φ) = 0, L the distance from
/// the point to p: the sines of the angles from n to w and from v to n. Where the point is
/// lit (|α − φ| < π/2) and p sees it (D cos φ > r), h′ < 0, so the root is unique, in
/// [max(0, α − π/2), min(α, acos(r / D))], where h goes from ≥ 0 to ≤ 0. Newton steps kept in
/// that bracket find it; (cos φ, sin φ) turns by each step through polynomials, and the start's
/// angles are `scene::trig`'s polynomials too, so that the solver calls no libm function (and
/// the CPU tracer's lanes repeat it bit for bit: `cpu::lanes`).
pub fn point(p: Vec3A, c: Vec3A, r: f32, w: Vec3A) -> Option<Reflection> {
    let pc = p - c;
    let d = pc.length();
    if d.is_nan() || d <= r * 1.0001 {
        return None;
    }
    let e1 = pc / d;
    let ca = w.dot(e1).clamp(-1.0, 1.0);
    let perp = w - ca * e1;
    let sa = perp.length();
    // w along e1: the root is φ = 0, and any e2 serves.
    let e2 = if sa > 1e-7 { perp / sa } else { basis(e1)[0] };
    let alpha = atan2_turns(sa, ca) * TAU;
    let phi_max = acos_over_pi(r / d) * PI;
    if alpha.is_nan() || alpha >= phi_max + FRAC_PI_2 {
        return None;
    }
    let (mut lo, mut hi) = ((alpha - FRAC_PI_2).max(0.0), alpha.min(phi_max));
    // Far from the sphere v is nearly e1 and φ nearly α / 2.
    let mut phi = (0.5 * alpha).clamp(lo, hi);
    let (mut sn, mut cs) = sin_cos_turns(phi * FRAC_1_TAU);
    for _ in 0..STEPS {
        let l2 = d * d - 2.0 * d * r * cs + r * r;
        let l = l2.sqrt();
        let h = (sa * cs - ca * sn) - d * sn / l;
        // h′ = −cos(α − φ) − D (D cos φ − r)(D − r cos φ) / L³.
        let slope = -(ca * cs + sa * sn) - d * (d * cs - r) * (d - r * cs) / (l2 * l);
        if h < 0.0 {
            hi = phi;
        } else {
            lo = phi;
        }
        let next = phi - h / slope;
        // (Inclusive: at the root itself h is 0, the bracket's end is φ, and φ stays.)
        let to = if next >= lo && next <= hi {
            next
        } else {
            0.5 * (lo + hi)
        };
        let step = to - phi;
        let (s1, c1) = turn(step);
        (sn, cs) = (sn * c1 + cs * s1, cs * c1 - sn * s1);
        let norm = 1.0 / (sn * sn + cs * cs).sqrt();
        (sn, cs) = (sn * norm, cs * norm);
        phi = to;
        if step.abs() < 1e-6 {
            break;
        }
    }
    let normal = cs * e1 + sn * e2;
    let to = c + r * normal - p;
    let dist = to.length();
    let dir = to / dist;
    let cos_i = normal.dot(w);
    if !(cos_i > 0.0 && normal.dot(dir) < 0.0 && dist > 0.0) {
        return None;
    }
    Some(Reflection {
        dir,
        dist,
        normal,
        cos_i,
    })
}

/// (sin x, cos x) for |x| ≤ π/2 by their Taylor polynomials to x⁹ and x⁸ (errors below
/// 4·10⁻⁶ there, far less for the small steps near a root, which Newton's next step corrects).
#[inline(always)]
fn turn(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let [s6, s20, s42, s72] = TURN_SIN;
    let [c2, c12, c30, c56] = TURN_COS;
    let s = x * (1.0 - x2 * s6 * (1.0 - x2 * s20 * (1.0 - x2 * s42 * (1.0 - x2 * s72))));
    let c = 1.0 - x2 * c2 * (1.0 - x2 * c12 * (1.0 - x2 * c30 * (1.0 - x2 * c56)));
    (s, c)
}

/// `turn`'s factors, 1/6, 1/20, 1/42, 1/72 for the sine and 1/2, 1/12, 1/30, 1/56 for the
/// cosine, multiplied rather than divided by: seven divisions a Newton step were most of the
/// solve's time in the CPU tracer's lanes (BENCHMARKS.md, "The walk below the root").
pub(crate) const TURN_SIN: [f32; 4] = [1.0 / 6.0, 1.0 / 20.0, 1.0 / 42.0, 1.0 / 72.0];
pub(crate) const TURN_COS: [f32; 4] = [1.0 / 2.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 56.0];

/// The solid angle a point at distance `dist` from a mirror sphere of radius `r` sees a
/// distant source's reflection subtend, per unit solid angle of the source, at incidence
/// cos θ = `cos_i`: f_t f_s / ((d + f_t)(d + f_s)) with Coddington's focal lengths of the
/// convex mirror, tangential f_t = r cos θ / 2 and sagittal f_s = r / (2 cos θ). 1 at the
/// mirror, r² / (4 d²) far from it (a mirror ball reflects a parallel beam evenly into every
/// direction); written without f_s so that grazing incidence gives 0, not ∞ / ∞.
pub fn spread(r: f32, dist: f32, cos_i: f32) -> f32 {
    (0.25 * r * r * cos_i) / ((dist + 0.5 * r * cos_i) * (dist * cos_i + 0.5 * r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::lcg::Lcg;

    /// The solved point obeys the law of reflection (the normal bisects the light's direction
    /// and the direction back to p: the cosine between them above 1 − 1e-5, within 0.26°),
    /// lies on the sphere, and faces both; and a light behind the sphere has none.
    #[test]
    fn the_point_reflects_the_light_to_p() {
        let mut rng = Lcg(7);
        let (mut found, mut none) = (0, 0);
        for _ in 0..20000 {
            let c = Vec3A::new(rng.f(), rng.f(), rng.f()) * 4.0 - 2.0;
            let r = 0.05 + rng.f();
            let p = c + rng.unit() * r * (1.01 + 6.0 * rng.f());
            let w = rng.unit();
            let Some(x) = point(p, c, r, w) else {
                none += 1;
                continue;
            };
            found += 1;
            let at = p + x.dir * x.dist;
            assert!(
                ((at - c).length() - r).abs() < 1e-4 * (1.0 + r),
                "off the sphere"
            );
            let back = -x.dir;
            let bisector = (w + back).normalize();
            assert!(
                bisector.dot(x.normal) > 1.0 - 1e-5,
                "p {p} c {c} r {r} w {w}: {} from the bisector",
                bisector.dot(x.normal).acos()
            );
            assert!(x.cos_i > 0.0 && back.dot(x.normal) > 0.0);
            // The same light arrives at p by the mirror's reflection of the ray to the point.
            let reflected = x.dir - 2.0 * x.dir.dot(x.normal) * x.normal;
            assert!(reflected.dot(w) > 1.0 - 2e-5);
        }
        assert!(found > 10000 && none > 300, "found {found}, none {none}");
        // Straight behind the sphere: no reflection; straight behind p: the nearest point.
        let (c, p) = (Vec3A::ZERO, Vec3A::new(0.0, 0.0, 3.0));
        assert!(point(p, c, 1.0, -Vec3A::Z).is_none());
        let x = point(p, c, 1.0, Vec3A::Z).unwrap();
        assert!((x.dist - 2.0).abs() < 1e-6 && (x.cos_i - 1.0).abs() < 1e-6);
        // Inside the sphere: none.
        assert!(point(Vec3A::new(0.0, 0.0, 0.5), c, 1.0, Vec3A::Z).is_none());
    }

    /// `spread` is the ratio of solid angles the solver's own map from light directions to
    /// directions at p gives, measured by finite differences (to 1 %), near the sphere and far
    /// from it, at small and grazing incidence; and its limits, 1 at the mirror and r²/(4d²)
    /// far away.
    #[test]
    fn the_spread_is_the_jacobian_of_the_reflection() {
        let mut rng = Lcg(11);
        let mut checked = 0;
        for _ in 0..4000 {
            let c = Vec3A::ZERO;
            let r = 0.5;
            let p = rng.unit() * r * (1.05 + 8.0 * rng.f());
            let w = rng.unit();
            let Some(x) = point(p, c, r, w) else {
                continue;
            };
            if x.cos_i < 0.05 {
                continue;
            }
            let [t1, t2] = {
                let t1 = w.any_orthonormal_vector();
                [t1, w.cross(t1)]
            };
            let h = 2e-3;
            let dir_at = |dw: Vec3A| point(p, c, r, (w + dw).normalize()).map(|y| y.dir);
            let (Some(a1), Some(b1), Some(a2), Some(b2)) = (
                dir_at(t1 * h),
                dir_at(-t1 * h),
                dir_at(t2 * h),
                dir_at(-t2 * h),
            ) else {
                continue;
            };
            let (u, v) = (a1 - b1, a2 - b2);
            let source = (2.0 * h) * (2.0 * h);
            let seen = u.cross(v).dot(x.dir).abs();
            let k = spread(r, x.dist, x.cos_i);
            assert!(
                (seen / source / k - 1.0).abs() < 0.01,
                "d {} cos {}: measured {} against {k}",
                x.dist,
                x.cos_i,
                seen / source
            );
            checked += 1;
        }
        assert!(checked > 1000, "{checked}");
        assert!((spread(1.0, 0.0, 0.7) - 1.0).abs() < 1e-6);
        let far = spread(0.5, 1000.0, 0.3) / (0.25 * 0.25 / 1e6);
        assert!((far - 1.0).abs() < 1e-3, "{far}");
        assert_eq!(spread(0.5, 2.0, 0.0), 0.0);
    }
}
