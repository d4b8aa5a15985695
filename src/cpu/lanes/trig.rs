//! `scene::trig` in lanes: the same polynomials and the same reductions, operation for
//! operation, so that a lane's value is the scalar function's bit for bit (tested).

use crate::cpu::simd::{F, Isa, Make};
use crate::scene::trig::{ASIN, ATAN, FRAC_1_TAU, TAN_PI_8};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

/// `trig::sin_cos_turns` in lanes: the same polynomials, the same quadrant turns.
#[inline(always)]
pub(super) fn sin_cos_turns<S: Isa>(s: S, t: F<S>) -> (F<S>, F<S>) {
    let qi = (s.splat(4.0) * t + s.splat(0.5)).truncate();
    let q = qi.to_float();
    let x = s.splat(2.0 * PI) * (t - s.splat(0.25) * q);
    let x2 = x * x;
    // x * (1 + x2 * (-1/6 + x2 * (1/120 + x2 * (-1/5040 + x2 / 362880))))
    let sin = x
        * (s.splat(1.0)
            + x2 * (s.splat(-1.0 / 6.0)
                + x2 * (s.splat(1.0 / 120.0)
                    + x2 * (s.splat(-1.0 / 5040.0) + x2 / s.splat(362880.0)))));
    // 1 + x2 * (-1/2 + x2 * (1/24 + x2 * (-1/720 + x2 * (1/40320))))
    let cos = s.splat(1.0)
        + x2 * (s.splat(-0.5)
            + x2 * (s.splat(1.0 / 24.0)
                + x2 * (s.splat(-1.0 / 720.0) + x2 * s.splat(1.0 / 40320.0))));
    let (one, two) = (s.int(1), s.int(2));
    let odd = qi.and(one).eq(one);
    let a = sin.blend(cos, odd);
    let b = cos.blend(sin, odd);
    let flip_a = qi.and(two).shl30();
    let flip_b = (qi + one).and(two).shl30();
    (
        a.to_bits().xor(flip_a).float_of_bits(),
        b.to_bits().xor(flip_b).float_of_bits(),
    )
}

/// `trig::asin_poly` in lanes.
#[inline(always)]
fn asin_poly<S: Isa>(s: S, x: F<S>, z: F<S>) -> F<S> {
    let [c4, c3, c2, c1, c0] = ASIN;
    ((((s.splat(c4) * z + s.splat(c3)) * z + s.splat(c2)) * z + s.splat(c1)) * z + s.splat(c0))
        * z
        * x
        + x
}

/// `trig::atan_poly` in lanes.
#[inline(always)]
fn atan_poly<S: Isa>(s: S, x: F<S>, z: F<S>) -> F<S> {
    let [c3, c2, c1, c0] = ATAN;
    (((s.splat(c3) * z + s.splat(c2)) * z + s.splat(c1)) * z + s.splat(c0)) * z * x + x
}

/// `trig::acos_over_pi` in lanes (y not NaN: a NaN lane's value is not the scalar one's).
#[inline(always)]
pub(super) fn acos_over_pi<S: Isa>(s: S, y: F<S>) -> F<S> {
    let one = s.splat(1.0);
    let a = y.abs();
    let big = a.gt(s.splat(0.5));
    let z = (a * a).blend(s.splat(0.5) * (one - a), big);
    let x = a.blend(z.sqrt(), big);
    let p = asin_poly(s, x, z);
    let r = (s.splat(FRAC_PI_2) - p).blend(s.splat(2.0) * p, big);
    let r = r.blend(s.splat(PI) - r, y.lt(s.zero()));
    r * s.splat(FRAC_1_PI)
}

