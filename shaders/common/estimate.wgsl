// The two-halves error estimate's per-pixel terms (src/common/estimate.rs, whose comments
// say why): the factor that makes a pixel's (A − B)² the variance of its pooled mean, and the
// weight of its squared error in pbrt's relative MSE, 1 / (reference² proxy + 0.01), the
// proxy being the smaller of the halves' 3×3 means times their pooled 3×3 mean. Included by
// resolve.wgsl and denoise.wgsl, whose `window_weight` walks `proxy_window` with their own
// `half_mean` (each reads the accumulation its own way).

// pbrt's relative-MSE epsilon (src/common/estimate.rs: REL_MSE_EPSILON).
const REL_MSE_EPSILON: f32 = 0.01;
// src/common/estimate.rs: PROXY_RADIUS.
const PROXY_RADIUS: i32 = 1;

// n_A·n_B / (n_A + n_B)², or 0 until each half holds a sample.
fn pair_factor(na: f32, nb: f32) -> f32 {
    if na >= 1.0 && nb >= 1.0 {
        return na * nb / ((na + nb) * (na + nb));
    }
    return 0.0;
}

// The halves' sums over a pixel's window, for the reference² proxy.
struct ProxySums {
    a: vec3f,
    b: vec3f,
    na: f32,
    nb: f32,
}

// The window around traced pixel (x, y) of a `size` image, clipped at its edges: x0, y0
// (inclusive), x1, y1 (exclusive).
fn proxy_window(x: u32, y: u32, size: vec2u) -> vec4u {
    let r = u32(PROXY_RADIUS);
    return vec4u(max(x, r) - r, max(y, r) - r, min(x + r + 1u, size.x), min(y + r + 1u, size.y));
}

// Adds one window pixel's half means `a` and `b` (mean, samples; common/estimate.wgsl's
// includers' `half_mean`), each where its half has samples.
fn proxy_add(s: ptr<function, ProxySums>, a: vec4f, b: vec4f) {
    if a.w > 0.0 {
        (*s).a += a.xyz;
        (*s).na += 1.0;
    }
    if b.w > 0.0 {
        (*s).b += b.xyz;
        (*s).nb += 1.0;
    }
}

// The relative MSE's weight of a pixel from its window's sums, per channel.
fn relative_weight(s: ProxySums) -> vec3f {
    let a = s.a / max(s.na, 1.0);
    let b = s.b / max(s.nb, 1.0);
    let square = max(min(a, b), vec3f(0.0)) * max(0.5 * (a + b), vec3f(0.0));
    return 1.0 / (square + REL_MSE_EPSILON);
}
