//! An environment map's directions and its importance sampling, the same arithmetic for both
//! tracers (`common::envmap` lays it out for the GPU; shaders/common/envmap.wgsl mirrors it):
//! RGBE texels, the equirectangular mapping from a direction to the map's (u, v), the
//! bilinear lookup, and a piecewise-constant 2D distribution over the texels (their light
//! above the map's mean: MIS compensation, `Distribution::build`), sampled by
//! inverting a marginal CDF over rows and a conditional CDF within the row (Pharr, Jakob and
//! Humphreys, "Physically Based Rendering", 4th ed., §A.5.6 and §12.5.2). CDFs rather than
//! alias tables: the inversion is continuous (neighbouring random numbers give neighbouring
//! directions, which stratified and Sobol samples need), and a binary search of log₂(4096) =
//! 12 steps costs little beside a path segment.

pub use super::color::luminance;
use super::trig::{FRAC_1_TAU, acos_over_pi, atan2_turns, sin_cos_turns};
use glam::Vec3;
use std::f32::consts::PI;

/// One texel as both tracers store it: Radiance's RGBE, three 8-bit mantissas and a shared
/// 8-bit exponent, value = m × 2^(e − 136) (Ward, "Real Pixels", Graphics Gems II, 1991).
/// Four bytes a texel (an 8k map is 128 MiB, not 384), a range of 2^±127 (a sun of 10⁵ next
/// to a sky of 10⁻³ fits, which half floats do not), and lossless for `.hdr` files, which
/// hold exactly these numbers: `image` decodes them as m × 2^(e − 136), and this packing
/// gives the same bytes back. An EXR's channels keep 8 bits relative to the texel's
/// brightest one (0.4 % at worst). Bytes r, g, b, e from the lowest.
pub fn rgbe_pack(c: [f32; 3]) -> u32 {
    let v = c[0].max(c[1]).max(c[2]);
    // Below 2^-100 is black: both tracers then decode only normal floats.
    if v.is_nan() || v < 2f32.powi(-100) {
        return 0;
    }
    // v = f × 2^k with f in [0.5, 1): the brightest mantissa f × 256 is in [128, 256).
    let mut k = v.log2().floor() as i32 + 1;
    let scale = |k: i32| 2f32.powi(8 - k);
    // log2 may round across a power of two: put v × 2^(8−k) in [128, 256) exactly.
    while v * scale(k) >= 256.0 {
        k += 1;
    }
    while v * scale(k) < 128.0 {
        k -= 1;
    }
    if k + 128 > 255 {
        // Beyond 2^127: the largest value RGBE holds.
        return 0xffff_ffff;
    }
    let m = |x: f32| ((x * scale(k) + 0.5).floor() as u32).min(255);
    let (r, g, b) = (m(c[0]), m(c[1]), m(c[2]));
    // Rounding the brightest up to 256 is one more step of the exponent.
    if r.max(g).max(b) > 255 || v * scale(k) + 0.5 >= 256.0 {
        let m2 = |x: f32| ((x * scale(k + 1) + 0.5).floor() as u32).min(255);
        return m2(c[0]) | m2(c[1]) << 8 | m2(c[2]) << 16 | ((k + 1 + 128) as u32) << 24;
    }
    r | g << 8 | b << 16 | ((k + 128) as u32) << 24
}

/// A packed texel's radiance (as `env_texel` in shaders/common/envmap.wgsl decodes it).
pub fn rgbe_unpack(w: u32) -> [f32; 3] {
    let e = w >> 24;
    if e == 0 {
        return [0.0; 3];
    }
    // 2^(e − 136) built from its bits, as env_texel does (e ≥ 10: a normal float; `rgbe_pack`
    // writes e ≥ 29): `powi` was a libcall, four per bilinear lookup.
    let f = if e >= 10 {
        f32::from_bits((e - 9) << 23)
    } else {
        2f32.powi(e as i32 - 136)
    };
    [
        (w & 0xff) as f32 * f,
        (w >> 8 & 0xff) as f32 * f,
        (w >> 16 & 0xff) as f32 * f,
    ]
}

