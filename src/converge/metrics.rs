//! Error of an image against a reference, in linear radiance, and the per-tile bias test.

use crate::common::estimate::REL_MSE_EPSILON;
use crate::output::LinearImage;
use crate::render::Snapshot;
use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// Errors of one image against a reference, over every pixel and channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    pub rmse: f64,
    /// pbrt's relative MSE: mean of (v - ref)² / (ref² + 0.01).
    pub relmse: f64,
    /// Mean absolute error.
    pub mae: f64,
}

impl Errors {
    /// √relMSE: the "relative RMSE" the noise estimate and `--target-error` speak of.
    pub fn rel_rmse(&self) -> f64 {
        self.relmse.sqrt()
    }
}

/// Errors of `img` against `reference` (same size), taking the reference as exact.
pub fn errors(img: &LinearImage, reference: &LinearImage) -> Errors {
    errors_against_noisy(img, reference, None)
}

/// The variance of each pixel's mean, per channel, estimated from the difference of its two
/// halves: for a mean m = (nₑ·mₑ + nₒ·mₒ)/(nₑ + nₒ) of independent halves,
/// E[(mₑ − mₒ)²]·nₑnₒ/(nₑ + nₒ)² = Var(m).
pub fn mean_variance(snap: &Snapshot) -> Vec<[f32; 3]> {
    snap.data
        .even
        .iter()
        .zip(&snap.data.odd)
        .map(|(e, o)| {
            let (ne, no) = (e[3] as f64, o[3] as f64);
            if ne < 1.0 || no < 1.0 {
                return [0.0; 3];
            }
            let k = ne * no / ((ne + no) * (ne + no));
            std::array::from_fn(|c| ((e[c] as f64 / ne - o[c] as f64 / no).powi(2) * k) as f32)
        })
        .collect()
}

/// Errors of `img` against a reference that is itself a Monte Carlo estimate. With the
/// reference's per-pixel variance `reference_variance` (from [`mean_variance`]), the squared
/// differences are corrected for the reference's own noise: for independent unbiased images,
/// E[(v − r)²] = (v − v̄)² terms + Var(r), so subtracting Var(r) leaves an unbiased estimate of
/// the image's own MSE and relMSE (summed over many pixels; the total is floored at zero).
/// Without it the measured error levels off at the reference's noise, which would flatten the
/// convergence slope. MAE has no such correction and is reported as measured.
pub fn errors_against_noisy(
    img: &LinearImage,
    reference: &LinearImage,
    reference_variance: Option<&[[f32; 3]]>,
) -> Errors {
    assert_eq!((img.width, img.height), (reference.width, reference.height));
    if let Some(v) = reference_variance {
        assert_eq!(v.len(), reference.pixels.len());
    }
    let (mut se, mut rel, mut ae) = (0.0f64, 0.0f64, 0.0f64);
    for (i, (p, r)) in img.pixels.iter().zip(&reference.pixels).enumerate() {
        for c in 0..3 {
            let (v, rv) = (p[c] as f64, r[c] as f64);
            let d = v - rv;
            let var = reference_variance.map_or(0.0, |vs| vs[i][c] as f64);
            se += d * d - var;
            rel += (d * d - var) / (rv * rv + REL_MSE_EPSILON);
            ae += d.abs();
        }
    }
    let n = (3 * img.pixels.len()).max(1) as f64;
    Errors {
        rmse: (se / n).max(0.0).sqrt(),
        relmse: (rel / n).max(0.0),
        mae: ae / n,
    }
}

/// The luminance of a pixel's mean and the estimated variance of that mean, from the
/// difference of its two halves (see `Snapshot::error_estimate`).
fn pixel_mean_and_variance(e: &[f32; 4], o: &[f32; 4]) -> Option<(f64, f64)> {
    let (ne, no) = (e[3] as f64, o[3] as f64);
    if ne < 1.0 || no < 1.0 {
        return None;
    }
    let lum = |v: [f64; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    let me = lum(std::array::from_fn(|c| e[c] as f64 / ne));
    let mo = lum(std::array::from_fn(|c| o[c] as f64 / no));
    let m = lum(std::array::from_fn(|c| {
        (e[c] as f64 + o[c] as f64) / (ne + no)
    }));
    Some((m, (me - mo).powi(2) * ne * no / ((ne + no) * (ne + no))))
}

/// One tile's comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileTest {
    /// Tile position, in tiles.
    pub x: u32,
    pub y: u32,
    pub mean: f64,
    pub reference: f64,
    pub t: f64,
    pub dof: f64,
    pub p: f64,
}

/// The outcome of a bias check.
#[derive(Clone, Debug)]
pub struct BiasReport {
    pub tiles: usize,
    pub alpha: f64,
    /// Tiles whose means differ significantly (p below alpha / tiles).
    pub significant: Vec<TileTest>,
    /// The smallest p-value seen.
    pub min_p: f64,
}

