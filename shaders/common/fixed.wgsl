// Twin: src/cpu/fixed.rs (tests/twins.rs keeps their functions paired).
// Exact fixed-point sums of radiance: the accumulation's number format (src/common/accum.rs
// decodes it).

// The accumulation is integer arithmetic, exact and independent of order: a compiler may
// reassociate float arithmetic (WGSL has no `precise`), and Mesa's does, which removes the
// error term of compensated sums such as Knuth's TwoSum (measured: a million frames drifted by
// 3.7e-3, exactly a plain f32 sum). Radiance is never negative, so each channel of each sample
// becomes an unsigned 96-bit fixed-point number with 32 fraction bits (exact for any f32
// ≥ 2^-8; below that truncated by < 2^-32) and is added with explicit carries.
const ACCUM_WORDS: u32 = 10u;
// The largest f32 below 2^32: samples are clamped to it (a radiance of 4e9 is no radiance).
const FIXED_MAX: f32 = 4294967040.0;

struct Fixed {
    frac: vec3u,
    low: vec3u,
    high: vec3u,
    samples: u32,
}

fn fixed_add(acc: ptr<function, Fixed>, v: vec3f) {
    let c = clamp(v, vec3f(0.0), vec3f(FIXED_MAX));
    let whole = floor(c);
    let add_frac = vec3u((c - whole) * 4294967296.0);
    let add_low = vec3u(whole);
    let frac = (*acc).frac + add_frac;
    let carry0 = select(vec3u(0u), vec3u(1u), frac < add_frac);
    let low1 = (*acc).low + add_low;
    let carry1 = select(vec3u(0u), vec3u(1u), low1 < add_low);
    let low = low1 + carry0;
    let carry2 = select(vec3u(0u), vec3u(1u), low < carry0);
    (*acc).frac = frac;
    (*acc).low = low;
    (*acc).high += carry1 + carry2;
    (*acc).samples += 1u;
}

// a + b, exactly (96-bit additions with carries): the sums of several lanes of one pixel
// merge into the same words whatever their order (src/gpu/reduce.rs).
fn fixed_merge(a: Fixed, b: Fixed) -> Fixed {
    let frac = a.frac + b.frac;
    let carry0 = select(vec3u(0u), vec3u(1u), frac < b.frac);
    let low1 = a.low + b.low;
    let carry1 = select(vec3u(0u), vec3u(1u), low1 < b.low);
    let low = low1 + carry0;
    let carry2 = select(vec3u(0u), vec3u(1u), low < carry0);
    return Fixed(frac, low, a.high + b.high + carry1 + carry2, a.samples + b.samples);
}

// The ACCUM_WORDS words of one pixel's sums: [r.frac, r.low, r.high, g…, b…, samples].
fn fixed_from_words(w: array<u32, 10>) -> Fixed {
    return Fixed(vec3u(w[0], w[3], w[6]), vec3u(w[1], w[4], w[7]), vec3u(w[2], w[5], w[8]), w[9]);
}

fn fixed_to_words(f: Fixed) -> array<u32, 10> {
    return array<u32, 10>(
        f.frac.x, f.low.x, f.high.x, f.frac.y, f.low.y, f.high.y, f.frac.z, f.low.z, f.high.z, f.samples
    );
}

fn fixed_zero() -> Fixed {
    return Fixed(vec3u(0u), vec3u(0u), vec3u(0u), 0u);
}

// The sums as floats (exact in the fixed point, rounded to f32 only here).
fn fixed_value(f: Fixed) -> vec3f {
    return vec3f(f.high) * 4294967296.0 + vec3f(f.low) + vec3f(f.frac) * (1.0 / 4294967296.0);
}

// A half's mean (0 without samples) and its sample count (common/estimate.wgsl's terms read
// it).
fn fixed_mean(f: Fixed) -> vec4f {
    let n = f32(f.samples);
    if n > 0.0 {
        return vec4f(fixed_value(f) / n, n);
    }
    return vec4f(0.0);
}
