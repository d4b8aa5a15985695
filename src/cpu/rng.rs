//! Random numbers, bit for bit those of shaders/common/rng.wgsl: one sampler per (pixel,
//! sample, seed). The first `QMC_SLOTS` draws of a sample (camera, lens and the first
//! bounces) are points of Owen-scrambled Sobol sequences, the rest a PCG stream.
//!
//! Quasi-Monte Carlo as Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020: each
//! draw (a 1D or a 2D one) is its own "padded" sequence, indexed by the sample's number
//! within its half, shuffled by a nested uniform scramble of that number and Owen-scrambled,
//! both with seeds hashed from (pixel, half, draw). Every prefix of 2^m samples of a half is
//! then a stratified (0, m, 2)-net in each draw's dimensions, and every point is uniform in
//! its cube, so the estimate stays unbiased. The even and odd samples (the two halves the
//! noise estimate compares) are independently scrambled sequences, so their difference still
//! measures the error of their mean without bias. Owen scrambling by Vegdahl's improved
//! Laine–Karras hash ("Building a Better LK Hash", psychopath.io, 2021). The second Sobol
//! dimension's generator (the Pascal matrix mod 2) is applied by the superset-sum transform:
//! by Lucas' theorem its output digit k is the XOR of the index bits j with j ⊇ k.
//!
//! PCG hash and pcg3d from Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 9(3),
//! 2020; the stream's steps are PCG-RXS-M-XS 32 (O'Neill 2014).

/// Draws (1D or 2D) per sample taken from the scrambled Sobol sequences; later draws come
/// from the PCG stream, where stratification no longer pays for its cost.
pub const QMC_SLOTS: u32 = 10;

#[inline(always)]
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

#[inline(always)]
pub(super) fn hash3(v: [u32; 3]) -> u32 {
    let h = pcg3d(v);
    h[0] ^ h[1] ^ h[2]
}

/// PCG's linear congruential step.
#[inline(always)]
fn lcg(x: u32) -> u32 {
    x.wrapping_mul(747796405).wrapping_add(2891336453)
}

/// The PCG hash (Jarzynski & Olano): one word to one well-mixed word.
#[inline(always)]
fn pcg_hash(x: u32) -> u32 {
    let s = lcg(x);
    let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// A cheap bijective mix (multiply and xorshift) for the seeds derived from a hashed one.
#[inline(always)]
fn mix(s: u32) -> u32 {
    let x = (s ^ (s >> 16)).wrapping_mul(0x2c1b_3c6d);
    x ^ (x >> 15)
}

/// Vegdahl's Laine–Karras-style hash: every output bit depends only on the input bits at
/// and below it, so on bit-reversed digits it is a nested uniform scramble.
#[inline(always)]
fn lk_hash(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x05526c56);
    x ^= x.wrapping_mul(0x53a22864);
    x
}

/// A nested uniform scramble of an integer's digits from the most significant one: a
/// shuffle of sample numbers that maps every aligned block of 2^m numbers onto one. It takes
/// the number with its bits reversed (kept so by `Rng`).
#[inline(always)]
fn shuffle(reversed: u32, seed: u32) -> u32 {
    lk_hash(reversed, seed).reverse_bits()
}

/// The superset-sum transform over GF(2): bit k of the result is the XOR of the bits j of
/// `i` with j ⊇ k (as bit sets of the positions).
#[inline(always)]
pub fn pascal(mut y: u32) -> u32 {
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= (y >> 16) & 0x0000_ffff;
    y
}

/// A 32-bit fraction (its digits most significant first in the bits from 31 down) as a
/// float in [0, 1) with 24 of them.
#[inline(always)]
pub(super) fn unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16777216.0)
}

/// The low bits of rng.wgsl's draw index that count the stratified draws taken (here
/// `Rng::taken`).
const SLOT_BITS: u32 = 0xf;
const _: () = assert!(QMC_SLOTS <= SLOT_BITS);
const SLOTS: usize = QMC_SLOTS as usize;

/// Pixels whose samplers `Rng::group` makes at once.
pub const GROUP: usize = 8;

