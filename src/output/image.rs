//! Linear-light images and their encoding for display (MODEL.md "Output": average in linear
//! light first, encode last).

use crate::scene::color::{linear_to_gamma22, linear_to_srgb};

/// How linear radiance is encoded for 8/16-bit output.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Transfer {
    /// The exact sRGB curve (IEC 61966-2-1).
    #[default]
    Srgb,
    /// The lecture's `pow(c, 0.4545)`.
    #[value(name = "gamma2.2")]
    Gamma22,
}

impl Transfer {
    /// Encodes one linear channel to [0, 1] (clamping first).
    pub fn encode(self, c: f64) -> f64 {
        match self {
            Transfer::Srgb => linear_to_srgb(c),
            Transfer::Gamma22 => linear_to_gamma22(c),
        }
    }
}

/// Per transfer, the linear value at which the 8-bit code `v + 1` begins (v = 0…254): where
/// `round(255 · encode(c))` steps up. A value's code is then the number of thresholds at or
/// below it, found by binary search instead of a `powf` per channel (the preview encodes
/// every frame; this is the same code, several times faster).
fn thresholds(t: Transfer) -> &'static [f64; 255] {
    static SRGB: std::sync::OnceLock<[f64; 255]> = std::sync::OnceLock::new();
    static GAMMA: std::sync::OnceLock<[f64; 255]> = std::sync::OnceLock::new();
    let cell = match t {
        Transfer::Srgb => &SRGB,
        Transfer::Gamma22 => &GAMMA,
    };
    cell.get_or_init(|| {
        std::array::from_fn(|v| {
            // The smallest c with round(255 · encode(c)) ≥ v + 1, by bisection on the
            // monotonic curve (exact to f64).
            let code = |c: f64| (t.encode(c) * 255.0).round();
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if code(mid) >= (v + 1) as f64 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            hi
        })
    })
}

/// The 8-bit sRGB code of linear `c` (as `to_rgb8` makes it).
pub fn srgb8(c: f32) -> u8 {
    encode8(thresholds(Transfer::Srgb), c)
}

/// The 8-bit code of linear `c`: `round(255 · encode(c))` by the thresholds.
fn encode8(table: &[f64; 255], c: f32) -> u8 {
    let c = c as f64;
    if c.is_nan() {
        return 0;
    }
    table.partition_point(|&t| t <= c) as u8
}

/// An image of linear radiance, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl LinearImage {
    pub fn new(width: u32, height: u32) -> LinearImage {
        LinearImage {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// 8-bit encoded image.
    pub fn to_rgb8(&self, t: Transfer) -> ::image::RgbImage {
        let mut out = ::image::RgbImage::new(self.width, self.height);
        let table = thresholds(t);
        for (o, p) in out.pixels_mut().zip(&self.pixels) {
            o.0 = p.map(|c| encode8(table, c));
        }
        out
    }

    /// 16-bit encoded image.
    pub fn to_rgb16(&self, t: Transfer) -> ::image::ImageBuffer<::image::Rgb<u16>, Vec<u16>> {
        let mut out = ::image::ImageBuffer::new(self.width, self.height);
        for (o, p) in out.pixels_mut().zip(&self.pixels) {
            *o = ::image::Rgb(p.map(|c| (t.encode(c as f64) * 65535.0).round() as u16));
        }
        out
    }

    /// Linear float image (for OpenEXR).
    pub fn to_rgb32f(&self) -> ::image::Rgb32FImage {
        let mut out = ::image::Rgb32FImage::new(self.width, self.height);
        for (o, p) in out.pixels_mut().zip(&self.pixels) {
            o.0 = *p;
        }
        out
    }

    /// Mean of every pixel, per channel (f64 sums).
    pub fn mean(&self) -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
        s.map(|v| v / self.pixels.len().max(1) as f64)
    }
}

#[cfg(test)]
mod encode_tests {
    use super::*;

    #[test]
    fn the_threshold_table_gives_the_rounded_curve() {
        // Every code's neighbourhood, and a sweep, against the direct formula.
        for t in [Transfer::Srgb, Transfer::Gamma22] {
            let table = thresholds(t);
            let direct = |c: f32| (t.encode(c as f64) * 255.0).round() as u8;
            let mut checked = 0;
            for &edge in table.iter() {
                for c in [edge * (1.0 - 1e-6), edge * (1.0 + 1e-6)] {
                    assert_eq!(encode8(table, c as f32), direct(c as f32), "{t:?} at {c}");
                    checked += 1;
                }
            }
            for i in 0..=100_000 {
                let c = i as f32 / 80_000.0 - 0.1;
                assert_eq!(encode8(table, c), direct(c), "{t:?} at {c}");
                checked += 1;
            }
            assert!(checked > 100_000);
        }
    }
}
