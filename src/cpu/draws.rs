//! `cpu::rng`'s samplers in vector lanes (`cpu::simd`), one a lane, for `cpu::lanes`' paths:
//! the same hashes, the same Owen-scrambled Sobol points and PCG stream, bit for bit (tested
//! against `Rng` on every lane). A draw's point is made when drawn, for every lane drawing at
//! once; `Rng::group` makes a sample's first points ahead, eight pixels at a time, a cost per
//! sample that was a sixth to a quarter of the lanes' time. Sources: `cpu::rng`.

use super::rng::QMC_SLOTS;
use super::simd::{F, I, Isa, M, Make};

/// The samplers of the paths in the lanes: per lane the sample's root and reversed number
/// (`Rng`'s `root` and `index`), the Sobol draws taken, and the PCG stream's state.
pub struct Draws<S: Isa> {
    root: I<S>,
    index: I<S>,
    taken: I<S>,
    state: I<S>,
}

impl<S: Isa> Draws<S> {
    #[inline(always)]
    pub fn new(s: S) -> Self {
        let zero = s.int(0);
        Draws {
            root: zero,
            index: zero,
            taken: zero,
            state: zero,
        }
    }

    /// The lanes of `m` take the sampler of sample `sample` of pixel `pixel` (`Rng::new`).
    #[inline(always)]
    pub fn start(&mut self, s: S, m: M<S>, pixel: I<S>, sample: I<S>, seed: u32) {
        // rng::root: hash3([pixel, u32::MAX − (sample & 1), seed]).
        let half = s.int(-1) - sample.and(s.int(1));
        let root = hash3(s, [pixel, half, s.uint(seed)]);
        // rng::sample_index.
        let index = sample.shr(1).and(s.uint(0x0fff_ffff)).reverse_bits();
        let state = pcg_hash(s, root ^ pcg_hash(s, index));
        self.root = self.root.blend(root, m);
        self.index = self.index.blend(index, m);
        self.taken = self.taken.blend(s.int(0), m);
        self.state = self.state.blend(state, m);
    }

    /// A point of [0, 1)² for each lane of `m` (`Rng::rand2`; 0 elsewhere).
    #[inline(always)]
    pub fn draw2(&mut self, s: S, m: M<S>) -> (F<S>, F<S>) {
        let (sobol, stream) = self.split(s, m);
        let (mut u, mut v) = (s.zero(), s.zero());
        if sobol.any() {
            let (x, y) = slot_point(s, self.root, self.index, self.taken);
            (u, v) = (u.blend(x, sobol), v.blend(y, sobol));
            self.taken = self.taken.count(sobol);
        }
        if stream.any() {
            u = u.blend(self.stream(s, stream), stream);
            v = v.blend(self.stream(s, stream), stream);
        }
        (u, v)
    }

    /// A number in [0, 1) for each lane of `m` (`Rng::rand`; 0 elsewhere).
    #[inline(always)]
    pub fn draw(&mut self, s: S, m: M<S>) -> F<S> {
        let (sobol, stream) = self.split(s, m);
        let mut u = s.zero();
        if sobol.any() {
            let (x, _) = slot_point(s, self.root, self.index, self.taken);
            u = u.blend(x, sobol);
            self.taken = self.taken.count(sobol);
        }
        if stream.any() {
            u = u.blend(self.stream(s, stream), stream);
        }
        u
    }

    /// The Sobol draws each lane has taken (`Rng::taken`) and its stream's state.
    #[inline(always)]
    pub fn taken_and_state(&self) -> (I<S>, I<S>) {
        (self.taken, self.state)
    }

    /// The lanes of `m` whose next draw is a Sobol point, and those whose is the stream's.
    #[inline(always)]
    fn split(&self, s: S, m: M<S>) -> (M<S>, M<S>) {
        let sobol = s.int(QMC_SLOTS as i32).gt(self.taken) & m;
        (sobol, m.without(sobol))
    }

