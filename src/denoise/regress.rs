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
//! Chosen by measurement (120×76, 32 + 32 and 128 + 128 samples, cornell, showcase, weekend):
//! the true relative RMSE of ½(D(A) + D(B)) fell from 3.7, 3.5, 5.3 % to 2.0–2.5, 2.9, 3.7 %
//! at 64 spp, and from 2.5, 2.1, 2.9 % to 2.0, 1.6, 1.9 % at 256 spp (BENCHMARKS.md).

// The normal equations and the Cholesky factorization are written with the textbook's
// indices, as shaders/denoise.wgsl writes them.
#![allow(clippy::needless_range_loop)]

use super::atrous::{Guide, Texel, exp_neg, luminance, texels};
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
/// Terms of the model: 1, albedo (3), unit normal (3), y and x offsets (in radii).
pub const TERMS: usize = 9;

/// A tap's terms, relative to the pixel's (so the intercept is the prediction there).
#[inline(always)]
fn terms(p: &Texel, q: &Texel, dy: isize, dx: isize) -> [f32; TERMS] {
    let r = RADIUS as f32;
    [
        1.0,
        q.albedo[0] - p.albedo[0],
        q.albedo[1] - p.albedo[1],
        q.albedo[2] - p.albedo[2],
        q.normal[0] - p.normal[0],
        q.normal[1] - p.normal[1],
        q.normal[2] - p.normal[2],
        dy as f32 / r,
        dx as f32 / r,
    ]
}

/// Entries of the lower triangle of a TERMS × TERMS matrix.
const TRIANGLE: usize = TERMS * (TERMS + 1) / 2;

/// The lower triangle of t tᵀ, row by row (one tap's, shared by the two halves' equations).
#[inline(always)]
fn products(t: &[f32; TERMS]) -> [f32; TRIANGLE] {
    let mut tt = [0.0; TRIANGLE];
    let mut k = 0;
    for i in 0..TERMS {
        for j in 0..=i {
            tt[k] = t[i] * t[j];
            k += 1;
        }
    }
    tt
}

/// The weighted normal equations of one pixel: the lower triangle of XᵀWX, row by row, and
/// XᵀWY per channel.
struct Normal {
    xx: [f32; TRIANGLE],
    xy: [[f32; 3]; TERMS],
}

impl Normal {
    fn new() -> Normal {
        Normal {
            xx: [0.0; TRIANGLE],
            xy: [[0.0; 3]; TERMS],
        }
    }

    /// Adds a tap of terms `t` (whose products `tt` are `products(t)`), weight `w` and
    /// radiance `y`.
    #[inline(always)]
    fn add(&mut self, t: &[f32; TERMS], tt: &[f32; TRIANGLE], w: f32, y: [f32; 3]) {
        for k in 0..TRIANGLE {
            self.xx[k] += w * tt[k];
        }
        let wy = y.map(|v| w * v);
        for i in 0..TERMS {
            for c in 0..3 {
                self.xy[i][c] += t[i] * wy[c];
            }
        }
    }

    /// The intercept of the ridge-regularized solution (Cholesky, in f32 as the GPU does),
    /// or `None` where the factorization fails.
    fn intercept(&self) -> Option<[f32; 3]> {
        let ridge = RIDGE * self.xx[0];
        let mut l = [[0.0f32; TERMS]; TERMS];
        let mut k = 0;
        for i in 0..TERMS {
            for j in 0..=i {
                l[i][j] = self.xx[k] + if i == j && i > 0 { ridge } else { 0.0 };
                k += 1;
            }
        }
        for j in 0..TERMS {
            let mut d = l[j][j];
            for m in 0..j {
                d -= l[j][m] * l[j][m];
            }
            if d <= 0.0 || !d.is_finite() {
                return None;
            }
            let d = d.sqrt();
            l[j][j] = d;
            for i in j + 1..TERMS {
                let mut s = l[i][j];
                for m in 0..j {
                    s -= l[i][m] * l[j][m];
                }
                l[i][j] = s / d;
            }
        }
        let mut out = [0.0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            // L z = b, then Lᵀ β = z; only β₀ is needed, but it is the last found.
            let mut z = [0.0f32; TERMS];
            for i in 0..TERMS {
                let mut s = self.xy[i][c];
                for m in 0..i {
                    s -= l[i][m] * z[m];
                }
                z[i] = s / l[i][i];
            }
            let mut b = [0.0f32; TERMS];
            for i in (0..TERMS).rev() {
                let mut s = z[i];
                for m in i + 1..TERMS {
                    s -= l[m][i] * b[m];
                }
                b[i] = s / l[i][i];
            }
            *o = b[0];
        }
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
                    let tt = products(&terms);
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
                        na.add(&terms, &tt, wa, a[q]);
                    }
                    if wb > MIN_WEIGHT {
                        nb.add(&terms, &tt, wb, b[q]);
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
