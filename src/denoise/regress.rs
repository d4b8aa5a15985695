//! The second stage: each half's pixel made the intercept of a weighted first-order
//! regression of its neighbours' radiance on the guides and the position (Bitterli, Rousselle,
//! Moon, Iglesias-Guitián, Adler, Mitchell, Jarosz & Novák, "Nonlinearly Weighted First-order
//! Regression for Denoising Monte Carlo Renderings", EGSR 2016; Moon, Carr & Yoon, "Adaptive
//! Rendering based on Weighted Local Regression", TOG 2014). A pixel that straddles two
//! surfaces has radiance and guides that are both the mix of the two by coverage, so a
//! linear model in the guides predicts it where the à-trous filter, stopped by its mixed
//! guides, finds few pixels like it. The weights come from the half's own à-trous output
//! (never from the other half, so the estimator of `super` stays unbiased), and the
//! radiance regressed is the half's own, its fireflies clamped (`atrous::clamp_outliers`).
//!
//! Chosen by measurement against the other weights and filters tried (BENCHMARKS.md,
//! "Denoising, second filter"): at 64 spp at 120×76 the shown image's true relative RMSE fell
//! from 3.50, 3.31, 3.96 % to 2.75, 2.93, 3.68 % (cornell, showcase, weekend), at 256 spp from
//! 2.56, 1.84, 1.88 % to 2.06, 1.68, 1.84 %.

use super::atrous::{Guide, Texel, exp_neg, luminance, texels};
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// Neighbours each way of the regression's window (5×5).
pub const RADIUS: isize = 2;
/// The spatial weight's standard deviation, in pixels.
const SPATIAL_SIGMA: f32 = 1.5;
/// The luminance weight's scale, in standard deviations of the difference of two pixels.
const LUMINANCE_SIGMA: f32 = 1.0;
/// Keeps the luminance weight finite where the noise is zero.
const LUMINANCE_EPSILON: f32 = 1e-10;
/// Taps weighing less are left out (the pixel itself weighs 1).
const MIN_WEIGHT: f32 = 1e-12;
/// Ridge added to the diagonal of every term but the intercept, relative to the weights' sum.
const RIDGE: f32 = 1e-3;
/// The model's terms come in three blocks of three (3×3 matrices, as the GPU holds them):
/// the albedo's difference from the pixel's, the unit normal's, and (1, y, x), the offsets in
/// radii; the intercept, the prediction at the pixel, is the last block's first.
struct Terms {
    albedo: Vec3,
    normal: Vec3,
    place: Vec3,
}

/// A tap's terms, relative to the pixel's.
#[inline(always)]
fn terms(p: &Texel, q: &Texel, dy: isize, dx: isize) -> Terms {
    let r = RADIUS as f32;
    Terms {
        albedo: Vec3::from(q.albedo) - Vec3::from(p.albedo),
        normal: Vec3::from(q.normal) - Vec3::from(p.normal),
        place: Vec3::new(1.0, dy as f32 / r, dx as f32 / r),
    }
}

/// u vᵀ.
#[inline(always)]
fn outer(u: Vec3, v: Vec3) -> Mat3 {
    Mat3::from_cols(u * v.x, u * v.y, u * v.z)
}

/// The weighted normal equations of one pixel in blocks: XᵀWX = [A B C; Bᵀ D E; Cᵀ Eᵀ F]
/// (albedo, normal, place) and XᵀWY (a column per channel).
struct Normal {
    a: Mat3,
    b: Mat3,
    c: Mat3,
    d: Mat3,
    e: Mat3,
    f: Mat3,
    y_albedo: Mat3,
    y_normal: Mat3,
    y_place: Mat3,
}

impl Normal {
    /// No taps yet (glam's `Mat3::default()` is the identity, not zero).
    fn new() -> Normal {
        Normal {
            a: Mat3::ZERO,
            b: Mat3::ZERO,
            c: Mat3::ZERO,
            d: Mat3::ZERO,
            e: Mat3::ZERO,
            f: Mat3::ZERO,
            y_albedo: Mat3::ZERO,
            y_normal: Mat3::ZERO,
            y_place: Mat3::ZERO,
        }
    }

    /// Adds a tap of terms `t`, weight `w` and radiance `y`.
    #[inline(always)]
    fn add(&mut self, t: &Terms, w: f32, y: Vec3) {
        let (wa, wn, wp) = (t.albedo * w, t.normal * w, t.place * w);
        self.a += outer(wa, t.albedo);
        self.b += outer(wa, t.normal);
        self.c += outer(wa, t.place);
        self.d += outer(wn, t.normal);
        self.e += outer(wn, t.place);
        self.f += outer(wp, t.place);
        self.y_albedo += outer(wa, y);
        self.y_normal += outer(wn, y);
        self.y_place += outer(wp, y);
    }

    /// The intercept of the ridge-regularized solution, by block elimination of the albedo's
    /// then the normal's terms (Schur complements; f32, as the GPU does), or `None` where a
    /// block is singular.
    fn intercept(&self) -> Option<[f32; 3]> {
        let ridge = RIDGE * self.f.x_axis.x;
        let inverse = |m: Mat3| {
            let det = m.determinant();
            (det > 0.0 && det.is_finite()).then(|| m.inverse())
        };
        let ai = inverse(self.a + Mat3::from_diagonal(Vec3::splat(ridge)))?;
        let (bt_ai, ct_ai) = (self.b.transpose() * ai, self.c.transpose() * ai);
        let d = self.d + Mat3::from_diagonal(Vec3::splat(ridge)) - bt_ai * self.b;
        let e = self.e - bt_ai * self.c;
        let f = self.f + Mat3::from_diagonal(Vec3::new(0.0, ridge, ridge)) - ct_ai * self.c;
        let y_normal = self.y_normal - bt_ai * self.y_albedo;
        let y_place = self.y_place - ct_ai * self.y_albedo;
        let et_di = e.transpose() * inverse(d)?;
        let x = inverse(f - et_di * e)? * (y_place - et_di * y_normal);
        let out = [x.x_axis.x, x.y_axis.x, x.z_axis.x];
        out.iter().all(|v| v.is_finite()).then_some(out)
    }
}