    /// The stream's next number in the lanes of `m` (`Rng::stream`).
    #[inline(always)]
    fn stream(&mut self, s: S, m: M<S>) -> F<S> {
        let x = pcg_hash(s, self.state);
        self.state = self.state.blend(lcg(s, self.state), m);
        unit(s, x)
    }
}

/// `rng::pcg3d`.
#[inline(always)]
fn pcg3d<S: Isa>(s: S, v: [I<S>; 3]) -> [I<S>; 3] {
    let (a, c) = (s.uint(1664525), s.uint(1013904223));
    let mut v = [v[0] * a + c, v[1] * a + c, v[2] * a + c];
    v[0] = v[0] + v[1] * v[2];
    v[1] = v[1] + v[2] * v[0];
    v[2] = v[2] + v[0] * v[1];
    v = [
        v[0] ^ v[0].shr(16),
        v[1] ^ v[1].shr(16),
        v[2] ^ v[2].shr(16),
    ];
    v[0] = v[0] + v[1] * v[2];
    v[1] = v[1] + v[2] * v[0];
    v[2] = v[2] + v[0] * v[1];
    v
}

/// `rng::hash3`.
#[inline(always)]
fn hash3<S: Isa>(s: S, v: [I<S>; 3]) -> I<S> {
    let h = pcg3d(s, v);
    (h[0] ^ h[1]) ^ h[2]
}

/// `rng::lcg`.
#[inline(always)]
fn lcg<S: Isa>(s: S, x: I<S>) -> I<S> {
    x * s.uint(747796405) + s.uint(2891336453)
}

/// `rng::pcg_hash`.
#[inline(always)]
fn pcg_hash<S: Isa>(s: S, x: I<S>) -> I<S> {
    let h = lcg(s, x);
    let word = (h.shr_each(h.shr(28) + s.int(4)) ^ h) * s.uint(277803737);
    word.shr(22) ^ word
}

/// `rng::mix`.
#[inline(always)]
fn mix<S: Isa>(s: S, h: I<S>) -> I<S> {
    let x = (h ^ h.shr(16)) * s.uint(0x2c1b_3c6d);
    x ^ x.shr(15)
}

/// `rng::lk_hash`.
#[inline(always)]
fn lk_hash<S: Isa>(s: S, x: I<S>, seed: I<S>) -> I<S> {
    let mut x = x ^ (x * s.uint(0x3d20adea));
    x = x + seed;
    x = x * (seed.shr(16) | s.int(1));
    x = x ^ (x * s.uint(0x05526c56));
    x ^ (x * s.uint(0x53a22864))
}

/// `rng::pascal`.
#[inline(always)]
fn pascal<S: Isa>(s: S, y: I<S>) -> I<S> {
    let mut y = y ^ y.shr(1).and(s.uint(0x5555_5555));
    y = y ^ y.shr(2).and(s.uint(0x3333_3333));
    y = y ^ y.shr(4).and(s.uint(0x0f0f_0f0f));
    y = y ^ y.shr(8).and(s.uint(0x00ff_00ff));
    y ^ y.shr(16).and(s.uint(0x0000_ffff))
}

/// `rng::unit`: the top 24 bits as a float in [0, 1).
#[inline(always)]
fn unit<S: Isa>(s: S, x: I<S>) -> F<S> {
    x.shr(8).to_float() * s.splat(1.0 / 16777216.0)
}

/// `rng::slot_point`: both dimensions of Sobol draw `slot` of each lane's sample.
#[inline(always)]
fn slot_point<S: Isa>(s: S, root: I<S>, index: I<S>, slot: I<S>) -> (F<S>, F<S>) {
    let h = pcg_hash(s, root + slot * s.uint(0x9e37_79b9));
    let i = lk_hash(s, index, h).reverse_bits();
    let s1 = mix(s, h);
    let s2 = mix(s, s1);
    (
        unit(s, lk_hash(s, i, s1).reverse_bits()),
        unit(s, lk_hash(s, pascal(s, i), s2).reverse_bits()),
    )
}
