// The two-halves error estimate's per-pixel terms (src/common/estimate.rs, whose comments
// say why): the factor that makes a pixel's (A − B)² the variance of its pooled mean, and the
// weight of its squared error in pbrt's relative MSE, 1 / (reference² proxy + 0.01), the
// proxy being the smaller of the halves' 3×3 means times their pooled 3×3 mean. Included by resolve.wgsl and
// denoise.wgsl, each of which defines `half_mean(half, pixel) -> vec4f` (the half's mean, 0
// without samples, and its sample count) and `params` (a ResolveUniforms: the traced size).

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

// The relative MSE's weight of traced pixel (x, y), per channel.
fn relative_weight(x: u32, y: u32) -> vec3f {
    var sa = vec3f(0.0);
    var sb = vec3f(0.0);
    var ca = 0.0;
    var cb = 0.0;
    for (var dy = -PROXY_RADIUS; dy <= PROXY_RADIUS; dy++) {
        for (var dx = -PROXY_RADIUS; dx <= PROXY_RADIUS; dx++) {
            let qx = i32(x) + dx;
            let qy = i32(y) + dy;
            if qx < 0 || qy < 0 || qx >= i32(params.width) || qy >= i32(params.height) {
                continue;
            }
            let q = u32(qy) * params.width + u32(qx);
            let a = half_mean(0u, q);
            let b = half_mean(1u, q);
            if a.w > 0.0 {
                sa += a.xyz;
                ca += 1.0;
            }
            if b.w > 0.0 {
                sb += b.xyz;
                cb += 1.0;
            }
        }
    }
    let a = sa / max(ca, 1.0);
    let b = sb / max(cb, 1.0);
    let square = max(min(a, b), vec3f(0.0)) * max(0.5 * (a + b), vec3f(0.0));
    return 1.0 / (square + REL_MSE_EPSILON);
}
