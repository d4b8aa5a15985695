//! The denoiser: filters each half of the samples on its own, guided by the albedo and normal
//! the tracers make (`common::Guides`), twice: an à-trous filter (`atrous`), and a
//! first-order regression of each pixel's neighbours on the guides weighted by that filter's
//! output (`regress`); shows the halves' mean, and estimates its error from the halves, tile
//! by tile, showing in each tile whichever of the raw image and the two filters' is
//! estimated best.
//!
//! The estimator. Each pixel keeps two independent means of its samples, A and B (the even
//! and odd halves), of variances v_A and v_B, unbiased for the true value μ. D(X) is the
//! filter applied to X alone (its weights come from X and from guides traced with their own
//! random streams), so D(A) is independent of B and D(B) of A. With a = D(A) − μ and
//! b = D(B) − μ:
//! - E[(D(A) − B)²] = E[a²] + v_B, E[(D(B) − A)²] = E[b²] + v_A, and E[(A − B)²] = v_A + v_B,
//!   so ½(D(A) − B)² + ½(D(B) − A)² − ½(A − B)² estimates ½(E[a²] + E[b²]) without bias;
//! - the image shown is D̄ = ½(D(A) + D(B)), whose squared error is
//!   ¼(a + b)² = ½(a² + b²) − ¼(a − b)², and a − b = D(A) − D(B) is observed.
//!
//! So e = ½(D(A) − B)² + ½(D(B) − A)² − ½(A − B)² − ¼(D(A) − D(B))² is an unbiased estimate
//! of D̄'s squared error at every pixel (one term per channel), whatever the filter. It is
//! noisy pixel by pixel, and is summed over tiles. Two biases remain:
//! - the filters' luminance weights read a noise variance that is a 7×7 mean of (A − B)², so
//!   D(A) depends on B through it. Measured, it is small: over 96 runs of the firefly scenes,
//!   a map per half made of each half's own samples (which needs their squared luminances
//!   accumulated) moved the estimate by 0.04–0.07 (tests/estimate.rs, whose `OPEN` says what
//!   was measured). What reads `glass` low is not a bias but the tail: the error of bright
//!   paths a run did not find, which the filters do not average away and the run's samples
//!   do not show; only the runs that find them do;
//! - choosing per tile the lowest of three noisy estimates (the raw image's, the à-trous
//!   filter's, the regression's) understates the shown image's error (the minimum of noisy
//!   estimates is biased low), most where they are close; [`cross_fitted`] corrects it.
//!
//! Two filters, chosen per tile by that estimate: the à-trous filter (`atrous`) averages
//! widely and wins in the first frames of a few samples; the regression (`regress`), run on
//! the radiance with weights from the à-trous output, keeps what a pixel straddling two
//! surfaces holds and wins from tens of samples on (BENCHMARKS.md, "Denoising").
//!
//! The raw image's estimate is `render::Snapshot::error_estimate`'s: (A − B)²·n_A·n_B/(n_A +
//! n_B)². Both are reported as pbrt's relative MSE, each channel's term divided by the
//! reference² proxy + 0.01 (`common::estimate::relative_weights` for the raw image's terms),
//! as the preview's noise figure is, or by D(A)·D(B) + 0.01 for each filter's terms (by
//! (min(A, B)/2)² + 0.01 where that is larger: `filtered_weight`); the per-tile choice divides
//! by A·B + 0.01 (`product_weight`).

pub mod atrous;
pub mod regress;

use crate::common::estimate::{
    filtered_weight, half_mean, pair_factor, product_weight, relative_weights,
};
use crate::common::resolved::{Doubt, Estimate};
use crate::common::{Guides, Resolved};
use crate::output::LinearImage;
use atrous::{Guide, box_blur, clamp_outliers, filter_pair, luminance};

