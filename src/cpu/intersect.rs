//! Ray/primitive intersection and self-intersection avoidance: shaders/common/intersect.wgsl
//! in Rust, term for term (its comments give the sources and the reasoning).

use glam::{IVec3, Vec3A, Vec4};

/// Rays walked together: the camera rays of `LANES` neighbouring pixels (the packet walk,
/// `trace::Tracer::camera_hits`).
pub const LANES: usize = 8;

/// The primitives as the CPU tracer tests them: the arrays of `common::layout` as vectors
/// (`cpu::scene` converts them).
#[derive(Clone, Copy, Debug)]
pub struct Sphere {
    pub anchor: Vec3A,
    pub anchor_normal: Vec3A,
    pub radius: f32,
    pub material: u32,
}

#[derive(Clone, Copy, Debug)]
pub struct Quad {
    pub q: Vec3A,
    pub u: Vec3A,
    pub v: Vec3A,
    pub normal: Vec3A,
    pub w: Vec3A,
    pub material: u32,
}

#[derive(Clone, Copy, Debug)]
pub struct Cuboid {
    pub center: Vec3A,
    pub half_extents: Vec3A,
    pub axes: [Vec3A; 3],
    pub material: u32,
}

/// repr(C): the CPU tracer's lanes gather its fields by word (`lanes::surface`).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Triangle {
    pub v0: Vec3A,
    pub e1: Vec3A,
    pub e2: Vec3A,
    pub material: u32,
}

/// A copy of a mesh (`common::layout::GpuInstance`): rows of its affine maps, and the root of
/// its mesh's tree.
#[derive(Clone, Copy, Debug)]
pub struct Instance {
    pub object_from_world: [Vec4; 3],
    pub world_from_object: [Vec4; 3],
    pub root: u32,
}

/// A world ray in the mesh's coordinates, its direction not normalized (distances along it
/// stay the world's).
#[inline(always)]
pub fn instance_ray(inst: &Instance, ray: &Ray) -> Ray {
    let m = &inst.object_from_world;
    let o = ray.origin.extend(1.0);
    let d = ray.dir.extend(0.0);
    Ray {
        origin: Vec3A::new(m[0].dot(o), m[1].dot(o), m[2].dot(o)),
        dir: Vec3A::new(m[0].dot(d), m[1].dot(d), m[2].dot(d)),
    }
}

/// A point of the mesh in the world.
#[inline(always)]
pub fn instance_point(inst: &Instance, p: Vec3A) -> Vec3A {
    let m = &inst.world_from_object;
    let q = p.extend(1.0);
    Vec3A::new(m[0].dot(q), m[1].dot(q), m[2].dot(q))
}

/// A tangent `(t, w)` of the mesh in the world (by the matrix), `w` turned over where the map
/// mirrors (intersect.wgsl's `instance_tangent`).
#[inline(always)]
pub fn instance_tangent(inst: &Instance, (t, w): (Vec3A, f32)) -> (Vec3A, f32) {
    let m = inst.world_from_object.map(Vec3A::from_vec4);
    let v = Vec3A::new(m[0].dot(t), m[1].dot(t), m[2].dot(t));
    let mirrors = m[0].cross(m[1]).dot(m[2]) < 0.0;
    (v, if mirrors { -w } else { w })
}

/// A normal of the mesh in the world (by the inverse transpose), normalized.
#[inline(always)]
pub fn instance_normal(inst: &Instance, n: Vec3A) -> Vec3A {
    let m = &inst.object_from_world;
    (n.x * Vec3A::from_vec4(m[0]) + n.y * Vec3A::from_vec4(m[1]) + n.z * Vec3A::from_vec4(m[2]))
        .normalize()
}

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3A,
    /// Unit length (but in an instance's coordinates: `Instance::ray`).
    pub dir: Vec3A,
}

pub const NO_HIT: f32 = -1.0;

