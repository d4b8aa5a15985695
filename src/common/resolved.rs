//! One preview frame as either tracer resolves it: the downsampled image, its noise estimate
//! and each pixel's standard error, from the terms `shaders/resolve.wgsl` computes on the GPU
//! and `cpu` on the host.

use super::LinearImage;
use super::accum::{ACCUM_WORDS, decode_pixel};
use super::estimate::{pair_factor, relative_weights};
use rayon::prelude::*;

/// An estimated relative RMSE as the status line shows it: the value, or, where the
/// estimate is within two standard errors of zero (its noise as large as itself: few
/// samples, or a filter that removed nearly all the noise), only a bound above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimate {
    Value(f64),
    Below(f64),
}

impl Estimate {
    pub fn text(self) -> String {
        match self {
            Estimate::Value(v) => format!("{:.2}%", v * 100.0),
            Estimate::Below(v) => format!("<{:.2}%", v * 100.0),
        }
    }

    /// Rounded to two digits (`~0.9%`, `<0.12%`): where the raw estimate it was made beside
    /// is rough (`Doubt`), so is this one.
    pub fn rough_text(self) -> String {
        match self {
            Estimate::Value(v) => rough(v),
            Estimate::Below(v) => format!("<{}%", round_to_two_digits(v * 100.0)),
        }
    }
}

/// Fewer samples than this in either half of some pixel, and the noise estimate is shown as
/// rough: with a handful of samples the halves' difference says little about the noise.
pub const DOUBT_HALF_SAMPLES: f32 = 4.0;
/// Fewer effective pixels than this behind the relative estimate (its sum squared over the
/// sum of its pixels' squared terms: the image's pixel count where every pixel weighs alike,
/// 1 where one pixel holds it all), and it is shown as rough: a few fireflies decide it, and
/// the next one can move it many times over (BENCHMARKS.md, "An honest error estimate").
pub const DOUBT_EFFECTIVE_PIXELS: f64 = 16.0;

/// Why an estimate is shown as rough.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Doubt {
    /// Few samples in some pixel's half.
    FewSamples,
    /// A few pixels (fireflies, most often) hold most of the estimate.
    FewPixels,
}

impl Doubt {
    /// Of an estimate from pixel terms summing to `rel` with squares summing to `rel2`, over
    /// pixels whose halves hold at least `fewest` samples (`None`: not known).
    pub fn of(fewest: Option<f32>, rel: f64, rel2: f64) -> Option<Doubt> {
        if fewest.is_some_and(|f| f < DOUBT_HALF_SAMPLES) {
            Some(Doubt::FewSamples)
        } else if rel > 0.0 && rel * rel < DOUBT_EFFECTIVE_PIXELS * rel2 {
            Some(Doubt::FewPixels)
        } else {
            None
        }
    }

    /// Why, in the status line's words.
    pub fn why(self) -> &'static str {
        match self {
            Doubt::FewSamples => "few samples",
            Doubt::FewPixels => "fireflies",
        }
    }

    /// The status line's words: the figure, rounded to two digits, and why it is rough.
    pub fn text(self, rel_rmse: f64) -> String {
        format!("{} ({})", rough(rel_rmse), self.why())
    }

    /// The raw figure `raw` and the denoised image's `denoised`, both made from the same
    /// samples and so both rough: `~12% → ~0.9% (fireflies)`. The denoised image's estimate
    /// is no surer than the raw one's: where fireflies hold the raw estimate, the denoised
    /// one's error is largely the bright paths the run did or did not find, and the raw
    /// doubt marks 18 of the 22 runs whose denoised figure was off by more than 2×
    /// (tests/estimate.rs, `the_status_line_doubts_where_its_figure_is_off`).
    pub fn pair_text(self, raw: f64, denoised: Estimate) -> String {
        format!(
            "{} → {} ({})",
            rough(raw),
            denoised.rough_text(),
            self.why()
        )
    }
}

/// A relative RMSE as a rough figure: `~12%`.
fn rough(rel_rmse: f64) -> String {
    format!("~{}%", round_to_two_digits(rel_rmse * 100.0))
}

/// `v` rounded to two significant digits.
fn round_to_two_digits(v: f64) -> f64 {
    if v <= 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powf(1.0 - v.log10().floor());
    (v * scale).round() / scale
}

/// One resolved frame on the host.
#[derive(Clone, Debug)]
pub struct Resolved {
    pub image: LinearImage,
    /// The traced image's estimated relative RMSE (see `Snapshot::error_estimate`); `None`
    /// until every pixel has a sample in each half.
    pub noise: Option<f64>,
    /// Samples discarded as NaN or infinite since the last reset.
    pub invalid: u64,
    /// Per image pixel, the estimated standard error of its linear value (the two halves'
    /// estimate, averaged over channels and the block); 0 where not yet known.
    pub sigma: Vec<f32>,
    /// The estimated relative RMSE of the image when it is a denoised one (`denoise`).
    pub denoised: Option<Estimate>,
    /// Why `noise` is rough, if it is.
    pub doubt: Option<Doubt>,
}

