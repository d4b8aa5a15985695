// #include "common/rng.wgsl"
// Twin: src/cpu/sampling.rs (tests/twins.rs keeps their functions paired).
// Directions and points drawn from the random streams.

const PI: f32 = 3.14159265358979;

// Uniform on the unit sphere (Archimedes: z uniform in [-1, 1], azimuth uniform).
fn random_unit_vector(state: ptr<function, Rng>) -> vec3f {
    let u = rand2(state);
    let z = 1.0 - 2.0 * u.x;
    let phi = 2.0 * PI * u.y;
    let r = sqrt(max(0.0, 1.0 - z * z));
    return vec3f(r * cos(phi), r * sin(phi), z);
}

// Uniform in the unit disk (polar mapping, r = sqrt(u)).
fn random_in_disk(state: ptr<function, Rng>) -> vec2f {
    let u = rand2(state);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    return vec2f(r * cos(phi), r * sin(phi));
}

// normalize(v), or `fallback` when v is too short to have a direction.
fn normalize_or(v: vec3f, fallback: vec3f) -> vec3f {
    let l2 = dot(v, v);
    if l2 < 1e-12 {
        return fallback;
    }
    return v * inverseSqrt(l2);
}

// An orthonormal basis around a unit vector (Duff et al., "Building an Orthonormal Basis,
// Revisited", JCGT 6(1), 2017).
fn basis(n: vec3f) -> mat3x3f {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat3x3f(vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3f(b, s + n.y * n.y * a, -n.y), n);
}