/// Traced pixels per side of the tiles whose raw or denoised image is chosen.
pub const TILE: usize = 16;
/// The tile of traced pixel (x, y) in a row-major grid `tiles_x` tiles wide.
fn tile_index(x: usize, y: usize, tiles_x: usize) -> usize {
    (y / TILE) * tiles_x + x / TILE
}

/// Radius of the box over which the halves' difference gives the filter its noise variance.
const VARIANCE_RADIUS: usize = 3;
/// Added to the albedo before the radiance is divided by it (demodulation), so that a black
/// surface keeps its (zero) radiance finite.
const ALBEDO_EPSILON: f32 = 0.01;
/// `Mode::Auto` stops denoising once the raw image's estimated relative RMSE is below this.
pub const AUTO_FLOOR: f64 = 0.01;

/// When the denoiser runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// While the raw image's estimated error is above 1 % (relative RMSE) and the preview is
    /// accumulating (its final image at `--max-spp` is the raw one).
    #[default]
    Auto,
    On,
    Off,
}

impl Mode {
    /// Whether to denoise an image whose raw estimated relative RMSE is `raw` (`None`: not
    /// known yet, too few samples).
    pub fn wants(self, raw: Option<f64>) -> bool {
        match self {
            Mode::On => true,
            Mode::Off => false,
            Mode::Auto => raw.is_none_or(|r| r > AUTO_FLOOR),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Mode::Auto => "auto",
            Mode::On => "on",
            Mode::Off => "off",
        }
    }
}

/// Estimated squared errors, summed over pixels and channels: absolute and relative.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sums {
    pub mse: f64,
    pub rel: f64,
    /// The sum of the squares of the pixels' relative terms (their three channels together)
    /// and the pixels counted: the spread that gives the estimate's standard error.
    pub rel2: f64,
    pub pixels: f64,
}

impl Sums {
    fn add(&mut self, o: Sums) {
        self.mse += o.mse;
        self.rel += o.rel;
        self.rel2 += o.rel2;
        self.pixels += o.pixels;
    }

    /// The standard error of `rel`, the pixels' terms taken as independent.
    pub fn rel_standard_error(&self) -> f64 {
        let n = self.pixels.max(1.0);
        (self.rel2 - self.rel * self.rel / n).max(0.0).sqrt()
    }
}

/// A denoised frame at the traced size.
#[derive(Clone, Debug)]
pub struct Denoised {
    pub width: u32,
    pub height: u32,
    /// The pooled mean of both halves (the unbiased image).
    pub raw: Vec<[f32; 3]>,
    /// ½(D(A) + D(B)) everywhere, per tile of the filter estimated better: the à-trous
    /// filter's or the regression's.
    pub denoised: Vec<[f32; 3]>,
    /// Per tile (row-major, `tiles_x` a row) whether the denoised image is shown there.
    pub tiles: Vec<bool>,
    pub tiles_x: usize,
    /// Per tile whether the denoised image there is the regression's (else the à-trous
    /// filter's).
    pub tile_regression: Vec<bool>,
    /// Per tile, the estimated error sums of the raw and the denoised image (of the filter
    /// chosen there).
    pub tile_raw: Vec<Sums>,
    pub tile_denoised: Vec<Sums>,
    /// Per tile, the shown image's estimated relative squared error, cross-fitted so that
    /// the choice does not bias it ([`cross_fitted`]).
    pub tile_shown: Vec<f64>,
    /// Channels the sums are over (3 × pixels).
    pub channels: usize,
}

impl Denoised {
    /// A frame from its images, its tiles' choices ([`choose`]: whether the denoised image is
    /// shown, and whether it is the regression's) and their estimates.
    fn new(
        (width, height): (u32, u32),
        raw: Vec<[f32; 3]>,
        denoised: Vec<[f32; 3]>,
        tiles_x: usize,
        (tiles, tile_regression): (Vec<bool>, Vec<bool>),
        (tile_raw, tile_denoised): (Vec<Sums>, Vec<Sums>),
        tile_shown: Vec<f64>,
    ) -> Denoised {
        Denoised {
            width,
            height,
            raw,
            denoised,
            tiles,
            tiles_x,
            tile_regression,
            tile_raw,
            tile_denoised,
            tile_shown,
            channels: 3 * width as usize * height as usize,
        }
    }

