// #include "common/types.wgsl"
// #include "common/fixed.wgsl"
// Adds the per-lane sums that `trace` left in `scratch` into the accumulation, one invocation
// per pixel of the submission's rows (src/gpu/reduce.rs drives it). The sums are fixed point,
// so the result does not depend on how the samples were spread over lanes.

@group(0) @binding(0) var<uniform> scene: SceneUniforms;
@group(0) @binding(1) var<uniform> batch: DispatchUniforms;
@group(0) @binding(2) var<storage, read_write> accum_even: array<u32>;
@group(0) @binding(3) var<storage, read_write> accum_odd: array<u32>;
@group(0) @binding(4) var<storage, read> scratch: array<u32>;

fn load_words(buf: u32, base: u32) -> Fixed {
    var w: array<u32, 10>;
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        switch buf {
            case 0u: { w[i] = accum_even[base + i]; }
            case 1u: { w[i] = accum_odd[base + i]; }
            default: { w[i] = scratch[base + i]; }
        }
    }
    return fixed_from_words(w);
}

@compute @workgroup_size(64, 1, 1)
fn reduce(@builtin(global_invocation_id) gid: vec3u) {
    let row_pixels = batch.row_count * scene.width;
    if gid.x >= row_pixels {
        return;
    }
    let row = batch.row_offset + (gid.x / scene.width) * batch.row_stride;
    let pixel = row * scene.width + gid.x % scene.width;
    var even = fixed_zero();
    var odd = even;
    if batch.accumulate != 0u {
        even = load_words(0u, pixel * ACCUM_WORDS);
        odd = load_words(1u, pixel * ACCUM_WORDS);
    }
    for (var lane = 0u; lane < batch.lanes; lane++) {
        let b = (lane * row_pixels + gid.x) * 2u * ACCUM_WORDS;
        even = fixed_merge(even, load_words(2u, b));
        odd = fixed_merge(odd, load_words(2u, b + ACCUM_WORDS));
    }
    let e = fixed_to_words(even);
    let o = fixed_to_words(odd);
    for (var i = 0u; i < ACCUM_WORDS; i++) {
        accum_even[pixel * ACCUM_WORDS + i] = e[i];
        accum_odd[pixel * ACCUM_WORDS + i] = o[i];
    }
}
