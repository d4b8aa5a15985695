// #include "common/types.wgsl"
// #include "common/fixed.wgsl"
// The denoiser on the GPU (src/gpu/denoise.rs drives it; src/denoise is the same filter on
// the host, and its comments say why): the halves of the accumulation demodulated by the
// guides' albedo, fireflies clamped, five iterations of the edge-avoiding à-trous filter on
// both halves at once, the estimate of the shown image's error summed per 16×16 tile, and
// the preview's image composed tile by tile from the raw or the denoised image.

const TILE: u32 = 16u;
const ALBEDO_EPSILON: f32 = 0.01;
const ALBEDO_SIGMA: f32 = 0.1;
const LUMINANCE_SIGMA: f32 = 4.0;
const LUMINANCE_EPSILON: f32 = 1e-6;
const OUTLIER_RADIUS: i32 = 2;
const OUTLIER_SIGMAS: f32 = 3.0;
const VARIANCE_RADIUS: i32 = 3;
const REL_MSE_EPSILON: f32 = 0.01;
const GUIDE_WORDS: u32 = 7u;
const LAYER: u32 = 10u;
const DEMOD: u32 = 9u;

// `mode`: the à-trous iteration's step in pixels.
@group(0) @binding(0) var<uniform> params: ResolveUniforms;
@group(0) @binding(1) var<storage, read> accum_even: array<u32>;
@group(0) @binding(2) var<storage, read> accum_odd: array<u32>;
@group(0) @binding(3) var<storage, read> guide_sums: array<u32>;
// Per pixel: (albedo, sky ? 1 : 0), (unit normal or 0, 0).
@group(0) @binding(4) var<storage, read_write> texels: array<vec4f>;
// Per pixel: both halves demodulated (6), the squared difference of their luminances / 2, and
// their luminances (2, for the firefly clamp's neighbours).
@group(0) @binding(5) var<storage, read_write> demod: array<f32>;
// Per pixel, LAYER floats: each half's (r, g, b, luminance, variance); read from `src`,
// written to `dst` (the passes swap them).
@group(0) @binding(6) var<storage, read> src: array<f32>;
@group(0) @binding(7) var<storage, read_write> dst: array<f32>;
// Per pixel: the raw mean (3) and the denoised image ½(D(A) + D(B)) (3).
@group(0) @binding(8) var<storage, read_write> images: array<f32>;
// Per tile, 8 floats: raw (mse, rel, rel²), denoised (mse, rel, rel²), pixels, 0.
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
    let f = load(buf, pixel);
    let n = f32(f.samples);
    if n > 0.0 {
        return vec4f(fixed_value(f) / n, n);
    }
    return vec4f(0.0);
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
    let a = half_mean(0u, p).xyz / m;
    let b = half_mean(1u, p).xyz / m;
    let la = lum(a);
    let lb = lum(b);
    let d = la - lb;
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
}

fn demod_half(p: u32, h: u32) -> vec3f {
    let o = p * DEMOD + 3u * h;
    return vec3f(demod[o], demod[o + 1u], demod[o + 2u]);
}

