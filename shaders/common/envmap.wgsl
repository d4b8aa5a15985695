// Twin: src/scene/envmap_sampling.rs (tests/twins.rs keeps their functions paired).
// The environment map (src/scene/envmap_sampling.rs does the same arithmetic for the CPU tracer):
// its texels, looked up where a ray leaves the scene, and its piecewise-constant
// distribution (per texel its luminance less the map's mean, where above it, × sin θ: MIS
// compensation, built on the host), sampled by inverting the marginal CDF over rows
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

fn env_texel_at(c: vec2f) -> EnvTexel {
    let w = env_width();
    let h = env_height();
    let x = min(u32(c.x * f32(w)), w - 1u);
    let y = min(u32(c.y * f32(h)), h - 1u);
    return EnvTexel(x, y, c.y);
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

// The map coordinates (u, v) of unit direction d.
fn env_coordinates(d: vec3f, rotation: f32) -> vec2f {
    let v = acos(clamp(d.y, -1.0, 1.0)) / ENV_PI;
    let turns = (atan2(-d.x, d.z) - rotation) / (2.0 * ENV_PI);
    var u = turns - floor(turns);
    if u >= 1.0 {
        u = 0.0;
    }
    return vec2f(u, v);
}

// The radiance at map coordinates c = (u, v) (env_coordinates of the direction seen):
// bilinear between the four nearest texel centres, wrapping in u, clamped at the poles
// (src/scene/envmap_sampling.rs: bilinear). Unbiased beside the piecewise-constant sampling
// density: where the density is 0 and the filtered radiance is not (next to a black texel, or
// at or below the map's mean), the BSDF sample's MIS weight is 1.
fn env_lookup(c: vec2f) -> vec3f {
    let w = env_width();
    let h = env_height();
    let fx = c.x * f32(w) - 0.5;
    let fy = max(c.y * f32(h) - 0.5, 0.0);
    let x0f = floor(fx);
    let y0f = floor(fy);
    let tx = fx - x0f;
    let ty = fy - y0f;
    let x0 = u32(i32(x0f) + select(0, i32(w), x0f < 0.0)) % w;
    let x1 = (x0 + 1u) % w;
    let y0 = min(u32(y0f), h - 1u);
    let y1 = min(y0 + 1u, h - 1u);
    let a = env_texel(x0, y0);
    let b = env_texel(x1, y0);
    let top = a + tx * (b - a);
    let c0 = env_texel(x0, y1);
    let c1 = env_texel(x1, y1);
    let bottom = c0 + tx * (c1 - c0);
    return top + ty * (bottom - top);
}

// The solid-angle density with which env_sample gives unit direction d.
fn env_pdf(d: vec3f, rotation: f32) -> f32 {
    return env_pdf_at(env_coordinates(d, rotation));
}

// env_pdf of the direction at map coordinates c (env_coordinates): an escaped ray computes
// them once for the radiance and the density.
fn env_pdf_at(c: vec2f) -> f32 {
    let t = env_texel_at(c);
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
    // Looked up at the sampled (u, v), as the CPU tracer does (not through acos and atan2).
    return EnvSample(dir, env_density(r.width, c.width, sv), env_lookup(vec2f(su, sv)));
}
