// #include "common/types.wgsl"
// Twin: src/cpu/intersect.rs (tests/twins.rs keeps their functions paired).
// Ray/primitive intersection and self-intersection avoidance.

struct Ray {
    origin: vec3f,
    dir: vec3f,   // unit length
}

const NO_HIT: f32 = -1.0;

// Ray/sphere in the numerically careful form of Haines, Günther & Akenine-Möller,
// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7:
//   - the discriminant as r² - |f - (f·d)·d|² (f = o - C): the squared distance from the
//     centre to the ray's line, which stays exact for a small sphere far away, where b² - c
//     subtracts two numbers of size |f|² and loses everything;
//   - the roots as c/q and q with q = -(b + sign(b)·sqrt(disc)), so neither cancels.
// Beyond the chapter, c is taken relative to the sphere's anchor A (a surface point near
// the view) with outward normal N there (centre C = A - r·N): with g = o - A,
//   f = g + r·N,   b = f·d = g·d + r·(N·d),   c = |f|² - r² = g·g + 2r·(g·N),
// so c, which sets the near root, has no cancellation of two r²-sized terms: a ground sphere
// of radius 1e6 is exact to float precision near the anchor. Returns the nearest t in
// (0, t_max), or NO_HIT.
fn hit_sphere(s: Sphere, ray: Ray, t_max: f32) -> f32 {
    let r = abs(s.radius);
    let g = ray.origin - s.anchor;
    let f = g + r * s.anchor_normal;
    let b = dot(f, ray.dir);
    let l = f - b * ray.dir;
    let disc = (r - length(l)) * (r + length(l));
    if disc < 0.0 {
        return NO_HIT;
    }
    let c = dot(g, g) + 2.0 * r * dot(g, s.anchor_normal);
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

// Where a ray hit a surface: the point, moved onto the surface, and the geometric normal
// (outward as the primitive defines it). The point is reprojected rather than taken as
// ray.origin + t·ray.dir, whose error along the normal scales with the ray's origin and
// length: from a camera 1000 units away that error (≈ 3e-5) exceeds the offset offset_ray
// makes near the scene's origin, and reflected rays would start below the surface. After
// reprojection the error scales with the point itself, as offset_ray assumes (Wächter &
// Binder, Ray Tracing Gems ch. 6, §6.2: compute the hit point from the surface).
struct SurfacePoint {
    position: vec3f,
    normal: vec3f,
}

// On a sphere, relative to its anchor A (outward normal N, centre A - r·N): with q = p - A,
// the height above the sphere is |q + r·N| - r = (q·q + 2r·q·N) / (|q + r·N| + r), computed
// without cancellation, and p moves by that height along the radial direction.
fn sphere_surface(s: Sphere, ray: Ray, t: f32) -> SurfacePoint {
    let r = abs(s.radius);
    let q = ray.origin - s.anchor + t * ray.dir;
    let m = q / r + s.anchor_normal;
    let len = length(m);
    let n = m / len;
    let h = (dot(q, q) + 2.0 * r * dot(q, s.anchor_normal)) / (r * len + r);
    return SurfacePoint(s.anchor + (q - h * n), select(n, -n, s.radius < 0.0));
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

// On a quad: p projected onto its plane.
fn quad_surface(quad: Quad, ray: Ray, t: f32) -> SurfacePoint {
    let p = ray.origin + t * ray.dir;
    return SurfacePoint(p - quad.normal * dot(quad.normal, p - quad.q), quad.normal);
}

// On a box: the face is the slab the local hit point is closest to leaving; the local
// coordinate across that face is snapped onto it.
fn box_surface(bx: Cuboid, ray: Ray, t: f32) -> SurfacePoint {
    let oc = ray.origin + t * ray.dir - bx.center;
    var lp = vec3f(dot(oc, bx.axis_x), dot(oc, bx.axis_y), dot(oc, bx.axis_z));
    let a = abs(lp / bx.half_extents);
    var local = vec3f(0.0, 0.0, sign(lp.z));
    if a.x >= a.y && a.x >= a.z {
        local = vec3f(sign(lp.x), 0.0, 0.0);
        lp.x = local.x * bx.half_extents.x;
    } else if a.y >= a.z {
        local = vec3f(0.0, sign(lp.y), 0.0);
        lp.y = local.y * bx.half_extents.y;
    } else {
        lp.z = local.z * bx.half_extents.z;
    }
    let world = bx.center + lp.x * bx.axis_x + lp.y * bx.axis_y + lp.z * bx.axis_z;
    let n = normalize(local.x * bx.axis_x + local.y * bx.axis_y + local.z * bx.axis_z);
    return SurfacePoint(world, n);
}

// Ray/triangle (Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection",
// JGT 1997), two-sided. The barycentric bounds are widened by TRIANGLE_SLACK so that a ray
// through an edge shared by two triangles hits at least one of them: the test is not
// watertight, and a ray slipping into a closed mesh would bounce inside it.
const TRIANGLE_SLACK: f32 = 1e-6;

fn hit_triangle(tri: Triangle, ray: Ray, t_max: f32) -> f32 {
    let p = cross(ray.dir, tri.e2);
    let det = dot(tri.e1, p);
    if det == 0.0 {
        return NO_HIT;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = dot(s, p) * inv;
    if u < -TRIANGLE_SLACK || u > 1.0 + TRIANGLE_SLACK {
        return NO_HIT;
    }
    let q = cross(s, tri.e1);
    let v = dot(ray.dir, q) * inv;
    if v < -TRIANGLE_SLACK || u + v > 1.0 + TRIANGLE_SLACK {
        return NO_HIT;
    }
    let t = dot(tri.e2, q) * inv;
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    return t;
}

// On a triangle: the point from its barycentric coordinates (relative to v0, not to the ray
// origin), and the normal of its winding.
// The barycentric coordinates (along e1, along e2) of p, taken relative to v0, by least
// squares in the triangle's plane, and 1 where they are a point of the triangle's, 0 where a
// sliver (corners all but in a line) cancelled its terms to NaN or to a point far outside
// (src/cpu/intersect.rs: plane_barycentrics; a hit point is always within these bounds).
fn plane_barycentrics(tri: Triangle, p: vec3f) -> vec3f {
    let d00 = dot(tri.e1, tri.e1);
    let d01 = dot(tri.e1, tri.e2);
    let d11 = dot(tri.e2, tri.e2);
    let d20 = dot(p, tri.e1);
    let d21 = dot(p, tri.e2);
    let denom = d00 * d11 - d01 * d01;
    let b = vec2f((d11 * d20 - d01 * d21) / denom, (d00 * d21 - d01 * d20) / denom);
    let found = b.x >= -0.5 && b.y >= -0.5 && b.x + b.y <= 1.5;
    return vec3f(b, select(0.0, 1.0, found));
}

// plane_barycentrics, or a sliver's centroid: where the corners' attributes are read.
fn triangle_barycentrics(tri: Triangle, p: vec3f) -> vec2f {
    let b = plane_barycentrics(tri, p);
    return select(vec2f(1.0 / 3.0), b.xy, b.z > 0.0);
}

// The point in the triangle's plane, or on a sliver the ray's own point.
fn triangle_surface(tri: Triangle, ray: Ray, t: f32) -> SurfacePoint {
    let p = ray.origin + t * ray.dir;
    let b = plane_barycentrics(tri, p - tri.v0);
    let q = tri.v0 + b.x * tri.e1 + b.y * tri.e2;
    return SurfacePoint(select(p, q, b.z > 0.0), normalize(cross(tri.e1, tri.e2)));
}

// An instance's maps (common/types.wgsl: Instance): a world ray into its mesh's coordinates,
// its direction not normalized so that distances along it stay the world's; a point of the
// mesh into the world; a normal into the world by the inverse transpose (the transpose of
// object_from_world's linear part), normalized.
fn instance_ray(inst: Instance, ray: Ray) -> Ray {
    let m = inst.object_from_world;
    let o = vec4f(ray.origin, 1.0);
    let d = vec4f(ray.dir, 0.0);
    return Ray(vec3f(dot(m[0], o), dot(m[1], o), dot(m[2], o)), vec3f(dot(m[0], d), dot(m[1], d), dot(m[2], d)));
}

fn instance_point(inst: Instance, p: vec3f) -> vec3f {
    let m = inst.world_from_object;
    let q = vec4f(p, 1.0);
    return vec3f(dot(m[0], q), dot(m[1], q), dot(m[2], q));
}

// A tangent of the mesh in the world (by the matrix), and whether the map mirrors (its
// determinant's sign: a mirrored frame turns the bitangent over, as the flattened mesh's
// frames do).
fn instance_tangent(inst: Instance, t: vec4f) -> vec4f {
    let m = inst.world_from_object;
    let v = vec3f(dot(m[0].xyz, t.xyz), dot(m[1].xyz, t.xyz), dot(m[2].xyz, t.xyz));
    let mirrors = dot(cross(m[0].xyz, m[1].xyz), m[2].xyz) < 0.0;
    return vec4f(v, select(t.w, -t.w, mirrors));
}

fn instance_normal(inst: Instance, n: vec3f) -> vec3f {
    let m = inst.object_from_world;
    return normalize(n.x * m[0].xyz + n.y * m[1].xyz + n.z * m[2].xyz);
}

// 1 / dir with components too small to invert replaced by a tiny positive number: the slab
// test then sees an axis-parallel ray, and nothing becomes infinite or NaN (WGSL may assume
// neither occurs).
fn safe_inverse(dir: vec3f) -> vec3f {
    return 1.0 / select(vec3f(1e-30), dir, abs(dir) >= vec3f(1e-30));
}

// Moves a hit point off its surface along the geometric normal `n` (pointing to the side the
// new ray leaves into) by an amount that scales with the point's magnitude: a fixed number of
// float ulps, or a fixed distance near the origin where ulps vanish. Wächter & Binder,
// "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6. The
// chapter's 256 ulps cover hit points with hundreds of ulps of error; ours are reprojected
// onto their surface (a few ulps), so 32 suffice, and smaller offsets leak less light where
// objects touch. Near the origin (where the floating origin of src/gpu/scene_buffers.rs puts
// the camera's target) the chapter's fixed 2^-16; 2^-20 lost paths in the camera-inside-glass
// scene. Chosen by `termtrace check --stress` (docs/STABILITY.md).
const OFFSET_ORIGIN: f32 = 1.0 / 32.0;
const OFFSET_FLOAT_SCALE: f32 = 1.0 / 65536.0;
const OFFSET_INT_SCALE: f32 = 32.0;

fn offset_ray(p: vec3f, n: vec3f) -> vec3f {
    let of_i = vec3i(OFFSET_INT_SCALE * n);
    let p_i = bitcast<vec3f>(bitcast<vec3i>(p) + select(of_i, -of_i, p < vec3f(0.0)));
    return select(p_i, p + OFFSET_FLOAT_SCALE * n, abs(p) < vec3f(OFFSET_ORIGIN));
}
