// #include "common/types.wgsl"
// #include "common/fixed.wgsl"
// #include "common/estimate.wgsl"
// The preview's image, made on the GPU from the accumulation so that only the small image is
// read back (src/gpu/resolve.rs drives it): one invocation per output pixel averages the
// `factor × factor` block of traced pixels below it in linear light (each pixel its sum over
// its weight, the lecture's `accumulated / peso`), and sums the block's terms of the
// two-halves noise estimate (common/estimate.wgsl's terms; src/render/snapshot.rs,
// `error_estimate`, says why they are unbiased). On several devices (src/ui/helpers.rs) the other devices' sums, uploaded into
// `extra_even` and `extra_odd`, are added to each pixel's exactly (`fixed_merge`) when
// `params.mode` is 1.


@group(0) @binding(0) var<uniform> params: ResolveUniforms;
@group(0) @binding(1) var<storage, read> accum_even: array<u32>;
@group(0) @binding(2) var<storage, read> accum_odd: array<u32>;
// Two vec4f per output pixel: (r, g, b, fewest samples in either half of any block pixel)
// and (squared-error sum, relative squared-error sum, the sum of the pixels' relative terms
// squared, 0): the last tells a few fireflies' estimate (src/common/resolved.rs, `Doubt`).
@group(0) @binding(3) var<storage, read_write> out: array<vec4f>;
@group(0) @binding(4) var<storage, read> extra_even: array<u32>;
@group(0) @binding(5) var<storage, read> extra_odd: array<u32>;

fn load(buf: u32, pixel: u32) -> Fixed {
    var w: array<u32, 10>;
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        w[i] = select(accum_odd[pixel * ACCUM_WORDS + i], accum_even[pixel * ACCUM_WORDS + i], buf == 0u);
    }
    let own = fixed_from_words(w);
    if params.mode == 0u {
        return own;
    }
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        w[i] = select(extra_odd[pixel * ACCUM_WORDS + i], extra_even[pixel * ACCUM_WORDS + i], buf == 0u);
    }
    return fixed_merge(own, fixed_from_words(w));
}

// A half's mean (0 without samples) and its sample count (common/estimate.wgsl reads it).
fn half_mean(buf: u32, pixel: u32) -> vec4f {
    return fixed_mean(load(buf, pixel));
}

// The relative MSE's weight of traced pixel (x, y) (common/estimate.wgsl).
fn window_weight(x: u32, y: u32) -> vec3f {
    let win = proxy_window(x, y, vec2u(params.width, params.height));
    var s = ProxySums();
    for (var qy = win.y; qy < win.w; qy++) {
        for (var qx = win.x; qx < win.z; qx++) {
            if qx != x || qy != y {
                let q = qy * params.width + qx;
                proxy_add(&s, half_mean(0u, q), half_mean(1u, q));
            }
        }
    }
    let p = y * params.width + x;
    return relative_weight(s, half_mean(0u, p), half_mean(1u, p));
}

@compute @workgroup_size(8, 8, 1)
fn resolve(@builtin(global_invocation_id) gid: vec3u) {
    if gid.x >= params.out_width || gid.y >= params.out_height {
        return;
    }
    var rgb = vec3f(0.0);
    var fewest = 4294967295.0;
    var mse = 0.0;
    var rel = 0.0;
    var rel2 = 0.0;
    for (var dy = 0u; dy < params.factor; dy++) {
        for (var dx = 0u; dx < params.factor; dx++) {
            let x = gid.x * params.factor + dx;
            let y = gid.y * params.factor + dy;
            let pixel = y * params.width + x;
            let e = load(0u, pixel);
            let o = load(1u, pixel);
            let ne = f32(e.samples);
            let no = f32(o.samples);
            let se = fixed_value(e);
            let so = fixed_value(o);
            if ne + no > 0.0 {
                rgb += (se + so) / (ne + no);
            } else {
                // A row the first look has not reached yet (src/render: `first_look`): show
                // the row above (below, for the first), for display only.
                let near = select(pixel - params.width, pixel + params.width, y == 0u);
                if near < params.width * params.height {
                    let e2 = load(0u, near);
                    let o2 = load(1u, near);
                    let n2 = f32(e2.samples + o2.samples);
                    if n2 > 0.0 {
                        rgb += (fixed_value(e2) + fixed_value(o2)) / n2;
                    }
                }
            }
            fewest = min(fewest, min(ne, no));
            let k = pair_factor(ne, no);
            if k > 0.0 {
                let d = se / ne - so / no;
                let v = d * d * k;
                mse += v.x + v.y + v.z;
                let rv = v * window_weight(x, y);
                let pixel_rel = rv.x + rv.y + rv.z;
                rel += pixel_rel;
                rel2 += pixel_rel * pixel_rel;
            }
        }
    }
    let n = f32(params.factor * params.factor);
    let i = gid.y * params.out_width + gid.x;
    out[2u * i] = vec4f(rgb / n, fewest);
    out[2u * i + 1u] = vec4f(mse, rel, rel2, 0.0);
}
