// Twin: src/cpu/rng.rs (tests/twins.rs keeps their functions paired).
// Random numbers: one sampler per (pixel, sample, seed), so a render is the same whatever the
// batching. The first QMC_SLOTS draws of a sample are points of Owen-scrambled Sobol
// sequences, the rest a PCG stream; src/cpu/rng.rs gives the reasoning and the sources
// (Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020; Vegdahl's LK hash; PCG
// hash and pcg3d from Jarzynski & Olano, JCGT 9(3), 2020; PCG-RXS-M-XS 32, O'Neill 2014).

const QMC_SLOTS: u32 = 10u;

// The low bits of Rng.index that count the stratified draws taken.
const SLOT_BITS: u32 = 0xfu;

// src/cpu/rng.rs says what the words hold. The stream is seeded at once: seeding it at its
// first draw put a test in every draw, which cost showcase 6 % on the H200.
struct Rng {
    seed: u32,
    index: u32,
    state: u32,
}

fn pcg3d(v_in: vec3u) -> vec3u {
    var v = v_in * 1664525u + 1013904223u;
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v ^= v >> vec3u(16u);
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    return v;
}

fn hash3(v: vec3u) -> u32 {
    let h = pcg3d(v);
    return h.x ^ h.y ^ h.z;
}

// PCG's linear congruential step.
fn lcg(x: u32) -> u32 {
    return x * 747796405u + 2891336453u;
}

fn pcg_hash(x: u32) -> u32 {
    let s = lcg(x);
    let word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (word >> 22u) ^ word;
}

fn seed_mix(s: u32) -> u32 {
    let x = (s ^ (s >> 16u)) * 0x2c1b3c6du;
    return x ^ (x >> 15u);
}

// Every output bit depends only on the input bits at and below it.
fn lk_hash(x_in: u32, seed: u32) -> u32 {
    var x = x_in;
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16u) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

// Sobol's second dimension before the bit reversal: the superset-sum transform.
fn pascal(y_in: u32) -> u32 {
    var y = y_in;
    y ^= (y >> 1u) & 0x55555555u;
    y ^= (y >> 2u) & 0x33333333u;
    y ^= (y >> 4u) & 0x0f0f0f0fu;
    y ^= (y >> 8u) & 0x00ff00ffu;
    y ^= (y >> 16u) & 0x0000ffffu;
    return y;
}

fn unit_float(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

fn rng_init(pixel: u32, sample: u32, seed: u32) -> Rng {
    let root = hash3(vec3u(pixel, 0xffffffffu - (sample & 1u), seed));
    let index = reverseBits((sample >> 1u) & 0x0fffffffu);
    return Rng(root, index, pcg_hash(root ^ pcg_hash(index)));
}

// The PCG stream's next float in [0, 1): 24 random bits.
fn rng_stream(r: ptr<function, Rng>) -> f32 {
    let x = pcg_hash((*r).state);
    (*r).state = lcg((*r).state);
    return unit_float(x);
}

// The next draw's scramble seed (x) and the sample's shuffled number in it (y).
fn rng_slot(r: ptr<function, Rng>) -> vec2u {
    let s = pcg_hash((*r).seed + ((*r).index & SLOT_BITS) * 0x9e3779b9u);
    (*r).index += 1u;
    return vec2u(s, reverseBits(lk_hash((*r).index & ~SLOT_BITS, s)));
}

// One uniform float in [0, 1).
fn rand(r: ptr<function, Rng>) -> f32 {
    if ((*r).index & SLOT_BITS) >= QMC_SLOTS {
        return rng_stream(r);
    }
    let si = rng_slot(r);
    return unit_float(reverseBits(lk_hash(si.y, seed_mix(si.x))));
}

// A uniform point of [0, 1)².
fn rand2(r: ptr<function, Rng>) -> vec2f {
    if ((*r).index & SLOT_BITS) >= QMC_SLOTS {
        let a = rng_stream(r);
        return vec2f(a, rng_stream(r));
    }
    let si = rng_slot(r);
    let s1 = seed_mix(si.x);
    let s2 = seed_mix(s1);
    return vec2f(unit_float(reverseBits(lk_hash(si.y, s1))),
        unit_float(reverseBits(lk_hash(pascal(si.y), s2))));
}