/// The direction of map coordinates (u, v) ∈ [0, 1]², `rotation` in radians about +y: v runs
/// from the zenith (+y, v = 0) to the nadir; u = ½ looks down −z (the default camera's view,
/// so a panorama's middle is seen straight ahead) and u = ¾ towards +x (its right half to
/// the right): φ = 2πu + rotation, d = (−sin θ sin φ, cos θ, sin θ cos φ).
pub fn direction(u: f32, v: f32, rotation: f32) -> Vec3 {
    direction_and_sin(u, v, rotation).0
}

/// [`direction`] and sin θ = sin πv, which the density divides by.
/// The angles in turns (`scene::trig`, whose polynomials the CPU tracer's lanes repeat):
/// θ = v/2 turns, φ = u + rotation/2π turns, brought into [0, 1].
#[inline(always)]
fn direction_and_sin(u: f32, v: f32, rotation: f32) -> (Vec3, f32) {
    let (sin_t, cos_t) = sin_cos_turns(0.5 * v);
    let phi = u + rotation * FRAC_1_TAU;
    let (sin_p, cos_p) = sin_cos_turns(phi - floor(phi));
    (Vec3::new(-sin_t * sin_p, cos_t, sin_t * cos_p), sin_t)
}

/// The map coordinates of unit direction `d` (the inverse of [`direction`]), u in [0, 1).
/// (`env_coordinates` in shaders/common/envmap.wgsl, the same formula; here acos and atan2
/// are `scene::trig`'s polynomials, in turns.)
#[inline(always)]
pub fn coordinates(d: Vec3, rotation: f32) -> (f32, f32) {
    let v = acos_over_pi(d.y.clamp(-1.0, 1.0));
    let turns = atan2_turns(-d.x, d.z) - rotation * FRAC_1_TAU;
    let u = turns - floor(turns);
    (if u >= 1.0 { 0.0 } else { u }, v)
}

/// `x.floor()` without libm's `floorf` (a call on x86-64 below SSE4.1, three per escaped ray
/// and per light sample of a map): the same value wherever |x| < 2²³ (exactly representable
/// integers, which truncation finds), `floorf` elsewhere (NaN, huge); tested bit for bit.
#[inline(always)]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        // (`copysign`: floorf(-0) is -0.)
        let t = x as i32 as f32;
        if t > x { t - 1.0 } else { t.copysign(x) }
    } else {
        x.floor()
    }
}

/// The radiance at map coordinates (u, v) of a `width × height` map whose texel (x, y) is
/// `texel(x, y)`: bilinear between the four nearest texel centres, wrapping around in u and
/// clamped at the poles in v (`env_lookup` in shaders/common/envmap.wgsl). Each step is
/// a + t (b − a), so that equal texels give exactly their value.
pub fn bilinear(
    width: u32,
    height: u32,
    u: f32,
    v: f32,
    texel: impl Fn(u32, u32) -> [f32; 3],
) -> [f32; 3] {
    let fx = u * width as f32 - 0.5;
    let fy = (v * height as f32 - 0.5).max(0.0);
    let (x0f, y0f) = (floor(fx), floor(fy));
    let (tx, ty) = (fx - x0f, fy - y0f);
    // Wrapped in u without a division (u in [0, 1] puts x0f in [-1, width]).
    let x0 = match x0f as i64 {
        -1 => width - 1,
        x if (0..width as i64).contains(&x) => x as u32,
        x => x.rem_euclid(width as i64) as u32,
    };
    let x1 = if x0 + 1 == width { 0 } else { x0 + 1 };
    let y0 = (y0f as u32).min(height - 1);
    let y1 = (y0 + 1).min(height - 1);
    let lerp = |a: [f32; 3], b: [f32; 3], t: f32| {
        [
            a[0] + t * (b[0] - a[0]),
            a[1] + t * (b[1] - a[1]),
            a[2] + t * (b[2] - a[2]),
        ]
    };
    let top = lerp(texel(x0, y0), texel(x1, y0), tx);
    let bottom = lerp(texel(x0, y1), texel(x1, y1), tx);
    lerp(top, bottom, ty)
}

