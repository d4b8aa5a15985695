// #include "common/types.wgsl"
// #include "common/fixed.wgsl"
// #include "common/estimate.wgsl"
// The denoiser on the GPU (src/gpu/denoise.rs drives it; src/denoise is the same filters on
// the host, and its comments say why): the halves of the accumulation demodulated by the
// guides' albedo, fireflies clamped, five iterations of the edge-avoiding à-trous filter on
// both halves at once, then each half's radiance regressed on the guides with weights from
// that filter's output (src/denoise/regress.rs), the estimates of the raw image's and both
// filters' errors summed per 16×16 tile, and the preview's image composed tile by tile from
// whichever is estimated best.

const TILE: u32 = 16u;
const ALBEDO_EPSILON: f32 = 0.01;
const ALBEDO_SIGMA: f32 = 0.1;
const LUMINANCE_SIGMA: f32 = 4.0;
const LUMINANCE_EPSILON: f32 = 1e-6;
const OUTLIER_RADIUS: i32 = 2;
const OUTLIER_SIGMAS: f32 = 3.0;
const VARIANCE_RADIUS: i32 = 3;
const GUIDE_WORDS: u32 = 7u;
const LAYER: u32 = 10u;
const DEMOD: u32 = 12u;
const IMAGES: u32 = 9u;
// src/denoise/mod.rs: TILE_FLOATS.
const TILE_FLOATS: u32 = 10u;
// Terms summed per tile in `finish`: raw, à-trous and regression (mse, rel, rel²) each, the
// pixels; the relative terms of the raw image and both filters over the odd pixels, and
// those pixels; the choice's relative terms of the three (src/common/estimate.rs,
// `product_weight`), over all pixels and over the odd ones. Reduced CHUNK at a time.
const TERMS: u32 = 20u;
const CHUNK: u32 = 10u;
// The regression (src/denoise/regress.rs): window radius, spatial sigma, luminance sigma and
// epsilon, the least weight of a tap, and the ridge.
const REGRESS_RADIUS: i32 = 2;
const REGRESS_SPATIAL_SIGMA: f32 = 1.5;
const REGRESS_LUMINANCE_SIGMA: f32 = 1.0;
const REGRESS_LUMINANCE_EPSILON: f32 = 1e-10;
const REGRESS_MIN_WEIGHT: f32 = 1e-12;
const RIDGE: f32 = 1e-3;

// `mode`: the à-trous iteration's step in pixels.
@group(0) @binding(0) var<uniform> params: ResolveUniforms;
@group(0) @binding(1) var<storage, read> accum_even: array<u32>;
@group(0) @binding(2) var<storage, read> accum_odd: array<u32>;
@group(0) @binding(3) var<storage, read> guide_sums: array<u32>;
// Per pixel: (albedo, sky ? 1 : 0), (unit normal or 0, the variance of one half's radiance
// luminance: a 7×7 mean, for the regression's weights).
@group(0) @binding(4) var<storage, read_write> texels: array<vec4f>;
// Per pixel: both halves demodulated (6), the squared difference of their luminances / 2, and
// their luminances (2, for the firefly clamp's neighbours); then the same three of the
// radiance (not demodulated).
@group(0) @binding(5) var<storage, read_write> demod: array<f32>;
// Per pixel, LAYER floats: each half's (r, g, b, luminance, variance); read from `src`,
// written to `dst` (the passes swap them). After the iterations `src` holds the à-trous
// output, and `regress` writes the regression's (radiance, not demodulated) to `dst`.
@group(0) @binding(6) var<storage, read> src: array<f32>;
@group(0) @binding(7) var<storage, read_write> dst: array<f32>;
// Per pixel: the raw mean (3) and the denoised image ½(D(A) + D(B)) of the à-trous filter (3)
// and of the regression (3). Until `finish`, each half's radiance with its fireflies clamped
// (`settle` writes it, `regress` reads it).
@group(0) @binding(8) var<storage, read_write> images: array<f32>;
// Per tile, TILE_FLOATS floats: raw (mse, rel, rel²), denoised (mse, rel, rel², of the filter
// chosen), pixels, 1 where the regression is chosen (0: the à-trous filter), the shown
// image's relative sum, cross-fitted (`cross_fitted`), and 1 where the denoised image is
// shown.
@group(0) @binding(9) var<storage, read_write> tiles: array<f32>;
// Per output pixel: r, g, b (12 bytes: the preview at 960×608 reads back 7 MB, not the 19
// of resolve.wgsl's two vec4f).
@group(0) @binding(10) var<storage, read_write> out: array<f32>;

