// Random numbers: one independent stream per (pixel, sample, seed), so a render is the same
// whatever the batching. PCG hash and pcg3d from Jarzynski & Olano, "Hash Functions for GPU
// Rendering", JCGT 9(3), 2020; steps are PCG-RXS-M-XS 32 (O'Neill 2014).

fn pcg3d(v_in: vec3u) -> vec3u {
    var v = v_in * 1664525u + 1013904223u;
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v ^= v >> vec3u(16u);
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    return v;
}

fn rng_init(pixel: u32, sample: u32, seed: u32) -> u32 {
    let h = pcg3d(vec3u(pixel, sample, seed));
    return h.x ^ h.y ^ h.z;
}

// Next uniform float in [0, 1): 24 random bits.
fn rand(state: ptr<function, u32>) -> f32 {
    let s = *state * 747796405u + 2891336453u;
    *state = s;
    let word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    let x = (word >> 22u) ^ word;
    return f32(x >> 8u) * (1.0 / 16777216.0);
}
