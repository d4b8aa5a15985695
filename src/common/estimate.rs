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
//! **The reference² proxy.** The estimate divides each pixel's (A − B)² by a proxy of its
//! reference², which must not grow with the pixel's own noise: a firefly in one half makes
//! (A − B)² large, and a proxy that grows with it (A·B, or any window mean that holds the
//! pixel) counts that pixel's error for little exactly where it is large. Such proxies made
//! the estimate's *expectation* 0.14–0.52 of the true relative MSE's on the firefly scenes,
//! though a run's figure often looked right (BENCHMARKS.md, "An estimate that counts
//! fireflies"). The proxy is now the mean of the pixel's 3×3 neighbours, which its own
//! samples do not touch, at most the larger of its two half means (a dark pixel beside an
//! emitter is not divided by the emitter) and at least what its halves agree on: the
//! smaller half mean where the larger is within [`SPIKE`] times it, else less, down to half
//! of it where the larger is 2·SPIKE times it or more (`proxy_weight`). So a pixel that both
//! halves find far brighter than its neighbours (a lamp, the sun's image in a mirror ball) is
//! not divided by its darker neighbours. The lower bound was the smaller half mean itself
//! until a firefly scene showed it reading the error low: where the pixel's light has a
//! heavy tail (the sun's thin ring in `outdoor`'s glossy red ball), the run whose one sample
//! of about 20 000 holds the pixel's error had its other half lifted by the ring's own
//! samples (1.33 against a reference of 0.76), and divided by it the error read 0.33 of its
//! truth; the estimate of `outdoor` at 64 spp read 0.62 of the truth in expectation
//! (BENCHMARKS.md, "A glossy lobe mixed with the diffuse one"). With the exact reference as
//! the proxy the expectation is right on every shipped scene (tests/estimate.rs,
//! `the_reference_as_the_proxy`), so what is left is the proxy's: a
//! bright path that only one half found, where the neighbours did not, reads as a firefly
//! even where it is the pixel's usual light (`pbr`'s glossy highlights of small lamps and the
//! caustic scene read up to 2.5× high). The denoiser's estimates of its filtered images divide
//! by the product of the filter's two outputs instead (`product_weight`, which says why), or
//! by the smaller half where a filter crushes a spike both halves see (`filtered_weight`).

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

/// The pixels of pixel `p`'s window in a `w × h` image (radius `PROXY_RADIUS`, clipped at
/// the edges), row by row: the order the GPU sums them in.
fn window(p: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y, r) = (p % w, p / w, PROXY_RADIUS);
    (y.saturating_sub(r)..(y + r + 1).min(h))
        .flat_map(move |qy| (x.saturating_sub(r)..(x + r + 1).min(w)).map(move |qx| qy * w + qx))
}

/// A pixel's terms for the proxy, per channel: its mean (the mean of its halves' means where
/// both have samples, else the one half's), and the smaller and the larger of its halves'
/// means; `None` without samples.
type ProxyTerms = ([f32; 3], [f32; 3], [f32; 3]);

fn proxy_terms(e: [f32; 4], o: [f32; 4]) -> Option<ProxyTerms> {
    let (a, b) = (half_mean(e), half_mean(o));
    match (e[3] > 0.0, o[3] > 0.0) {
        (true, true) => Some((
            std::array::from_fn(|c| 0.5 * (a[c] + b[c])),
            std::array::from_fn(|c| a[c].min(b[c])),
            std::array::from_fn(|c| a[c].max(b[c])),
        )),
        (true, false) => Some((a, a, a)),
        (false, true) => Some((b, b, b)),
        (false, false) => None,
    }
}

/// 1 / (proxy² + ε) from a pixel's mean `m`, its halves' smaller and larger means `lo` and
/// `hi`, and its neighbours' mean `n` (`None` without neighbours): the proxy is `n` clamped
/// to [lift, hi] (`hi` first), or `m` without neighbours. The lift is `lo` where the halves
/// agree within a factor [`SPIKE`], falling as lo · SPIKE · lo / hi to lo / SPIKE where they
/// disagree by 2·SPIKE or more: a spike in one half does not lift the proxy by the other's.
fn proxy_weight(m: f32, lo: f32, hi: f32, n: Option<f32>) -> f32 {
    let spike = SPIKE as f32;
    let lift = if hi > 0.0 {
        lo * (spike * lo / hi).clamp(1.0 / spike, 1.0)
    } else {
        0.0
    };
    let v = n.map_or(m, |n| n.min(hi).max(lift)).max(0.0);
    1.0 / (v * v + REL_MSE_EPSILON as f32)
}