/// Relative difference below which two f32 means count as equal in the bias check (about 8
/// ulps of an f32).
pub const F32_RESOLUTION: f64 = 1e-6;

/// Per-tile Welch t-test of the mean luminance of `img` against `reference`: catches an
/// image that converges fast to the wrong answer. The variance of each tile's mean comes
/// from the halves of every pixel (the image's content does not count as noise); its degrees
/// of freedom from the Welch–Satterthwaite formula, one per pixel. A reference given without
/// halves (an EXR file) counts as exact. Significance is Bonferroni-corrected: a tile fails
/// when p < alpha / (number of tiles).
pub fn bias_check(
    img: &Snapshot,
    reference: &Snapshot,
    reference_exact: bool,
    tile: u32,
    alpha: f64,
) -> BiasReport {
    let (w, h) = (img.width, img.height);
    let (tx, ty) = (w.div_ceil(tile), h.div_ceil(tile));
    let mut tests = Vec::new();
    for by in 0..ty {
        for bx in 0..tx {
            // (sum of means, sum of variances, sum of squared variances, count) per image.
            let mut acc = [(0.0f64, 0.0f64, 0.0f64, 0usize); 2];
            for y in by * tile..((by + 1) * tile).min(h) {
                for x in bx * tile..((bx + 1) * tile).min(w) {
                    let i = (y * w + x) as usize;
                    for (k, s) in [img, reference].iter().enumerate() {
                        if let Some((m, v)) =
                            pixel_mean_and_variance(&s.data.even[i], &s.data.odd[i])
                        {
                            let a = &mut acc[k];
                            a.0 += m;
                            a.1 += v;
                            a.2 += v * v;
                            a.3 += 1;
                        }
                    }
                }
            }
            let [a, b] = acc;
            if a.3 == 0 || b.3 == 0 {
                continue;
            }
            let (ma, mb) = (a.0 / a.3 as f64, b.0 / b.3 as f64);
            let va = a.1 / (a.3 * a.3) as f64;
            let vb = if reference_exact {
                0.0
            } else {
                b.1 / (b.3 * b.3) as f64
            };
            // Satterthwaite: the variance of a sum of one-dof estimates v_i has (Σv)²/Σv² dof.
            let dfa = if a.2 > 0.0 {
                a.1 * a.1 / a.2
            } else {
                f64::INFINITY
            };
            let dfb = if b.2 > 0.0 {
                b.1 * b.1 / b.2
            } else {
                f64::INFINITY
            };
            // The means are read back as f32 (sums rounded, then divided): a difference of a
            // few ulps is rounding, not bias, even in a tile with no noise at all (a uniform
            // sky, where every sample is the same number).
            let rounding = (F32_RESOLUTION * ma.abs().max(mb.abs())).powi(2);
            let var = va + vb + rounding;
            let (t, dof, p) = if var <= 0.0 {
                // No noise at all: any difference is significant, none is not.
                let t = if ma == mb { 0.0 } else { f64::INFINITY };
                (t, f64::INFINITY, if ma == mb { 1.0 } else { 0.0 })
            } else {
                let t = (ma - mb) / var.sqrt();
                let vb_term = if reference_exact { 0.0 } else { vb * vb / dfb };
                let dof = (var * var / (va * va / dfa + vb_term)).max(1.0);
                // Past 1e6 degrees of freedom (or with only the rounding term) the t
                // distribution is the normal one.
                let cdf = if dof.is_finite() && dof < 1e6 {
                    StudentsT::new(0.0, 1.0, dof)
                        .expect("valid t distribution")
                        .cdf(t.abs())
                } else {
                    Normal::new(0.0, 1.0).expect("standard normal").cdf(t.abs())
                };
                (t, dof, 2.0 * (1.0 - cdf))
            };
            tests.push(TileTest {
                x: bx,
                y: by,
                mean: ma,
                reference: mb,
                t,
                dof,
                p,
            });
        }
    }
    let n = tests.len().max(1);
    let threshold = alpha / n as f64;
    BiasReport {
        tiles: tests.len(),
        alpha,
        min_p: tests.iter().map(|t| t.p).fold(1.0, f64::min),
        significant: tests.into_iter().filter(|t| t.p < threshold).collect(),
    }
}

/// Least-squares slope and intercept of log10(y) against log10(x).
pub fn log_log_fit(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.log10(), y.log10()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    let (mx, my) = (sx / n, sy / n);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx == 0.0 {
        return None;
    }
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let slope = sxy / sxx;
    Some((slope, my - slope * mx))
}