/// A hint that `at` will be read soon (x86-64's `prefetcht0`; nothing elsewhere).
#[inline(always)]
pub(crate) fn prefetch<T>(at: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing and cannot fault; `at` is a live reference.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((at as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = at;
}

/// The sampling distribution of a `width × height` map: for each row the CDF of its texels
/// (`width + 1` entries, from 0 to 1), and the CDF of the rows (`height + 1`). Built in f64,
/// stored in f32, which is what both tracers read.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution {
    pub width: u32,
    pub height: u32,
    /// Row-major conditional CDFs, `height × (width + 1)`.
    pub conditional: Vec<f32>,
    /// The marginal CDF over rows, `height + 1`.
    pub marginal: Vec<f32>,
    /// The integral of the weights over [0, 1]² (their mean): the piecewise-constant density
    /// of texel (x, y) is its weight / `integral`. Zero when the map is black (and only
    /// then: a map with nothing above its mean is weighted by its luminance alone).
    pub integral: f64,
    /// Guide tables of the CDFs (`guide`): the marginal's, and the conditionals' row by row,
    /// `height × (guide_buckets + 1)`. The native CPU tracer's; the GPU searches the CDFs
    /// whole and finds the same intervals.
    guide_marginal: Vec<u32>,
    guide_conditional: Vec<u32>,
    /// Buckets of each conditional's guide table.
    guide_buckets: usize,
}

/// One sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub dir: Vec3,
    /// The density with respect to solid angle (0 where the map is black).
    pub pdf: f32,
    /// The texel the sample fell in.
    pub texel: (u32, u32),
    /// Its map coordinates (u, v), from which `dir` was made: the radiance is looked up here,
    /// not at the coordinates recomputed from `dir` (acos and atan2 would add their rounding).
    pub uv: (f32, f32),
}

/// A guide table over a CDF of `n + 1` entries (the cutpoint method: Chen and Asau, "On
/// generating random variates from an empirical distribution", AIIE Transactions 6(2), 1974;
/// Devroye, "Non-Uniform Random Variate Generation", 1986, §III.2.4): for each of `buckets`
/// equal parts of [0, 1) (a power of two, so that `u × buckets` is exact), the last interval
/// whose start is at most the part's start. Inverting u then searches only the intervals its
/// part spans, one or two on average instead of log₂ n, and finds the very interval the whole
/// search finds (`invert_guided`): the images do not change. The issue that built maps
/// measured 15–20 % of an HDR-lit scene's time in the two searches (issue 47).
fn guide(cdf: &[f32], buckets: usize) -> impl Iterator<Item = u32> + '_ {
    let n = cdf.len() - 1;
    let mut i = 0;
    (0..=buckets).map(move |k| {
        let t = k as f32 / buckets as f32;
        while i + 1 < n && cdf[i + 1] <= t {
            i += 1;
        }
        i as u32
    })
}

/// `invert` through a guide table of `cdf` (`guide`, `guide.len() - 1` buckets): the same
/// interval and place in it.
fn invert_guided(cdf: &[f32], guide: &[u32], u: f32) -> (usize, f32) {
    let buckets = guide.len() - 1;
    let n = cdf.len() - 1;
    let k = ((u * buckets as f32) as usize).min(buckets - 1);
    // cdf[lo] ≤ k / buckets ≤ u, and cdf[hi] > (k + 1) / buckets > u unless hi = n: the last
    // i with cdf[i] ≤ u lies in [lo, hi), where the search of `invert` ends too.
    search(
        cdf,
        u,
        guide[k] as usize,
        (guide[k + 1] as usize + 1).min(n),
    )
}