    /// The image shown: per tile, whichever of the raw and the denoised one is estimated
    /// better.
    pub fn shown(&self) -> Vec<[f32; 3]> {
        let w = self.width as usize;
        (0..self.raw.len())
            .map(|p| {
                if self.tiles[tile_index(p % w, p / w, self.tiles_x)] {
                    self.denoised[p]
                } else {
                    self.raw[p]
                }
            })
            .collect()
    }

    fn total(&self, pick: impl Fn(usize) -> Sums) -> Sums {
        let mut s = Sums::default();
        for t in 0..self.tiles.len() {
            s.add(pick(t));
        }
        s
    }

    /// The raw image's estimated error sums.
    pub fn raw_sums(&self) -> Sums {
        self.total(|t| self.tile_raw[t])
    }

    /// The denoised image's (everywhere) estimated error sums.
    pub fn denoised_sums(&self) -> Sums {
        self.total(|t| self.tile_denoised[t])
    }

    /// The shown image's estimated error sums: the chosen image's per tile, its relative sum
    /// cross-fitted ([`cross_fitted`]).
    pub fn shown_sums(&self) -> Sums {
        self.total(|t| {
            let chosen = if self.tiles[t] {
                self.tile_denoised[t]
            } else {
                self.tile_raw[t]
            };
            Sums {
                rel: self.tile_shown[t],
                ..chosen
            }
        })
    }

    /// The preview's frame: the shown image averaged over `factor × factor` blocks, the raw
    /// image's estimated error as its noise and the shown image's as `denoised`, and per
    /// output pixel a standard error from its tile's estimate.
    /// (The preview traces a multiple of `factor` each way.)
    pub fn resolved(&self, factor: u32, invalid: u64) -> Resolved {
        let shown = LinearImage {
            width: self.width,
            height: self.height,
            pixels: self.shown(),
        };
        let pixels = crate::output::cells::downsample(&shown, factor).pixels;
        self.frame(pixels, factor, invalid)
    }

    /// The preview's frame of an image already averaged by `factor` (`pixels`, row-major),
    /// with the estimates and standard errors from the tiles.
    fn frame(&self, pixels: Vec<[f32; 3]>, factor: u32, invalid: u64) -> Resolved {
        let f = factor.max(1) as usize;
        let (w, h) = (self.width as usize, self.height as usize);
        let out = ((w / f).max(1), (h / f).max(1));
        let tile_pixels = |t: usize| {
            let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
            ((w - tx * TILE).min(TILE) * (h - ty * TILE).min(TILE)) as f64
        };
        let mut sigma = Vec::with_capacity(out.0 * out.1);
        for oy in 0..out.1 {
            for ox in 0..out.0 {
                let t = tile_index((ox * f).min(w - 1), (oy * f).min(h - 1), self.tiles_x);
                let s = if self.tiles[t] {
                    self.tile_denoised[t]
                } else {
                    self.tile_raw[t]
                };
                let per_value = s.mse.max(0.0) / (3.0 * tile_pixels(t));
                sigma.push((per_value.sqrt() / f as f64) as f32);
            }
        }
        let raw = self.raw_sums();
        Resolved {
            image: LinearImage {
                width: out.0 as u32,
                height: out.1 as u32,
                pixels,
            },
            noise: Some(self.rel_rmse(raw)),
            invalid,
            sigma,
            denoised: Some(self.shown_estimate()),
            doubt: Doubt::of(None, raw.rel, raw.rel2),
        }
    }

