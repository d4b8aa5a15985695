//! What the accumulation holds at one moment, on the host: per-pixel sums of the even and
//! odd samples, from which the image and its noise estimate are computed.

use crate::common::AccumData;
use crate::common::estimate::{pair_factor, relative_weights};
use crate::common::resolved::Doubt;
use crate::output::LinearImage;

/// An image's estimated error, in linear radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorEstimate {
    pub rmse: f64,
    pub rel_rmse: f64,
    /// Why `rel_rmse` is rough, if it is: the status line's doubt (few samples in some
    /// pixel's half, or a few pixels holding most of it), from the same terms.
    pub doubt: Option<Doubt>,
}

impl ErrorEstimate {
    /// `rel_rmse` as `render` reports it: `4.912%`, or rounded with why it is rough,
    /// `~26% (fireflies)`.
    pub fn text(&self) -> String {
        match self.doubt {
            Some(d) => d.text(self.rel_rmse),
            None => format!("{:.3}%", self.rel_rmse * 100.0),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Snapshot {
    pub width: u32,
    pub height: u32,
    pub data: AccumData,
    /// Samples per pixel in every completed round.
    pub samples: u32,
}

impl Snapshot {
    /// The displayed image: sum / weight per pixel (the lecture's `accumulated / peso`).
    pub fn image(&self) -> LinearImage {
        let pixels = self
            .data
            .even
            .iter()
            .zip(&self.data.odd)
            .map(|(e, o)| {
                let w = e[3] as f64 + o[3] as f64;
                if w > 0.0 {
                    std::array::from_fn(|c| ((e[c] as f64 + o[c] as f64) / w) as f32)
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        LinearImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Each pixel's samples (both halves), row by row.
    pub fn sample_counts(&self) -> impl Iterator<Item = u64> + '_ {
        (self.data.even.iter().zip(&self.data.odd)).map(|(e, o)| (e[3] + o[3]) as u64)
    }

    /// Most samples any pixel holds (more than `min_samples` while a round is unfinished).
    pub fn max_samples(&self) -> u64 {
        self.sample_counts().max().unwrap_or(0)
    }

    /// Fewest samples any pixel holds (pixels in an unfinished round hold more).
    pub fn min_samples(&self) -> u64 {
        self.sample_counts().min().unwrap_or(0)
    }

    /// The estimated error of the image, from the difference of its two halves (no reference
    /// needed); `None` until each half of every pixel holds a sample.
    ///
    /// Each pixel keeps the sums of its even and of its odd samples: two independent means
    /// E and O of n_e and n_o samples, and the image is their pooled mean M. With i.i.d.
    /// samples (variance σ²), Var(E - O) = σ²(1/n_e + 1/n_o) and Var(M) = σ²/(n_e + n_o), so
    /// D² · n_e·n_o / (n_e + n_o)², with D = E - O, is an unbiased estimate of Var(M), the
    /// mean squared error of M when the estimator is unbiased (E[M] is the true value). The
    /// tracers stratify a half's samples (scrambled Sobol points, `cpu::rng`), so Var(E) and
    /// Var(O) fall faster than 1/n; the halves are independently scrambled sequences of equal
    /// or next-to-equal length, Var(E) ≈ Var(O), and with k = n_e·n_o/(n_e + n_o)² ≈ 1/4 the
    /// same D²·k still estimates Var(M) = (Var(E) + Var(O))/4 without bias. Bias is
    /// invisible to this estimate (that is what `converge --bias-check` is for).
    ///
    /// Returned as errors over the whole image: `rmse` the root of the mean estimated MSE, and
    /// `rel_rmse` the root of pbrt's relative MSE, MSE / (reference² + 0.01), with the
    /// unknown reference² estimated by the mean of each pixel's 3×3 neighbours, at most the
    /// larger of its half means and at least what they agree on (`common::estimate` says
    /// why).
    pub fn error_estimate(&self) -> Option<ErrorEstimate> {
        if self.min_half_samples() < 1 {
            return None;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        self.error_estimate_weighted(&relative_weights(&self.data.even, &self.data.odd, w, h))
    }

    /// [`Self::error_estimate`] with each pixel's squared error weighted by `weights` (per
    /// pixel and channel, 1 / (reference² + 0.01)) for the relative figure, instead of the
    /// proxy's: with the true reference's, what a perfect proxy would estimate
    /// (tests/estimate.rs, `the_reference_as_the_proxy`).
    pub fn error_estimate_weighted(&self, weights: &[[f32; 3]]) -> Option<ErrorEstimate> {
        assert_eq!(weights.len(), self.data.even.len());
        let (mut mse, mut rel, mut rel2) = (0.0f64, 0.0f64, 0.0f64);
        let mut fewest = f32::INFINITY;
        for ((e, o), wt) in self.data.even.iter().zip(&self.data.odd).zip(weights) {
            let k = pair_factor(e[3] as f64, o[3] as f64)?;
            let mut pixel = 0.0;
            for c in 0..3 {
                let (me, mo) = (e[c] as f64 / e[3] as f64, o[c] as f64 / o[3] as f64);
                let var = (me - mo).powi(2) * k;
                mse += var;
                pixel += var * wt[c] as f64;
            }
            rel += pixel;
            rel2 += pixel * pixel;
            fewest = fewest.min(e[3].min(o[3]));
        }
        let n = (3 * self.data.even.len()).max(1) as f64;
        Some(ErrorEstimate {
            rmse: (mse / n).sqrt(),
            rel_rmse: (rel / n).sqrt(),
            doubt: Doubt::of(Some(fewest), rel, rel2),
        })
    }

    /// Fewest samples either half of any pixel holds.
    pub fn min_half_samples(&self) -> u64 {
        self.data
            .even
            .iter()
            .zip(&self.data.odd)
            .map(|(e, o)| e[3].min(o[3]) as u64)
            .min()
            .unwrap_or(0)
    }

    /// The estimated relative RMSE (see [`Snapshot::error_estimate`]).
    pub fn noise_estimate(&self) -> Option<f64> {
        self.error_estimate().map(|e| e.rel_rmse)
    }

    /// Samples discarded as NaN or infinite since the last reset.
    pub fn invalid_samples(&self) -> u64 {
        self.data.invalid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 16 × 16 snapshot whose pixels' halves hold `n` samples each, with means 0.5 ± 0.05,
    /// and, where `firefly`, one pixel's even half at 50.
    fn snapshot(n: f32, firefly: bool) -> Snapshot {
        let half = |m: f32| [m * n, m * n, m * n, n];
        let mut even = vec![half(0.55); 256];
        if firefly {
            even[100] = half(50.0);
        }
        Snapshot {
            width: 16,
            height: 16,
            data: AccumData {
                even,
                odd: vec![half(0.45); 256],
                invalid: 0,
                segments: 0,
                node_visits: 0,
                primitive_tests: 0,
            },
            samples: 2 * n as u32,
        }
    }

    #[test]
    fn the_estimate_says_when_it_is_rough_as_the_status_line_does() {
        // Every pixel alike, 8 samples a half: a sure figure, three decimals.
        let e = snapshot(8.0, false).error_estimate().unwrap();
        assert_eq!(e.doubt, None);
        assert_eq!(e.text(), format!("{:.3}%", e.rel_rmse * 100.0));
        // Two samples a half: rough.
        let e = snapshot(2.0, false).error_estimate().unwrap();
        assert_eq!(e.doubt, Some(Doubt::FewSamples));
        assert!(e.text().starts_with('~') && e.text().ends_with("% (few samples)"));
        // One pixel holds nearly all of it.
        let e = snapshot(8.0, true).error_estimate().unwrap();
        assert_eq!(e.doubt, Some(Doubt::FewPixels));
        assert!(e.text().ends_with("% (fireflies)"), "{}", e.text());
    }
}