/// When a falling curve (seconds, error) first reaches `target`: interpolated on the log-log
/// curve between checkpoints, or extrapolated with the fitted line (flagged) if it never does.
pub fn time_to(points: &[(f64, f64)], target: f64) -> Option<(f64, bool)> {
    for w in points.windows(2) {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        if e0 > target && e1 <= target && e0 > 0.0 && e1 > 0.0 {
            let f = (target.log10() - e0.log10()) / (e1.log10() - e0.log10());
            return Some((
                10f64.powf(t0.log10() + f * (t1.log10() - t0.log10())),
                false,
            ));
        }
    }
    if let Some(&(t, e)) = points.first()
        && e <= target
    {
        return Some((t, false));
    }
    let (slope, intercept) = log_log_fit(points)?;
    (slope < 0.0).then(|| (10f64.powf((target.log10() - intercept) / slope), true))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_of_a_known_difference() {
        let r = LinearImage {
            width: 2,
            height: 1,
            pixels: vec![[0.0; 3], [1.0; 3]],
        };
        let i = LinearImage {
            width: 2,
            height: 1,
            pixels: vec![[0.1; 3], [1.0; 3]],
        };
        let e = errors(&i, &r);
        assert!((e.rmse - (0.01f64 / 2.0).sqrt()).abs() < 1e-7);
        assert!((e.mae - 0.05).abs() < 1e-7);
        assert!((e.relmse - 0.01 / 0.01 / 2.0).abs() < 1e-6);
    }

    #[test]
    fn the_reference_noise_is_taken_out_of_the_error() {
        // A reference pixel with halves 0.9 and 1.1 (one sample each): mean 1, variance of
        // the mean (0.2)² · 1/4 = 0.01. An image at 1.2 differs by 0.2 (0.04 squared), of
        // which 0.01 is the reference's noise.
        let snap = Snapshot {
            width: 1,
            height: 1,
            samples: 2,
            data: crate::common::AccumData::from_halves(
                vec![[0.9, 0.9, 0.9, 1.0]],
                vec![[1.1, 1.1, 1.1, 1.0]],
            ),
        };
        let var = mean_variance(&snap);
        assert!((var[0][0] - 0.01).abs() < 1e-7);
        let r = snap.image();
        let i = LinearImage {
            width: 1,
            height: 1,
            pixels: vec![[1.2; 3]],
        };
        let raw = errors(&i, &r);
        let e = errors_against_noisy(&i, &r, Some(&var));
        assert!((raw.rmse - 0.2).abs() < 1e-6);
        assert!((e.rmse - 0.03f64.sqrt()).abs() < 1e-6);
        assert!((e.relmse - 0.03 / 1.01).abs() < 1e-6);
        assert_eq!(e.mae, raw.mae);
        // An image closer than the reference's own noise: floored at zero, never negative.
        let near = LinearImage {
            width: 1,
            height: 1,
            pixels: vec![[1.05; 3]],
        };
        assert_eq!(errors_against_noisy(&near, &r, Some(&var)).relmse, 0.0);
    }

    /// A uniform tile (every sample the same number) whose means differ by f32 rounding only
    /// is not biased; a difference of 1e-4 is.
    #[test]
    fn the_bias_check_forgives_rounding_but_not_a_real_difference() {
        let snap = |v: f32, n: f32| Snapshot {
            width: 4,
            height: 4,
            samples: 2 * n as u32,
            data: crate::common::AccumData::from_halves(
                vec![[v * n, v * n, v * n, n]; 16],
                vec![[v * n, v * n, v * n, n]; 16],
            ),
        };
        let reference = snap(0.010_72, 4096.0);
        let one_ulp = snap(f32::from_bits(0.010_72f32.to_bits() + 1), 1000.0);
        let r = bias_check(&one_ulp, &reference, false, 4, 0.01);
        assert!(r.significant.is_empty(), "{:?}", r.significant);
        let off = snap(0.010_72 * (1.0 + 1e-4), 1000.0);
        let r = bias_check(&off, &reference, false, 4, 0.01);
        assert_eq!(r.significant.len(), 1);
    }

    #[test]
    fn slope_and_crossing_of_a_power_law() {
        let pts: Vec<(f64, f64)> = (0..10)
            .map(|k| {
                let t = 0.1 * 2f64.powi(k);
                (t, 0.3 * t.powf(-0.5))
            })
            .collect();
        let (slope, _) = log_log_fit(&pts).unwrap();
        assert!((slope + 0.5).abs() < 1e-12);
        let (t, extrapolated) = time_to(&pts, 0.3 * 4f64.powf(-0.5)).unwrap();
        assert!((t - 4.0).abs() < 1e-9 && !extrapolated);
        let (t, extrapolated) = time_to(&pts, 0.3 * 10000f64.powf(-0.5)).unwrap();
        assert!((t / 10000.0 - 1.0).abs() < 1e-9 && extrapolated);
    }
}
