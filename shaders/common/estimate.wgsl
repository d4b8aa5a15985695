// The two-halves error estimate's per-pixel terms (src/common/estimate.rs, whose comments
// say why): the factor that makes a pixel's (A − B)² the variance of its pooled mean, and the
// weight of its squared error in pbrt's relative MSE, 1 / (reference² proxy + 0.01), the
// proxy being the mean of the pixel's 3×3 neighbours, at most the larger of its two half
// means and at least what they agree on; the weight made of two independent
// estimates (`product_weight`), and a filtered image's (`filtered_weight`). Included by
// resolve.wgsl and denoise.wgsl, which walk `proxy_window` with their own `half_mean` (each
// reads the accumulation its own way).

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

// A pixel's proxy terms (src/common/estimate.rs, `proxy_terms`): its mean (the mean of its
// halves' means where both have samples, else the one half's), the smaller and the larger of
// its halves' means, and whether it has samples at all.
struct ProxyTerms {
    mean: vec3f,
    lo: vec3f,
    hi: vec3f,
    some: bool,
}

fn proxy_terms(a: vec4f, b: vec4f) -> ProxyTerms {
    if a.w > 0.0 && b.w > 0.0 {
        return ProxyTerms(0.5 * (a.xyz + b.xyz), min(a.xyz, b.xyz), max(a.xyz, b.xyz), true);
    }
    if a.w > 0.0 {
        return ProxyTerms(a.xyz, a.xyz, a.xyz, true);
    }
    return ProxyTerms(b.xyz, b.xyz, b.xyz, b.w > 0.0);
}

// The neighbours' sum of means over a pixel's window, and how many have samples.
struct ProxySums {
    sum: vec3f,
    count: f32,
}

// The window around traced pixel (x, y) of a `size` image, clipped at its edges: x0, y0
// (inclusive), x1, y1 (exclusive).
fn proxy_window(x: u32, y: u32, size: vec2u) -> vec4u {
    let r = u32(PROXY_RADIUS);
    return vec4u(max(x, r) - r, max(y, r) - r, min(x + r + 1u, size.x), min(y + r + 1u, size.y));
}

// Adds one neighbour's half means `a` and `b` (mean, samples; common/estimate.wgsl's
// includers' `half_mean`), if it has samples.
fn proxy_add(s: ptr<function, ProxySums>, a: vec4f, b: vec4f) {
    let t = proxy_terms(a, b);
    if t.some {
        (*s).sum += t.mean;
        (*s).count += 1.0;
    }
}

// The relative MSE's weight of a pixel with half means `a` and `b` from its neighbours'
// sums, per channel (src/common/estimate.rs, `proxy_weight`).
fn relative_weight(s: ProxySums, a: vec4f, b: vec4f) -> vec3f {
    let t = proxy_terms(a, b);
    var v = t.mean;
    if s.count > 0.0 {
        // What the halves agree on (src/common/estimate.rs, `proxy_weight`).
        let lift = t.lo * clamp(SPIKE * t.lo / max(t.hi, vec3f(1e-30)), vec3f(1.0 / SPIKE), vec3f(1.0));
        v = max(min(s.sum / s.count, t.hi), lift);
    }
    v = max(v, vec3f(0.0));
    return 1.0 / (v * v + REL_MSE_EPSILON);
}

// 1 / (max(a·b, 0) + 0.01) per channel from two independent estimates of a value: the
// weight of the denoiser's choice (the half means) and of a filtered image's estimate (the
// filter's two outputs); src/common/estimate.rs, `product_weight`.
fn product_weight(a: vec3f, b: vec3f) -> vec3f {
    return 1.0 / (max(a * b, vec3f(0.0)) + REL_MSE_EPSILON);
}

// How far a pixel's halves may disagree and still lift the proxy by their smaller mean, and
// the factor of a spike that a filter crushes (src/common/estimate.rs, SPIKE).
const SPIKE: f32 = 2.0;

// The weight of a filtered image's term, from the filter's two outputs da and db and the
// pixel's half means a and b: product_weight of the outputs, unless both halves are more
// than SPIKE times as bright (src/common/estimate.rs, `filtered_weight`, which says why).
fn filtered_weight(da: vec3f, db: vec3f, a: vec3f, b: vec3f) -> vec3f {
    let lo = max(min(a, b), vec3f(0.0)) / SPIKE;
    return min(product_weight(da, db), 1.0 / (lo * lo + REL_MSE_EPSILON));
}