/// Ray/sphere relative to the sphere's anchor (Haines, Günther & Akenine-Möller, Ray
/// Tracing Gems ch. 7): the nearest t in (0, t_max), or NO_HIT.
#[inline(always)]
pub fn hit_sphere(s: &Sphere, ray: &Ray, t_max: f32) -> f32 {
    let r = s.radius.abs();
    let g = ray.origin - s.anchor;
    let f = g + r * s.anchor_normal;
    let b = f.dot(ray.dir);
    let l = f - b * ray.dir;
    let ll = l.length();
    let disc = (r - ll) * (r + ll);
    if disc < 0.0 {
        return NO_HIT;
    }
    let c = g.dot(g) + 2.0 * r * g.dot(s.anchor_normal);
    let sq = disc.sqrt();
    let q = -b - if b < 0.0 { -sq } else { sq };
    if q == 0.0 {
        return NO_HIT;
    }
    let t0 = c / q;
    let (t_near, t_far) = (t0.min(q), t0.max(q));
    if t_near > 0.0 && t_near < t_max {
        return t_near;
    }
    if t_far > 0.0 && t_far < t_max {
        return t_far;
    }
    NO_HIT
}

/// Where a ray hit a surface: the point, moved onto the surface, and the geometric normal.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3A,
    pub normal: Vec3A,
}

pub fn sphere_surface(s: &Sphere, ray: &Ray, t: f32) -> SurfacePoint {
    let r = s.radius.abs();
    let q = ray.origin - s.anchor + t * ray.dir;
    let m = q / r + s.anchor_normal;
    let len = m.length();
    let n = m / len;
    let h = (q.dot(q) + 2.0 * r * q.dot(s.anchor_normal)) / (r * len + r);
    SurfacePoint {
        position: s.anchor + (q - h * n),
        normal: if s.radius < 0.0 { -n } else { n },
    }
}

/// Ray/parallelogram, two-sided (Shirley, Ray Tracing: The Next Week §6).
#[inline]
pub fn hit_quad(quad: &Quad, ray: &Ray, t_max: f32) -> f32 {
    let denom = quad.normal.dot(ray.dir);
    if denom.abs() < 1e-20 {
        return NO_HIT;
    }
    let t = quad.normal.dot(quad.q - ray.origin) / denom;
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    let p = ray.origin + t * ray.dir - quad.q;
    let alpha = quad.w.dot(p.cross(quad.v));
    let beta = quad.w.dot(quad.u.cross(p));
    if !(0.0..=1.0).contains(&alpha) || !(0.0..=1.0).contains(&beta) {
        return NO_HIT;
    }
    t
}

/// Ray/oriented box: the slab test (Kay & Kajiya 1986) in the box's own frame.
#[inline]
pub fn hit_box(bx: &Cuboid, ray: &Ray, t_max: f32) -> f32 {
    let oc = ray.origin - bx.center;
    let lo = Vec3A::new(oc.dot(bx.axes[0]), oc.dot(bx.axes[1]), oc.dot(bx.axes[2]));
    let ld = Vec3A::new(
        ray.dir.dot(bx.axes[0]),
        ray.dir.dot(bx.axes[1]),
        ray.dir.dot(bx.axes[2]),
    );
    let safe = Vec3A::select(ld.abs().cmplt(Vec3A::splat(1e-30)), Vec3A::splat(1e-30), ld);
    let inv = safe.recip();
    let t1 = (-bx.half_extents - lo) * inv;
    let t2 = (bx.half_extents - lo) * inv;
    let t_enter = t1.min(t2).max_element();
    let t_exit = t1.max(t2).min_element();
    if t_enter > t_exit {
        return NO_HIT;
    }
    let t = if t_enter > 0.0 { t_enter } else { t_exit };
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    t
}

pub fn quad_surface(quad: &Quad, ray: &Ray, t: f32) -> SurfacePoint {
    let p = ray.origin + t * ray.dir;
    SurfacePoint {
        position: p - quad.normal * quad.normal.dot(p - quad.q),
        normal: quad.normal,
    }
}

/// WGSL's sign(): -1, 0 or 1.
fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

