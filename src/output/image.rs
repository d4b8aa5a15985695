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
        for (o, p) in out.pixels_mut().zip(&self.pixels) {
            o.0 = p.map(|c| (t.encode(c as f64) * 255.0).round() as u8);
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
