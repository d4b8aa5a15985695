//! The denoiser's guides both tracers make (`fn guides` in shaders/trace.wgsl,
//! `cpu::CpuEngine::guides`): per pixel, fixed-point sums of the albedo and the shading
//! normal of the first surface that is not a perfect specular one, and their decoding.

/// Words per pixel: the albedo's three channel sums, the normal's three (mapped to [0, 1]),
/// and the sample count (GUIDE_WORDS in trace.wgsl).
pub const GUIDE_WORDS: usize = 7;
/// The guides' random streams are the pixel's with the seed xor this (GUIDE_SEED in
/// trace.wgsl), independent of both halves of the radiance.
pub const GUIDE_SEED: u32 = 0x6a09_e667;
/// Guide samples per pixel a denoising render takes (one dispatch after every reset): enough
/// for edges to be antialiased as the radiance's are, cheap beside the radiance's samples.
pub const GUIDE_SAMPLES: u32 = 8;
/// The fixed-point step of one sample's value.
const STEP: f32 = 65535.0;

/// One sample's value in [0, 1] as a fixed-point step count (guide_quantize in trace.wgsl).
pub fn quantize(v: f32) -> u32 {
    (v.clamp(0.0, 1.0) * STEP + 0.5) as u32
}

/// The mean albedo and normal of every pixel (a pixel that no ray left as a surface, the sky,
/// has a zero normal).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Guides {
    pub width: u32,
    pub height: u32,
    pub albedo: Vec<[f32; 3]>,
    pub normal: Vec<[f32; 3]>,
}

impl Guides {
    /// Decodes `GUIDE_WORDS` words per pixel.
    pub fn decode(width: u32, height: u32, words: &[u32]) -> Guides {
        let mut g = Guides {
            width,
            height,
            albedo: Vec::with_capacity(words.len() / GUIDE_WORDS),
            normal: Vec::with_capacity(words.len() / GUIDE_WORDS),
        };
        for p in words.chunks_exact(GUIDE_WORDS) {
            let n = (p[6] as f64).max(1.0) * STEP as f64;
            let mean = |i: usize| (p[i] as f64 / n) as f32;
            g.albedo.push([mean(0), mean(1), mean(2)]);
            g.normal.push(std::array::from_fn(|c| {
                if p[6] == 0 {
                    0.0
                } else {
                    (2.0 * p[3 + c] as f64 / n - 1.0) as f32
                }
            }));
        }
        g
    }

    /// Adds one sample's albedo and normal to a pixel's words.
    pub fn add(words: &mut [u32], albedo: [f32; 3], normal: [f32; 3]) {
        for c in 0..3 {
            words[c] += quantize(albedo[c]);
            words[3 + c] += quantize(normal[c] * 0.5 + 0.5);
        }
        words[6] += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_match_the_shader() {
        use crate::common::wgsl::u32_constant;
        assert_eq!(
            u32_constant("trace.wgsl", "GUIDE_WORDS") as usize,
            GUIDE_WORDS
        );
        assert_eq!(u32_constant("trace.wgsl", "GUIDE_SEED"), GUIDE_SEED);
    }

    #[test]
    fn sums_decode_to_the_mean() {
        let mut w = [0u32; GUIDE_WORDS];
        Guides::add(&mut w, [1.0, 0.5, 0.0], [0.0, 1.0, 0.0]);
        Guides::add(&mut w, [1.0, 0.5, 0.0], [0.0, 1.0, 0.0]);
        let g = Guides::decode(1, 1, &w);
        assert_eq!(g.albedo[0][0], 1.0);
        assert!((g.albedo[0][1] - 0.5).abs() < 1.0 / 65535.0);
        assert_eq!(g.normal[0][1], 1.0);
        // A normal component is quantized in steps of 2/65535 (mapped to [0, 1]).
        assert!(g.normal[0][0].abs() <= 1.0 / 65535.0);
        let none = Guides::decode(1, 1, &[0; GUIDE_WORDS]);
        assert_eq!(none.normal[0], [0.0; 3]);
    }
}