    /// The shown image's estimated relative RMSE, or a bound on it where the estimate is
    /// within two standard errors of zero.
    pub fn shown_estimate(&self) -> Estimate {
        let s = self.shown_sums();
        let se = s.rel_standard_error();
        if s.rel < 2.0 * se {
            Estimate::Below(((s.rel.max(0.0) + 2.0 * se) / self.channels.max(1) as f64).sqrt())
        } else {
            Estimate::Value(self.rel_rmse(s))
        }
    }

    /// Relative RMSE from sums (pbrt's relative MSE's root; a negative estimate counts 0).
    pub fn rel_rmse(&self, s: Sums) -> f64 {
        (s.rel.max(0.0) / self.channels.max(1) as f64).sqrt()
    }
}

/// Floats per tile of a backend's denoiser pass (see [`DenoisedTiles`]).
pub const TILE_FLOATS: usize = 10;

/// What a backend's denoiser pass brings back (the GPU's, `gpu::denoise`): per output pixel
/// its colour, per tile (row-major, `tiles_x` a row) the estimate's sums (raw mse, rel, rel²,
/// denoised mse, rel, rel², pixels, 1 where the regression's image is the denoised one, 0
/// where the à-trous filter's is, the shown image's cross-fitted relative sum, and 1 where
/// the denoised image is shown), and the samples discarded as invalid so far.
pub struct DenoisedTiles {
    pub out: (u32, u32),
    pub blocks: Vec<[f32; 3]>,
    pub tiles_x: u32,
    pub tiles: Vec<[f32; TILE_FLOATS]>,
    pub invalid: u64,
}

/// The preview's frame from a backend's denoiser pass: its image, and the tiles' sums made
/// into the same estimates and choice as [`denoise`]'s.
pub fn from_tiles(g: DenoisedTiles, (width, height): (u32, u32), factor: u32) -> Resolved {
    let sums = |t: &[f32; TILE_FLOATS], at: usize| Sums {
        mse: t[at] as f64,
        rel: t[at + 1] as f64,
        rel2: t[at + 2] as f64,
        pixels: t[6] as f64,
    };
    let d = Denoised::new(
        (width, height),
        Vec::new(),
        Vec::new(),
        g.tiles_x as usize,
        (
            g.tiles.iter().map(|t| t[9] > 0.5).collect(),
            g.tiles.iter().map(|t| t[7] > 0.5).collect(),
        ),
        (
            g.tiles.iter().map(|t| sums(t, 0)).collect(),
            g.tiles.iter().map(|t| sums(t, 3)).collect(),
        ),
        g.tiles.iter().map(|t| t[8] as f64).collect(),
    );
    d.frame(g.blocks, factor, g.invalid)
}

/// The variance of one half's luminance, from halves `x` and `y` of a `w × h` image:
/// E[(X − Y)²] = v_X + v_Y, halved, and averaged over a 7×7 box.
fn half_variance(x: &[[f32; 3]], y: &[[f32; 3]], w: usize, h: usize) -> Vec<f32> {
    let per_pixel: Vec<f32> = x
        .iter()
        .zip(y)
        .map(|(x, y)| 0.5 * (luminance(*x) - luminance(*y)).powi(2))
        .collect();
    box_blur(&per_pixel, w, h, VARIANCE_RADIUS)
}

