// #include "common/types.wgsl"
// #include "common/sampling.wgsl"
// Twin: src/cpu/material.rs (tests/twins.rs keeps their functions paired).
// Scattering by the material rules of MODEL.md ("Materials", steps 2 and 3).

struct Scatter {
    dir: vec3f,
    attenuation: vec3f,
    absorbed: bool,   // the path ends here (a bounce below the surface)
}

// Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", 1994.
// (1 - cos)^5 by multiplication: pow() is exp2(5·log2(x)) on GPUs, 1e-5 off near x = 0.
fn schlick(cosine: f32, ratio: f32) -> f32 {
    var r0 = (1.0 - ratio) / (1.0 + ratio);
    r0 = r0 * r0;
    let x = 1.0 - cosine;
    let x2 = x * x;
    return r0 + (1.0 - r0) * (x2 * x2 * x);
}

// Snell's law in the lecture's form: with `n` facing the incoming unit direction `d`,
// r_perp = ratio·(d + cos·n), r_par = -sqrt(|1 - |r_perp|²|)·n.
fn refract_dir(d: vec3f, n: vec3f, cos_theta: f32, ratio: f32) -> vec3f {
    let r_perp = ratio * (d + cos_theta * n);
    let r_par = -sqrt(abs(1.0 - dot(r_perp, r_perp))) * n;
    return r_perp + r_par;
}

// A dielectric: reflect by total internal reflection or with Schlick's probability, else
// refract by Snell's law (r_perp, r_par as in the lecture). An index-matched interface
// (ratio exactly 1) has no reflectance, so the ray goes straight on: Schlick's formula would
// still give (1 - cos)^5 there, an artefact of the approximation (docs/MODEL-NOTES.md).
fn scatter_dielectric(m: Material, d: vec3f, n_out: vec3f, state: ptr<function, Rng>) -> Scatter {
    let front = dot(d, n_out) < 0.0;
    let n = select(-n_out, n_out, front);
    let ratio = select(m.ior, 1.0 / m.ior, front);
    let cos_theta = min(dot(-d, n), 1.0);
    let sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    var dir = d;
    if ratio != 1.0 {
        let u = rand(state);
        if ratio * sin_theta > 1.0 || schlick(cos_theta, ratio) > u {
            dir = normalize(reflect(d, n));
        } else {
            dir = normalize(refract_dir(d, n, cos_theta, ratio));
        }
    }
    if m.absorption > 0.0 {
        dir = normalize_or(dir + m.absorption * random_unit_vector(state), dir);
    }
    return Scatter(dir, m.color, false);
}

// Lambertian, smoothness blend, fuzz and the specular-probability lobe of the lecture; the
// lobe is chosen by the caller (`is_spec`: rand() < specular) so that light sampling can
// happen between the choice and the bounce. `n`: the (shading) normal on the side d comes from.
fn scatter_surface(m: Material, d: vec3f, n: vec3f, is_spec: bool, state: ptr<function, Rng>) -> Scatter {
    let diffuse = normalize_or(n + random_unit_vector(state), n);
    var dir = diffuse;
    var tint = m.color;
    if is_spec {
        var mirror = reflect(d, n);
        if m.absorption > 0.0 {
            mirror = normalize_or(mirror + m.absorption * random_unit_vector(state), n);
        }
        dir = normalize_or(mix(diffuse, mirror, m.smoothness), n);
        tint = m.specular_color;
    }
    return Scatter(dir, tint, dot(dir, n) <= 0.0);
}

// How far below 0 gloss_pdf's discriminant may round for a direction the lobe draws.
const DISC_ROUNDING: f32 = 1e-6;

// The density, in solid angle, with which the lecture's glossy lobe (scatter_surface's
// specular lobe at smoothness s in (0, 1), without fuzz) draws w, about the shading normal n
// with the mirror direction r: the sum over the points of the sphere of radius 1 − s about
// s·r on w's ray (the roots λ of λ² − 2λ s (w·r) + s² − (1 − s)² = 0) whose normal d lies
// above the surface, of (d·n) λ² / (π (1 − s) √disc) (src/cpu/material.rs: gloss_pdf, which
// derives it).
fn gloss_pdf(w: vec3f, n: vec3f, r: vec3f, s: f32) -> f32 {
    let t = 1.0 - s;
    let c = dot(w, r);
    // 1 − c² as |w × r|², which keeps its digits where w is near r.
    let wr = cross(w, r);
    let disc = t * t - s * s * dot(wr, wr);
    // At the cone's edge a drawn direction's disc may round to just below 0: it keeps a
    // large density.
    if !(disc > -DISC_ROUNDING) {
        return 0.0;
    }
    let q = sqrt(max(disc, DISC_ROUNDING * DISC_ROUNDING));
    var sum = 0.0;
    for (var k = 0; k < 2; k++) {
        let lambda = s * c + select(-q, q, k == 0);
        if lambda > 0.0 {
            let cos_d = dot(lambda * w - s * r, n) / t;
            if cos_d > 0.0 {
                sum += cos_d * lambda * lambda;
            }
        }
    }
    return sum / (PI * t * q);
}
