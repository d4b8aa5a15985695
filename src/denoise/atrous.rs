//! The filter: an edge-avoiding à-trous wavelet transform (Dammertz, Sewtz, Hanika & Lensch,
//! "Edge-Avoiding À-Trous Wavelet Transform for fast Global Illumination Filtering", HPG
//! 2010), its weights stopped by the normal and albedo guides and by luminance differences
//! measured in units of the pixel's own noise, with that noise's variance carried through
//! the iterations (Schied et al., "Spatiotemporal Variance-Guided Filtering", HPG 2017).
//! Both halves are filtered in one pass: the guides' part of every weight is computed once
//! for the two (shaders/denoise.wgsl does the same on the GPU).

use rayon::prelude::*;

/// Iterations, the taps 1, 2, 4, 8, 16 pixels apart.
pub const ITERATIONS: u32 = 5;
/// The kernel of each iteration, separable: the linear B-spline's (1, 2, 1) / 4, 3×3 taps.
/// The B3 spline's 5×5 (1, 4, 6, 4, 1) / 16 of Dammertz et al. and SVGF was measured on
/// cornell at 120×76 on 2 cores: 1.8× the time (22 against 13 ms a frame) for a larger error
/// (2.68 against 2.54 % at 1 s; BENCHMARKS.md, "Denoising").
const KERNEL: [f32; 3] = [0.25, 0.5, 0.25];
/// The normal weight is the cosine between the normals to this power (SVGF's σn = 128),
/// as seven squarings.
const NORMAL_SQUARINGS: u32 = 7;
/// The albedo weight's scale: a difference of this much (Euclidean, linear) costs e⁻¹.
const ALBEDO_SIGMA: f32 = 0.1;
/// The luminance weight's scale in standard deviations of the pixel's noise (SVGF's σl).
const LUMINANCE_SIGMA: f32 = 4.0;
/// Keeps the luminance weight finite where the noise is zero (a converged or noise-free
/// pixel then keeps its value).
const LUMINANCE_EPSILON: f32 = 1e-6;

/// Rec. 709 luminance of linear RGB.
#[inline(always)]
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// What the filter is stopped by at every pixel.
pub struct Guide<'a> {
    pub width: usize,
    pub height: usize,
    pub albedo: &'a [[f32; 3]],
    pub normal: &'a [[f32; 3]],
}

/// A pixel's guide as the weights read it: albedo, and the normal made unit length (zero
/// for the sky: a guide normal shorter than 0.1).
#[derive(Clone, Copy)]
pub(super) struct Texel {
    pub albedo: [f32; 3],
    pub normal: [f32; 3],
    pub sky: bool,
}

pub(super) fn texels(g: &Guide) -> Vec<Texel> {
    g.albedo
        .iter()
        .zip(g.normal)
        .map(|(&albedo, n)| {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let sky = len < 0.1;
            let normal = if sky { [0.0; 3] } else { n.map(|v| v / len) };
            Texel {
                albedo,
                normal,
                sky,
            }
        })
        .collect()
}

/// e^x for x ≤ 0 (and 0 below −80), to 10⁻⁴ relative: the integer part of x·log2(e)
/// in the exponent bits, 2^fraction by a degree-5 polynomial. libm's expf was a third of the
/// filter's time.
#[inline(always)]
pub(super) fn exp_neg(x: f32) -> f32 {
    if x < -80.0 {
        return 0.0;
    }
    let t = x * std::f32::consts::LOG2_E;
    // floor(t) without libm (x86-64's baseline has no rounding instruction).
    let i = t as i32 - i32::from(t < (t as i32) as f32);
    let f = t - i as f32;
    // 2^f on [0, 1): the Taylor terms of e^(f ln 2) to the fifth.
    let p = 1.0
        + f * (std::f32::consts::LN_2
            + f * (0.240_226_5 + f * (0.055_504_11 + f * (0.009_618_129 + f * 0.001_333_355))));
    p * f32::from_bits(((i + 127) as u32) << 23)
}