// A half's colour with a firefly clamped to its 24 neighbours' mean + 3 s.d. of luminance.
fn clamped(x: i32, y: i32, h: u32) -> vec3f {
    let w = i32(params.width);
    let hh = i32(params.height);
    var n = 0.0;
    var s = 0.0;
    var s2 = 0.0;
    for (var qy = max(y - OUTLIER_RADIUS, 0); qy <= min(y + OUTLIER_RADIUS, hh - 1); qy++) {
        for (var qx = max(x - OUTLIER_RADIUS, 0); qx <= min(x + OUTLIER_RADIUS, w - 1); qx++) {
            if qx != x || qy != y {
                let l = demod[u32(qy * w + qx) * DEMOD + 7u + h];
                n += 1.0;
                s += l;
                s2 += l * l;
            }
        }
    }
    let mean = s / max(n, 1.0);
    let sd = sqrt(max(s2 / max(n, 1.0) - mean * mean, 0.0));
    let limit = mean + OUTLIER_SIGMAS * sd;
    let c = demod_half(u32(y * w + x), h);
    let l = demod[u32(y * w + x) * DEMOD + 7u + h];
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
    var n = 0.0;
    for (var qy = max(y - VARIANCE_RADIUS, 0); qy <= min(y + VARIANCE_RADIUS, hh - 1); qy++) {
        for (var qx = max(x - VARIANCE_RADIUS, 0); qx <= min(x + VARIANCE_RADIUS, w - 1); qx++) {
            v += demod[u32(qy * w + qx) * DEMOD + 6u];
            n += 1.0;
        }
    }
    v /= n;
    let p = gid.y * params.width + gid.x;
    let a = clamped(x, y, 0u);
    let b = clamped(x, y, 1u);
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

var<workgroup> partial: array<array<f32, 7>, 256>;

// One workgroup per tile: the images and the tile's estimate sums (src/denoise/mod.rs, "The
// estimator").
@compute @workgroup_size(16, 16, 1)
fn finish(@builtin(global_invocation_id) gid: vec3u, @builtin(local_invocation_index) lid: u32,
          @builtin(workgroup_id) wid: vec3u) {
    var terms = array<f32, 7>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    if gid.x < params.width && gid.y < params.height {
        let p = gid.y * params.width + gid.x;
        let e = half_mean(0u, p);
        let o = half_mean(1u, p);
        let m = modulation(p);
        let fa = vec3f(src[p * LAYER], src[p * LAYER + 1u], src[p * LAYER + 2u]) * m;
        let fb = vec3f(src[p * LAYER + 5u], src[p * LAYER + 6u], src[p * LAYER + 7u]) * m;
        let n = e.w + o.w;
        var raw = vec3f(0.0);
        if n > 0.0 {
            raw = (e.xyz * e.w + o.xyz * o.w) / n;
        }
        let dbar = 0.5 * (fa + fb);
        let i = p * 6u;
        images[i] = raw.x;
        images[i + 1u] = raw.y;
        images[i + 2u] = raw.z;
        images[i + 3u] = dbar.x;
        images[i + 4u] = dbar.y;
        images[i + 5u] = dbar.z;
        if e.w >= 1.0 && o.w >= 1.0 {
            let k = e.w * o.w / (n * n);
            let x = e.xyz;
            let y = o.xyz;
            let scale = 1.0 / (max(x * y, vec3f(0.0)) + REL_MSE_EPSILON);
            let r = (x - y) * (x - y) * k;
            let dd = 0.5 * (fa - y) * (fa - y) + 0.5 * (fb - x) * (fb - x)
                - 0.5 * (x - y) * (x - y) - 0.25 * (fa - fb) * (fa - fb);
            let rr = dot(r * scale, vec3f(1.0));
            let rd = dot(dd * scale, vec3f(1.0));
            terms = array<f32, 7>(r.x + r.y + r.z, rr, rr * rr, dd.x + dd.y + dd.z, rd, rd * rd, 1.0);
        }
    }
    partial[lid] = terms;
    workgroupBarrier();
    for (var s = 128u; s > 0u; s >>= 1u) {
        if lid < s {
            for (var t = 0u; t < 7u; t++) {
                partial[lid][t] += partial[lid + s][t];
            }
        }
        workgroupBarrier();
    }
    if lid == 0u {
        let tiles_x = (params.width + TILE - 1u) / TILE;
        let t = wid.y * tiles_x + wid.x;
        for (var i = 0u; i < 7u; i++) {
            tiles[t * 8u + i] = partial[0][i];
        }
        tiles[t * 8u + 7u] = 0.0;
    }
}

// One invocation per output pixel: the mean of its factor × factor block of the shown
// image (per tile the denoised one where its estimate is below the raw one's).
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
            let denoised = tiles[t * 8u + 4u] < tiles[t * 8u + 1u];
            let i = p * 6u + select(0u, 3u, denoised);
            rgb += vec3f(images[i], images[i + 1u], images[i + 2u]);
        }
    }
    let c = rgb / f32(params.factor * params.factor);
    let i = 3u * (gid.y * params.out_width + gid.x);
    out[i] = c.x;
    out[i + 1u] = c.y;
    out[i + 2u] = c.z;
}
