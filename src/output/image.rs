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
/// `round(255 · encode(c))` steps up. A value's code is the number of thresholds at or below
/// it.
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

/// Bits of an f32 in [0, 1) below the bucket index: the index is the exponent and the top 7
/// bits of the mantissa, so a bucket spans 2^-7 of its values. Both curves rise by less than
/// one code over such a span (d code / d ln c ≤ 255 · 0.4545 ≈ 116 for gamma 2.2, ≈ 112 for
/// sRGB: at most 0.91 codes per bucket), so a bucket holds at most one threshold.
const BUCKET_SHIFT: u32 = 16;
const BUCKETS: usize = (0x3f80_0000 >> BUCKET_SHIFT) as usize;

/// The 8-bit encoding as a table over the f32 bit patterns (the preview encodes every
/// frame; a binary search over the thresholds per channel cost 25 ns a pixel): per bucket,
/// the code of its first value and the smallest f32 that takes the next code (a threshold
/// rounded up to f32, so that `c >= next` for an f32 `c` is `threshold <= c` exactly).
struct Encode8 {
    base: Vec<u8>,
    next: Vec<f32>,
}

fn table8(t: Transfer) -> &'static Encode8 {
    static SRGB: std::sync::OnceLock<Encode8> = std::sync::OnceLock::new();
    static GAMMA: std::sync::OnceLock<Encode8> = std::sync::OnceLock::new();
    let cell = match t {
        Transfer::Srgb => &SRGB,
        Transfer::Gamma22 => &GAMMA,
    };
    cell.get_or_init(|| {
        let th = thresholds(t);
        let code = |c: f32| th.partition_point(|&x| x <= c as f64) as u8;
        let (mut base, mut next) = (vec![0u8; BUCKETS], vec![f32::INFINITY; BUCKETS]);
        for b in 0..BUCKETS {
            let first = f32::from_bits((b as u32) << BUCKET_SHIFT);
            let last = f32::from_bits(((b as u32 + 1) << BUCKET_SHIFT) - 1);
            base[b] = code(first);
            if code(last) > base[b] {
                assert!(code(last) == base[b] + 1, "two thresholds in one bucket");
                // The smallest f32 at or above the threshold.
                let t = th[base[b] as usize];
                let mut x = t as f32;
                if (x as f64) < t {
                    x = f32::from_bits(x.to_bits() + 1);
                }
                next[b] = x;
            }
        }
        Encode8 { base, next }
    })
}

/// The 8-bit sRGB code of linear `c` (as `to_rgb8` makes it).
pub fn srgb8(c: f32) -> u8 {
    encode8(table8(Transfer::Srgb), c)
}

/// The 8-bit code of linear `c`: `round(255 · encode(c))`, clamped; 0 for NaN.
#[inline]
fn encode8(table: &Encode8, c: f32) -> u8 {
    if c.is_nan() || c <= 0.0 {
        return 0;
    }
    if c >= 1.0 {
        return 255;
    }
    let b = (c.to_bits() >> BUCKET_SHIFT) as usize;
    table.base[b] + u8::from(c >= table.next[b])
}

pub use crate::common::LinearImage;

/// Encoding the backend-neutral image (`common::image`) for files and terminals.
impl LinearImage {
    /// 8-bit encoded image.
    pub fn to_rgb8(&self, t: Transfer) -> ::image::RgbImage {
        let mut out = ::image::RgbImage::new(self.width, self.height);
        let table = table8(t);
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
    fn the_table_gives_the_rounded_curve() {
        // Every threshold's f32 neighbours (where the code steps), every bucket's first and
        // last value, and a sweep, against the direct formula.
        for t in [Transfer::Srgb, Transfer::Gamma22] {
            let table = table8(t);
            let direct = |c: f32| (t.encode(c as f64) * 255.0).round() as u8;
            let mut values = Vec::new();
            for &edge in thresholds(t).iter() {
                let x = edge as f32;
                let bits = x.to_bits();
                values.extend((bits - 2..=bits + 2).map(f32::from_bits));
            }
            for b in 0..BUCKETS as u32 {
                values.push(f32::from_bits(b << BUCKET_SHIFT));
                values.push(f32::from_bits(((b + 1) << BUCKET_SHIFT) - 1));
            }
            values.extend((0..=100_000).map(|i| i as f32 / 80_000.0 - 0.1));
            values.extend([0.0, -0.0, 1.0, 2.0, f32::MIN_POSITIVE, 1e-30, -1.0]);
            for &c in &values {
                assert_eq!(encode8(table, c), direct(c), "{t:?} at {c:e}");
            }
            assert_eq!(encode8(table, f32::NAN), 0);
            assert!(values.len() > 100_000);
        }
    }
}