/// `trig::atan2_turns` in lanes (x and y not NaN, as above).
#[inline(always)]
pub(super) fn atan2_turns<S: Isa>(s: S, y: F<S>, x: F<S>) -> F<S> {
    let (zero, one) = (s.zero(), s.splat(1.0));
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    let a = (lo / hi).keep(hi.gt(zero));
    let reduced = a.gt(s.splat(TAN_PI_8));
    let t = a.blend((a - one) / (a + one), reduced);
    let p = atan_poly(s, t, t * t);
    let r = p.blend(s.splat(FRAC_PI_4) + p, reduced);
    let r = r.blend(s.splat(FRAC_PI_2) - r, ay.gt(ax));
    let r = r.blend(s.splat(PI) - r, x.lt(zero));
    let r = r.blend(-r, y.lt(zero));
    r * s.splat(FRAC_1_TAU)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::simd::{Avx2, Avx512, MAX_LANES, Row};
    use crate::scene::trig;

    /// Each lane's value against the scalar function's, bit for bit, over `xs` (paired with
    /// `ys` for atan2).
    fn agree<S: Isa>(s: S, xs: &[f32], ys: &[f32]) {
        let n = S::N;
        for (xc, yc) in xs.chunks(n).zip(ys.chunks(n)) {
            let (mut x, mut y) = ([0.0; MAX_LANES], [0.0; MAX_LANES]);
            x[..xc.len()].copy_from_slice(xc);
            y[..yc.len()].copy_from_slice(yc);
            let (lx, ly) = (s.load(&x), s.load(&y));
            let out = |f: F<S>| {
                let mut r: Row = [0.0; MAX_LANES];
                f.store(&mut r);
                r
            };
            let acos = out(acos_over_pi(s, lx));
            let atan = out(atan2_turns(s, ly, lx));
            let t = out(lx.abs());
            let (sin, cos) = sin_cos_turns(s, s.load(&t));
            let (sin, cos) = (out(sin), out(cos));
            for k in 0..xc.len() {
                let bits = |a: f32| a.to_bits();
                if x[k].abs() <= 1.0 {
                    let want = trig::acos_over_pi(x[k]);
                    assert_eq!(bits(acos[k]), bits(want), "acos {:e} in {n} lanes", x[k]);
                    let (ws, wc) = trig::sin_cos_turns(t[k]);
                    assert_eq!(
                        (bits(sin[k]), bits(cos[k])),
                        (bits(ws), bits(wc)),
                        "{:e}",
                        t[k]
                    );
                }
                let want = trig::atan2_turns(y[k], x[k]);
                assert_eq!(bits(atan[k]), bits(want), "atan2({:e}, {:e})", y[k], x[k]);
            }
        }
    }

    #[test]
    fn lanes_compute_the_scalar_trigonometry_bit_for_bit() {
        // A grid over [-1, 1], the reductions' edges and their neighbours, and pairs in every
        // octant at several scales, zeros and equal magnitudes included.
        let mut xs: Vec<f32> = (-20_000..=20_000).map(|k| k as f32 / 20_000.0).collect();
        for e in [0.5f32, 1.0, trig::TAN_PI_8, 0.25, 0.75] {
            for v in [e, -e] {
                xs.extend([
                    v,
                    f32::from_bits(v.to_bits() - 1),
                    f32::from_bits(v.to_bits() + 1),
                ]);
            }
        }
        xs.extend([0.0, -0.0, f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-30]);
        let mut ys: Vec<f32> = xs.iter().rev().copied().collect();
        for k in 0..4096 {
            let phi = k as f32 / 4096.0 * std::f32::consts::TAU;
            for r in [1.0, 3e-3, 5e4] {
                xs.push(r * phi.cos());
                ys.push(r * phi.sin());
            }
        }
        xs.extend([0.0, 1.0, -1.0, 2.0, -2.0, 0.0]);
        ys.extend([0.0, 1.0, -1.0, -2.0, 2.0, -0.0]);
        if let Some(s) = Avx2::new() {
            agree(s, &xs, &ys);
        }
        if let Some(s) = Avx512::new() {
            agree(s, &xs, &ys);
        }
    }
}
