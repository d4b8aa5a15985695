// #include "common/types.wgsl"
// Ray/primitive intersection and self-intersection avoidance.

struct Ray {
    origin: vec3f,
    dir: vec3f,   // unit length
}

const NO_HIT: f32 = -1.0;

// Ray/sphere in the numerically careful form of Haines, Günther & Akenine-Möller,
// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7: the
// quadratic is solved with q = -(b + sign(b)·sqrt(disc)), roots c/q and q, so no root
// suffers cancellation. Beyond the chapter, every term is taken relative to the sphere's
// anchor A (a surface point near the view) with outward normal N there, centre C = A - r·N:
//   f = o - C = g + r·N with g = o - A,
//   b = f·d = g·d + r·(N·d),
//   c = |f|² - r² = g·g + 2r·(g·N)        (no cancellation of two r²-sized terms),
// which keeps a ground sphere of radius 1e6 exact to float precision near the anchor, where
// the plain form loses everything below 1e6·2^-24 ≈ 0.06. Returns the nearest t in
// (0, t_max), or NO_HIT.
fn hit_sphere(s: Sphere, ray: Ray, t_max: f32) -> f32 {
    let r = abs(s.radius);
    let g = ray.origin - s.anchor;
    let b = dot(g, ray.dir) + r * dot(s.anchor_normal, ray.dir);
    let c = dot(g, g) + 2.0 * r * dot(g, s.anchor_normal);
    let disc = b * b - c;
    if disc < 0.0 {
        return NO_HIT;
    }
    let sq = sqrt(disc);
    let q = -b - select(sq, -sq, b < 0.0);
    if q == 0.0 {
        return NO_HIT;
    }
    let t0 = c / q;
    let t1 = q;
    let t_near = min(t0, t1);
    let t_far = max(t0, t1);
    if t_near > 0.0 && t_near < t_max {
        return t_near;
    }
    if t_far > 0.0 && t_far < t_max {
        return t_far;
    }
    return NO_HIT;
}

// Geometric normal of a sphere at ray.origin + t·ray.dir, relative to the anchor as above;
// flipped inward for a negative radius.
fn sphere_normal(s: Sphere, ray: Ray, t: f32) -> vec3f {
    let r = abs(s.radius);
    let n = normalize((ray.origin - s.anchor + t * ray.dir) / r + s.anchor_normal);
    return select(n, -n, s.radius < 0.0);
}

// Ray/parallelogram (Shirley, Ray Tracing: The Next Week §6): plane hit, then planar
// coordinates (α, β) of the hit in the (u, v) frame must both lie in [0, 1]. Two-sided.
fn hit_quad(quad: Quad, ray: Ray, t_max: f32) -> f32 {
    let denom = dot(quad.normal, ray.dir);
    if abs(denom) < 1e-20 {
        return NO_HIT;   // edge-on: the ray lies in the quad's plane
    }
    let t = dot(quad.normal, quad.q - ray.origin) / denom;
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    let p = ray.origin + t * ray.dir - quad.q;
    let alpha = dot(quad.w, cross(p, quad.v));
    let beta = dot(quad.w, cross(quad.u, p));
    if alpha < 0.0 || alpha > 1.0 || beta < 0.0 || beta > 1.0 {
        return NO_HIT;
    }
    return t;
}

// Ray/oriented box: the slab test (Kay & Kajiya 1986) in the box's own frame.
fn hit_box(bx: Cuboid, ray: Ray, t_max: f32) -> f32 {
    let oc = ray.origin - bx.center;
    let lo = vec3f(dot(oc, bx.axis_x), dot(oc, bx.axis_y), dot(oc, bx.axis_z));
    let ld = vec3f(dot(ray.dir, bx.axis_x), dot(ray.dir, bx.axis_y), dot(ray.dir, bx.axis_z));
    // A tiny stand-in for a zero direction component keeps the slab arithmetic finite.
    let safe = select(ld, vec3f(1e-30), abs(ld) < vec3f(1e-30));
    let inv = 1.0 / safe;
    let t1 = (-bx.half_extents - lo) * inv;
    let t2 = (bx.half_extents - lo) * inv;
    let tmin = min(t1, t2);
    let tmax = max(t1, t2);
    let t_enter = max(max(tmin.x, tmin.y), tmin.z);
    let t_exit = min(min(tmax.x, tmax.y), tmax.z);
    if t_enter > t_exit {
        return NO_HIT;
    }
    let t = select(t_exit, t_enter, t_enter > 0.0);
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    return t;
}

// Outward normal of a box at ray.origin + t·ray.dir: the face whose slab the local hit point
// is closest to leaving.
fn box_normal(bx: Cuboid, ray: Ray, t: f32) -> vec3f {
    let oc = ray.origin + t * ray.dir - bx.center;
    let lp = vec3f(dot(oc, bx.axis_x), dot(oc, bx.axis_y), dot(oc, bx.axis_z)) / bx.half_extents;
    let a = abs(lp);
    var local = vec3f(0.0, 0.0, sign(lp.z));
    if a.x >= a.y && a.x >= a.z {
        local = vec3f(sign(lp.x), 0.0, 0.0);
    } else if a.y >= a.z {
        local = vec3f(0.0, sign(lp.y), 0.0);
    }
    return normalize(local.x * bx.axis_x + local.y * bx.axis_y + local.z * bx.axis_z);
}

// Moves a hit point off its surface along the geometric normal `n` (pointing to the side the
// new ray leaves into) by an amount that scales with the point's magnitude: a fixed number of
// float ulps, or a fixed distance near the origin where ulps vanish. Wächter & Binder,
// "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6.
const OFFSET_ORIGIN: f32 = 1.0 / 32.0;
const OFFSET_FLOAT_SCALE: f32 = 1.0 / 65536.0;
const OFFSET_INT_SCALE: f32 = 256.0;

fn offset_ray(p: vec3f, n: vec3f) -> vec3f {
    let of_i = vec3i(OFFSET_INT_SCALE * n);
    let p_i = bitcast<vec3f>(bitcast<vec3i>(p) + select(of_i, -of_i, p < vec3f(0.0)));
    return select(p_i, p + OFFSET_FLOAT_SCALE * n, abs(p) < vec3f(OFFSET_ORIGIN));
}