impl Resolved {
    /// The frame from the resolve's two vec4f per output pixel (see resolve.wgsl: colour,
    /// fewest samples; squared error, relative squared error, the sum of the pixels' relative
    /// terms squared, 0; the CPU
    /// tracer computes the same terms on the host): `out` pixels, each the mean of a
    /// `factor × factor` block.
    pub fn from_blocks(words: &[[f32; 8]], out: (u32, u32), factor: u32, invalid: u64) -> Resolved {
        let n = out.0 as usize * out.1 as usize;
        // The block's mean has 1/factor⁴ of its pixels' summed variance.
        let block = (factor * factor) as f32;
        let sigma = words
            .iter()
            .map(|w| (w[4] / (3.0 * block * block)).max(0.0).sqrt())
            .collect();
        let (mut rel, mut rel2, mut fewest) = (0.0f64, 0.0f64, f32::INFINITY);
        let pixels = words
            .iter()
            .map(|w| {
                fewest = fewest.min(w[3]);
                rel += w[5] as f64;
                rel2 += w[6] as f64;
                [w[0], w[1], w[2]]
            })
            .collect();
        // Over the traced pixels the output covers (all of them when the size divides).
        let channels = 3.0 * n as f64 * block as f64;
        Resolved {
            image: LinearImage {
                width: out.0,
                height: out.1,
                pixels,
            },
            noise: (fewest >= 1.0).then(|| (rel / channels).sqrt()),
            invalid,
            sigma,
            denoised: None,
            doubt: Doubt::of(Some(fewest), rel, rel2),
        }
    }

    /// The frame of exact sums `even` and `odd` (`ACCUM_WORDS` words a pixel, `size`
    /// pixels): resolve.wgsl's terms computed on the host (every output pixel the mean of a
    /// `factor × factor` block, and the two-halves noise terms), in parallel. The CPU
    /// tracer's frames, and the preview's on several devices (their sums added).
    pub fn from_sums(
        even: &[u32],
        odd: &[u32],
        size: (u32, u32),
        factor: u32,
        invalid: u64,
    ) -> Resolved {
        let f = factor.max(1);
        let out = ((size.0 / f).max(1), (size.1 / f).max(1));
        let (w, h) = (size.0 as usize, size.1 as usize);
        let decode = |words: &[u32]| -> Vec<[f32; 4]> {
            (0..w * h)
                .into_par_iter()
                .map(|p| decode_pixel(&words[p * ACCUM_WORDS..(p + 1) * ACCUM_WORDS]))
                .collect()
        };
        let (even, odd) = (decode(even), decode(odd));
        let weights = relative_weights(&even, &odd, w, h);
        let value = |half: &[[f32; 4]], p: usize| -> ([f32; 3], f32) {
            let [r, g, b, n] = half[p];
            ([r, g, b], n)
        };
        let blocks: Vec<[f32; 8]> = (0..out.0 as usize * out.1 as usize)
            .into_par_iter()
            .map(|i| {
                let (bx, by) = (i % out.0 as usize, i / out.0 as usize);
                let mut b = [0.0f32; 8];
                b[3] = f32::INFINITY;
                for dy in 0..f as usize {
                    for dx in 0..f as usize {
                        let (x, y) = (bx * f as usize + dx, by * f as usize + dy);
                        if x >= w || y >= h {
                            continue;
                        }
                        let p = y * w + x;
                        let ((se, ne), (so, no)) = (value(&even, p), value(&odd, p));
                        if ne + no > 0.0 {
                            for c in 0..3 {
                                b[c] += (se[c] + so[c]) / (ne + no);
                            }
                        } else {
                            // A row the first look has not reached: show its neighbour.
                            let near = if y == 0 { p + w } else { p - w };
                            if near < w * h {
                                let ((s2, n2), (t2, m2)) = (value(&even, near), value(&odd, near));
                                if n2 + m2 > 0.0 {
                                    for c in 0..3 {
                                        b[c] += (s2[c] + t2[c]) / (n2 + m2);
                                    }
                                }
                            }
                        }
                        b[3] = b[3].min(ne.min(no));
                        if let Some(k) = pair_factor(ne as f64, no as f64) {
                            let mut pixel_rel = 0.0;
                            for c in 0..3 {
                                let d = se[c] / ne - so[c] / no;
                                let v = d * d * k as f32;
                                b[4] += v;
                                pixel_rel += v * weights[p][c];
                            }
                            b[5] += pixel_rel;
                            b[6] += pixel_rel * pixel_rel;
                        }
                    }
                }
                let n = (f * f) as f32;
                for c in b.iter_mut().take(3) {
                    *c /= n;
                }
                b
            })
            .collect();
        Resolved::from_blocks(&blocks, out, f, invalid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_estimate_is_rough_with_few_samples_or_few_pixels_behind_it() {
        // 100 pixels of equal terms: 100 effective pixels.
        assert_eq!(Doubt::of(Some(8.0), 100.0, 100.0), None);
        // One pixel holds it all: one effective pixel.
        assert_eq!(
            Doubt::of(Some(8.0), 100.0, 10_000.0),
            Some(Doubt::FewPixels)
        );
        // Three samples a half: rough whatever the pixels.
        assert_eq!(Doubt::of(Some(3.0), 100.0, 100.0), Some(Doubt::FewSamples));
        // An estimate of zero (an exact image) is not rough.
        assert_eq!(Doubt::of(None, 0.0, 0.0), None);
        assert_eq!(Doubt::FewPixels.text(0.1234), "~12% (fireflies)");
        assert_eq!(Doubt::FewSamples.text(0.004567), "~0.46% (few samples)");
    }
}
