//! The filter: an edge-avoiding à-trous wavelet transform (Dammertz, Sewtz, Hanika & Lensch,
//! "Edge-Avoiding À-Trous Wavelet Transform for fast Global Illumination Filtering", HPG
//! 2010), its weights stopped by the normal and albedo guides and by luminance differences
//! measured in units of the pixel's own noise, with that noise's variance carried through
//! the iterations (Schied et al., "Spatiotemporal Variance-Guided Filtering", HPG 2017).

use rayon::prelude::*;

/// Iterations, the taps 1, 2, 4, 8, 16 pixels apart: a 5×5 B3-spline kernel each.
pub const ITERATIONS: u32 = 5;
/// The B3 spline's taps (1, 4, 6, 4, 1) / 16.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];
/// The normal weight's exponent (SVGF's σn).
const NORMAL_POWER: i32 = 128;
/// The albedo weight's scale: a difference of this much (Euclidean, linear) costs e⁻¹.
const ALBEDO_SIGMA: f32 = 0.1;
/// The luminance weight's scale in standard deviations of the pixel's noise (SVGF's σl).
const LUMINANCE_SIGMA: f32 = 4.0;
/// Keeps the luminance weight finite where the noise is zero (a converged or noise-free
/// pixel then keeps its value).
const LUMINANCE_EPSILON: f32 = 1e-6;

/// Rec. 709 luminance of linear RGB.
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

/// The normal weight: 1 between two sky pixels (zero normals), 0 between the sky and a
/// surface, else the cosine between the normals to the power 128.
#[inline(always)]
fn normal_weight(a: [f32; 3], b: [f32; 3]) -> f32 {
    let la = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    let lb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
    const SKY: f32 = 0.01;
    match (la < SKY, lb < SKY) {
        (true, true) => 1.0,
        (false, false) => {
            let c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb).sqrt();
            c.max(0.0).powi(NORMAL_POWER)
        }
        _ => 0.0,
    }
}

/// One iteration, taps `step` pixels apart: the filtered image and its variance.
fn iterate(
    g: &Guide,
    color: &[[f32; 3]],
    variance: &[f32],
    step: usize,
) -> (Vec<[f32; 3]>, Vec<f32>) {
    let (w, h) = (g.width, g.height);
    let mut out = vec![[0.0f32; 3]; w * h];
    let mut out_var = vec![0.0f32; w * h];
    out.par_chunks_mut(w)
        .zip(out_var.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (row, row_var))| {
            for x in 0..w {
                let p = y * w + x;
                let (cp, np, ap) = (color[p], g.normal[p], g.albedo[p]);
                let lp = luminance(cp);
                let scale =
                    1.0 / (LUMINANCE_SIGMA * variance[p].max(0.0).sqrt() + LUMINANCE_EPSILON);
                let (mut sum, mut sum_w, mut sum_v) = ([0.0f32; 3], 0.0f32, 0.0f32);
                for (j, ky) in KERNEL.iter().enumerate() {
                    let qy = y as isize + (j as isize - 2) * step as isize;
                    if qy < 0 || qy >= h as isize {
                        continue;
                    }
                    for (i, kx) in KERNEL.iter().enumerate() {
                        let qx = x as isize + (i as isize - 2) * step as isize;
                        if qx < 0 || qx >= w as isize {
                            continue;
                        }
                        let q = qy as usize * w + qx as usize;
                        let wt = if q == p {
                            ky * kx
                        } else {
                            let wn = normal_weight(np, g.normal[q]);
                            if wn == 0.0 {
                                continue;
                            }
                            let aq = g.albedo[q];
                            let da = (ap[0] - aq[0]).powi(2)
                                + (ap[1] - aq[1]).powi(2)
                                + (ap[2] - aq[2]).powi(2);
                            let dl = (lp - luminance(color[q])).abs() * scale;
                            ky * kx * wn * (-(da / (ALBEDO_SIGMA * ALBEDO_SIGMA)) - dl).exp()
                        };
                        let c = color[q];
                        sum[0] += wt * c[0];
                        sum[1] += wt * c[1];
                        sum[2] += wt * c[2];
                        sum_w += wt;
                        sum_v += wt * wt * variance[q];
                    }
                }
                row[x] = [sum[0] / sum_w, sum[1] / sum_w, sum[2] / sum_w];
                row_var[x] = sum_v / (sum_w * sum_w);
            }
        });
    (out, out_var)
}

/// The filtered image of `color`, whose luminance has per-pixel noise variance `variance`.
pub fn filter(g: &Guide, color: &[[f32; 3]], variance: &[f32]) -> Vec<[f32; 3]> {
    let mut c = color.to_vec();
    let mut v = variance.to_vec();
    for i in 0..ITERATIONS {
        (c, v) = iterate(g, &c, &v, 1 << i);
    }
    c
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
