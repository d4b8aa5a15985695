//! Random numbers, bit for bit those of shaders/common/rng.wgsl: one independent stream per
//! (pixel, sample, seed). PCG hash and pcg3d from Jarzynski & Olano, "Hash Functions for GPU
//! Rendering", JCGT 9(3), 2020; steps are PCG-RXS-M-XS 32 (O'Neill 2014).

fn pcg3d(v: [u32; 3]) -> [u32; 3] {
    let mut v = v.map(|x| x.wrapping_mul(1664525).wrapping_add(1013904223));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[2]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v = v.map(|x| x ^ (x >> 16));
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[2]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v
}

/// The random stream of one sample of one pixel.
pub struct Rng(u32);

impl Rng {
    pub fn new(pixel: u32, sample: u32, seed: u32) -> Rng {
        let h = pcg3d([pixel, sample, seed]);
        Rng(h[0] ^ h[1] ^ h[2])
    }

    /// Next uniform float in [0, 1): 24 random bits.
    #[inline(always)]
    pub fn rand(&mut self) -> f32 {
        let s = self.0.wrapping_mul(747796405).wrapping_add(2891336453);
        self.0 = s;
        let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277803737);
        let x = (word >> 22) ^ word;
        (x >> 8) as f32 * (1.0 / 16777216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_lie_in_the_unit_interval_and_streams_differ() {
        let mut a = Rng::new(3, 0, 7);
        let mut b = Rng::new(3, 1, 7);
        let xs: Vec<f32> = (0..1000).map(|_| a.rand()).collect();
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        let mean = xs.iter().sum::<f32>() / 1000.0;
        assert!((mean - 0.5).abs() < 0.05, "mean {mean}");
        assert_ne!(a.rand(), b.rand());
    }
}