/// The last interval i in [lo, hi) of `cdf` with cdf[i] ≤ u, given cdf[lo] ≤ u and cdf[hi] > u
/// (or hi the last interval's end), by bisection; and u's place in it.
fn search(cdf: &[f32], u: f32, mut lo: usize, mut hi: usize) -> (usize, f32) {
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if cdf[mid] <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let width = cdf[lo + 1] - cdf[lo];
    let t = if width > 0.0 {
        ((u - cdf[lo]) / width).clamp(0.0, 1.0)
    } else {
        0.5
    };
    (lo, t)
}

/// Buckets of a guide table over `n` intervals: about one interval each for the marginal; a
/// quarter of that for each row's (a row's table takes a quarter of its CDF's memory, and its
/// search two steps more).
fn buckets(n: usize, per_bucket: usize) -> usize {
    (n / per_bucket).max(1).next_power_of_two()
}

impl Distribution {
    /// The distribution of `texels` (row-major, rows from the top): each texel weighted by the
    /// luminance of the bilinear lookup averaged over its area, less the map's mean over the
    /// sphere where that leaves anything (MIS compensation, below), × sin θ at its row's
    /// centre (the solid angle it spans).
    pub fn new(width: u32, height: u32, texels: &[[f32; 3]]) -> Distribution {
        Self::build(width, height, texels, true)
    }