fn lum(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

// A branch, not `select`: select would load both halves.
fn load(buf: u32, pixel: u32) -> Fixed {
    var w: array<u32, 10>;
    let o = pixel * ACCUM_WORDS;
    if buf == 0u {
        for (var i = 0u; i < ACCUM_WORDS; i++) {
            w[i] = accum_even[o + i];
        }
    } else {
        for (var i = 0u; i < ACCUM_WORDS; i++) {
            w[i] = accum_odd[o + i];
        }
    }
    return fixed_from_words(w);
}

// A half's mean (0 without samples) and its sample count.
fn half_mean(buf: u32, pixel: u32) -> vec4f {
    return fixed_mean(load(buf, pixel));
}

fn modulation(p: u32) -> vec3f {
    return texels[2u * p].xyz + ALBEDO_EPSILON;
}

@compute @workgroup_size(8, 8, 1)
fn prepare(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let p = gid.y * params.width + gid.x;
    let g = p * GUIDE_WORDS;
    let n = max(f32(guide_sums[g + 6u]), 1.0) * 65535.0;
    let albedo = vec3f(f32(guide_sums[g]), f32(guide_sums[g + 1u]), f32(guide_sums[g + 2u])) / n;
    var normal = vec3f(0.0);
    if guide_sums[g + 6u] > 0u {
        normal = 2.0 * vec3f(f32(guide_sums[g + 3u]), f32(guide_sums[g + 4u]), f32(guide_sums[g + 5u])) / n - 1.0;
    }
    let len = length(normal);
    let sky = len < 0.1;
    texels[2u * p] = vec4f(albedo, select(0.0, 1.0, sky));
    texels[2u * p + 1u] = vec4f(select(normal / len, vec3f(0.0), sky), 0.0);
    let m = albedo + ALBEDO_EPSILON;
    let ra = half_mean(0u, p).xyz;
    let rb = half_mean(1u, p).xyz;
    let a = ra / m;
    let b = rb / m;
    let la = lum(a);
    let lb = lum(b);
    let d = la - lb;
    let lra = lum(ra);
    let lrb = lum(rb);
    let dr = lra - lrb;
    let o = p * DEMOD;
    demod[o] = a.x;
    demod[o + 1u] = a.y;
    demod[o + 2u] = a.z;
    demod[o + 3u] = b.x;
    demod[o + 4u] = b.y;
    demod[o + 5u] = b.z;
    demod[o + 6u] = 0.5 * d * d;
    demod[o + 7u] = la;
    demod[o + 8u] = lb;
    demod[o + 9u] = 0.5 * dr * dr;
    demod[o + 10u] = lra;
    demod[o + 11u] = lrb;
}

fn demod_half(p: u32, h: u32) -> vec3f {
    let o = p * DEMOD + 3u * h;
    return vec3f(demod[o], demod[o + 1u], demod[o + 2u]);
}

// The limits above which a firefly is clamped at (x, y), in one pass over the 24 neighbours:
// for the luminances in `demod` at slots 7, 8 (the demodulated halves), 10 and 11 (the
// radiance's), each its neighbours' mean + 3 s.d.
fn firefly_limits(x: i32, y: i32) -> vec4f {
    let w = i32(params.width);
    let hh = i32(params.height);
    var n = 0.0;
    var s = vec4f(0.0);
    var s2 = vec4f(0.0);
    for (var qy = max(y - OUTLIER_RADIUS, 0); qy <= min(y + OUTLIER_RADIUS, hh - 1); qy++) {
        for (var qx = max(x - OUTLIER_RADIUS, 0); qx <= min(x + OUTLIER_RADIUS, w - 1); qx++) {
            if qx != x || qy != y {
                let o = u32(qy * w + qx) * DEMOD;
                let l = vec4f(demod[o + 7u], demod[o + 8u], demod[o + 10u], demod[o + 11u]);
                n += 1.0;
                s += l;
                s2 += l * l;
            }
        }
    }
    let mean = s / max(n, 1.0);
    let sd = sqrt(max(s2 / max(n, 1.0) - mean * mean, vec4f(0.0)));
    return mean + OUTLIER_SIGMAS * sd;
}

// `c`, whose luminance is `l`, with a firefly clamped to `limit`.
fn clamp_firefly(c: vec3f, l: f32, limit: f32) -> vec3f {
    if l > limit && l > 0.0 {
        return c * (limit / l);
    }
    return c;
}

@compute @workgroup_size(8, 8, 1)
fn settle(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    let w = i32(params.width);
    let hh = i32(params.height);
    var v = 0.0;
    var vr = 0.0;
    var n = 0.0;
    for (var qy = max(y - VARIANCE_RADIUS, 0); qy <= min(y + VARIANCE_RADIUS, hh - 1); qy++) {
        for (var qx = max(x - VARIANCE_RADIUS, 0); qx <= min(x + VARIANCE_RADIUS, w - 1); qx++) {
            let o = u32(qy * w + qx) * DEMOD;
            v += demod[o + 6u];
            vr += demod[o + 9u];
            n += 1.0;
        }
    }
    v /= n;
    let p = gid.y * params.width + gid.x;
    texels[2u * p + 1u].w = vr / n;
    let limits = firefly_limits(x, y);
    let od = p * DEMOD;
    // Each half's radiance, fireflies clamped, for the regression.
    let m = modulation(p);
    let ra = clamp_firefly(demod_half(p, 0u) * m, demod[od + 10u], limits.z);
    let rb = clamp_firefly(demod_half(p, 1u) * m, demod[od + 11u], limits.w);
    let i = p * IMAGES;
    images[i] = ra.x;
    images[i + 1u] = ra.y;
    images[i + 2u] = ra.z;
    images[i + 3u] = rb.x;
    images[i + 4u] = rb.y;
    images[i + 5u] = rb.z;
    let a = clamp_firefly(demod_half(p, 0u), demod[od + 7u], limits.x);
    let b = clamp_firefly(demod_half(p, 1u), demod[od + 8u], limits.y);
    let o = p * LAYER;
    dst[o] = a.x;
    dst[o + 1u] = a.y;
    dst[o + 2u] = a.z;
    dst[o + 3u] = lum(a);
    dst[o + 4u] = v;
    dst[o + 5u] = b.x;
    dst[o + 6u] = b.y;
    dst[o + 7u] = b.z;
    dst[o + 8u] = lum(b);
    dst[o + 9u] = v;
}

// The edge-stopping weight of tap q for pixel p, given p's texels (`tp`: albedo and sky,
// `np`: normal).
fn guide_weight(tp: vec4f, np: vec3f, q: u32) -> f32 {
    let tq = texels[2u * q];
    if tp.w > 0.5 || tq.w > 0.5 {
        return select(0.0, 1.0, tp.w > 0.5 && tq.w > 0.5);
    }
    var c = max(dot(np, texels[2u * q + 1u].xyz), 0.0);
    for (var i = 0; i < 7; i++) {
        c *= c;
    }
    if c < 1e-6 {
        return 0.0;
    }
    let da = tp.xyz - tq.xyz;
    return c * exp(-dot(da, da) / (ALBEDO_SIGMA * ALBEDO_SIGMA));
}

// One half's layer at pixel q: (r, g, b, luminance) and variance.
fn layer_half(q: u32, k: u32) -> vec4f {
    let o = q * LAYER + 5u * k;
    return vec4f(src[o], src[o + 1u], src[o + 2u], src[o + 3u]);
}

fn store_half(p: u32, k: u32, sum_c: vec3f, sum_w: f32, sum_v: f32) {
    let c = sum_c / sum_w;
    let o = p * LAYER + 5u * k;
    dst[o] = c.x;
    dst[o + 1u] = c.y;
    dst[o + 2u] = c.z;
    dst[o + 3u] = lum(c);
    dst[o + 4u] = sum_v / (sum_w * sum_w);
}

// One iteration on both halves at once; the taps' weights are the linear B-spline's 3×3 kernel
// (¼, ½, ¼)², times the guides' and each half's luminance weight. Written without private
// arrays, which a driver may keep in memory rather than in registers.
@compute @workgroup_size(8, 8, 1)
fn atrous(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let step = i32(params.mode);
    let x = i32(gid.x);
    let y = i32(gid.y);
    let w = i32(params.width);
    let p = gid.y * params.width + gid.x;
    let tp = texels[2u * p];
    let np = texels[2u * p + 1u].xyz;
    var ca = vec3f(0.0);
    var cb = vec3f(0.0);
    var wa = 0.0;
    var wb = 0.0;
    var va = 0.0;
    var vb = 0.0;
    let lpa = src[p * LAYER + 3u];
    let lpb = src[p * LAYER + 8u];
    let sa = 1.0 / (LUMINANCE_SIGMA * sqrt(max(src[p * LAYER + 4u], 0.0)) + LUMINANCE_EPSILON);
    let sb = 1.0 / (LUMINANCE_SIGMA * sqrt(max(src[p * LAYER + 9u], 0.0)) + LUMINANCE_EPSILON);
    for (var j = -1; j <= 1; j++) {
        let qy = y + j * step;
        if qy < 0 || qy >= i32(params.height) {
            continue;
        }
        for (var i = -1; i <= 1; i++) {
            let qx = x + i * step;
            if qx < 0 || qx >= w {
                continue;
            }
            let q = u32(qy * w + qx);
            var gw = select(0.25, 0.5, j == 0) * select(0.25, 0.5, i == 0);
            if q != p {
                gw *= guide_weight(tp, np, q);
            }
            if gw == 0.0 {
                continue;
            }
            let a = layer_half(q, 0u);
            let b = layer_half(q, 1u);
            let wta = gw * exp(-abs(lpa - a.w) * sa);
            let wtb = gw * exp(-abs(lpb - b.w) * sb);
            ca += wta * a.xyz;
            cb += wtb * b.xyz;
            wa += wta;
            wb += wtb;
            va += wta * wta * src[q * LAYER + 4u];
            vb += wtb * wtb * src[q * LAYER + 9u];
        }
    }
    store_half(p, 0u, ca, wa, va);
    store_half(p, 1u, cb, wb, vb);
}

// u vᵀ.
fn outer(u: vec3f, v: vec3f) -> mat3x3f {
    return mat3x3f(u * v.x, u * v.y, u * v.z);
}

// The inverse of a 3×3 matrix by its cofactors (as glam's `Mat3::inverse`), and in `ok`
// whether its determinant is positive and finite.
struct Inverse {
    m: mat3x3f,
    ok: bool,
}

fn inverse3(m: mat3x3f) -> Inverse {
    let c0 = cross(m[1], m[2]);
    let c1 = cross(m[2], m[0]);
    let c2 = cross(m[0], m[1]);
    let det = dot(m[2], c2);
    let ok = det > 0.0 && det < 3.0e38;
    return Inverse(transpose(mat3x3f(c0, c1, c2)) * (1.0 / det), ok);
}

// The regression's neighbourhood of one workgroup: its 8×8 pixels and REGRESS_RADIUS around,
// for one half. Per pixel: (albedo, the à-trous output's luminance), (unit normal, radiance
// variance), (radiance fireflies clamped, 1 inside the image or 0).
const APRON: u32 = 12u;
var<workgroup> neighbourhood: array<array<vec4f, 3>, 144>;

// Each half's radiance at every pixel made the intercept of a weighted first-order regression
// of its neighbours' on the guides and the position (src/denoise/regress.rs: the normal
// equations in 3×3 blocks, albedo, normal and (1, y, x), solved by block elimination), the
// weights from that half's à-trous output in `src`; written to `dst` (radiance). One
// invocation per pixel and half (gid.z), its equations in registers; the workgroup first
// loads its neighbourhood into workgroup memory, each pixel once.
@compute @workgroup_size(8, 8, 1)
fn regress(@builtin(global_invocation_id) gid: vec3u, @builtin(local_invocation_index) lid: u32,
           @builtin(workgroup_id) wid: vec3u) {
    let half = gid.z;
    let layer = 5u * half;
    let w = i32(params.width);
    let hh = i32(params.height);
    // The neighbourhood's top-left pixel.
    let x0 = i32(wid.x * 8u) - REGRESS_RADIUS;
    let y0 = i32(wid.y * 8u) - REGRESS_RADIUS;
    for (var k = lid; k < APRON * APRON; k += 64u) {
        let qx = x0 + i32(k % APRON);
        let qy = y0 + i32(k / APRON);
        var cell = array<vec4f, 3>(vec4f(0.0), vec4f(0.0), vec4f(0.0));
        if qx >= 0 && qx < w && qy >= 0 && qy < hh {
            let q = u32(qy * w + qx);
            let tq = texels[2u * q];
            let mq = tq.xyz + ALBEDO_EPSILON;
            let lq = lum(vec3f(src[q * LAYER + layer], src[q * LAYER + layer + 1u],
                src[q * LAYER + layer + 2u]) * mq);
            let i = q * IMAGES + 3u * half;
            cell[0] = vec4f(tq.xyz, lq);
            cell[1] = texels[2u * q + 1u];
            cell[2] = vec4f(images[i], images[i + 1u], images[i + 2u], 1.0);
        }
        neighbourhood[k] = cell;
    }
    workgroupBarrier();
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let p = gid.y * params.width + gid.x;
    // This pixel in the neighbourhood.
    let c = (gid.y - wid.y * 8u + u32(REGRESS_RADIUS)) * APRON
        + gid.x - wid.x * 8u + u32(REGRESS_RADIUS);
    let tp = neighbourhood[c][0];
    let np = neighbourhood[c][1];
    let lp = tp.w;
    let f = vec3f(src[p * LAYER + layer], src[p * LAYER + layer + 1u], src[p * LAYER + layer + 2u])
        * modulation(p);
    var a = mat3x3f();
    var b = mat3x3f();
    var cc = mat3x3f();
    var d = mat3x3f();
    var e = mat3x3f();
    var g = mat3x3f();
    var ya = mat3x3f();
    var yn = mat3x3f();
    var yp = mat3x3f();
    let r = f32(REGRESS_RADIUS);
    for (var dy = -REGRESS_RADIUS; dy <= REGRESS_RADIUS; dy++) {
        for (var dx = -REGRESS_RADIUS; dx <= REGRESS_RADIUS; dx++) {
            let k = u32(i32(c) + dy * i32(APRON) + dx);
            let cell = neighbourhood[k];
            if cell[2].w == 0.0 {
                continue;
            }
            let nq = cell[1];
            let spatial = exp(-f32(dy * dy + dx * dx)
                / (2.0 * REGRESS_SPATIAL_SIGMA * REGRESS_SPATIAL_SIGMA));
            let scale = 1.0 / (REGRESS_LUMINANCE_SIGMA * REGRESS_LUMINANCE_SIGMA * (np.w + nq.w)
                + REGRESS_LUMINANCE_EPSILON);
            let dl = lp - cell[0].w;
            let wt = spatial * exp(-dl * dl * scale);
            if wt <= REGRESS_MIN_WEIGHT {
                continue;
            }
            let ta = cell[0].xyz - tp.xyz;
            let tn = nq.xyz - np.xyz;
            let tl = vec3f(1.0, f32(dy) / r, f32(dx) / r);
            let rad = cell[2].xyz;
            let wa = ta * wt;
            let wn = tn * wt;
            let wl = tl * wt;
            a += outer(wa, ta);
            b += outer(wa, tn);
            cc += outer(wa, tl);
            d += outer(wn, tn);
            e += outer(wn, tl);
            g += outer(wl, tl);
            ya += outer(wa, rad);
            yn += outer(wn, rad);
            yp += outer(wl, rad);
        }
    }
    // Block elimination of the albedo's terms, then the normal's (regress.rs's `intercept`).
    let ridge = RIDGE * g[0][0];
    let ai = inverse3(a + mat3x3f(ridge, 0.0, 0.0, 0.0, ridge, 0.0, 0.0, 0.0, ridge));
    let bt_ai = transpose(b) * ai.m;
    let ct_ai = transpose(cc) * ai.m;
    let d2 = d + mat3x3f(ridge, 0.0, 0.0, 0.0, ridge, 0.0, 0.0, 0.0, ridge) - bt_ai * b;
    let e2 = e - bt_ai * cc;
    let g2 = g + mat3x3f(0.0, 0.0, 0.0, 0.0, ridge, 0.0, 0.0, 0.0, ridge) - ct_ai * cc;
    let yn2 = yn - bt_ai * ya;
    let yp2 = yp - ct_ai * ya;
    let di = inverse3(d2);
    let et_di = transpose(e2) * di.m;
    let gi = inverse3(g2 - et_di * e2);
    let sol = gi.m * (yp2 - et_di * yn2);
    let v = vec3f(sol[0].x, sol[1].x, sol[2].x);
    let finite = all(abs(v) < vec3f(3.0e38));
    // Where a block is singular or the result not finite, the à-trous output stays.
    let out = select(f, v, ai.ok && di.ok && gi.ok && finite);
    let o = p * LAYER + layer;
    dst[o] = out.x;
    dst[o + 1u] = out.y;
    dst[o + 2u] = out.z;
}

// One workgroup's scratch, used twice by `finish`: first the tile's window of half means (its
// 16×16 pixels and a border of PROXY_RADIUS: WINDOW × WINDOW pixels, both halves, a vec4f
// each: 2592 floats), for the reference² proxy; then CHUNK of the TERMS sums of its 256
// pixels at a time, reduced (2560).
const WINDOW: u32 = TILE + 2u * u32(PROXY_RADIUS);
var<workgroup> scratch: array<f32, 2592>;

// Sets window pixel `k` (row-major, WINDOW a row) of half `h` to `v`.
fn set_window(k: u32, h: u32, v: vec4f) {
    let o = (2u * k + h) * 4u;
    scratch[o] = v.x;
    scratch[o + 1u] = v.y;
    scratch[o + 2u] = v.z;
    scratch[o + 3u] = v.w;
}

fn window(k: u32, h: u32) -> vec4f {
    let o = (2u * k + h) * 4u;
    return vec4f(scratch[o], scratch[o + 1u], scratch[o + 2u], scratch[o + 3u]);
}

// The candidate a set of pixels chooses from its relative sums (raw, à-trous, regression):
// src/denoise/mod.rs, `choose`. 0 raw, 1 à-trous, 2 regression.
fn choose(rel: vec3f) -> u32 {
    let f = select(1u, 2u, rel.z <= rel.y);
    return select(0u, f, rel[f] < rel.x);
}

// The shown tile's relative sum, cross-fitted: src/denoise/mod.rs, `cross_fitted`, says why.
fn cross_fitted(all: vec3f, odd: vec3f, choice_all: vec3f, choice_odd: vec3f, pixels: f32,
                odd_pixels: f32) -> f32 {
    let even = all - odd;
    let even_pixels = pixels - odd_pixels;
    let shown = choose(choice_all);
    let by_even = choose(choice_all - choice_odd);
    let by_odd = choose(choice_odd);
    if by_even == shown && by_odd != shown && odd_pixels > 0.0 {
        return odd[shown] * pixels / odd_pixels;
    }
    if by_odd == shown && by_even != shown && even_pixels > 0.0 {
        return even[shown] * pixels / even_pixels;
    }
    return all[shown];
}

// The estimate's terms of one denoised image at a pixel (src/denoise/mod.rs, "The
// estimator"): its squared error summed over channels, and the relative one.
fn estimate_terms(fa: vec3f, fb: vec3f, x: vec3f, y: vec3f, scale: vec3f) -> vec2f {
    let dd = 0.5 * (fa - y) * (fa - y) + 0.5 * (fb - x) * (fb - x)
        - 0.5 * (x - y) * (x - y) - 0.25 * (fa - fb) * (fa - fb);
    return vec2f(dd.x + dd.y + dd.z, dot(dd * scale, vec3f(1.0)));
}

// One workgroup per tile: the images and the tile's estimate sums of the raw image and of
// both filters' (the à-trous output in `src`, the regression's in `dst`); the tile keeps the
// filter estimated better (the regression on a tie, as the host's).
@compute @workgroup_size(16, 16, 1)
fn finish(@builtin(global_invocation_id) gid: vec3u, @builtin(local_invocation_index) lid: u32,
          @builtin(workgroup_id) wid: vec3u) {
    // The tile's window of half means, read once for its 256 pixels' 3×3 proxies: outside
    // the image a pixel has no samples, and counts for nothing (the host clips the window).
    let r = u32(PROXY_RADIUS);
    for (var k = lid; k < WINDOW * WINDOW; k += 256u) {
        let x = i32(wid.x * TILE + k % WINDOW) - PROXY_RADIUS;
        let y = i32(wid.y * TILE + k / WINDOW) - PROXY_RADIUS;
        var a = vec4f(0.0);
        var b = vec4f(0.0);
        if x >= 0 && y >= 0 && x < i32(params.width) && y < i32(params.height) {
            let q = u32(y) * params.width + u32(x);
            a = half_mean(0u, q);
            b = half_mean(1u, q);
        }
        set_window(k, 0u, a);
        set_window(k, 1u, b);
    }
    workgroupBarrier();
    let lx = lid % TILE;
    let ly = lid / TILE;
    var proxy = ProxySums();
    for (var dy = 0u; dy <= 2u * r; dy++) {
        for (var dx = 0u; dx <= 2u * r; dx++) {
            let k = (ly + dy) * WINDOW + lx + dx;
            if dx != r || dy != r {
                proxy_add(&proxy, window(k, 0u), window(k, 1u));
            }
        }
    }
    let centre = (ly + r) * WINDOW + lx + r;
    let e = window(centre, 0u);
    let o = window(centre, 1u);
    workgroupBarrier();
    var terms: array<f32, TERMS>;
    if gid.x < params.width && gid.y < params.height {
        let p = gid.y * params.width + gid.x;
        let m = modulation(p);
        let fa = vec3f(src[p * LAYER], src[p * LAYER + 1u], src[p * LAYER + 2u]) * m;
        let fb = vec3f(src[p * LAYER + 5u], src[p * LAYER + 6u], src[p * LAYER + 7u]) * m;
        let ga = vec3f(dst[p * LAYER], dst[p * LAYER + 1u], dst[p * LAYER + 2u]);
        let gb = vec3f(dst[p * LAYER + 5u], dst[p * LAYER + 6u], dst[p * LAYER + 7u]);
        let n = e.w + o.w;
        var raw = vec3f(0.0);
        if n > 0.0 {
            raw = (e.xyz * e.w + o.xyz * o.w) / n;
        }
        let da = 0.5 * (fa + fb);
        let dg = 0.5 * (ga + gb);
        let i = p * IMAGES;
        images[i] = raw.x;
        images[i + 1u] = raw.y;
        images[i + 2u] = raw.z;
        images[i + 3u] = da.x;
        images[i + 4u] = da.y;
        images[i + 5u] = da.z;
        images[i + 6u] = dg.x;
        images[i + 7u] = dg.y;
        images[i + 8u] = dg.z;
        let k = pair_factor(e.w, o.w);
        if k > 0.0 {
            let x = e.xyz;
            let y = o.xyz;
            let scale = relative_weight(proxy, e, o);
            let r = (x - y) * (x - y) * k;
            let rr = dot(r * scale, vec3f(1.0));
            let ta = estimate_terms(fa, fb, x, y, filtered_weight(fa, fb, x, y));
            let tg = estimate_terms(ga, gb, x, y, filtered_weight(ga, gb, x, y));
            let odd = select(0.0, 1.0, ((gid.x + gid.y) & 1u) == 1u);
            // The choice's sums (src/common/estimate.rs, `product_weight`).
            let cw = product_weight(x, y);
            let cr = dot(r * cw, vec3f(1.0));
            let ca = estimate_terms(fa, fb, x, y, cw).y;
            let cg = estimate_terms(ga, gb, x, y, cw).y;
            terms = array<f32, TERMS>(r.x + r.y + r.z, rr, rr * rr, ta.x, ta.y, ta.y * ta.y,
                                      tg.x, tg.y, tg.y * tg.y, 1.0, rr * odd, ta.y * odd,
                                      tg.y * odd, odd, cr, ca, cg, cr * odd, ca * odd,
                                      cg * odd);
        }
    }
    // The tile's sums, CHUNK terms at a time through the scratch.
    var total: array<f32, TERMS>;
    for (var c = 0u; c < TERMS; c += CHUNK) {
        for (var t = 0u; t < CHUNK; t++) {
            scratch[lid * CHUNK + t] = terms[c + t];
        }
        workgroupBarrier();
        for (var s = 128u; s > 0u; s >>= 1u) {
            if lid < s {
                for (var t = 0u; t < CHUNK; t++) {
                    scratch[lid * CHUNK + t] += scratch[(lid + s) * CHUNK + t];
                }
            }
            workgroupBarrier();
        }
        for (var t = 0u; t < CHUNK; t++) {
            total[c + t] = scratch[t];
        }
        workgroupBarrier();
    }
    if lid == 0u {
        let tiles_x = (params.width + TILE - 1u) / TILE;
        let t = wid.y * tiles_x + wid.x;
        let choice_all = vec3f(total[14], total[15], total[16]);
        let choice_odd = vec3f(total[17], total[18], total[19]);
        let regression = total[16] <= total[15];
        let f = select(3u, 6u, regression);
        let o = t * TILE_FLOATS;
        tiles[o] = total[0];
        tiles[o + 1u] = total[1];
        tiles[o + 2u] = total[2];
        tiles[o + 3u] = total[f];
        tiles[o + 4u] = total[f + 1u];
        tiles[o + 5u] = total[f + 2u];
        tiles[o + 6u] = total[9];
        tiles[o + 7u] = select(0.0, 1.0, regression);
        let all = vec3f(total[1], total[4], total[7]);
        let odd = vec3f(total[10], total[11], total[12]);
        tiles[o + 8u] = cross_fitted(all, odd, choice_all, choice_odd, total[9], total[13]);
        tiles[o + 9u] = select(0.0, 1.0, choose(choice_all) != 0u);
    }
}

// One invocation per output pixel: the mean of its factor × factor block of the shown
// image (per tile the denoised one, of the filter chosen there, where `finish` chose it).
@compute @workgroup_size(8, 8, 1)
fn compose(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.out_width || gid.y >= params.out_height {
        return;
    }
    let tiles_x = (params.width + TILE - 1u) / TILE;
    var rgb = vec3f(0.0);
    for (var dy = 0u; dy < params.factor; dy++) {
        for (var dx = 0u; dx < params.factor; dx++) {
            let x = gid.x * params.factor + dx;
            let y = gid.y * params.factor + dy;
            let p = y * params.width + x;
            let t = (y / TILE) * tiles_x + x / TILE;
            let denoised = tiles[t * TILE_FLOATS + 9u] > 0.5;
            let chosen = select(3u, 6u, tiles[t * TILE_FLOATS + 7u] > 0.5);
            let i = p * IMAGES + select(0u, chosen, denoised);
            rgb += vec3f(images[i], images[i + 1u], images[i + 2u]);
        }
    }
    let c = rgb / f32(params.factor * params.factor);
    let i = 3u * (gid.y * params.out_width + gid.x);
    out[i] = c.x;
    out[i + 1u] = c.y;
    out[i + 2u] = c.z;
}