/// Per pixel and channel of a `w × h` image whose halves' sums are `even` and `odd`
/// (`[r, g, b, samples]`), 1 / (reference² proxy + ε): the weight of the pixel's squared
/// error in the relative MSE. The proxy is the mean of its 3×3 neighbours' means (clipped at
/// the image's edges, over the neighbours with samples; the pixel itself left out), at most
/// the larger of the pixel's two half means and at least what they agree on (`proxy_weight`).
pub fn relative_weights(even: &[[f32; 4]], odd: &[[f32; 4]], w: usize, h: usize) -> Vec<[f32; 3]> {
    assert_eq!(even.len(), w * h);
    assert_eq!(odd.len(), w * h);
    let terms: Vec<Option<ProxyTerms>> = (0..w * h)
        .into_par_iter()
        .map(|p| proxy_terms(even[p], odd[p]))
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (mut sum, mut count) = ([0.0f32; 3], 0.0f32);
            for q in window(p, w, h) {
                if let (true, Some((m, _, _))) = (q != p, terms[q]) {
                    for c in 0..3 {
                        sum[c] += m[c];
                    }
                    count += 1.0;
                }
            }
            let (m, lo, hi) = terms[p].unwrap_or(([0.0; 3], [0.0; 3], [0.0; 3]));
            std::array::from_fn(|c| {
                proxy_weight(m[c], lo[c], hi[c], (count > 0.0).then(|| sum[c] / count))
            })
        })
        .collect()
}

/// 1 / (max(a·b, 0) + ε) from two independent estimates `a` and `b` of one channel's value:
/// their product is an unbiased estimate of its square, which no proxy that reads one of
/// them twice is. Two uses:
/// - **The denoiser's per-tile choice**, with the pixel's half means A and B: the choice was
///   tuned with it, and chosen with the error estimate's proxy instead the shown images lost
///   against Open Image Denoise (cornell at 16 spp 4.93 % against 4.22 %; BENCHMARKS.md, "An
///   honest error estimate"). Where the choice reads a firefly as small, the shown image's
///   estimate, made with [`relative_weights`] for raw tiles, does not.
/// - **The estimate of a filtered image**, with the filter's two outputs D(A) and D(B) at the
///   pixel: its terms are differences of large ones (src/denoise/mod.rs, "The estimator"),
///   unbiased only where the weight hardly follows the pixel's own halves, as a filtered half
///   does (it averages many pixels). The halves' 3×3 means, used before, held the pixel's
///   own firefly and read the shown estimate 0.69–0.79 of the truth on `cornell` and `basic`
///   in the first samples; the raw estimate's clamp reads the pixel's halves themselves, and
///   made the shown estimate 10× the truth at one sample a half (tests/denoise.rs).
pub fn product_weight(a: f64, b: f64) -> f64 {
    1.0 / ((a * b).max(0.0) + REL_MSE_EPSILON)
}

/// How far a pixel's halves must disagree before their smaller mean stops lifting the raw
/// image's proxy (`proxy_weight`), and the factor by which both halves must exceed a filtered
/// value for their smaller mean, over `SPIKE`, to set a filtered image's weight
/// (`filtered_weight`).
pub const SPIKE: f64 = 2.0;

