//! The accumulation's exact fixed-point sums, as shaders/common/fixed.wgsl makes them: per
//! channel an unsigned 96-bit number with 32 fraction bits, stored as the words
//! [r.frac, r.low, r.high, g…, b…, samples] (`ACCUM_WORDS` per pixel), so that the GPU's
//! readback decoding and every consumer of the sums work unchanged.

use crate::common::accum::ACCUM_WORDS;

/// The largest f32 below 2^32: samples are clamped to it.
pub const FIXED_MAX: f32 = 4294967040.0;
const MASK_96: u128 = (1 << 96) - 1;

/// A sample's channels as `Fixed::add` adds them (and `fixed_add`): clamped to
/// [0, FIXED_MAX], each the 64-bit number whole << 32 | fraction, the fraction truncated to
/// 32 bits. (`cpu::lanes` makes the same words in vector lanes.)
#[inline(always)]
pub fn words(v: [f32; 3]) -> [u64; 3] {
    v.map(|x| {
        let c = x.clamp(0.0, FIXED_MAX);
        // Truncation is the floor of a non-negative number (`floor` is a libm call below
        // SSE4.1), and the whole part converts back to f32 exactly.
        let whole = c as u32;
        let frac = ((c - whole as f32) * 4294967296.0) as u32;
        (whole as u64) << 32 | frac as u64
    })
}

/// One pixel's sums of one half, while it is being added to.
#[derive(Clone, Copy, Default)]
pub struct Fixed {
    channels: [u128; 3],
    samples: u32,
}

impl Fixed {
    pub fn load(w: &[u32]) -> Fixed {
        let ch = |c: usize| {
            w[3 * c] as u128 | (w[3 * c + 1] as u128) << 32 | (w[3 * c + 2] as u128) << 64
        };
        Fixed {
            channels: [ch(0), ch(1), ch(2)],
            samples: w[9],
        }
    }

    pub fn store(&self, w: &mut [u32]) {
        for (c, v) in self.channels.iter().enumerate() {
            w[3 * c] = *v as u32;
            w[3 * c + 1] = (*v >> 32) as u32;
            w[3 * c + 2] = (*v >> 64) as u32;
        }
        w[ACCUM_WORDS - 1] = self.samples;
    }

    /// Adds one sample, exactly as `fixed_add` does (clamped to [0, FIXED_MAX], the fraction
    /// truncated to 32 bits, the 96-bit sum wrapping).
    #[inline]
    pub fn add(&mut self, v: [f32; 3]) {
        self.add_words(words(v));
    }

    /// Adds one sample given as its `words`.
    #[inline(always)]
    pub fn add_words(&mut self, w: [u64; 3]) {
        for (acc, x) in self.channels.iter_mut().zip(w) {
            *acc = (*acc + x as u128) & MASK_96;
        }
        self.samples = self.samples.wrapping_add(1);
    }

    /// Adds sums made apart (another range of the same pixel's samples), as exactly.
    pub fn merge(&mut self, o: &Fixed) {
        for (acc, v) in self.channels.iter_mut().zip(o.channels) {
            *acc = (*acc + v) & MASK_96;
        }
        self.samples = self.samples.wrapping_add(o.samples);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_are_exact_and_round_trip_through_the_words() {
        let mut f = Fixed::default();
        for _ in 0..1000 {
            f.add([0.25, 3.5, 1e9]);
        }
        let mut w = [0u32; ACCUM_WORDS];
        f.store(&mut w);
        let g = Fixed::load(&w);
        assert_eq!(g.channels[0], 250u128 << 32);
        assert_eq!(g.channels[1], 3500u128 << 32);
        assert_eq!(g.channels[2], 1_000_000_000_000u128 << 32);
        assert_eq!(g.samples, 1000);
        // Negative and NaN-free clamping: a negative sample adds nothing.
        let mut h = Fixed::default();
        h.add([-1.0, 0.0, 0.0]);
        assert_eq!(h.channels, [0; 3]);
    }
}
