// The environment map (src/common/envmap.rs does the same arithmetic for the CPU tracer):
// its texels, looked up where a ray leaves the scene, and its piecewise-constant
// distribution (luminance × sin θ per texel), sampled by inverting the marginal CDF over rows
// and the conditional CDF within the row (PBRT 4th ed. §A.5.6, §12.5.2).
// Every function is only called under HAS_ENV_MAP (declared in trace.wgsl); `rotation` is the
// map's turn about +y in radians, the caller's intensity multiplies what they return.

// The map (src/common/envmap.rs, `words`): a header of ENV_HEADER words (width, height, the
// first word of the conditional CDFs, the first word of the texels), the marginal CDF
// (height + 1 f32), the conditional CDFs (height × (width + 1) f32), the RGBE texels.
@group(0) @binding(15) var<storage, read> env: array<u32>;

const ENV_HEADER: u32 = 4u;
const ENV_PI: f32 = 3.14159265358979;

fn env_width() -> u32 {
    return env[0];
}

fn env_height() -> u32 {
    return env[1];
}

// Texel (x, y)'s radiance: Radiance's RGBE, m × 2^(e − 136), the power of two made from its
// bits (exact; a packed texel's e is at least 29, so 2^(e − 136) is a normal float).
fn env_texel(x: u32, y: u32) -> vec3f {
    let w = env[env[3] + y * env_width() + x];
    let e = w >> 24u;
    if e == 0u {
        return vec3f(0.0);
    }
    let m = vec3f(f32(w & 0xffu), f32((w >> 8u) & 0xffu), f32((w >> 16u) & 0xffu));
    return m * bitcast<f32>((e - 9u) << 23u);
}

// The direction of map coordinates (u, v): v = 0 the zenith (+y), u = ½ looking down −z,
// u = ¾ towards +x, turned by the rotation about +y.
fn env_direction(u: f32, v: f32, rotation: f32) -> vec3f {
    let theta = ENV_PI * v;
    let phi = 2.0 * ENV_PI * u + rotation;
    let s = sin(theta);
    return vec3f(-s * sin(phi), cos(theta), s * cos(phi));
}

// Where unit direction d falls: its texel and its v (for sin θ).
struct EnvTexel {
    x: u32,
    y: u32,
    v: f32,
}

fn env_texel_of(d: vec3f, rotation: f32) -> EnvTexel {
    let v = acos(clamp(d.y, -1.0, 1.0)) / ENV_PI;
    let turns = (atan2(-d.x, d.z) - rotation) / (2.0 * ENV_PI);
    let u = turns - floor(turns);
    let w = env_width();
    let h = env_height();
    let x = min(u32(u * f32(w)), w - 1u);
    let y = min(u32(v * f32(h)), h - 1u);
    return EnvTexel(x, y, v);
}

fn env_cdf(word: u32) -> f32 {
    return bitcast<f32>(env[word]);
}

// The interval i of a CDF of n + 1 entries from word `base` with cdf[i] ≤ u < cdf[i + 1],
// u's place t in it, and its width (the interval's probability).
struct EnvInterval {
    i: u32,
    t: f32,
    width: f32,
}

fn env_invert(base: u32, n: u32, u: f32) -> EnvInterval {
    var lo = 0u;
    var hi = n;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if env_cdf(base + mid) <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let c0 = env_cdf(base + lo);
    let width = env_cdf(base + lo + 1u) - c0;
    var t = 0.5;
    if width > 0.0 {
        t = clamp((u - c0) / width, 0.0, 1.0);
    }
    return EnvInterval(lo, t, width);
}

// The density of direction (texel x, y at v) with respect to solid angle: the texel's
// probability × width × height over the Jacobian 2π² sin θ of (u, v) → direction.
fn env_density(row_p: f32, col_p: f32, v: f32) -> f32 {
    let s = sin(ENV_PI * v);
    if s <= 0.0 {
        return 0.0;
    }
    return row_p * f32(env_height()) * col_p * f32(env_width()) / (2.0 * ENV_PI * ENV_PI * s);
}

// The map's radiance seen along unit direction d.
fn env_radiance(d: vec3f, rotation: f32) -> vec3f {
    let t = env_texel_of(d, rotation);
    return env_texel(t.x, t.y);
}

// The solid-angle density with which env_sample gives unit direction d.
fn env_pdf(d: vec3f, rotation: f32) -> f32 {
    let t = env_texel_of(d, rotation);
    let row = env[2] + t.y * (env_width() + 1u);
    let row_p = env_cdf(ENV_HEADER + t.y + 1u) - env_cdf(ENV_HEADER + t.y);
    let col_p = env_cdf(row + t.x + 1u) - env_cdf(row + t.x);
    return env_density(row_p, col_p, t.v);
}

struct EnvSample {
    dir: vec3f,
    pdf: f32,
    radiance: vec3f,
}

// A direction drawn from the map's distribution for random numbers u: u.y picks the row,
// u.x the column; with its density and radiance.
fn env_sample(u: vec2f, rotation: f32) -> EnvSample {
    let w = env_width();
    let h = env_height();
    let r = env_invert(ENV_HEADER, h, u.y);
    let c = env_invert(env[2] + r.i * (w + 1u), w, u.x);
    let su = (f32(c.i) + c.t) / f32(w);
    let sv = (f32(r.i) + r.t) / f32(h);
    let dir = env_direction(su, sv, rotation);
    return EnvSample(dir, env_density(r.width, c.width, sv), env_texel(c.i, r.i));
}
