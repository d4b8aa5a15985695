//! The exact-sum accumulation format both tracers write: per pixel and half, three 96-bit
//! fixed-point channel sums and a sample count (`fixed_add` in shaders/common/fixed.wgsl,
//! `cpu::fixed` on the host), and its decoding to `[r, g, b, samples]`.

/// Words of one pixel in one half: three per channel (fraction, low and high 32 bits of
/// the integer part) and the sample count (ACCUM_WORDS in trace.wgsl).
pub const ACCUM_WORDS: usize = 10;
/// The per-pixel sums read back from a tracer, each `[r, g, b, samples]` (the exact sums,
/// rounded to f32 only here).
#[derive(Clone, Debug)]
pub struct AccumData {
    pub even: Vec<[f32; 4]>,
    pub odd: Vec<[f32; 4]>,
    /// Samples discarded because they were NaN or infinite, since the last reset.
    pub invalid: u64,
    /// Path segments traced since the last reset (counted only when asked for).
    pub segments: u64,
    /// BVH nodes visited and primitives tested since the last reset (likewise).
    pub node_visits: u64,
    pub primitive_tests: u64,
}

impl AccumData {
    /// Sums from elsewhere (a cache, a test), with every counter at zero.
    pub fn from_halves(even: Vec<[f32; 4]>, odd: Vec<[f32; 4]>) -> AccumData {
        AccumData {
            even,
            odd,
            invalid: 0,
            segments: 0,
            node_visits: 0,
            primitive_tests: 0,
        }
    }
}

/// One pixel's fixed-point sums (its `ACCUM_WORDS` words) as `[r, g, b, samples]`, exact
/// until this rounding to f32.
pub fn decode_pixel(p: &[u32]) -> [f32; 4] {
    let channel = |c: usize| {
        let (frac, low, high) = (p[3 * c], p[3 * c + 1], p[3 * c + 2]);
        (high as f64 * 4294967296.0 + low as f64 + frac as f64 / 4294967296.0) as f32
    };
    [channel(0), channel(1), channel(2), p[9] as f32]
}

/// Decodes fixed-point sums (`ACCUM_WORDS` words per pixel) to `[r, g, b, samples]`.
pub fn decode(words: &[u32]) -> Vec<[f32; 4]> {
    words.chunks_exact(ACCUM_WORDS).map(decode_pixel).collect()
}

/// Adds the sums `b` to `a`, word for word as the tracers add samples: per pixel three
/// 96-bit fixed-point channels (fraction, low, high) and a sample count.
pub fn add_words(a: &mut [u32], b: &[u32]) {
    for (p, q) in a
        .chunks_exact_mut(ACCUM_WORDS)
        .zip(b.chunks_exact(ACCUM_WORDS))
    {
        for c in 0..3 {
            let v = |w: &[u32]| {
                w[3 * c] as u128 | (w[3 * c + 1] as u128) << 32 | (w[3 * c + 2] as u128) << 64
            };
            let s = (v(p) + v(q)) & ((1u128 << 96) - 1);
            p[3 * c] = s as u32;
            p[3 * c + 1] = (s >> 32) as u32;
            p[3 * c + 2] = (s >> 64) as u32;
        }
        p[ACCUM_WORDS - 1] = p[ACCUM_WORDS - 1].wrapping_add(q[ACCUM_WORDS - 1]);
    }
}

/// A device's exact sums of an image (`ACCUM_WORDS` words per pixel, each half) and the
/// samples it discarded as invalid, as `Renderer::exact_sums` reads them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Sums {
    pub even: Vec<u32>,
    pub odd: Vec<u32>,
    pub invalid: u64,
}

impl Sums {
    /// Adds the sums of another device (or part) of the same image.
    pub fn add(&mut self, other: &Sums) {
        add_words(&mut self.even, &other.even);
        add_words(&mut self.odd, &other.odd);
        self.invalid += other.invalid;
    }
}
