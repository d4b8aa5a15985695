//! The map in a mirror ball in lanes: `cpu::mirror`'s reflection point (its safeguarded
//! Newton steps, every lane's to its own end) and spread, operation for operation, so that
//! each lane's values are the scalar solver's bit for bit (tested here on their own, and with
//! the paths, `lanes_trace_the_scalar_paths_bit_for_bit`). The start's angles are the scalar
//! solver's polynomials (`trig`).

use super::trig::{acos_over_pi, atan2_turns, sin_cos_turns};
use crate::cpu::mirror::{TURN_COS, TURN_SIN};
use crate::cpu::sampling::basis;
use crate::cpu::simd::{F, Isa, M, Make, V3, dot, lanes_of, rows};
use crate::scene::trig::FRAC_1_TAU;
use glam::Vec3A;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// `mirror::point`'s most Newton steps.
const STEPS: u32 = 8;

/// `mirror::Reflection` in lanes, and the lanes that have one (`found`).
pub(super) struct Reflection<S: Isa> {
    pub dir: V3<S>,
    pub dist: F<S>,
    pub normal: V3<S>,
    pub cos_i: F<S>,
    pub found: M<S>,
}

/// `mirror::point` for the lanes of `lanes`: where points `p` see light from directions `w`
/// reflected by mirror spheres of centres `c` and radii `r`.
#[inline(always)]
pub(super) fn point<S: Isa>(
    s: S,
    (p, c, r): (V3<S>, V3<S>, F<S>),
    w: V3<S>,
    lanes: M<S>,
) -> Reflection<S> {
    let (zero, one) = (s.zero(), s.splat(1.0));
    let pc: V3<S> = each!(|k| p[k] - c[k]);
    let d = dot(pc, pc).sqrt();
    // (NaN: none, as `d.is_nan()`.)
    let live = lanes & d.gt(r * s.splat(1.0001));
    let e1: V3<S> = each!(|k| pc[k] / d);
    let cosine = dot(w, e1);
    // `clamp(−1, 1)`, which keeps a NaN where max and min would not: such a lane has none.
    let live = live & cosine.cmp::<{ std::arch::x86_64::_CMP_ORD_Q }>(cosine);
    let ca = cosine.max(s.splat(-1.0)).min(one);
    let perp: V3<S> = each!(|k| w[k] - ca * e1[k]);
    let sa = dot(perp, perp).sqrt();
    let mut e2: V3<S> = each!(|k| perp[k] / sa);
    // w along e1: the root is φ = 0, and any e2 serves (the scalar `basis`, lane by lane).
    let along = live.without(sa.gt(s.splat(1e-7)));
    if along.any() {
        let (mut e2_r, e1_r) = (rows(e2), rows(e1));
        for k in lanes_of(along.bits()) {
            let e = basis(Vec3A::new(e1_r[0][k], e1_r[1][k], e1_r[2][k]))[0];
            (e2_r[0][k], e2_r[1][k], e2_r[2][k]) = (e.x, e.y, e.z);
        }
        e2 = each!(|k| s.load(&e2_r[k]));
    }
    let alpha = atan2_turns(s, sa, ca) * s.splat(TAU);
    let phi_max = acos_over_pi(s, r / d) * s.splat(PI);
    let quarter = s.splat(FRAC_PI_2);
    // (NaN: none, as `alpha.is_nan()`.)
    let live = live & alpha.lt(phi_max + quarter);
    let (mut lo, mut hi) = ((alpha - quarter).max(zero), alpha.min(phi_max));
    let mut phi = (s.splat(0.5) * alpha).max(lo).min(hi);
    let (mut sn, mut cs) = sin_cos_turns(s, phi * s.splat(FRAC_1_TAU));
    let (two, half, tiny) = (s.splat(2.0), s.splat(0.5), s.splat(1e-6));
    let mut going = live;
    for _ in 0..STEPS {
        if !going.any() {
            break;
        }
        let l2 = (d * d - ((two * d) * r) * cs) + r * r;
        let l = l2.sqrt();
        let h = (sa * cs - ca * sn) - (d * sn) / l;
        let slope = -(ca * cs + sa * sn) - ((d * (d * cs - r)) * (d - r * cs)) / (l2 * l);
        let below = h.lt(zero);
        hi = hi.blend(phi, going & below);
        lo = lo.blend(phi, going.without(below));
        let next = phi - h / slope;
        // (Inclusive: at the root itself h is 0, the bracket's end is φ, and φ stays.)
        let to = (half * (lo + hi)).blend(next, next.ge(lo) & next.le(hi));
        let step = to - phi;
        let (s1, c1) = turn(s, step);
        let (sn1, cs1) = (sn * c1 + cs * s1, cs * c1 - sn * s1);
        let norm = one / (sn1 * sn1 + cs1 * cs1).sqrt();
        sn = sn.blend(sn1 * norm, going);
        cs = cs.blend(cs1 * norm, going);
        phi = phi.blend(to, going);
        going = going.without(step.abs().lt(tiny));
    }
    let normal: V3<S> = each!(|k| cs * e1[k] + sn * e2[k]);
    let to: V3<S> = each!(|k| (c[k] + r * normal[k]) - p[k]);
    let dist = dot(to, to).sqrt();
    let dir = each!(|k| to[k] / dist);
    let cos_i = dot(normal, w);
    let found = live & cos_i.gt(zero) & dot(normal, dir).lt(zero) & dist.gt(zero);
    Reflection {
        dir,
        dist,
        normal,
        cos_i,
        found,
    }
}