/// The random numbers of one sample of one pixel.
///
/// The Sobol points of its first `ahead` draws are made when the sampler is: hashing them
/// draw by draw put a chain of about twenty dependent multiplications in front of every
/// bounce (16 % of the CPU tracer's time on `weekend`), while made at once for eight pixels
/// (`group`) they are independent work for SIMD lanes, done before the path starts. The
/// others, and all of them in rng.wgsl, are made when drawn; the numbers are the same.
#[derive(Clone, Copy)]
pub struct Rng {
    /// The points of the Sobol draws, (first, second dimension); a 1D draw is the first.
    points: [[f32; 2]; SLOTS],
    /// Draws taken so far (counting stops past the Sobol ones).
    taken: u32,
    /// Sobol points made ahead (the rest are made when drawn, from `root` and `index`).
    ahead: u32,
    /// `root` and `sample_index` of the sample.
    root: u32,
    index: u32,
    /// The PCG stream's state, for the draws after `QMC_SLOTS`. Seeded at once: seeding it
    /// at its first draw put a test in every draw, which cost showcase 6 % on the H200.
    state: u32,
}

/// The sample's number within its half, its bits reversed (free below 2^28 samples per
/// half; past that the number wraps: the same points again, unbiased but no longer new).
#[inline(always)]
fn sample_index(sample: u32) -> u32 {
    ((sample >> 1) & 0x0fff_ffff).reverse_bits()
}

/// The root of every scramble of a sample: a hash of (pixel, half, seed).
#[inline(always)]
fn root(pixel: u32, sample: u32, seed: u32) -> u32 {
    hash3([pixel, u32::MAX - (sample & 1), seed])
}

/// The point of Sobol draw `slot` of the sample with root `root` and reversed number
/// `index`: both Sobol dimensions, the sample's number shuffled and the digits
/// Owen-scrambled with seeds hashed from (root, slot).
#[inline(always)]
fn slot_point(root: u32, index: u32, slot: u32) -> [f32; 2] {
    let s = pcg_hash(root.wrapping_add(slot.wrapping_mul(0x9e37_79b9)));
    let i = shuffle(index, s);
    let s1 = mix(s);
    let s2 = mix(s1);
    [
        unit(lk_hash(i, s1).reverse_bits()),
        unit(lk_hash(pascal(i), s2).reverse_bits()),
    ]
}

/// `Rng::group`'s work, lane by lane in loops the compiler vectorizes.
#[inline(always)]
fn group_lanes(pixels: &[u32; GROUP], sample: u32, seed: u32, ahead: usize) -> [Rng; GROUP] {
    let ahead = ahead.min(SLOTS);
    let index = sample_index(sample);
    let pi = pcg_hash(index);
    let mut roots = [0u32; GROUP];
    for (r, &p) in roots.iter_mut().zip(pixels) {
        *r = root(p, sample, seed);
    }
    let mut out = [Rng {
        points: [[0.0; 2]; SLOTS],
        taken: 0,
        ahead: ahead as u32,
        root: 0,
        index,
        state: 0,
    }; GROUP];
    for (o, &r) in out.iter_mut().zip(&roots) {
        o.state = pcg_hash(r ^ pi);
        o.root = r;
    }
    for slot in 0..ahead {
        let mut p = [[0.0f32; 2]; GROUP];
        for (p, &r) in p.iter_mut().zip(&roots) {
            *p = slot_point(r, index, slot as u32);
        }
        for (o, p) in out.iter_mut().zip(p) {
            o.points[slot] = p;
        }
    }
    out
}

/// `group_lanes` compiled for AVX2 (eight lanes of 32-bit multiplies and shifts).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn group_avx2(pixels: &[u32; GROUP], sample: u32, seed: u32, ahead: usize) -> [Rng; GROUP] {
    group_lanes(pixels, sample, seed, ahead)
}

/// Whether the CPU has what `group_avx512` is compiled for (the checks are cached).
#[cfg(target_arch = "x86_64")]
fn has_avx512() -> bool {
    use std::arch::is_x86_feature_detected as has;
    has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq") && has!("gfni")
}