/// Denoises the image whose even and odd halves' sums are `even` and `odd` (`[r, g, b,
/// samples]` per pixel, as `common::AccumData` holds them), guided by `guides` (same size).
pub fn denoise(even: &[[f32; 4]], odd: &[[f32; 4]], guides: &Guides) -> Denoised {
    let (w, h) = (guides.width as usize, guides.height as usize);
    assert_eq!(even.len(), w * h, "halves and guides of one size");
    let a: Vec<[f32; 3]> = even.iter().map(|&s| half_mean(s)).collect();
    let b: Vec<[f32; 3]> = odd.iter().map(|&s| half_mean(s)).collect();
    let raw: Vec<[f32; 3]> = even
        .iter()
        .zip(odd)
        .map(|(e, o)| {
            let n = e[3] + o[3];
            if n > 0.0 {
                std::array::from_fn(|c| ((e[c] as f64 + o[c] as f64) / n as f64) as f32)
            } else {
                [0.0; 3]
            }
        })
        .collect();
    // Demodulation: the filter smooths the light arriving, not the texture it lights.
    let modulation: Vec<[f32; 3]> = guides
        .albedo
        .iter()
        .map(|a| a.map(|v| v + ALBEDO_EPSILON))
        .collect();
    let demod = |x: &[[f32; 3]]| -> Vec<[f32; 3]> {
        x.iter()
            .zip(&modulation)
            .map(|(c, m)| std::array::from_fn(|i| c[i] / m[i]))
            .collect()
    };
    let (da, db) = (demod(&a), demod(&b));
    let variance = half_variance(&da, &db, w, h);
    let g = Guide {
        width: w,
        height: h,
        albedo: &guides.albedo,
        normal: &guides.normal,
    };
    let remod = |x: Vec<[f32; 3]>| -> Vec<[f32; 3]> {
        x.iter()
            .zip(&modulation)
            .map(|(c, m)| std::array::from_fn(|i| c[i] * m[i]))
            .collect()
    };
    let (fa, fb) = filter_pair(&g, &da, &db, &variance);
    let (fa, fb) = (remod(fa), remod(fb));
    // The regression's luminance weights read the variance of one half's radiance.
    let radiance_variance = half_variance(&a, &b, w, h);
    let (ca, cb) = (clamp_outliers(w, h, &a), clamp_outliers(w, h, &b));
    let (ra, rb) = regress::regress_pair(&g, (&ca, &cb), (&fa, &fb), &radiance_variance);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    // The raw image's estimate, and each filter's (the à-trous output, the regression's).
    let mut tile_raw = vec![Sums::default(); tiles_x * tiles_y];
    let mut tile_filters = [tile_raw.clone(), tile_raw.clone()];
    // Per tile, the relative sums of the raw image, the à-trous filter's and the
    // regression's over the pixels of odd parity (x + y odd), and those pixels: the
    // cross-fitted estimate. And the choice's sums ([`product_weight`]), over all pixels and
    // over the odd ones.
    let mut tile_odd = vec![[0.0f64; 4]; tiles_x * tiles_y];
    let mut tile_choice = vec![[[0.0f64; 3]; 2]; tiles_x * tiles_y];
    let filters = [(&fa, &fb), (&ra, &rb)];
    let weights = relative_weights(even, odd, w, h);
    for p in 0..w * h {
        let t = tile_index(p % w, p / w, tiles_x);
        let Some(k) = pair_factor(even[p][3] as f64, odd[p][3] as f64) else {
            continue;
        };
        let (mut pixel_r, mut pixel_d) = (0.0, [0.0; 2]);
        let mut pixel_choice = [0.0; 3];
        for c in 0..3 {
            let (x, y) = (a[p][c] as f64, b[p][c] as f64);
            let scale = weights[p][c] as f64;
            let choice = product_weight(x, y);
            let r = (x - y).powi(2) * k;
            pixel_choice[0] += r * choice;
            tile_raw[t].add(Sums {
                mse: r,
                rel: r * scale,
                ..Sums::default()
            });
            pixel_r += r * scale;
            for (f, (da, db)) in filters.iter().enumerate() {
                let (dx, dy) = (da[p][c] as f64, db[p][c] as f64);
                let scale = filtered_weight(dx, dy, x, y);
                let e = 0.5 * (dx - y).powi(2) + 0.5 * (dy - x).powi(2)
                    - 0.5 * (x - y).powi(2)
                    - 0.25 * (dx - dy).powi(2);
                tile_filters[f][t].add(Sums {
                    mse: e,
                    rel: e * scale,
                    ..Sums::default()
                });
                pixel_d[f] += e * scale;
                pixel_choice[1 + f] += e * choice;
            }
        }
        let odd_pixel = (p % w + p / w) % 2 == 1;
        for (i, v) in pixel_choice.into_iter().enumerate() {
            tile_choice[t][0][i] += v;
            if odd_pixel {
                tile_choice[t][1][i] += v;
            }
        }
        if odd_pixel {
            tile_odd[t] = [
                tile_odd[t][0] + pixel_r,
                tile_odd[t][1] + pixel_d[0],
                tile_odd[t][2] + pixel_d[1],
                tile_odd[t][3] + 1.0,
            ];
        }
        tile_raw[t].rel2 += pixel_r * pixel_r;
        tile_raw[t].pixels += 1.0;
        for f in 0..2 {
            tile_filters[f][t].rel2 += pixel_d[f] * pixel_d[f];
            tile_filters[f][t].pixels += 1.0;
        }
    }
    // Per tile the image chosen (as the GPU's `finish`).
    let chosen: Vec<usize> = tile_choice.iter().map(|c| choose(c[0])).collect();
    // The filter estimated better (the regression on a tie), shown where `chosen` is not 0.
    let regression: Vec<bool> = tile_choice.iter().map(|c| c[0][2] <= c[0][1]).collect();
    let tile_denoised = (0..tiles_x * tiles_y)
        .map(|t| tile_filters[usize::from(regression[t])][t])
        .collect();
    let tile_shown = (0..tiles_x * tiles_y)
        .map(|t| {
            let all = [
                tile_raw[t].rel,
                tile_filters[0][t].rel,
                tile_filters[1][t].rel,
            ];
            let [r, at, g, n] = tile_odd[t];
            cross_fitted((all, [r, at, g]), tile_choice[t], (tile_raw[t].pixels, n))
        })
        .collect();
    let denoised: Vec<[f32; 3]> = (0..w * h)
        .map(|p| {
            let (x, y) = filters[usize::from(regression[tile_index(p % w, p / w, tiles_x)])];
            std::array::from_fn(|c| 0.5 * (x[p][c] + y[p][c]))
        })
        .collect();
    Denoised::new(
        (w as u32, h as u32),
        raw,
        denoised,
        tiles_x,
        (chosen.iter().map(|&c| c != 0).collect(), regression),
        (tile_raw, tile_denoised),
        tile_shown,
    )
}

