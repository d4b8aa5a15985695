//! The two-halves error estimate's per-pixel terms, in one place for every host copy (the
//! snapshot's estimate, the CPU tracer's preview frames, the denoiser); its WGSL twin is
//! `shaders/common/estimate.wgsl` (the resolve and denoise passes).
//!
//! Each pixel keeps two independent means of its samples, A and B (the even and odd halves,
//! of n_A and n_B samples). (A − B)²·n_A·n_B/(n_A + n_B)² estimates the variance of the pooled
//! mean without bias (`render::Snapshot::error_estimate` says why). The error is reported as
//! pbrt's relative MSE: each channel's squared error over reference² + 0.01, and the
//! reference is not known.
//!
//! **The reference² proxy.** The estimate divides by the product of the halves' smaller 3×3
//! mean and their pooled 3×3 mean. The proxy it replaces, A·B, is unbiased for reference²,
//! but it is correlated with the numerator exactly where the error is: a firefly in one half
//! makes (A − B)² and A·B large together, so a pixel whose true relative error is
//! (firefly/n)²/reference² counted for firefly/B. A 3×3 mean takes most of a single pixel's
//! noise out of the proxy. Of the two means, the smaller one (the half without the firefly)
//! is right where the firefly is rare (a sun's caustic landing in a diffuse pixel) and counts
//! a firefly many times over where such samples are the light's usual path (a glossy lobe
//! that finds a small lamp: there the true reference holds their mean); the pooled mean is
//! right there and counts for little a rare one. Their product (a geometric mean of the two
//! squares) was measured against both and against A·B on every shipped scene
//! (tests/estimate.rs; BENCHMARKS.md, "An honest error estimate"): the smaller mean alone read
//! 2–5× the true error on `pbr` and the caustic scene, the pooled mean 0.3–0.6× on `glass`,
//! A·B 0.24–0.60× on `glass` and 0.27–0.80× on the caustic scene.

use rayon::prelude::*;

/// pbrt's relative MSE adds this to the squared reference so that black pixels do not divide
/// by zero (pbrt-v4, `imgtool diff --metric relmse`).
pub const REL_MSE_EPSILON: f64 = 0.01;

/// Radius of the window whose means give the reference² proxy (3×3).
pub const PROXY_RADIUS: usize = 1;

/// A half's mean per channel, 0 without samples.
pub fn half_mean(s: [f32; 4]) -> [f32; 3] {
    if s[3] > 0.0 {
        [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
    } else {
        [0.0; 3]
    }
}

/// The factor n_A·n_B/(n_A + n_B)² that makes a pixel's (A − B)² the variance of its pooled
/// mean; `None` until each half holds a sample.
pub fn pair_factor(na: f64, nb: f64) -> Option<f64> {
    (na >= 1.0 && nb >= 1.0).then(|| na * nb / ((na + nb) * (na + nb)))
}

/// Per pixel and channel of a `w × h` image whose halves' sums are `even` and `odd`
/// (`[r, g, b, samples]`), 1 / (reference² proxy + ε): the weight of the pixel's squared
/// error in the relative MSE. The proxy is the smaller of the halves' means over the 3×3
/// window (clipped at the image's edges, and over the pixels where that half has samples)
/// times the mean of the two.
pub fn relative_weights(even: &[[f32; 4]], odd: &[[f32; 4]], w: usize, h: usize) -> Vec<[f32; 3]> {
    assert_eq!(even.len(), w * h);
    assert_eq!(odd.len(), w * h);
    // Each half's mean, and 1 where it has samples (0: left out of the window).
    let means: Vec<[[f32; 4]; 2]> = (0..w * h)
        .into_par_iter()
        .map(|p| {
            [even[p], odd[p]].map(|half| {
                let [r, g, b] = half_mean(half);
                [r, g, b, if half[3] > 0.0 { 1.0 } else { 0.0 }]
            })
        })
        .collect();
    let r = PROXY_RADIUS;
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (x, y) = (p % w, p / w);
            let mut sums = [[0.0f32; 4]; 2];
            for qy in y.saturating_sub(r)..(y + r + 1).min(h) {
                let row = qy * w;
                for cell in &means[row + x.saturating_sub(r)..row + (x + r + 1).min(w)] {
                    for (k, m) in cell.iter().enumerate() {
                        for c in 0..4 {
                            sums[k][c] += m[c];
                        }
                    }
                }
            }
            std::array::from_fn(|c| {
                let a = sums[0][c] / sums[0][3].max(1.0);
                let b = sums[1][c] / sums[1][3].max(1.0);
                let square = a.min(b).max(0.0) * (0.5 * (a + b)).max(0.0);
                1.0 / (square + REL_MSE_EPSILON as f32)
            })
        })
        .collect()
}

/// The weight of a pixel's squared error in the denoiser's per-tile choice (its relative
/// sums), from the channel's half means `a` and `b`: 1 / (A·B + ε), the unbiased
/// per-pixel estimate of reference² that the choice was tuned with. The choice keeps it:
/// chosen with the error estimate's proxy instead, the shown images lost against Open Image
/// Denoise (cornell at 16 spp 4.93 % against 4.22 %; BENCHMARKS.md, "An honest error
/// estimate"). Where the choice reads a firefly as small, the shown image's estimate, made
/// with `relative_weights`, does not.
pub fn choice_weight(a: f64, b: f64) -> f64 {
    1.0 / ((a * b).max(0.0) + REL_MSE_EPSILON)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_firefly_in_one_half_raises_the_proxy_by_the_root_of_its_share() {
        // A 3×3 image of value 0.5 in both halves, but for a firefly of 9.5 in the centre of
        // the even half: at the centre that half's window mean is 1.5, the smaller one 0.5, the pooled one
        // 1.0; the proxy 0.5 · 1.0 (A·B would say 9.5 · 0.5 at the centre).
        let mut even = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        let odd = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        even[4] = [9.5, 9.5, 9.5, 1.0];
        let wts = relative_weights(&even, &odd, 3, 3);
        assert!(
            (wts[4][0] - 1.0 / (0.5 + 0.01)).abs() < 1e-4,
            "{:?}",
            wts[4]
        );
    }

    #[test]
    fn the_window_is_clipped_at_the_edges_and_skips_empty_halves() {
        // A 2×1 image: pixel 0 even half empty, so the even window is pixel 1's alone.
        let even = vec![[0.0, 0.0, 0.0, 0.0], [0.8, 0.8, 0.8, 2.0]];
        let odd = vec![[0.2, 0.2, 0.2, 1.0], [0.2, 0.2, 0.2, 1.0]];
        let wts = relative_weights(&even, &odd, 2, 1);
        // even window mean 0.4, odd 0.2: proxy 0.2 · 0.3.
        assert!((wts[0][1] - 1.0 / 0.07).abs() < 1e-3, "{:?}", wts[0]);
    }

    #[test]
    fn the_pair_factor_is_a_quarter_for_equal_halves_and_waits_for_samples() {
        assert_eq!(pair_factor(8.0, 8.0), Some(0.25));
        assert_eq!(pair_factor(0.0, 8.0), None);
    }
}
