//! Sine and cosine, arc cosine and arc tangent in turns, as polynomials: the host's and the
//! native CPU tracer's, which its SIMD lanes repeat operation for operation (`cpu::lanes`),
//! so that a lane and the scalar loop agree bit for bit. libm's took a tenth of an HDR-lit
//! scene's time there, one call per lane. Each is within 3·10⁻⁷ of the exact value (tested);
//! the GPU uses WGSL's built-ins.

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// 1 / 2π.
pub const FRAC_1_TAU: f32 = 0.5 / PI;

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

/// Cephes' `asinf` polynomial (Moshier, Cephes Math Library 2.2, asinf.c), from the highest
/// power: asin x = x + x z P(z) for |x| ≤ ½, z = x².
#[allow(clippy::excessive_precision)] // Cephes' digits, as published
pub const ASIN: [f32; 5] = [
    4.216_319_904_8e-2,
    2.418_131_104_9e-2,
    4.547_002_599_8e-2,
    7.495_300_268_6e-2,
    1.666_675_242_2e-1,
];

/// Cephes' `atanf` polynomial (atanf.c), from the highest power: atan x = x + x z P(z) for
/// |x| ≤ tan π/8, z = x².
#[allow(clippy::excessive_precision)]
pub const ATAN: [f32; 4] = [
    8.053_744_495_38e-2,
    -1.387_768_560_32e-1,
    1.997_771_064_78e-1,
    -3.333_294_915_39e-1,
];

/// tan π/8: above it, atan a = π/4 + atan((a − 1)/(a + 1)).
pub const TAN_PI_8: f32 = 0.414_213_57;

/// asin x for |x| ≤ ½, given z = x² (`ASIN`).
#[inline(always)]
pub fn asin_poly(x: f32, z: f32) -> f32 {
    let [c4, c3, c2, c1, c0] = ASIN;
    ((((c4 * z + c3) * z + c2) * z + c1) * z + c0) * z * x + x
}

/// atan x for |x| ≤ tan π/8, given z = x² (`ATAN`).
#[inline(always)]
pub fn atan_poly(x: f32, z: f32) -> f32 {
    let [c3, c2, c1, c0] = ATAN;
    (((c3 * z + c2) * z + c1) * z + c0) * z * x + x
}

/// acos(y) / π for y in [-1, 1] (the map's v): π/2 − asin |y| up to ½, 2 asin √((1 − |y|)/2)
/// above (1 − |y| exact there), mirrored for y < 0.
#[inline(always)]
pub fn acos_over_pi(y: f32) -> f32 {
    let a = y.abs();
    let big = a > 0.5;
    let z = if big { 0.5 * (1.0 - a) } else { a * a };
    let x = if big { z.sqrt() } else { a };
    let p = asin_poly(x, z);
    let r = if big { 2.0 * p } else { FRAC_PI_2 - p };
    let r = if y < 0.0 { PI - r } else { r };
    r * std::f32::consts::FRAC_1_PI
}

/// atan2(y, x) / 2π, in [-½, ½]: the octant by |x| and |y|, atan of their ratio a ≤ 1
/// (reduced by π/4 above tan π/8), mirrored into the quadrant. 0 at the origin.
#[inline(always)]
pub fn atan2_turns(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let reduced = a > TAN_PI_8;
    let t = if reduced { (a - 1.0) / (a + 1.0) } else { a };
    let p = atan_poly(t, t * t);
    let r = if reduced { FRAC_PI_4 + p } else { p };
    let r = if ay > ax { FRAC_PI_2 - r } else { r };
    let r = if x < 0.0 { PI - r } else { r };
    let r = if y < 0.0 { -r } else { r };
    r * FRAC_1_TAU
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

    #[test]
    fn acos_over_pi_matches_libm() {
        let mut worst = 0.0f64;
        for k in -1_000_000..=1_000_000i32 {
            let y = k as f32 / 1_000_000.0;
            let want = (y as f64).acos() / std::f64::consts::PI;
            worst = worst.max((acos_over_pi(y) as f64 - want).abs());
        }
        for y in [
            -1.0,
            -0.5,
            -0.0,
            0.0,
            0.5,
            1.0,
            f32::EPSILON,
            1.0 - f32::EPSILON,
        ] {
            let want = (y as f64).acos() / std::f64::consts::PI;
            worst = worst.max((acos_over_pi(y) as f64 - want).abs());
        }
        assert!(worst < 2e-7, "worst error {worst:e}");
        assert_eq!(acos_over_pi(1.0), 0.0);
        assert_eq!(acos_over_pi(-1.0), 1.0);
    }

    #[test]
    fn atan2_turns_matches_libm_in_every_octant() {
        let mut worst = 0.0f64;
        for k in 0..2_000_000u32 {
            let phi = k as f64 / 2_000_000.0 * std::f64::consts::TAU;
            for r in [1.0f64, 1e-3, 7e4] {
                let (y, x) = ((r * phi.sin()) as f32, (r * phi.cos()) as f32);
                let want = (y as f64).atan2(x as f64) / std::f64::consts::TAU;
                let got = atan2_turns(y, x) as f64;
                // ±½ is one direction.
                let d = (got - want).abs();
                worst = worst.max(d.min((d - 1.0).abs()));
            }
        }
        assert!(worst < 2e-7, "worst error {worst:e}");
        assert_eq!(atan2_turns(0.0, 0.0), 0.0);
        assert_eq!(atan2_turns(0.0, 1.0), 0.0);
        assert_eq!(atan2_turns(1.0, 0.0), 0.25);
        assert_eq!(atan2_turns(-1.0, 0.0), -0.25);
    }
}