/// The candidate a set of pixels chooses from its relative sums `[raw, à-trous,
/// regression]`: the filter estimated better (the regression on a tie), then that filter's
/// image where its estimate is strictly below the raw one's; 0 raw, 1 à-trous, 2 regression.
/// The rule of [`denoise`]'s tiles and of shaders/denoise.wgsl's `finish`.
pub fn choose(rel: [f64; 3]) -> usize {
    let filter = if rel[2] <= rel[1] { 2 } else { 1 };
    if rel[filter] < rel[0] { filter } else { 0 }
}

/// The shown tile's estimated relative squared error, cross-fitted. `all` holds the tile's
/// relative sums `[raw, à-trous, regression]`, `odd` those over its pixels of odd parity (x +
/// y odd); `choice` the same two made with the choice's weights ([`product_weight`]: the tile
/// and each parity choose by them), and `pixels` the tile's pixels and its odd ones.
///
/// The tile shows the choice of all its pixels, the lowest of three noisy estimates, and that
/// estimate is biased low (the minimum of noisy estimates is below the minimum of their
/// means), most where they are close. So each parity's pixels choose by their own sums
/// ([`choose`]), and the image shown is judged by the pixels whose noise did not select it (a
/// pixel's estimate terms carry mostly its own samples' noise):
/// - where both parities choose the image shown, each parity's sum judges the other's choice,
///   and the estimate is the tile's sum;
/// - where only one parity chose it, by the other parity alone, its sum scaled to the tile's
///   pixels;
/// - where neither parity chose it (three candidates), by both: the tile's sum.
///
/// Earlier versions judged each parity's own choice by the other parity also where the image
/// shown was not that choice. That estimates an image the tile does not show: where one
/// candidate's error sits in a few pixels (a filter smearing an emitter's edge) it read 40 for
/// a raw tile whose true error was 0.4, and where neither parity chose the image shown, a
/// firefly in one parity's raw sum made the shown image's estimate of `outdoor` 2.2–2.7× its
/// true error over 96 runs (9× in expectation; BENCHMARKS.md, "The filtered images'
/// estimate").
pub fn cross_fitted(
    (all, odd): ([f64; 3], [f64; 3]),
    [choice_all, choice_odd]: [[f64; 3]; 2],
    (pixels, odd_pixels): (f64, f64),
) -> f64 {
    let even: [f64; 3] = std::array::from_fn(|i| all[i] - odd[i]);
    let choice_even: [f64; 3] = std::array::from_fn(|i| choice_all[i] - choice_odd[i]);
    let even_pixels = pixels - odd_pixels;
    let (shown, by_even, by_odd) = (choose(choice_all), choose(choice_even), choose(choice_odd));
    if by_even == shown && by_odd != shown && odd_pixels > 0.0 {
        odd[shown] * pixels / odd_pixels
    } else if by_odd == shown && by_even != shown && even_pixels > 0.0 {
        even[shown] * pixels / even_pixels
    } else {
        all[shown]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tile_layout_is_the_shaders() {
        use crate::common::wgsl::u32_constant;
        assert_eq!(
            u32_constant("denoise.wgsl", "TILE_FLOATS") as usize,
            TILE_FLOATS
        );
    }

    #[test]
    fn the_choice_and_its_cross_fitted_estimate() {
        // The regression on a tie, then a filter only where strictly below the raw image.
        assert_eq!(choose([1.0, 0.5, 0.5]), 2);
        assert_eq!(choose([1.0, 0.4, 0.5]), 1);
        assert_eq!(choose([0.4, 0.4, 0.5]), 0);
        // Both parities choose the regression: the estimate is the regression's sum.
        let same = |all: [f64; 3], odd: [f64; 3]| cross_fitted((all, odd), [all, odd], (8.0, 4.0));
        assert_eq!(same([4.0, 3.0, 2.0], [2.0, 1.5, 1.0]), 2.0);
        // The tile shows the regression (2.1 < 3.0). The even pixels chose it (1.0 against
        // raw 2.0), the odd ones the raw image (1.0 < 1.1): the regression is judged by the
        // odd pixels alone, 1.1 over 4 of the 8 pixels.
        assert_eq!(same([3.0, 4.0, 2.1], [1.0, 2.0, 1.1]), 2.2);
        // An emitter's edge smeared by a filter in the even pixels: they keep the raw image,
        // the odd ones (whose filter sums are low) choose the filter; the raw image shown is
        // judged by the odd pixels, not the filter by the even ones.
        assert_eq!(same([0.3, 37.0, 38.0], [0.15, -0.1, 0.0]), 0.3);
        // Three ways: the tile shows the à-trous filter's image (3.0 against raw 3.5 and the
        // regression's 3.2), the even pixels chose the raw image (even sums 0.5, 1.8, 2.1),
        // the odd ones the regression (3.0, 1.2, 1.1). Neither chose the image shown, so both
        // judge it: its tile sum, 3.0, not the sum of each parity's choice judged by the
        // other (even's regression 2.1 + odd's raw 3.0 = 5.1, a firefly in the odd pixels'
        // raw sum counted for an image the tile does not show).
        assert_eq!(same([3.5, 3.0, 3.2], [3.0, 1.2, 1.1]), 3.0);
        // Chosen by other sums than those estimated: both parities choose the regression by
        // the choice's sums, and the estimate is the regression's estimated sum.
        assert_eq!(
            cross_fitted(
                ([1.0, 2.0, 3.0], [0.5, 1.0, 1.5]),
                [[4.0, 3.0, 2.0], [2.0, 1.5, 1.0]],
                (8.0, 4.0)
            ),
            3.0
        );
    }
}