/// The weight of a filtered image's term at a pixel, from the filter's two outputs `da` and
/// `db` and the pixel's half means `a` and `b`: [`product_weight`] of the outputs, unless
/// both halves are more than [`SPIKE`] times as bright, then 1 / ((min(a, b)/SPIKE)² + ε).
/// A bright feature smaller than a pixel that every sample finds (the sun in a mirror ball,
/// `sample_view`) is crushed by the filters, so D(A)·D(B) falls far below its reference²,
/// and the term, the filter's bias there, read relative to it was up to 90× its truth: the
/// shown estimate on `pbr` at 16 spp read 3.14 of the true error. The smaller half is
/// large only where both halves are, so a firefly in one half leaves the weight as it was;
/// the margin keeps the ordinary pixels, where a half mean and the filtered value differ by
/// noise, on the product (with the margin 1 the shown estimate on `cornell` at 16 spp fell
/// to 0.73 of the truth; tests/estimate.rs, BENCHMARKS.md "The sun in a mirror ball, seen").
pub fn filtered_weight(da: f64, db: f64, a: f64, b: f64) -> f64 {
    let lo = a.min(b).max(0.0) / SPIKE;
    product_weight(da, db).min(1.0 / (lo * lo + REL_MSE_EPSILON))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Asserts that every channel of `w` is the weight of a proxy of `proxy`.
    fn weight_is(w: [f32; 3], proxy: f32) {
        let want = 1.0 / (proxy * proxy + REL_MSE_EPSILON as f32);
        assert!(
            w.iter().all(|v| (v - want).abs() < 1e-3 * want),
            "{w:?}: not {want}"
        );
    }

    #[test]
    fn a_firefly_in_one_half_leaves_the_proxy_at_its_neighbours() {
        // A 3×3 image of value 0.5 in both halves, but for a firefly of 9.5 in the centre of
        // the even half: the neighbours' mean is 0.5, inside [0.5, 9.5] (the centre's half
        // means), so the proxy is 0.5, as without the firefly (A·B would say 9.5 · 0.5).
        let mut even = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        let odd = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        even[4] = [9.5, 9.5, 9.5, 1.0];
        let wts = relative_weights(&even, &odd, 3, 3);
        weight_is(wts[4], 0.5);
        // A neighbour of the firefly: its neighbours' mean (0.5·7 + 5.0)/8 is above both of
        // its half means, 0.5, which cap it.
        weight_is(wts[1], 0.5);
    }

    #[test]
    fn a_pixel_both_halves_find_bright_keeps_what_they_agree_on() {
        // A highlight: 4.0 and 3.0 in the centre's halves, 0.5 around. The halves agree
        // within SPIKE, so the smaller half mean, 3.0, is the proxy.
        let mut even = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        let mut odd = vec![[0.5, 0.5, 0.5, 1.0]; 9];
        let centre = |even: &mut Vec<[f32; 4]>, odd: &mut Vec<[f32; 4]>, a: f32, b: f32| {
            even[4] = [a, a, a, 1.0];
            odd[4] = [b, b, b, 1.0];
        };
        centre(&mut even, &mut odd, 4.0, 3.0);
        weight_is(relative_weights(&even, &odd, 3, 3)[4], 3.0);
        // 4.0 and 1.5 disagree by more: 1.5 · (2 · 1.5 / 4.0) = 1.125.
        centre(&mut even, &mut odd, 4.0, 1.5);
        weight_is(relative_weights(&even, &odd, 3, 3)[4], 1.125);
        // A spike in one half, 9.0, over 1.5: the lift falls to half the smaller, 0.75.
        centre(&mut even, &mut odd, 9.0, 1.5);
        weight_is(relative_weights(&even, &odd, 3, 3)[4], 0.75);
        // At 1.2 and 0.8 the lift, 0.8, is above the neighbours' 0.5.
        centre(&mut even, &mut odd, 1.2, 0.8);
        weight_is(relative_weights(&even, &odd, 3, 3)[4], 0.8);
    }

    #[test]
    fn the_window_is_clipped_at_the_edges_and_skips_empty_pixels() {
        // A 3×1 image: pixel 0 has no samples, so pixel 1's only neighbour with samples is
        // pixel 2 (mean 0.2), inside pixel 1's half means [0.1, 0.4].
        let even = vec![[0.0; 4], [0.8, 0.8, 0.8, 2.0], [0.2, 0.2, 0.2, 1.0]];
        let odd = vec![[0.0; 4], [0.1, 0.1, 0.1, 1.0], [0.2, 0.2, 0.2, 1.0]];
        let wts = relative_weights(&even, &odd, 3, 1);
        weight_is(wts[1], 0.2);
        // A 1×1 image has no neighbours: the proxy is the pixel's mean, 0.25.
        let wts = relative_weights(&even[1..2], &odd[1..2], 1, 1);
        weight_is(wts[0], 0.25);
    }

    #[test]
    fn the_pair_factor_is_a_quarter_for_equal_halves_and_waits_for_samples() {
        assert_eq!(pair_factor(8.0, 8.0), Some(0.25));
        assert_eq!(pair_factor(0.0, 8.0), None);
    }
}