/// `mirror::turn` in lanes: (sin x, cos x) by their Taylor polynomials.
#[inline(always)]
fn turn<S: Isa>(s: S, x: F<S>) -> (F<S>, F<S>) {
    let one = s.splat(1.0);
    let x2 = x * x;
    let [s6, s20, s42, s72] = TURN_SIN;
    let (s6, s20, s42, s72) = (s.splat(s6), s.splat(s20), s.splat(s42), s.splat(s72));
    let [c2, c12, c30, c56] = TURN_COS;
    let (c2, c12, c30, c56) = (s.splat(c2), s.splat(c12), s.splat(c30), s.splat(c56));
    let sin = x * (one - (x2 * s6) * (one - (x2 * s20) * (one - (x2 * s42) * (one - x2 * s72))));
    let cos = one - (x2 * c2) * (one - (x2 * c12) * (one - (x2 * c30) * (one - x2 * c56)));
    (sin, cos)
}

/// `mirror::spread` in lanes.
#[inline(always)]
pub(super) fn spread<S: Isa>(s: S, r: F<S>, dist: F<S>, cos_i: F<S>) -> F<S> {
    let half_r = s.splat(0.5) * r;
    ((s.splat(0.25) * r) * r * cos_i) / ((dist + half_r * cos_i) * (dist * cos_i + half_r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::lcg::Lcg;
    use crate::cpu::mirror;
    use crate::cpu::simd::{Avx2, Avx512, MAX_LANES};

    fn row<S: Isa>(f: F<S>) -> [f32; MAX_LANES] {
        let mut r = [0.0; MAX_LANES];
        f.store(&mut r);
        r
    }

    fn load3<S: Isa>(s: S, v: &[Vec3A]) -> V3<S> {
        let mut r = [[0.0; MAX_LANES]; 3];
        for (k, x) in v.iter().enumerate() {
            (r[0][k], r[1][k], r[2][k]) = (x.x, x.y, x.z);
        }
        [s.load(&r[0]), s.load(&r[1]), s.load(&r[2])]
    }

    /// 20 000 cases in lanes against `mirror::point` and `mirror::spread`, bit for bit: which
    /// lanes have a point, and its direction, distance, normal, incidence and spread. The
    /// cases include points inside the sphere, lights straight behind and straight ahead
    /// (the solver's fallback frame), and NaN directions.
    fn agree<S: Isa>(s: S) {
        let mut rng = Lcg(5);
        let n = S::N;
        let (mut found, mut none) = (0, 0);
        for round in 0..20_000 / n {
            let mut ps = vec![];
            let mut cs = vec![];
            let mut rs = [0.0; MAX_LANES];
            let mut ws = vec![];
            for (k, radius) in rs.iter_mut().enumerate().take(n) {
                let c = Vec3A::new(rng.f(), rng.f(), rng.f()) * 4.0 - 2.0;
                let r = 0.05 + rng.f();
                let p = c + rng.unit() * r * (0.9 + 6.0 * rng.f());
                let w = match (round + k) % 97 {
                    0 => (p - c).normalize(),
                    1 => (c - p).normalize(),
                    2 => Vec3A::NAN,
                    _ => rng.unit(),
                };
                ps.push(p);
                cs.push(c);
                ws.push(w);
                *radius = r;
            }
            let got = point(
                s,
                (load3(s, &ps), load3(s, &cs), s.load(&rs)),
                load3(s, &ws),
                s.mask((1 << n) - 1),
            );
            let k_spread = row(spread(s, s.load(&rs), got.dist, got.cos_i));
            let (dir, normal) = (rows(got.dir), rows(got.normal));
            let (dist, cos_i) = (row(got.dist), row(got.cos_i));
            for k in 0..n {
                let want = mirror::point(ps[k], cs[k], rs[k], ws[k]);
                assert_eq!(got.found.bits() >> k & 1 == 1, want.is_some(), "case {k}");
                let Some(x) = want else {
                    none += 1;
                    continue;
                };
                found += 1;
                let v = |a: &[[f32; MAX_LANES]; 3]| [a[0][k], a[1][k], a[2][k]].map(f32::to_bits);
                assert_eq!(v(&dir), x.dir.to_array().map(f32::to_bits));
                assert_eq!(v(&normal), x.normal.to_array().map(f32::to_bits));
                assert_eq!(dist[k].to_bits(), x.dist.to_bits());
                assert_eq!(cos_i[k].to_bits(), x.cos_i.to_bits());
                let sp = mirror::spread(rs[k], x.dist, x.cos_i);
                assert_eq!(k_spread[k].to_bits(), sp.to_bits());
            }
        }
        assert!(found > 8000 && none > 1000, "found {found}, none {none}");
    }

    #[test]
    fn lanes_solve_for_the_mirror_point_as_the_scalar_code() {
        if let Some(s) = Avx2::new() {
            agree(s);
        }
        if let Some(s) = Avx512::new() {
            agree(s);
        }
    }
}