pub fn box_surface(bx: &Cuboid, ray: &Ray, t: f32) -> SurfacePoint {
    let oc = ray.origin + t * ray.dir - bx.center;
    let mut lp = Vec3A::new(oc.dot(bx.axes[0]), oc.dot(bx.axes[1]), oc.dot(bx.axes[2]));
    let a = (lp / bx.half_extents).abs();
    let mut local = Vec3A::new(0.0, 0.0, sign(lp.z));
    if a.x >= a.y && a.x >= a.z {
        local = Vec3A::new(sign(lp.x), 0.0, 0.0);
        lp.x = local.x * bx.half_extents.x;
    } else if a.y >= a.z {
        local = Vec3A::new(0.0, sign(lp.y), 0.0);
        lp.y = local.y * bx.half_extents.y;
    } else {
        lp.z = local.z * bx.half_extents.z;
    }
    let world = bx.center + lp.x * bx.axes[0] + lp.y * bx.axes[1] + lp.z * bx.axes[2];
    let n = (local.x * bx.axes[0] + local.y * bx.axes[1] + local.z * bx.axes[2]).normalize();
    SurfacePoint {
        position: world,
        normal: n,
    }
}

/// Barycentric slack so that a ray through a shared edge hits at least one triangle.
pub(super) const TRIANGLE_SLACK: f32 = 1e-6;