/// The guides' part of the weight between pixels p and q (the kernel's tap not included):
/// 1 between two sky pixels, 0 between the sky and a surface, else the normals' cosine to the
/// power 128 times e^(−|Δalbedo|²/σ²).
#[inline(always)]
fn guide_weight(p: &Texel, q: &Texel) -> f32 {
    if p.sky || q.sky {
        return if p.sky && q.sky { 1.0 } else { 0.0 };
    }
    let mut c = (p.normal[0] * q.normal[0] + p.normal[1] * q.normal[1] + p.normal[2] * q.normal[2])
        .max(0.0);
    for _ in 0..NORMAL_SQUARINGS {
        c *= c;
    }
    if c < 1e-6 {
        return 0.0;
    }
    let da = (p.albedo[0] - q.albedo[0]).powi(2)
        + (p.albedo[1] - q.albedo[1]).powi(2)
        + (p.albedo[2] - q.albedo[2]).powi(2);
    c * exp_neg(-da / (ALBEDO_SIGMA * ALBEDO_SIGMA))
}

/// One image being filtered: per pixel its colour, luminance and luminance variance
/// (together, so that a tap reads one place).
#[derive(Clone)]
struct Layer(Vec<[f32; 5]>);

impl Layer {
    fn new(color: &[[f32; 3]], var: &[f32]) -> Layer {
        Layer(
            color
                .iter()
                .zip(var)
                .map(|(&c, &v)| [c[0], c[1], c[2], luminance(c), v])
                .collect(),
        )
    }

    fn color(&self) -> Vec<[f32; 3]> {
        self.0.iter().map(|p| [p[0], p[1], p[2]]).collect()
    }
}

/// Accumulates one image's taps at one pixel.
#[derive(Default)]
struct Sum {
    c: [f32; 3],
    w: f32,
    v: f32,
}

impl Sum {
    #[inline(always)]
    fn tap(&mut self, q: &[f32; 5], lp: f32, scale: f32, g: f32) {
        let w = g * exp_neg(-(lp - q[3]).abs() * scale);
        self.c[0] += w * q[0];
        self.c[1] += w * q[1];
        self.c[2] += w * q[2];
        self.w += w;
        self.v += w * w * q[4];
    }

    fn result(&self) -> [f32; 5] {
        let k = 1.0 / self.w;
        let c = self.c.map(|v| v * k);
        [c[0], c[1], c[2], luminance(c), self.v * k * k]
    }
}

/// One iteration over both layers, taps `step` pixels apart.
fn iterate(g: &Guide, t: &[Texel], layers: &[Layer; 2], step: usize) -> [Layer; 2] {
    let (w, h) = (g.width, g.height);
    let rows: Vec<[Vec<[f32; 5]>; 2]> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = [Vec::with_capacity(w), Vec::with_capacity(w)];
            for x in 0..w {
                let p = y * w + x;
                let tp = &t[p];
                let lp = [layers[0].0[p][3], layers[1].0[p][3]];
                let scale = [0, 1].map(|i| {
                    1.0 / (LUMINANCE_SIGMA * layers[i].0[p][4].max(0.0).sqrt() + LUMINANCE_EPSILON)
                });
                let mut sums = [Sum::default(), Sum::default()];
                for (j, &ky) in KERNEL.iter().enumerate() {
                    let qy = y as isize + (j as isize - 1) * step as isize;
                    if qy < 0 || qy >= h as isize {
                        continue;
                    }
                    for (i, &kx) in KERNEL.iter().enumerate() {
                        let qx = x as isize + (i as isize - 1) * step as isize;
                        if qx < 0 || qx >= w as isize {
                            continue;
                        }
                        let q = qy as usize * w + qx as usize;
                        let gw = ky * kx * if q == p { 1.0 } else { guide_weight(tp, &t[q]) };
                        if gw == 0.0 {
                            continue;
                        }
                        for k in 0..2 {
                            sums[k].tap(&layers[k].0[q], lp[k], scale[k], gw);
                        }
                    }
                }
                out[0].push(sums[0].result());
                out[1].push(sums[1].result());
            }
            out
        })
        .collect();
    let layer = |k: usize| Layer(rows.iter().flat_map(|r| r[k].iter().copied()).collect());
    [layer(0), layer(1)]
}