    /// [`Distribution::new`], or with `compensate` false the texels' luminance alone (what
    /// the tracers sampled before; the tests compare the two).
    ///
    /// MIS compensation (Karlík, Šik, Vévoda, Skřivan and Křivánek, "MIS Compensation:
    /// Optimizing Sampling Techniques in Multiple Importance Sampling", ACM TOG 38(6), 2019,
    /// §5): light sampling is always combined with the BSDF's sampling, which finds the dim,
    /// even part of a sky well, so the map's distribution takes the sphere's mean radiance off
    /// every texel and samples only the excess: a sun and the bright sky near it get the light
    /// samples that the dim sky took. Texels at or below the mean get density 0 and are found
    /// by the BSDF's samples alone, whose MIS weight is then 1: unbiased. A map with nothing
    /// above its mean (a constant one) keeps the luminance alone, so that its light sampling
    /// is not left with nothing to sample.
    pub fn build(width: u32, height: u32, texels: &[[f32; 3]], compensate: bool) -> Distribution {
        let (w, h) = (width as usize, height as usize);
        assert_eq!(texels.len(), w * h, "texels of a {width}×{height} map");
        // Rows in parallel: each row's CDF is its own.
        use rayon::prelude::*;
        // Each texel's weight is the mean over its area of the bilinear radiance the tracers
        // look up (`bilinear`): in each direction ¾ of the texel and ⅛ of either neighbour
        // (wrapping in u, clamped at the poles), so that wherever the lookup sees more light
        // than the mean, the density is above zero (pbrt-v4's ImageInfiniteLight blurs alike).
        // In f32 (an 8k map's two passes take 256 MiB, not 512); the sums below are f64.
        let lum: Vec<f32> = texels.par_iter().map(|t| luminance(*t).max(0.0)).collect();
        let across: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let at = |x: usize| lum[y * w + x];
                0.75 * at(x) + 0.125 * (at((x + w - 1) % w) + at((x + 1) % w))
            })
            .collect();
        drop(lum);
        let sin_of = |y: usize| (std::f64::consts::PI * (y as f64 + 0.5) / h as f64).sin();
        // Row y's blurred weights, before the sine.
        let blurred = |y: usize| {
            let row = |y: usize| &across[y * w..(y + 1) * w];
            let (above, here, below) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)));
            (0..w).map(move |x| 0.75 * here[x] as f64 + 0.125 * (above[x] as f64 + below[x] as f64))
        };
        // The mean over the sphere: Σ weight × sin θ / Σ sin θ.
        let mean = if compensate {
            let (sum, solid): (f64, f64) = (0..h)
                .into_par_iter()
                .map(|y| (blurred(y).sum::<f64>() * sin_of(y), w as f64 * sin_of(y)))
                .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
            sum / solid
        } else {
            0.0
        };
        // The conditional CDFs and each row's mean weight × sin θ, with `less` taken off every
        // texel's weight.
        let rows_with = |less: f64| {
            let mut conditional = vec![0f32; h * (w + 1)];
            let rows: Vec<f64> = conditional
                .par_chunks_mut(w + 1)
                .enumerate()
                .map(|(y, cdf)| {
                    let sin_t = sin_of(y);
                    let mut sum = 0f64;
                    cdf[0] = 0.0;
                    // The running sums in f64 first (in place of the f32 CDF would lose them).
                    let mut acc = Vec::with_capacity(w);
                    for weight in blurred(y) {
                        sum += (weight - less).max(0.0) * sin_t;
                        acc.push(sum);
                    }
                    for (x, a) in acc.iter().enumerate() {
                        // A black row's CDF is uniform; the marginal never picks it.
                        cdf[x + 1] = if sum > 0.0 {
                            (a / sum) as f32
                        } else {
                            (x + 1) as f32 / w as f32
                        };
                    }
                    cdf[w] = 1.0;
                    sum / w as f64
                })
                .collect();
            (conditional, rows)
        };
        let (mut conditional, mut rows) = rows_with(mean);
        if mean > 0.0 && rows.iter().all(|&r| r <= 0.0) {
            (conditional, rows) = rows_with(0.0);
        }
        let total: f64 = rows.iter().sum();
        let mut marginal = Vec::with_capacity(h + 1);
        let mut acc = 0f64;
        marginal.push(0f32);
        for r in &rows {
            acc += r;
            marginal.push(if total > 0.0 {
                (acc / total) as f32
            } else {
                0.0
            });
        }
        marginal[h] = 1.0;
        let guide_marginal = guide(&marginal, buckets(h, 1)).collect();
        let guide_buckets = buckets(w, 4);
        let guide_conditional = conditional
            .par_chunks(w + 1)
            .flat_map_iter(|cdf| guide(cdf, guide_buckets).collect::<Vec<_>>())
            .collect();
        Distribution {
            width,
            height,
            conditional,
            marginal,
            integral: total / h as f64,
            guide_marginal,
            guide_conditional,
            guide_buckets,
        }
    }

    /// The conditional CDF of row `y`.
    fn row(&self, y: usize) -> &[f32] {
        let w = self.width as usize + 1;
        &self.conditional[y * w..(y + 1) * w]
    }

    /// The density over [0, 1]² of texel (x, y) (its weight / the integral), from the CDFs.
    fn density_uv(&self, x: usize, y: usize) -> f32 {
        let (w, h) = (self.width as f32, self.height as f32);
        let row = self.row(y);
        (self.marginal[y + 1] - self.marginal[y]) * h * (row[x + 1] - row[x]) * w
    }

    /// A direction for the random numbers (u1, u2) ∈ [0, 1)², with its solid-angle density.
    pub fn sample(&self, u1: f32, u2: f32, rotation: f32) -> Sample {
        let (y, ty) = invert_guided(&self.marginal, &self.guide_marginal, u2);
        let g = self.guide_buckets + 1;
        let (x, tx) = invert_guided(self.row(y), &self.guide_conditional[y * g..(y + 1) * g], u1);
        let u = (x as f32 + tx) / self.width as f32;
        let v = (y as f32 + ty) / self.height as f32;
        let (dir, sin_t) = direction_and_sin(u, v, rotation);
        let pdf = if sin_t > 0.0 && self.integral > 0.0 {
            self.density_uv(x, y) / (2.0 * PI * PI * sin_t)
        } else {
            0.0
        };
        Sample {
            dir,
            pdf,
            texel: (x as u32, y as u32),
            uv: (u, v),
        }
    }

    /// The texel map coordinates (u, v) fall in, and v (`env_texel_at` in
    /// shaders/common/envmap.wgsl, the same arithmetic).
    pub fn texel_at(&self, u: f32, v: f32) -> (u32, u32, f32) {
        let x = ((u * self.width as f32) as u32).min(self.width - 1);
        let y = ((v * self.height as f32) as u32).min(self.height - 1);
        (x, y, v)
    }

    /// The solid-angle density with which [`Distribution::sample`] gives unit direction `d`.
    pub fn pdf(&self, d: Vec3, rotation: f32) -> f32 {
        let (u, v) = coordinates(d, rotation);
        self.pdf_at(u, v)
    }

    /// [`Distribution::pdf`] of the direction at map coordinates (u, v) (`coordinates`): a
    /// ray that escapes computes them once for the radiance and the density.
    pub fn pdf_at(&self, u: f32, v: f32) -> f32 {
        if self.integral <= 0.0 {
            return 0.0;
        }
        let (x, y, v) = self.texel_at(u, v);
        let sin_t = sin_cos_turns(0.5 * v).0;
        if sin_t <= 0.0 {
            return 0.0;
        }
        self.density_uv(x as usize, y as usize) / (2.0 * PI * PI * sin_t)
    }

    /// The guide tables (the marginal's, the rows', row by row) and the buckets of a row's:
    /// what the CPU tracer's lanes gather from.
    pub fn guides(&self) -> (&[u32], &[u32], usize) {
        (
            &self.guide_marginal,
            &self.guide_conditional,
            self.guide_buckets,
        )
    }

    /// Bytes the CDFs take, as both tracers hold them (the host's guide tables add about a
    /// quarter of this on the CPU tracer).
    pub fn bytes(&self) -> usize {
        4 * (self.conditional.len() + self.marginal.len())
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Inverts a CDF of `n + 1` entries at `u`: the interval i with cdf[i] ≤ u < cdf[i + 1] (a
    /// zero-width interval is never returned while a wider one holds u) and u's place in it: the
    /// whole search, as shaders/common/envmap.wgsl does it, which `invert_guided` shortens.
    fn invert(cdf: &[f32], u: f32) -> (usize, f32) {
        search(cdf, u, 0, cdf.len() - 1)
    }

    #[test]
    fn a_guided_inversion_finds_the_interval_the_whole_search_finds() {
        // CDFs with zero-width intervals (black texels), steps far narrower than a bucket (a
        // sun) and ends that meet the buckets' edges exactly; every u on a fine grid, the
        // edges themselves and their neighbours in f32.
        let cdfs: Vec<Vec<f32>> = vec![
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 1.0, 1.0],
            vec![0.0, 0.25, 0.5, 0.75, 1.0],
            vec![0.0, 1e-7, 1e-6, 0.999_999, 1.0],
            (0..=1000).map(|i| (i as f32 / 1000.0).powi(8)).collect(),
            (0..=777)
                .map(|i| {
                    if i < 700 {
                        0.0
                    } else {
                        (i - 700) as f32 / 77.0
                    }
                })
                .collect(),
        ];
        for cdf in &cdfs {
            for per in [1, 4, 64] {
                let g: Vec<u32> = guide(cdf, buckets(cdf.len() - 1, per)).collect();
                let mut us: Vec<f32> = (0..20_000).map(|i| i as f32 / 20_000.0).collect();
                for &c in cdf.iter().chain(&[0.5, 0.25]) {
                    us.extend([
                        c,
                        f32::from_bits(c.to_bits().saturating_sub(1)),
                        c.next_up(),
                    ]);
                }
                for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                    assert_eq!(invert_guided(cdf, &g, u), invert(cdf, u), "u = {u}");
                }
            }
        }
    }

    #[test]
    fn directions_and_coordinates_are_inverse_and_face_as_documented() {
        for &(u, v) in &[(0.1, 0.2), (0.5, 0.5), (0.75, 0.5), (0.99, 0.9), (0.0, 0.3)] {
            for rot in [0.0, 1.0, -2.5] {
                let d = direction(u, v, rot);
                assert!((d.length() - 1.0).abs() < 1e-5);
                let (u2, v2) = coordinates(d, rot);
                let du = (u2 - u).abs().min(1.0 - (u2 - u).abs());
                assert!(du < 1e-4 && (v2 - v).abs() < 1e-4, "{u},{v} → {u2},{v2}");
            }
        }
        assert!(direction(0.5, 0.5, 0.0).abs_diff_eq(Vec3::NEG_Z, 1e-6));
        assert!(direction(0.75, 0.5, 0.0).abs_diff_eq(Vec3::X, 1e-6));
        assert!(direction(0.3, 0.0, 0.0).abs_diff_eq(Vec3::Y, 1e-6));
    }

    #[test]
    fn the_floor_without_libm_is_floorf() {
        // Every f32 in [-4, 4] at a step of 2^-20 (the map's coordinates live in [-1, 2^16]),
        // the integers and their neighbours up to 2^24, and what only libm's can take.
        let mut xs: Vec<f32> = (-(4 << 20)..=(4 << 20))
            .map(|i| i as f32 / (1 << 20) as f32)
            .collect();
        for k in 0..=24 {
            let p = (1u32 << k) as f32;
            for x in [p, -p] {
                xs.extend([x, x.next_up(), x.next_down()]);
            }
        }
        xs.extend([
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.5,
            -0.5,
        ]);
        for x in xs {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "floor({x:e})");
        }
        assert!(floor(f32::NAN).is_nan());
    }

    #[test]
    fn rgbe_unpacks_every_exponent_as_a_power_of_two() {
        for e in 1..=255u32 {
            let [r, ..] = rgbe_unpack(128 | e << 24);
            assert_eq!(r, 128.0 * 2f32.powi(e as i32 - 136), "exponent {e}");
        }
    }

    #[test]
    fn rgbe_round_trips_radiance_files_and_keeps_eight_bits() {
        // Every value a .hdr file can hold (normalized: the brightest mantissa ≥ 128) packs
        // back to its own bytes.
        for e in [1u32, 100, 127, 128, 136, 150, 200, 255] {
            for (r, g, b) in [(128, 0, 0), (255, 255, 255), (200, 13, 128), (3, 129, 77)] {
                let w = r | g << 8 | b << 16 | e << 24;
                if e < 36 {
                    continue; // below 2^-100: packed as black
                }
                assert_eq!(rgbe_pack(rgbe_unpack(w)), w, "e {e} rgb {r} {g} {b}");
            }
        }
        for c in [
            [1.0, 1.0, 1.0],
            [1e5, 2e4, 3e3],
            [1e-3, 0.0, 5e-4],
            [0.9999, 0.5, 0.25],
        ] {
            let d = rgbe_unpack(rgbe_pack(c));
            let max = c[0].max(c[1]).max(c[2]);
            for i in 0..3 {
                assert!((d[i] - c[i]).abs() <= max / 256.0, "{c:?} → {d:?}");
            }
        }
        assert_eq!(rgbe_unpack(rgbe_pack([1.0; 3])), [1.0; 3]);
        assert_eq!(rgbe_pack([0.0; 3]), 0);
    }

    #[test]
    fn a_black_map_samples_nothing_and_a_black_row_is_never_chosen() {
        let black = Distribution::new(4, 2, &[[0.0; 3]; 8]);
        assert_eq!(black.integral, 0.0);
        assert_eq!(black.sample(0.3, 0.6, 0.0).pdf, 0.0);
        // Rows 0 and 1 black: the lookup sees no light in row 0, but some in row 1 (blended
        // with row 2), so without compensation row 0 is never chosen and row 1 is, rarely;
        // with it, row 1 is below the mean and never chosen either.
        let mut t = vec![[1.0f32; 3]; 16];
        t[..8].fill([0.0; 3]);
        for (compensate, row_1) in [(false, true), (true, false)] {
            let d = Distribution::build(4, 4, &t, compensate);
            let mut rows = [0; 4];
            for i in 0..1000 {
                let s = d.sample((i as f32 + 0.5) / 1000.0, (i as f32 * 0.3719) % 1.0, 0.0);
                rows[s.texel.1 as usize] += 1;
                assert!(s.pdf > 0.0);
            }
            assert_eq!(rows[0], 0, "{rows:?}");
            assert_eq!(rows[1] > 0, row_1, "{rows:?}");
            assert!(rows[1] < rows[2], "{rows:?}");
        }
    }

    #[test]
    fn without_compensation_the_density_is_above_zero_wherever_the_lookup_sees_light() {
        // One bright texel of an 8 × 4 map: the bilinear lookup spreads it half a texel into
        // each neighbour, which the density must cover.
        let mut t = vec![[0.0f32; 3]; 32];
        t[8 + 3] = [5.0; 3];
        let d = Distribution::build(8, 4, &t, false);
        let texel = |x: u32, y: u32| t[(y * 8 + x) as usize];
        let mut lit = 0;
        for i in 0..400 {
            let (u, v) = ((i % 20) as f32 / 20.0 + 0.01, (i / 20) as f32 / 20.0 + 0.01);
            let dir = direction(u, v, 0.0);
            let (cu, cv) = coordinates(dir, 0.0);
            if luminance(bilinear(8, 4, cu, cv, texel)) > 0.0 {
                lit += 1;
                assert!(d.pdf(dir, 0.0) > 0.0, "light at ({u}, {v}) but no density");
            }
        }
        assert!(lit > 10, "{lit}");
    }

    #[test]
    fn compensation_samples_the_light_above_the_mean_in_proportion_to_its_excess() {
        // Columns 0–3 of radiance 1, 4–7 of 3, every row alike: blurred across (¾ own, ⅛ each
        // neighbour, wrapping), columns 0–7 read 1.25, 1, 1, 1.25, 2.75, 3, 3, 2.75, whose
        // mean over the sphere is 2. Less the mean: 0 on the left half, then 0.75, 1, 1, 0.75.
        let t: Vec<[f32; 3]> = (0..32)
            .map(|i| if i % 8 < 4 { [1.0; 3] } else { [3.0; 3] })
            .collect();
        let d = Distribution::new(8, 4, &t);
        let pdf = |x: u32| d.pdf_at((x as f32 + 0.5) / 8.0, 0.375);
        for x in 0..4 {
            assert_eq!(pdf(x), 0.0, "column {x}");
        }
        let ratio = pdf(5) / pdf(4);
        assert!((ratio - 4.0 / 3.0).abs() < 1e-5, "{ratio}");
        // (Equal weights, equal densities but for the f32 CDFs' rounding.)
        let near = |a: f32, b: f32| (a / b - 1.0).abs() < 1e-5;
        assert!(
            near(pdf(5), pdf(6)) && near(pdf(4), pdf(7)),
            "{:?}",
            (4..8).map(pdf).collect::<Vec<_>>()
        );
        // Without it, the blurred luminance alone: 3 against 2.75.
        let plain = Distribution::build(8, 4, &t, false);
        let ratio = plain.pdf_at(5.5 / 8.0, 0.375) / plain.pdf_at(4.5 / 8.0, 0.375);
        assert!((ratio - 3.0 / 2.75).abs() < 1e-5, "{ratio}");
        // A constant map has nothing above its mean: it keeps the uniform density.
        let flat = Distribution::new(8, 4, &[[2.0; 3]; 32]);
        assert_eq!(flat, Distribution::build(8, 4, &[[2.0; 3]; 32], false));
    }
}
