// #include "common/sampling.wgsl"
// Twin: src/cpu/mirror.rs (tests/twins.rs keeps their functions paired).
// The map's light as a perfect mirror sphere reflects it onto a point (next-event estimation
// through a mirror ball, docs/MODEL-NOTES.md "The map in a mirror ball"): where on the sphere
// a point sees a direction's light reflected (the specular vertex of manifold next-event
// estimation, Hanika, Droske & Fascione, EGSR 2015, found on a sphere by safeguarded Newton
// steps on one angle), and how much the sphere spreads it (the reflected ray tube's, from
// Coddington's focal lengths of a convex mirror). The arithmetic is src/cpu/mirror.rs's.

// The most Newton steps of mirror_point; it stops at a step under 1e-6 radians.
const MIRROR_STEPS: u32 = 8u;

struct MirrorReflection {
    // Unit direction from the point to the reflection point, and its distance.
    dir: vec3f,
    dist: f32,
    // The sphere's outward normal there, and the cosine of the angle of incidence.
    normal: vec3f,
    cos_i: f32,
    // False where there is no reflection point.
    ok: bool,
}

// (sin x, cos x) for |x| ≤ π/2 by their Taylor polynomials to x⁹ and x⁸.
fn mirror_turn(x: f32) -> vec2f {
    let x2 = x * x;
    let s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0))));
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)));
    return vec2f(s, c);
}

// The point of the mirror sphere (centre c, radius r > 0) at which p sees light arriving from
// direction w (unit, towards the light) reflected: the root of h(φ) = sin(α − φ) − D sin φ / L
// in the plane of e1 (centre to p) and w (src/cpu/mirror.rs: point, which derives it).
fn mirror_point(p: vec3f, c: vec3f, r: f32, w: vec3f) -> MirrorReflection {
    var out = MirrorReflection(vec3f(0.0), 0.0, vec3f(0.0), 0.0, false);
    let pc = p - c;
    let d = length(pc);
    if !(d > r * 1.0001) {
        return out;
    }
    let e1 = pc / d;
    let ca = clamp(dot(w, e1), -1.0, 1.0);
    let perp = w - ca * e1;
    let sa = length(perp);
    var e2 = basis(e1)[0];
    if sa > 1e-7 {
        e2 = perp / sa;
    }
    let alpha = atan2(sa, ca);
    let phi_max = acos(r / d);
    let half_pi = 0.5 * PI;
    if !(alpha < phi_max + half_pi) {
        return out;
    }
    var lo = max(alpha - half_pi, 0.0);
    var hi = min(alpha, phi_max);
    var phi = clamp(0.5 * alpha, lo, hi);
    var sn = sin(phi);
    var cs = cos(phi);
    for (var i = 0u; i < MIRROR_STEPS; i++) {
        let l2 = d * d - 2.0 * d * r * cs + r * r;
        let l = sqrt(l2);
        let h = (sa * cs - ca * sn) - d * sn / l;
        let slope = -(ca * cs + sa * sn) - d * (d * cs - r) * (d - r * cs) / (l2 * l);
        if h < 0.0 {
            hi = phi;
        } else {
            lo = phi;
        }
        let next = phi - h / slope;
        let to = select(0.5 * (lo + hi), next, next >= lo && next <= hi);
        let step = to - phi;
        let t = mirror_turn(step);
        let s2 = sn * t.y + cs * t.x;
        let c2 = cs * t.y - sn * t.x;
        let norm = inverseSqrt(s2 * s2 + c2 * c2);
        sn = s2 * norm;
        cs = c2 * norm;
        phi = to;
        if abs(step) < 1e-6 {
            break;
        }
    }
    let normal = cs * e1 + sn * e2;
    let to = c + r * normal - p;
    let dist = length(to);
    let dir = to / dist;
    let cos_i = dot(normal, w);
    out = MirrorReflection(dir, dist, normal, cos_i, cos_i > 0.0 && dot(normal, dir) < 0.0 && dist > 0.0);
    return out;
}

// The solid angle a point at distance dist from a mirror sphere of radius r sees a distant
// source's reflection subtend, per unit solid angle of the source, at incidence cos_i.
fn mirror_spread(r: f32, dist: f32, cos_i: f32) -> f32 {
    return (0.25 * r * r * cos_i) / ((dist + 0.5 * r * cos_i) * (dist * cos_i + 0.5 * r));
}
