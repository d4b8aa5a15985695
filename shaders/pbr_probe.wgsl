// #include "common/types.wgsl"
// #include "common/rng.wgsl"
// #include "common/sampling.wgsl"
// #include "common/pbr.wgsl"
// The pbr model's sampler (common/pbr.wgsl) run on a lobe from the host: invocation i draws
// once from the random stream of (pixel 5, sample i, the input's seed), as the tracer would,
// so that the test of the WGSL sampler (tests/pbr.rs) bins what it draws against the density
// it reports (src/stability/probe.rs runs it).

struct PbrProbeInput {
    material: Material, //   0
    wo: vec3f,          //  96  unit, the direction toward the viewer
    seed: u32,          // 108
    n: vec3f,           // 112  unit shading normal
    front: u32,         // 124  1: wo on the outer side (a volume's boundary is entered)
}                       // 128

struct PbrProbeOutput {
    dir: vec3f,         //   0
    pdf: f32,           //  12
    weight: vec3f,      //  16
    ok: u32,            //  28
}                       //  32

@group(0) @binding(0) var<storage, read> inputs: array<PbrProbeInput>;
@group(0) @binding(1) var<storage, read_write> outputs: array<PbrProbeOutput>;

@compute @workgroup_size(64, 1, 1)
fn pbr_probe(@builtin(global_invocation_id) gid: vec3u) {
    let i = gid.x;
    if i >= arrayLength(&outputs) {
        return;
    }
    let p = inputs[0];
    var rng = rng_init(5u, i, p.seed);
    let s = pbr_sample(pbr_lobe(p.material, p.wo, p.n, p.front != 0u), &rng);
    outputs[i] = PbrProbeOutput(s.dir, s.pdf, s.weight, u32(s.ok));
}