/// `group_lanes` compiled for AVX-512 (with GFNI): the eight lanes' bit reversals and
/// rotations in fewer operations; 4-5 % more samples/s on `cornell` than AVX2, the points
/// the same bit for bit (integer arithmetic).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl,avx512bw,avx512dq,gfni")]
fn group_avx512(pixels: &[u32; GROUP], sample: u32, seed: u32, ahead: usize) -> [Rng; GROUP] {
    group_lanes(pixels, sample, seed, ahead)
}

impl Rng {
    pub fn new(pixel: u32, sample: u32, seed: u32) -> Rng {
        let (root, index) = (root(pixel, sample, seed), sample_index(sample));
        Rng {
            points: std::array::from_fn(|slot| slot_point(root, index, slot as u32)),
            taken: 0,
            ahead: QMC_SLOTS,
            root,
            index,
            state: pcg_hash(root ^ pcg_hash(index)),
        }
    }

    /// The samplers of sample `sample` of eight pixels, as `new` makes them, with the
    /// points of the first `ahead` Sobol draws made at once (those most paths take; a point
    /// made and not drawn is wasted work), the others when drawn. Only on a CPU with AVX2:
    /// without it the lanes' 32-bit multiplications and shifts are emulated, and making
    /// points ahead was measured 2-3 % slower than making each when drawn (BENCHMARKS.md).
    #[inline]
    pub fn group(pixels: &[u32; GROUP], sample: u32, seed: u32, ahead: usize) -> [Rng; GROUP] {
        #[cfg(target_arch = "x86_64")]
        if has_avx512() {
            // SAFETY: the CPU has the features `group_avx512` is compiled for.
            return unsafe { group_avx512(pixels, sample, seed, ahead) };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { group_avx2(pixels, sample, seed, ahead) };
        }
        let _ = ahead;
        group_lanes(pixels, sample, seed, 0)
    }

    /// The sampler of (pixel, sample, seed) after `taken` Sobol draws, its stream at
    /// `state`: where a path traced in lanes left it (`cpu::lanes`' tests).
    #[cfg(all(test, target_arch = "x86_64"))]
    pub fn resumed(pixel: u32, sample: u32, seed: u32, taken: u32, state: u32) -> Rng {
        Rng {
            taken,
            state,
            ..Rng::new(pixel, sample, seed)
        }
    }

    /// The Sobol draws taken so far (at most `QMC_SLOTS`).
    #[inline(always)]
    pub fn taken(&self) -> u32 {
        self.taken
    }

    /// The next Sobol draw's point, or None once the draws come from the PCG stream.
    #[inline(always)]
    fn next_point(&mut self) -> Option<[f32; 2]> {
        let k = self.taken as usize;
        if k >= SLOTS {
            return None;
        }
        self.taken += 1;
        if k >= self.ahead as usize {
            return Some(slot_point(self.root, self.index, k as u32));
        }
        Some(self.points[k])
    }

    /// The PCG stream's next float in [0, 1): 24 random bits.
    #[inline(always)]
    fn stream(&mut self) -> f32 {
        // A PCG step: the hash of the state is the output, its LCG step the next state.
        let x = pcg_hash(self.state);
        self.state = lcg(self.state);
        unit(x)
    }

    /// One uniform float in [0, 1) (an Owen-scrambled van der Corput point while the
    /// sample's draws are stratified).
    #[inline(always)]
    pub fn rand(&mut self) -> f32 {
        match self.next_point() {
            Some([x, _]) => x,
            None => self.stream(),
        }
    }