/// Both halves regressed: `a` and `b` the halves' radiance (fireflies clamped), `fa` and `fb` their à-trous
/// outputs (radiance), `variance` the per-pixel variance of one half's luminance. Where a
/// system cannot be solved the à-trous output stays.
pub fn regress_pair(
    g: &Guide,
    (a, b): (&[[f32; 3]], &[[f32; 3]]),
    (fa, fb): (&[[f32; 3]], &[[f32; 3]]),
    variance: &[f32],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let t = texels(g);
    let (w, h) = (g.width as isize, g.height as isize);
    let lum_a: Vec<f32> = fa.iter().map(|&c| luminance(c)).collect();
    let lum_b: Vec<f32> = fb.iter().map(|&c| luminance(c)).collect();
    const SIDE: usize = 2 * RADIUS as usize + 1;
    let spatial: [[f32; SIDE]; SIDE] = std::array::from_fn(|j| {
        std::array::from_fn(|i| {
            let (dy, dx) = (j as f32 - RADIUS as f32, i as f32 - RADIUS as f32);
            (-(dy * dy + dx * dx) / (2.0 * SPATIAL_SIGMA * SPATIAL_SIGMA)).exp()
        })
    });
    let pixels: Vec<([f32; 3], [f32; 3])> = (0..(w * h) as usize)
        .into_par_iter()
        .map(|p| {
            let (x, y) = ((p as isize) % w, (p as isize) / w);
            let (mut na, mut nb) = (Normal::new(), Normal::new());
            for dy in -RADIUS..=RADIUS {
                let qy = y + dy;
                if qy < 0 || qy >= h {
                    continue;
                }
                for dx in -RADIUS..=RADIUS {
                    let qx = x + dx;
                    if qx < 0 || qx >= w {
                        continue;
                    }
                    let q = (qy * w + qx) as usize;
                    let terms = terms(&t[p], &t[q], dy, dx);
                    let s = spatial[(dy + RADIUS) as usize][(dx + RADIUS) as usize];
                    let scale = 1.0
                        / (LUMINANCE_SIGMA * LUMINANCE_SIGMA * (variance[p] + variance[q])
                            + LUMINANCE_EPSILON);
                    let da = lum_a[p] - lum_a[q];
                    let db = lum_b[p] - lum_b[q];
                    let (wa, wb) = (s * exp_neg(-da * da * scale), s * exp_neg(-db * db * scale));
                    // A weight this small changes nothing, and its products would be
                    // subnormal floats (a hundred times slower on x86).
                    if wa > MIN_WEIGHT {
                        na.add(&terms, wa, Vec3::from(a[q]));
                    }
                    if wb > MIN_WEIGHT {
                        nb.add(&terms, wb, Vec3::from(b[q]));
                    }
                }
            }
            (
                na.intercept().unwrap_or(fa[p]),
                nb.intercept().unwrap_or(fb[p]),
            )
        })
        .collect();
    pixels.into_iter().unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_elimination_solves_the_whole_system() {
        // 25 taps of random terms, weights and radiance: the intercept the blocks give is a
        // dense solve's of the same ridge-regularized 9×9 system (f64 Gaussian elimination).
        let mut n = Normal::new();
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 33) as f32 / (1u64 << 31) as f32) - 0.5
        };
        let mut m = [[0.0f64; 12]; 9];
        for _ in 0..25 {
            let t = Terms {
                albedo: Vec3::new(rnd(), rnd(), rnd()),
                normal: Vec3::new(rnd(), rnd(), rnd()),
                place: Vec3::new(1.0, rnd(), rnd()),
            };
            let (w, y) = (rnd() + 0.6, Vec3::new(rnd(), rnd(), rnd()));
            n.add(&t, w, y);
            // Terms (1, y, x, albedo, normal), then the three channels.
            let x: Vec<f64> = [t.place.to_array(), t.albedo.to_array(), t.normal.to_array()]
                .concat()
                .iter()
                .map(|&v| v as f64)
                .collect();
            for i in 0..9 {
                for j in 0..9 {
                    m[i][j] += w as f64 * x[i] * x[j];
                }
                for c in 0..3 {
                    m[i][9 + c] += w as f64 * x[i] * y[c] as f64;
                }
            }
        }
        let got = n.intercept().expect("solvable");
        let ridge = RIDGE as f64 * m[0][0];
        for (i, row) in m.iter_mut().enumerate().skip(1) {
            row[i] += ridge;
        }
        for k in 0..9 {
            let pivot = m[k];
            for row in m.iter_mut().skip(k + 1) {
                let f = row[k] / pivot[k];
                for (v, p) in row.iter_mut().zip(pivot).skip(k) {
                    *v -= f * p;
                }
            }
        }
        let mut x = [[0.0f64; 3]; 9];
        for i in (0..9).rev() {
            for c in 0..3 {
                let s: f64 = (i + 1..9).map(|j| m[i][j] * x[j][c]).sum();
                x[i][c] = (m[i][9 + c] - s) / m[i][i];
            }
        }
        for c in 0..3 {
            assert!(
                (got[c] as f64 - x[0][c]).abs() < 1e-4,
                "{got:?} against {:?}",
                x[0]
            );
        }
    }
}