/// Ray/triangle, two-sided (Möller & Trumbore, JGT 1997).
#[inline]
pub fn hit_triangle(tri: &Triangle, ray: &Ray, t_max: f32) -> f32 {
    let p = ray.dir.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det == 0.0 {
        return NO_HIT;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv;
    if !(-TRIANGLE_SLACK..=1.0 + TRIANGLE_SLACK).contains(&u) {
        return NO_HIT;
    }
    let q = s.cross(tri.e1);
    let v = ray.dir.dot(q) * inv;
    if v < -TRIANGLE_SLACK || u + v > 1.0 + TRIANGLE_SLACK {
        return NO_HIT;
    }
    let t = tri.e2.dot(q) * inv;
    if !(t > 0.0 && t < t_max) {
        return NO_HIT;
    }
    t
}

/// The barycentric coordinates (along e1, along e2) of `p`, taken relative to v0, by least
/// squares in the triangle's plane (intersect.wgsl: plane_barycentrics), or None where they
/// are not a point of the triangle's: a sliver (three corners all but in a line, which a mesh
/// may hold and a ray may still hit) cancels its terms to NaN or to a point far outside. A
/// hit point's are within the hit test's slack of the triangle, so the loose bounds here
/// never reject them.
#[inline(always)]
pub fn plane_barycentrics(tri: &Triangle, p: Vec3A) -> Option<(f32, f32)> {
    let d00 = tri.e1.dot(tri.e1);
    let d01 = tri.e1.dot(tri.e2);
    let d11 = tri.e2.dot(tri.e2);
    let d20 = p.dot(tri.e1);
    let d21 = p.dot(tri.e2);
    let denom = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    // (NaN fails every comparison.)
    (v >= -0.5 && w >= -0.5 && v + w <= 1.5).then_some((v, w))
}

/// [`plane_barycentrics`], or a sliver's centroid (intersect.wgsl: triangle_barycentrics):
/// where the corners' attributes (texture coordinates, normals) are read.
#[inline(always)]
pub fn triangle_barycentrics(tri: &Triangle, p: Vec3A) -> (f32, f32) {
    plane_barycentrics(tri, p).unwrap_or((1.0 / 3.0, 1.0 / 3.0))
}

/// The hit at distance `t` along `ray`: the point in the triangle's plane, or on a sliver
/// the ray's own point (a NaN point there had made a NaN path: 1 sample in 2·10⁸ of
/// `benches/peer/map-dog.toml`, whose dog has such triangles).
pub fn triangle_surface(tri: &Triangle, ray: &Ray, t: f32) -> SurfacePoint {
    let p = ray.origin + t * ray.dir;
    SurfacePoint {
        position: match plane_barycentrics(tri, p - tri.v0) {
            Some((v, w)) => tri.v0 + v * tri.e1 + w * tri.e2,
            None => p,
        },
        normal: tri.e1.cross(tri.e2).normalize(),
    }
}

/// 1 / dir with components too small to invert replaced by a tiny positive number.
#[inline]
pub fn safe_inverse(dir: Vec3A) -> Vec3A {
    Vec3A::select(
        dir.abs().cmpge(Vec3A::splat(1e-30)),
        dir,
        Vec3A::splat(1e-30),
    )
    .recip()
}

// Self-intersection avoidance (Wächter & Binder, Ray Tracing Gems ch. 6), with the constants
// intersect.wgsl chose by `termtrace check --stress`.
pub(super) const OFFSET_ORIGIN: f32 = 1.0 / 32.0;
pub(super) const OFFSET_FLOAT_SCALE: f32 = 1.0 / 65536.0;
pub(super) const OFFSET_INT_SCALE: f32 = 32.0;

/// Moves a hit point off its surface along `n` by a number of ulps (a fixed distance near
/// the origin).
#[inline]
pub fn offset_ray(p: Vec3A, n: Vec3A) -> Vec3A {
    let of_i: IVec3 = (OFFSET_INT_SCALE * n).as_ivec3();
    let pa = p.to_array();
    let oi = of_i.to_array();
    let na = n.to_array();
    let mut out = [0.0f32; 3];
    for c in 0..3 {
        out[c] = if pa[c].abs() < OFFSET_ORIGIN {
            pa[c] + OFFSET_FLOAT_SCALE * na[c]
        } else {
            let d = if pa[c] < 0.0 { -oi[c] } else { oi[c] };
            f32::from_bits((pa[c].to_bits() as i32).wrapping_add(d) as u32)
        };
    }
    Vec3A::from_array(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sliver_that_a_ray_hits_gives_a_finite_point_and_a_sane_triangle_its_own() {
        // Triangle 67 of the Cube Pets dog (benches/peer/map-dog.toml) as the tracer holds it,
        // its corners all but in a line, and the ray of a path that met it: the least squares
        // gave NaN, and the path a NaN sample.
        let sliver = Triangle {
            v0: Vec3A::new(0.4372699, 0.59595704, 0.5),
            e1: Vec3A::new(-0.03726989, -0.139094, 0.0),
            e2: Vec3A::new(0.03727001, 0.13909292, 0.0),
            material: 1,
        };
        let ray = Ray {
            origin: Vec3A::new(0.31351867, 0.3713119, 0.55765605),
            dir: Vec3A::new(0.5996587, 0.7086864, -0.3717164),
        };
        let t = hit_triangle(&sliver, &ray, f32::INFINITY);
        assert!(t > 0.0 && t.is_finite(), "the ray hits it: {t}");
        let p = ray.origin + t * ray.dir;
        assert_eq!(plane_barycentrics(&sliver, p - sliver.v0), None);
        let s = triangle_surface(&sliver, &ray, t);
        assert_eq!(s.position, p);
        assert!(s.normal.is_finite());
        assert_eq!(
            triangle_barycentrics(&sliver, p - sliver.v0),
            (1.0 / 3.0, 1.0 / 3.0)
        );
        // A triangle with area keeps the point in its plane, from its barycentrics.
        let tri = Triangle {
            v0: Vec3A::new(0.0, 0.0, -1.0),
            e1: Vec3A::new(1.0, 0.0, 0.0),
            e2: Vec3A::new(0.0, 1.0, 0.0),
            material: 0,
        };
        let ray = Ray {
            origin: Vec3A::new(0.25, 0.3, 1.0),
            dir: Vec3A::new(0.0, 0.0, -1.0),
        };
        let t = hit_triangle(&tri, &ray, f32::INFINITY);
        let (v, w) = plane_barycentrics(&tri, ray.origin + t * ray.dir - tri.v0).unwrap();
        assert_eq!((v, w), (0.25, 0.3));
        assert_eq!(
            triangle_surface(&tri, &ray, t).position,
            tri.v0 + v * tri.e1 + w * tri.e2
        );
    }
}