    /// A uniform point of [0, 1)² (the first two Sobol dimensions, Owen-scrambled, while
    /// the sample's draws are stratified).
    #[inline(always)]
    pub fn rand2(&mut self) -> (f32, f32) {
        match self.next_point() {
            Some([x, y]) => (x, y),
            None => {
                let a = self.stream();
                (a, self.stream())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sobol's second dimension by its definition: direction numbers v₀ = 2³¹,
    /// vⱼ₊₁ = vⱼ ^ (vⱼ >> 1), XORed for the set bits of the index.
    fn sobol1(mut i: u32) -> u32 {
        let (mut v, mut x) = (1u32 << 31, 0);
        while i != 0 {
            if i & 1 == 1 {
                x ^= v;
            }
            i >>= 1;
            v ^= v >> 1;
        }
        x
    }

    /// rng.wgsl stratifies as many draws and keeps the draw count in the same bits.
    #[test]
    fn the_shader_sampler_has_the_same_constants() {
        let constant = |name| crate::common::wgsl::u32_constant("common/rng.wgsl", name);
        assert_eq!(constant("QMC_SLOTS"), QMC_SLOTS);
        assert_eq!(constant("SLOT_BITS"), SLOT_BITS);
    }

    /// The draws of one sample as rng.wgsl takes them, each Sobol point hashed when drawn
    /// (the definition `Rng` computes ahead): `pattern` says which draws are 2D.
    fn drawn_one_by_one(pixel: u32, sample: u32, seed: u32, pattern: &[bool]) -> Vec<f32> {
        let root = hash3([pixel, u32::MAX - (sample & 1), seed]);
        let mut index = ((sample >> 1) & 0x0fff_ffff).reverse_bits();
        let mut state = pcg_hash(root ^ pcg_hash(index));
        let mut stream = || {
            let x = pcg_hash(state);
            state = lcg(state);
            unit(x)
        };
        let mut out = Vec::new();
        for &two in pattern {
            let slot = index & SLOT_BITS;
            if slot >= QMC_SLOTS {
                out.push(stream());
                if two {
                    out.push(stream());
                }
                continue;
            }
            let s = pcg_hash(root.wrapping_add(slot.wrapping_mul(0x9e37_79b9)));
            index += 1;
            let i = shuffle(index & !SLOT_BITS, s);
            let s1 = mix(s);
            out.push(unit(lk_hash(i, s1).reverse_bits()));
            if two {
                out.push(unit(lk_hash(pascal(i), mix(s1)).reverse_bits()));
            }
        }
        out
    }

    #[test]
    fn points_made_ahead_and_in_lanes_are_those_drawn_one_by_one() {
        let pattern: Vec<bool> = (0..QMC_SLOTS + 4).map(|k| k % 3 != 1).collect();
        let draws = |r: &mut Rng| -> Vec<f32> {
            let mut v = Vec::new();
            for &two in &pattern {
                if two {
                    let (a, b) = r.rand2();
                    v.extend([a, b]);
                } else {
                    v.push(r.rand());
                }
            }
            v
        };
        for (sample, seed) in [
            (0u32, 0u32),
            (1, 7),
            (2, 7),
            (77, 3),
            (1 << 20, 1),
            (u32::MAX, 9),
        ] {
            let pixels: [u32; GROUP] = std::array::from_fn(|l| 1000 * l as u32 + sample % 13);
            for (l, &p) in pixels.iter().enumerate() {
                let want = drawn_one_by_one(p, sample, seed, &pattern);
                assert_eq!(
                    draws(&mut Rng::new(p, sample, seed)),
                    want,
                    "new: {p} {sample}"
                );
                for ahead in [0, 4, SLOTS, SLOTS + 1] {
                    let mut group = Rng::group(&pixels, sample, seed, ahead);
                    assert_eq!(draws(&mut group[l]), want, "group: {p} {sample} {ahead}");
                    assert_eq!(
                        draws(&mut group_lanes(&pixels, sample, seed, ahead)[l]),
                        want,
                        "portable lanes: {p} {sample} {ahead}"
                    );
                    // `group` takes AVX-512 where the CPU has it: AVX2's lanes too.
                    #[cfg(target_arch = "x86_64")]
                    if std::arch::is_x86_feature_detected!("avx2") {
                        // SAFETY: the CPU has AVX2.
                        let mut g = unsafe { group_avx2(&pixels, sample, seed, ahead) };
                        assert_eq!(draws(&mut g[l]), want, "AVX2 lanes: {p} {sample} {ahead}");
                    }
                }
            }
        }
    }

    #[test]
    fn pascal_transform_is_sobols_second_dimension() {
        for i in (0..70_000u32).chain([u32::MAX, 0x8000_0000, 0xdead_beef]) {
            assert_eq!(pascal(i).reverse_bits(), sobol1(i), "index {i}");
        }
    }

    #[test]
    fn shuffle_permutes_aligned_blocks() {
        // The first 2^m numbers go to one aligned block of 2^m, each once.
        for m in [1u32, 4, 8] {
            let n = 1u32 << m;
            let mut seen: Vec<u32> = (0..n)
                .map(|i| shuffle(i.reverse_bits(), 0x1234_5678))
                .collect();
            let block = seen[0] >> m;
            assert!(seen.iter().all(|&x| x >> m == block));
            seen.sort();
            seen.dedup();
            assert_eq!(seen.len(), n as usize);
        }
    }

    #[test]
    fn every_power_of_two_prefix_is_stratified() {
        // 2^m samples of a half: in every draw, each 1D stratum of width 2^-m holds one, and
        // for 2D draws each elementary box of 2^-a × 2^-(m-a) holds one.
        for pixel in [0u32, 17, 999] {
            let m = 6;
            let n = 1u32 << m;
            let draws: Vec<[(f32, f32); 3]> = (0..n)
                .map(|i| {
                    let mut r = Rng::new(pixel, 2 * i + 1, 7);
                    let a = r.rand2();
                    let b = r.rand();
                    let c = r.rand2();
                    [a, (b, 0.0), c]
                })
                .collect();
            for d in [0, 2] {
                for a in 0..=m {
                    let mut cells = vec![0; n as usize];
                    for p in &draws {
                        let (x, y) = p[d];
                        let cx = (x * (1u32 << a) as f32) as u32;
                        let cy = (y * (1u32 << (m - a)) as f32) as u32;
                        cells[(cx << (m - a) | cy) as usize] += 1;
                    }
                    assert!(cells.iter().all(|&c| c == 1), "draw {d}, boxes 2^-{a}");
                }
            }
            let mut strata = vec![0; n as usize];
            for p in &draws {
                strata[(p[1].0 * n as f32) as usize] += 1;
            }
            assert!(strata.iter().all(|&c| c == 1));
        }
    }

    #[test]
    fn floats_lie_in_the_unit_interval_and_streams_differ() {
        let mut a = Rng::new(3, 0, 7);
        let mut b = Rng::new(3, 2, 7);
        let xs: Vec<f32> = (0..1000).map(|_| a.rand()).collect();
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        let mean = xs[20..].iter().sum::<f32>() / 980.0;
        assert!((mean - 0.5).abs() < 0.05, "mean {mean}");
        assert_ne!(Rng::new(3, 0, 7).rand(), b.rand());
    }

    #[test]
    fn draws_are_uniform_over_pixels_and_samples() {
        // Each draw of each slot, over many pixels and samples: mean 1/2, variance 1/12,
        // and the two coordinates of a 2D draw uncorrelated (3.5 standard errors).
        let n = 40_000usize;
        for slot in 0..QMC_SLOTS + 2 {
            let (mut sx, mut sxx, mut sxy) = (0.0f64, 0.0f64, 0.0f64);
            for k in 0..n as u32 {
                let mut r = Rng::new(k / 8, k % 8, 1);
                for _ in 0..slot {
                    r.rand();
                }
                let (x, y) = r.rand2();
                let (x, y) = (x as f64 - 0.5, y as f64 - 0.5);
                sx += x;
                sxx += x * x;
                sxy += x * y;
            }
            let nf = n as f64;
            assert!(
                (sx / nf).abs() < 3.5 * (1.0 / 12.0 / nf).sqrt(),
                "slot {slot} mean"
            );
            assert!((sxx / nf - 1.0 / 12.0).abs() < 3.5 * (1.0 / 180.0 / nf).sqrt());
            assert!(
                (sxy / nf).abs() < 3.5 * (1.0 / 144.0 / nf).sqrt(),
                "slot {slot}"
            );
        }
    }
}