/// Neighbours each way of the window whose luminance statistics bound a pixel's
/// (`clamp_outliers`).
const OUTLIER_RADIUS: isize = 2;
/// A pixel's luminance may exceed its neighbours' mean by this many of their standard
/// deviations.
const OUTLIER_SIGMAS: f32 = 3.0;

/// Clamps outliers (fireflies: a rare path that found a light, many standard deviations
/// above its neighbours) to the mean plus three standard deviations of the luminance of the
/// 24 pixels around them in the same image, scaling the colour. A firefly would otherwise
/// stop every luminance weight and stay as it is. Biased, as any filter is; the estimate
/// measures it, and the raw image wins back a tile where it is better.
pub(super) fn clamp_outliers(w: usize, h: usize, color: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let lum: Vec<f32> = color.iter().map(|&c| luminance(c)).collect();
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (x, y) = ((p % w) as isize, (p / w) as isize);
            let (mut n, mut s, mut s2) = (0.0f32, 0.0f32, 0.0f32);
            for qy in (y - OUTLIER_RADIUS).max(0)..=(y + OUTLIER_RADIUS).min(h as isize - 1) {
                for qx in (x - OUTLIER_RADIUS).max(0)..=(x + OUTLIER_RADIUS).min(w as isize - 1) {
                    if (qx, qy) != (x, y) {
                        let l = lum[qy as usize * w + qx as usize];
                        n += 1.0;
                        s += l;
                        s2 += l * l;
                    }
                }
            }
            let mean = s / n.max(1.0);
            let sd = (s2 / n.max(1.0) - mean * mean).max(0.0).sqrt();
            let limit = mean + OUTLIER_SIGMAS * sd;
            if lum[p] > limit && lum[p] > 0.0 {
                color[p].map(|c| c * (limit / lum[p]))
            } else {
                color[p]
            }
        })
        .collect()
}

/// Both images filtered, each by its own luminance (`a` and `b` with per-pixel luminance
/// noise variance `variance`).
pub fn filter_pair(
    g: &Guide,
    a: &[[f32; 3]],
    b: &[[f32; 3]],
    variance: &[f32],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let t = texels(g);
    let (a, b) = (
        clamp_outliers(g.width, g.height, a),
        clamp_outliers(g.width, g.height, b),
    );
    let mut layers = [Layer::new(&a, variance), Layer::new(&b, variance)];
    for i in 0..ITERATIONS {
        layers = iterate(g, &t, &layers, 1 << i);
    }
    (layers[0].color(), layers[1].color())
}

/// A box filter of radius `r` (clamped at the borders) over a `w × h` image of scalars.
pub fn box_blur(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let pass = |src: &[f32], w: usize, h: usize| -> Vec<f32> {
        // Along rows of `src` (w × h), written transposed (h × w).
        let mut out = vec![0.0f32; w * h];
        for y in 0..h {
            let row = &src[y * w..(y + 1) * w];
            for x in 0..w {
                let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
                let s: f32 = row[a..=b].iter().sum();
                out[x * h + y] = s / (b - a + 1) as f32;
            }
        }
        out
    };
    let t = pass(v, w, h);
    pass(&t, h, w)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_fast_exponential_is_close() {
        let mut worst = 0.0f64;
        for i in 0..100_000 {
            let x = -(i as f32) * 0.0008;
            let (a, b) = (super::exp_neg(x) as f64, (x as f64).exp());
            worst = worst.max((a - b).abs() / b);
        }
        assert!(worst < 1e-4, "relative error {worst:e}");
        assert_eq!(super::exp_neg(-100.0), 0.0);
        assert_eq!(super::exp_neg(0.0), 1.0);
    }
}
