//! One path (MODEL.md "Scattering"), as `trace_path` in shaders/trace.wgsl traces it: the
//! same camera, sky, materials, next-event estimation with MIS, Russian roulette and random
//! streams, so that the CPU's images converge to the GPU's (tests/cpu.rs checks every
//! shipped scene with the bias check). Comments on the model are in trace.wgsl; here only
//! what differs.
//!
//! Leaving out what a scene does not need: the tracer is monomorphized over the primitive
//! kinds (`P`: spheres only, or any) and over next-event estimation (`NEE`), the choices a
//! CPU's branch predictor cannot make free (a kind switch per primitive test, the light
//! sampling's code and registers); the rarer features (glass, emitters, depth of field, the
//! sun) are runtime flags, a predicted branch each (measured in BENCHMARKS.md).

use super::bvh::{Stack, Tally};
#[cfg(target_arch = "x86_64")]
use super::bvh8::Stack8;
use super::intersect::*;
use super::lens;
use super::material::{
    Scatter, gloss_pdf, reflect, refract_dir, scatter_dielectric, scatter_surface, schlick,
};
use super::mirror;
#[cfg(target_arch = "x86_64")]
use super::packet::Packets;
use super::pbr;
use super::rng::Rng;
use super::sampling::{PI, basis, random_in_disk, sin_cos_turns};
use super::scene::{CpuScene, Material};
use crate::common::Features;
use crate::common::arrays::INSTANCE_BIT;
use crate::common::arrays::REF_INDEX as INDEX;
use crate::common::arrays::{ENV_NONE, ENV_VISIBLE};
use crate::common::layout::GpuLight;
use glam::{Vec2, Vec3A};

/// `P`: only spheres.
pub const SPHERES: u32 = 1;
/// `P`: any primitive kind.
pub const ANY: u32 = 15;

pub(super) const T_FAR: f32 = 3.0e38;
/// No primitive (a reference no scene has: the 2^30-th triangle).
const NONE: u32 = u32::MAX;
const RR_START: u32 = 3;
const RR_MAX_SURVIVAL: f32 = 0.95;
const LOCAL_SELECTION_MAX: u32 = 32;
pub(super) const BACKFACE_WEIGHT: f32 = 0.1;

/// Where a textured hit read its maps: its texture record, barycentrics and coordinates.
#[derive(Clone, Copy)]
struct Mapped {
    rec: u32,
    bary: (f32, f32),
    uv: Vec2,
}

#[derive(Clone, Copy)]
struct Hit {
    t: f32,
    /// A BVH reference: kind in the top two bits (an instance's hit: its mesh's triangle).
    r: u32,
    /// The instance whose mesh holds the triangle, or NONE.
    inst: u32,
}

/// The hit of top-level reference `r` at `t`: an instance's names the triangle its walk found
/// (`INSTANCE_WALK`).
#[inline(always)]
fn hit_of(t: f32, r: u32) -> Hit {
    if r >> 30 == 3 && r & INSTANCE_BIT != 0 {
        let tri = INSTANCE_WALK.with(|w| w.borrow().triangle);
        return Hit {
            t,
            r: 3 << 30 | tri,
            inst: r & (INSTANCE_BIT - 1),
        };
    }
    Hit { t, r, inst: NONE }
}

/// The walk into an instanced mesh (a second stack, so that the top level's stays), and the
/// triangle it found last, per thread.
struct InstanceWalk {
    stack: Stack,
    tally: Tally,
    triangle: u32,
}

thread_local! {
    static INSTANCE_WALK: std::cell::RefCell<InstanceWalk> = std::cell::RefCell::new(InstanceWalk {
        stack: Stack::default(),
        tally: Tally::default(),
        triangle: 0,
    });
}

/// The nearest of instance `i`'s triangles before `t_max`, or NO_HIT; the triangle is left
/// in `INSTANCE_WALK` (trace.wgsl's `hit_instance`).
#[inline(never)]
fn hit_instance(s: &CpuScene, i: usize, ray: &Ray, t_max: f32) -> f32 {
    let inst = &s.instances[i];
    let local = instance_ray(inst, ray);
    INSTANCE_WALK.with(|w| {
        let w = &mut *w.borrow_mut();
        let found = s.bvh.closest_from(
            inst.root as usize,
            &local,
            t_max,
            &mut w.tally,
            &mut w.stack,
            |r, t| {
                let k = r & INDEX;
                let tri = &s.triangles[k as usize];
                let th = hit_triangle(tri, &local, t);
                if s.cutouts && th > 0.0 && super::texture::cut_out(&s.tex, tri, k, &local, th) {
                    return NO_HIT;
                }
                th
            },
        );
        match found {
            Some((t, r)) => {
                w.triangle = r & INDEX;
                t
            }
            None => NO_HIT,
        }
    })
}

/// The distance to primitive `r` if nearer than t_max, else NO_HIT.
#[inline(always)]
pub(super) fn hit_primitive<const P: u32>(s: &CpuScene, r: u32, ray: &Ray, t_max: f32) -> f32 {
    let i = (r & INDEX) as usize;
    if P == SPHERES {
        return hit_sphere(&s.spheres[i], ray, t_max);
    }
    match r >> 30 {
        0 => hit_sphere(&s.spheres[i], ray, t_max),
        1 => hit_quad(&s.quads[i], ray, t_max),
        2 => hit_box(&s.boxes[i], ray, t_max),
        _ if r & INSTANCE_BIT != 0 => hit_instance(s, i & (INSTANCE_BIT as usize - 1), ray, t_max),
        _ => {
            let tri = &s.triangles[i];
            let t = hit_triangle(tri, ray, t_max);
            if s.cutouts && t > 0.0 && super::texture::cut_out(&s.tex, tri, i as u32, ray, t) {
                return NO_HIT;
            }
            t
        }
    }
}

/// `hit_primitive`, but NO_HIT for primitive `skip` (counted in `skipped`).
#[inline(always)]
fn hit_except<const P: u32>(
    s: &CpuScene,
    r: u32,
    ray: &Ray,
    t_max: f32,
    skip: u32,
    skipped: &mut u64,
) -> f32 {
    if r == skip {
        *skipped += 1;
        return NO_HIT;
    }
    hit_primitive::<P>(s, r, ray, t_max)
}

/// Whether primitive `r`, neither `skip` nor `from`, blocks a shadow ray before t_max
/// (`Tracer::occluded`'s test, whichever walk asks it).
#[inline(always)]
fn blocks<const P: u32>(
    s: &CpuScene,
    r: u32,
    ray: &Ray,
    t_max: f32,
    (skip, from): (u32, u32),
) -> bool {
    r != skip && r != from && hit_primitive::<P>(s, r, ray, t_max) > 0.0
}

/// A mirror sphere met right after a lobe light sampling weighs (`Tracer::mirror_hit`).
#[derive(Clone, Copy)]
struct MirrorHit {
    /// The lobe's density of the ray that met it.
    pdf: f32,
    /// `mirror::spread` at the point met.
    spread: f32,
}

/// A path through a glass sphere of `lenses` right after a lobe light sampling weighs: where
/// it is on its way (`Tracer::lens_step`), so that the map it reaches on leaving is weighed
/// against `sample_lens`.
#[derive(Clone, Copy)]
struct LensPath {
    /// The sphere (its index in `spheres`).
    sphere: u32,
    /// The point whose lobe drew the ray into it, the ray's direction and the lobe's density.
    from: Vec3A,
    dir: Vec3A,
    pdf: f32,
    /// 1: met from outside; 2: refracted in (or reflected inside); 3: met from inside; 4:
    /// refracted out.
    stage: u8,
    /// Reflections inside so far (at most one: `lens::Frame::inner`).
    inner: u8,
}

pub(super) fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    a2 / (a2 + b * b)
}

/// The lobe whose light samples light sampling weighs (trace.wgsl: light_weighted's `pbr`,
/// `lobe` and `gloss`).
#[derive(Clone, Copy)]
enum Weighed<'a> {
    /// The cosine lobe: the Lambertian one, or the lecture's specular one at smoothness 0.
    Cosine,
    /// The lecture's glossy lobe (`material::gloss_pdf`): the shading normal, the mirror
    /// direction and the smoothness.
    Gloss { n: Vec3A, r: Vec3A, s: f32 },
    /// The lecture's glossy lobe taken at probability `p` beside the cosine lobe (its
    /// `specular` below 1): their mixture, with each lobe's tint (`spec`, `diff`), so that
    /// every sample's light sample finds the highlight, whichever lobe the path goes on by.
    Mixed {
        n: Vec3A,
        r: Vec3A,
        s: f32,
        p: f32,
        spec: Vec3A,
        diff: Vec3A,
    },
    /// glTF's BRDF.
    Pbr(&'a pbr::Lobe),
}

/// A light sample's estimate for the lobe that light sampling weighs: `radiance` arriving from
/// `dir` (cos_s against the shading normal), drawn with density `pl`, times glTF's BRDF, or
/// the lecture's lobe's f·cos, which is its density (the cosine lobe's cos_s / π; its tint the
/// caller applies), or the mixture of the glossy and the cosine lobe (`Weighed::Mixed`, tints
/// included), weighed by the power heuristic against the lobe's density (trace.wgsl:
/// light_weighted).
#[inline(always)]
fn light_weighted(radiance: Vec3A, dir: Vec3A, cos_s: f32, pl: f32, lobe: Weighed) -> Vec3A {
    match lobe {
        Weighed::Pbr(l) => {
            let (f, pdf) = pbr::eval(l, dir);
            radiance * f * (power_heuristic(pl, pdf) / pl)
        }
        Weighed::Cosine => radiance * (cos_s / PI / pl * power_heuristic(pl, cos_s / PI)),
        Weighed::Gloss { n, r, s } => {
            let pdf = gloss_pdf(dir, n, r, s);
            radiance * (pdf / pl * power_heuristic(pl, pdf))
        }
        Weighed::Mixed {
            n,
            r,
            s,
            p,
            spec,
            diff,
        } => {
            let (pg, pd) = (p * gloss_pdf(dir, n, r, s), (1.0 - p) * (cos_s / PI));
            radiance * (spec * pg + diff * pd) * (power_heuristic(pl, pg + pd) / pl)
        }
    }
}

/// The density of the lobe light sampling weighs at direction `dir` that the path drew (its
/// MIS weight against light samples; trace.wgsl: path_step): the lecture's lobes' (glTF's BRDF
/// gives its own).
fn lobe_pdf(lobe: Weighed, dir: Vec3A, ns: Vec3A) -> f32 {
    let cosine = dir.dot(ns).max(0.0) / PI;
    match lobe {
        Weighed::Gloss { n, r, s } => gloss_pdf(dir, n, r, s),
        Weighed::Mixed { n, r, s, p, .. } => p * gloss_pdf(dir, n, r, s) + (1.0 - p) * cosine,
        _ => cosine,
    }
}

pub(super) fn sphere_center(s: &Sphere) -> Vec3A {
    s.anchor - s.radius.abs() * s.anchor_normal
}

fn cone_one_minus_cos(r2: f32, dist2: f32) -> f32 {
    let sin2 = r2 / dist2;
    sin2 / (1.0 + (1.0 - sin2).max(0.0).sqrt())
}

/// Traces paths through one scene with one feature set.
pub struct Tracer<'a> {
    s: &'a CpuScene,
    f: Features,
    pub tally: Tally,
    stack: Stack,
    #[cfg(target_arch = "x86_64")]
    stack8: Stack8,
    /// The packet walk of camera rays, where it applies (see `camera_hits`).
    #[cfg(target_arch = "x86_64")]
    packets: Option<Packets>,
}

impl<'a> Tracer<'a> {
    pub fn new(s: &'a CpuScene, f: Features) -> Tracer<'a> {
        Tracer {
            s,
            f,
            tally: Tally::default(),
            stack: Stack::default(),
            #[cfg(target_arch = "x86_64")]
            stack8: Stack8::default(),
            #[cfg(target_arch = "x86_64")]
            packets: Packets::new(),
        }
    }

    /// The nearest hits of up to eight camera rays walked as one packet (spheres-only scenes
    /// on a CPU with AVX), or None where packets do not apply and each ray walks alone.
    #[inline(always)]
    pub fn camera_hits<const P: u32>(
        &mut self,
        rays: &[Option<Ray>; LANES],
    ) -> Option<[Option<(f32, u32)>; LANES]> {
        #[cfg(target_arch = "x86_64")]
        if P == SPHERES && self.f.bvh {
            let s = self.s;
            if let Some(p) = self.packets.as_mut() {
                return Some(p.closest(&s.bvh, &s.spheres, rays, T_FAR, &mut self.tally));
            }
        }
        let _ = rays;
        None
    }

    /// Every primitive's reference, for the walk without a BVH.
    fn all_refs(&self) -> impl Iterator<Item = u32> + use<'a> {
        let s = self.s;
        let counts = [
            s.spheres.len(),
            s.quads.len(),
            s.boxes.len(),
            s.top_triangles,
        ];
        (0..4u32)
            .flat_map(move |k| (0..counts[k as usize] as u32).map(move |i| k << 30 | i))
            .chain((0..s.instances.len() as u32).map(|i| 3 << 30 | INSTANCE_BIT | i))
    }

    /// The nearest hit of `ray`, primitive `skip` left out (the one the ray leaves, where it
    /// cannot be hit again: `NONE` for none).
    #[inline(always)]
    fn intersect<const P: u32>(&mut self, ray: &Ray, skip: u32) -> Option<Hit> {
        let s = self.s;
        if !self.f.bvh {
            let mut best: Option<Hit> = None;
            for r in self.all_refs().filter(|&r| r != skip) {
                let t = hit_primitive::<P>(s, r, ray, best.map_or(T_FAR, |h| h.t));
                if t > 0.0 {
                    best = Some(hit_of(t, r));
                }
            }
            return best;
        }
        #[cfg(target_arch = "x86_64")]
        if let (Some(few), Some(b8)) = (&s.few, &s.bvh8) {
            // SAFETY: `bvh8` exists only where the CPU has AVX.
            let (hit, tests) = unsafe { few.closest(b8, ray, T_FAR, skip) };
            self.tally.visits += 1;
            self.tally.tests += tests;
            return hit.map(|(t, r)| hit_of(t, r));
        }
        // Walks count the primitives of the leaves they enter as tested; the one skipped is
        // not.
        let mut skipped = 0;
        let hit = self.walk_closest(
            ray,
            skip,
            #[inline(always)]
            |r, t| hit_except::<P>(s, r, ray, t, skip, &mut skipped),
        );
        self.tally.tests -= skipped;
        if !s.instances.is_empty() {
            INSTANCE_WALK.with(|w| {
                let w = &mut w.borrow_mut().tally;
                self.tally.visits += std::mem::take(&mut w.visits);
                self.tally.tests += std::mem::take(&mut w.tests);
            });
        }
        hit.map(|(t, r)| hit_of(t, r))
    }

    /// The nearest hit the BVH walk finds, `test` giving a primitive's (but `skip`'s): through
    /// the eight-wide nodes where the CPU has AVX (their leaves of triangles tested eight at a
    /// time, `CpuScene::leaves`), else the four-wide ones. The tests `skip` took are taken
    /// off the tally here where eight at a time, by `test` elsewhere.
    #[inline(always)]
    fn walk_closest(
        &mut self,
        ray: &Ray,
        skip: u32,
        test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        let s = self.s;
        #[cfg(not(target_arch = "x86_64"))]
        let _ = skip;
        #[cfg(target_arch = "x86_64")]
        if let Some(b8) = &s.bvh8 {
            let mut leaves = s.leaves(skip, NONE);
            // SAFETY: `bvh8` exists only where the CPU has AVX.
            let hit = unsafe {
                b8.closest_in(
                    &s.bvh.refs,
                    ray,
                    T_FAR,
                    &mut self.tally,
                    &mut self.stack8,
                    &mut leaves,
                    test,
                )
            };
            self.tally.tests -= leaves.skipped;
            return hit;
        }
        s.bvh
            .closest(ray, T_FAR, &mut self.tally, &mut self.stack, test)
    }

    /// Whether anything but primitives `skip` and `from` lies on the ray before t_max.
    #[inline(always)]
    pub(super) fn occluded<const P: u32>(
        &mut self,
        ray: &Ray,
        t_max: f32,
        skip: u32,
        from: u32,
    ) -> bool {
        let s = self.s;
        if !self.f.bvh {
            return self
                .all_refs()
                .any(|r| blocks::<P>(s, r, ray, t_max, (skip, from)));
        }
        #[cfg(target_arch = "x86_64")]
        if let (Some(few), Some(b8)) = (&s.few, &s.bvh8) {
            // SAFETY: `bvh8` exists only where the CPU has AVX.
            let (hit, tests) = unsafe { few.any(b8, ray, t_max, skip, from) };
            self.tally.visits += 1;
            self.tally.tests += tests;
            return hit;
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(b8) = &s.bvh8 {
            // SAFETY: `bvh8` exists only where the CPU has AVX.
            return unsafe {
                b8.any_in(
                    &s.bvh.refs,
                    ray,
                    t_max,
                    &mut self.tally,
                    &mut self.stack8,
                    &s.leaves(skip, from),
                    #[inline(always)]
                    |r| blocks::<P>(s, r, ray, t_max, (skip, from)),
                )
            };
        }
        s.bvh.any(
            ray,
            t_max,
            &mut self.tally,
            &mut self.stack,
            #[inline(always)]
            |r| blocks::<P>(s, r, ray, t_max, (skip, from)),
        )
    }

    /// `occluded` where the lanes have visited the eight-wide tree's root: `slots` are its
    /// slots the ray enters before t_max, less the leaves the lanes tested
    /// (`Bvh8::any_below_root`). A scene of no instances whose tree is eight wide.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn occluded_below_root(
        &mut self,
        ray: &Ray,
        t_max: f32,
        (skip, from): (u32, u32),
        slots: u32,
    ) -> bool {
        let s = self.s;
        let b8 = s
            .bvh8
            .as_ref()
            .expect("the lanes' root is an eight-wide tree's");
        // SAFETY: `bvh8` exists only where the CPU has AVX.
        unsafe {
            b8.any_below_root(
                &s.bvh.refs,
                ray,
                (t_max, slots),
                &mut self.tally,
                &mut self.stack8,
                &s.leaves(skip, from),
                #[inline(always)]
                |r| blocks::<ANY>(s, r, ray, t_max, (skip, from)),
            )
        }
    }

    /// A glTF material's texture maps applied at a textured hit (`None` elsewhere: the
    /// material as it is), and where they were read, for the normal map (trace.wgsl's
    /// `material_at`).
    #[inline(always)]
    fn material_at(
        &self,
        hit: Hit,
        local: Vec3A,
        material: u32,
    ) -> (Option<Material>, Option<Mapped>) {
        if self.s.tex.is_empty() || hit.r >> 30 != 3 {
            return (None, None);
        }
        let Some(rec) = super::texture::record(&self.s.tex, material) else {
            return (None, None);
        };
        let i = hit.r & INDEX;
        let tri = &self.s.triangles[i as usize];
        let bary = triangle_barycentrics(tri, local - tri.v0);
        let uv = super::texture::uv_at(&self.s.tex, i, bary);
        let m = &self.s.materials[material as usize];
        (
            Some(super::texture::material(&self.s.tex, m, rec, uv)),
            Some(Mapped { rec, bary, uv }),
        )
    }

    /// The shading normal on the side of `n` at `p`: a normal map's where the hit has one
    /// (docs/MODEL-NOTES.md, "Normal maps"), else the file's normals interpolated where its
    /// mesh has them ("Smooth shading"), else `n` (trace.wgsl's `shading_normal_at`).
    #[inline(always)]
    fn shading_normal_at(
        &self,
        hit: Hit,
        mapped: Option<Mapped>,
        p: Vec3A,
        n_out: Vec3A,
        n: Vec3A,
    ) -> Vec3A {
        let i = hit.r & INDEX;
        // An instance's frames are its mesh's, brought into the world by its normal matrix.
        let inst = self.s.instances.get(hit.inst as usize);
        let n_geo = match inst {
            Some(_) => {
                let tri = &self.s.triangles[i as usize];
                tri.e1.cross(tri.e2).normalize()
            }
            None => n_out,
        };
        let toward = |ns: Vec3A| if ns.dot(n) < 0.0 { -ns } else { ns };
        let tex = &self.s.tex;
        if self.s.normal_maps
            && let Some(Mapped { rec, bary, uv }) = mapped
            && super::texture::has_normal_map(tex, rec)
        {
            toward(match inst {
                // The frame brought into the world first, as a flattened mesh's frames are.
                Some(m) => {
                    let nw = instance_normal(m, super::texture::smooth_normal(tex, i, bary, n_geo));
                    let tw = instance_tangent(m, super::texture::tangent(tex, i, bary));
                    super::texture::perturbed(tex, rec, uv, nw, tw)
                }
                None => super::texture::shading_normal(tex, rec, i, bary, uv, n_geo),
            })
        } else if self.s.smooth_normals
            && hit.r >> 30 == 3
            && super::texture::has_frames(&self.s.tex)
        {
            let bary = match mapped {
                Some(m) => m.bary,
                None => {
                    let tri = &self.s.triangles[i as usize];
                    triangle_barycentrics(tri, p - tri.v0)
                }
            };
            let ns = super::texture::smooth_normal(tex, i, bary, n_geo);
            toward(inst.map_or(ns, |m| instance_normal(m, ns)))
        } else {
            n
        }
    }

    /// The hit's surface point, its material, and the point in its mesh's coordinates (an
    /// instance's; elsewhere the point itself), as trace.wgsl's `surface_at`.
    #[inline(always)]
    fn surface_at(&self, hit: Hit, ray: &Ray) -> (SurfacePoint, u32, Vec3A) {
        let s = self.s;
        let i = (hit.r & INDEX) as usize;
        let (p, m) = match hit.r >> 30 {
            0 => (
                sphere_surface(&s.spheres[i], ray, hit.t),
                s.spheres[i].material,
            ),
            1 => (quad_surface(&s.quads[i], ray, hit.t), s.quads[i].material),
            2 => (box_surface(&s.boxes[i], ray, hit.t), s.boxes[i].material),
            _ if hit.inst != NONE => {
                let inst = &s.instances[hit.inst as usize];
                let local = triangle_surface(&s.triangles[i], &instance_ray(inst, ray), hit.t);
                let world = SurfacePoint {
                    position: instance_point(inst, local.position),
                    normal: instance_normal(inst, local.normal),
                };
                return (world, s.triangles[i].material, local.position);
            }
            _ => (
                triangle_surface(&s.triangles[i], ray, hit.t),
                s.triangles[i].material,
            ),
        };
        (p, m, p.position)
    }

    /// The gradient sky with optional sun, or a uniform sky (MODEL.md "Sky").
    fn sky(&self, dir: Vec3A) -> Vec3A {
        let u = &self.s.u;
        if u.sky_uniform {
            return u.sky_bottom;
        }
        let t = 0.5 * (dir.y + 1.0);
        let mut c = (1.0 - t) * u.sky_bottom + t * u.sky_top;
        if self.f.sun {
            let cz = u.sun_dir.dot(dir).max(0.0);
            if cz > 0.0 {
                c += u.sun_radiance * cz.powf(u.sun_size);
            }
        }
        c
    }

    /// The probability that light sampling picks the environment map (0 without one).
    #[inline(always)]
    fn env_pick(&self) -> f32 {
        if self.f.env_map {
            self.s.u.env_pick
        } else {
            0.0
        }
    }

    /// What a ray that leaves the scene sees (trace.wgsl: escaped): the environment map,
    /// MIS-weighted where light sampling could have found its direction, or the sky.
    /// `mirrored`: where the ray left a mirror sphere of `mirrors` right after a lobe light
    /// sampling weighs, that lobe's density and the sphere's spread there (`MirrorHit`), so
    /// that the map seen in the mirror is weighed against `sample_mirror`.
    fn escaped(
        &self,
        dir: Vec3A,
        bounce: u32,
        prev_pdf: f32,
        mirrored: Option<MirrorHit>,
        lensed: Option<LensPath>,
    ) -> Vec3A {
        let u = &self.s.u;
        if let Some(map) = self.s.env.as_ref().filter(|_| self.f.env_map)
            && u.env_mode != ENV_NONE
            && (bounce > 0 || u.env_mode == ENV_VISIBLE)
        {
            // The map coordinates once, for the radiance and the density.
            let (cu, cv) =
                crate::scene::envmap_sampling::coordinates(glam::Vec3::from(dir), u.env_rotation);
            let l = Vec3A::from_array(map.radiance_at(cu, cv)) * u.env_intensity;
            let pe = self.env_pick();
            if self.f.nee && prev_pdf > 0.0 && pe > 0.0 {
                let pl = pe * map.distribution.pdf_at(cu, cv);
                return l * power_heuristic(prev_pdf, pl);
            }
            if let Some(h) = mirrored {
                let pl = self.mirror_pdf(map.distribution.pdf_at(cu, cv), h.spread);
                return l * power_heuristic(h.pdf, pl);
            }
            if let Some(h) = lensed.filter(|h| h.stage == 4)
                && let Some(spread) = self.lens_spread(&h, dir)
            {
                let pl = self.lens_pdf(map.distribution.pdf_at(cu, cv), spread);
                return l * power_heuristic(h.pdf, pl);
            }
            return l;
        }
        self.sky(dir)
    }

    /// The environment map's share of `sample_light`, picked with probability `pe`
    /// (trace.wgsl: sample_env).
    #[allow(clippy::too_many_arguments)]
    fn sample_env<const P: u32>(
        &mut self,
        p: Vec3A,
        n: Vec3A,
        n_geo: Vec3A,
        from: (u32, u32),
        pe: f32,
        lobe: Weighed,
        rng: &mut Rng,
    ) -> Vec3A {
        let Some(map) = self.s.env.as_ref() else {
            return Vec3A::ZERO;
        };
        let u = &self.s.u;
        let (u1, u2) = rng.rand2();
        let s = map.distribution.sample(u1, u2, u.env_rotation);
        let dir = Vec3A::from(s.dir);
        let cos_s = n.dot(dir);
        if s.pdf <= 0.0 {
            return Vec3A::ZERO;
        }
        let Some((side, from)) = self.shadow_side(cos_s, n_geo, dir, lobe, from) else {
            return Vec3A::ZERO;
        };
        let radiance = Vec3A::from_array(map.radiance_at(s.uv.0, s.uv.1)) * u.env_intensity;
        let shadow = Ray {
            origin: offset_ray(p, side),
            dir,
        };
        if self.occluded::<P>(&shadow, T_FAR, NONE, from) {
            return Vec3A::ZERO;
        }
        light_weighted(radiance, dir, cos_s, pe * s.pdf, lobe)
    }

    /// The density, in solid angle at the point that sees it, with which `sample_mirror`
    /// finds the map's direction of density `pdf` in a mirror sphere of spread `spread`.
    #[inline(always)]
    fn mirror_pdf(&self, pdf: f32, spread: f32) -> f32 {
        pdf / (self.s.reflectors.len() as f32 * spread)
    }

    /// The density, in solid angle at the point that sees it, with which `sample_lens` finds
    /// the map's direction of density `pdf` through a glass sphere of spread `spread`.
    #[inline(always)]
    fn lens_pdf(&self, pdf: f32, spread: f32) -> f32 {
        pdf / (self.s.lenses.len() as f32 * spread)
    }

    /// The spread of path `h`, which left its sphere toward `dir`, where `sample_lens` finds
    /// it (`lens::spread_of`), else None.
    fn lens_spread(&self, h: &LensPath, dir: Vec3A) -> Option<f32> {
        let s = &self.s.spheres[h.sphere as usize];
        let c = sphere_center(s);
        let ior = self.s.materials[s.material as usize].ior;
        let f = lens::Frame {
            inner: h.inner as u32,
            ..lens::frame(h.from, c, s.radius, ior, dir)?
        };
        lens::spread_of(&f, h.from, c, s.radius, h.dir)
    }

    /// The glass-sphere path `lensed` after the ray met `hit` (`scattered` false) or after
    /// the surface there scattered it toward `dir` (`scattered` true): a ray of a lobe light
    /// sampling weighs (`prev_pdf` > 0, from `prev_point`; or a camera ray, `sample_view`)
    /// that meets one of `lenses` from outside starts one; it goes on while the ray refracts
    /// into the sphere, meets it from inside, reflects there at most once and refracts out,
    /// and ends at anything else (trace.wgsl: lens_step).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn lens_step(
        &self,
        lensed: Option<LensPath>,
        hit: Hit,
        ray: &Ray,
        n_out: Vec3A,
        prev_pdf: f32,
        prev_point: Vec3A,
        scattered: Option<Vec3A>,
    ) -> Option<LensPath> {
        if !self.f.lens_nee {
            return None;
        }
        let same = |h: &LensPath| hit.r >> 30 == 0 && hit.r & INDEX == h.sphere;
        let inward = |d: Vec3A| d.dot(n_out) < 0.0;
        match (lensed, scattered) {
            (Some(h), Some(d)) if h.stage == 1 && inward(d) => Some(LensPath { stage: 2, ..h }),
            (Some(h), Some(d)) if h.stage == 3 && !inward(d) => Some(LensPath { stage: 4, ..h }),
            (Some(h), Some(_)) if h.stage == 3 && h.inner == 0 => Some(LensPath {
                stage: 2,
                inner: 1,
                ..h
            }),
            (_, Some(_)) => None,
            (Some(h), None) if h.stage == 2 && same(&h) && !inward(ray.dir) => {
                Some(LensPath { stage: 3, ..h })
            }
            (_, None) => {
                let i = hit.r & INDEX;
                (prev_pdf > 0.0
                    && hit.r >> 30 == 0
                    && inward(ray.dir)
                    && self.s.lenses.contains(&i))
                .then_some(LensPath {
                    sphere: i,
                    from: prev_point,
                    dir: ray.dir,
                    pdf: prev_pdf,
                    stage: 1,
                    inner: 0,
                })
            }
        }
    }

    /// The environment map's light as a clear glass sphere refracts it onto p (facing
    /// shading normal n), for the lobe light sampling weighs (or the camera, `view`), as
    /// `sample_mirror` for mirror spheres: one of the scene's glass spheres chosen evenly, a
    /// direction drawn from the map's distribution, and every path from p through the sphere
    /// toward it (`lens::roots`, up to three), and with up to `inner` reflections inside up
    /// to three more, each with its legs unoccluded, carrying the glass's tint at each
    /// interface and the chance that `scatter_dielectric` refracts in, reflects and refracts
    /// out as the path does (`lens::transmittance`), in p's solid angle at the map's density
    /// over the path's spread, MIS-weighted against the lobe, which finds the same paths by
    /// scattering through the sphere (`escaped`). Docs: MODEL-NOTES.md, "The map through a
    /// glass ball" (trace.wgsl: sample_lens).
    #[allow(clippy::too_many_arguments)]
    fn sample_lens<const P: u32>(
        &mut self,
        p: Vec3A,
        n: Vec3A,
        n_geo: Vec3A,
        from: u32,
        lobe: Weighed,
        view: Option<(u32, u32)>,
        inner: u32,
        rng: &mut Rng,
    ) -> Vec3A {
        let Some(map) = self.s.env.as_ref() else {
            return Vec3A::ZERO;
        };
        let count = self.s.lenses.len();
        let pick = if count > 1 { rng.rand() } else { 0.0 };
        let i = self.s.lenses[((pick * count as f32) as usize).min(count - 1)];
        let sphere = self.s.spheres[i as usize];
        let (c, r) = (sphere_center(&sphere), sphere.radius);
        if n.dot(c - p) <= -r {
            return Vec3A::ZERO;
        }
        let u = &self.s.u;
        let (u1, u2) = rng.rand2();
        let smp = map.distribution.sample(u1, u2, u.env_rotation);
        let w = Vec3A::from(smp.dir);
        let m = &self.s.materials[sphere.material as usize];
        if smp.pdf <= 0.0 {
            return Vec3A::ZERO;
        }
        let Some(through) = lens::frame(p, c, r, m.ior, w) else {
            return Vec3A::ZERO;
        };
        // The map's radiance once, where a path reaches it.
        let mut radiance = None;
        let mut sum = Vec3A::ZERO;
        for inner in 0..=inner {
            let f = lens::Frame { inner, ..through };
            let (roots, found, _) = lens::roots(&f);
            for &s in &roots[..found] {
                let Some(x) = lens::path(&f, p, c, r, s) else {
                    continue;
                };
                let cos_s = n.dot(x.dir);
                if cos_s <= 0.0 || (self.s.shading_normals() && n_geo.dot(x.dir) <= 0.0) {
                    continue;
                }
                // To the sphere (the first thing the ray meets must be it), across it (twice,
                // with a reflection inside), and from where it leaves to the map.
                let to_lens = Ray {
                    origin: offset_ray(p, n_geo),
                    dir: x.dir,
                };
                let t_lens = hit_primitive::<ANY>(self.s, i, &to_lens, T_FAR);
                if t_lens <= 0.0 || self.occluded::<P>(&to_lens, t_lens, i, from) {
                    continue;
                }
                let entry = p + x.dir * x.dist;
                let chord = x.turn - entry;
                let across = Ray {
                    origin: entry,
                    dir: chord.normalize(),
                };
                // The path's length inside, where the medium attenuates it.
                let mut inside = chord.length();
                if self.occluded::<P>(&across, inside, i, i) {
                    continue;
                }
                if inner > 0 {
                    let back = x.exit - x.turn;
                    let across = Ray {
                        origin: x.turn,
                        dir: back.normalize(),
                    };
                    let length = back.length();
                    if self.occluded::<P>(&across, length, i, i) {
                        continue;
                    }
                    inside += length;
                }
                let to_map = Ray {
                    origin: offset_ray(x.exit, x.exit_normal),
                    dir: w,
                };
                if self.occluded::<P>(&to_map, T_FAR, NONE, i) {
                    continue;
                }
                let l = *radiance.get_or_insert_with(|| {
                    Vec3A::from_array(map.radiance_at(smp.uv.0, smp.uv.1)) * u.env_intensity
                });
                let carried = if self.follows_pbr(m) {
                    // glTF's: its Fresnel, share and tint at each interface, and the
                    // medium's attenuation over the path inside (KHR_materials_volume).
                    l * pbr::lens_transmittance(m, x.cos_i, x.cos_r, inner)
                        * (-m.attenuation * inside).exp()
                } else {
                    // The lecture's: its tint at each interface, once more at the reflection.
                    let tint = if inner > 0 { m.color } else { Vec3A::ONE };
                    l * m.color
                        * m.color
                        * tint
                        * lens::transmittance(m.ior, x.cos_i, x.cos_r, inner)
                };
                sum += self.weighed(
                    carried,
                    p,
                    x.dir,
                    cos_s,
                    self.lens_pdf(smp.pdf, x.spread),
                    lobe,
                    view,
                );
            }
        }
        sum
    }

    /// Whether material `m`'s surface follows glTF's BRDF (`cpu::pbr`) rather than the
    /// lecture's lobes: a scene of glTF materials alone has no lecture (trace.wgsl:
    /// follows_pbr).
    #[inline(always)]
    fn follows_pbr(&self, m: &Material) -> bool {
        self.f.pbr && (!self.f.lecture || m.pbr)
    }

    /// Where a ray from a lobe that light sampling weighs (`prev_pdf` > 0, from
    /// `prev_point`) meets one of the mirror spheres `sample_mirror` samples from outside:
    /// its lobe's density and the sphere's spread (`mirror::spread`) there, else None
    /// (trace.wgsl: mirror_hit).
    #[inline(always)]
    fn mirror_hit(
        &self,
        hit: Hit,
        ray: &Ray,
        point: &SurfacePoint,
        prev_pdf: f32,
        prev_point: Vec3A,
    ) -> Option<MirrorHit> {
        if !(self.f.mirror_nee && prev_pdf > 0.0 && hit.r >> 30 == 0) {
            return None;
        }
        let i = hit.r & INDEX;
        if !self.s.reflectors.contains(&i) {
            return None;
        }
        let s = &self.s.spheres[i as usize];
        let cos_i = -ray.dir.dot(point.normal);
        let spread = mirror::spread(s.radius, (point.position - prev_point).length(), cos_i);
        (cos_i > 0.0 && spread > 0.0).then_some(MirrorHit {
            pdf: prev_pdf,
            spread,
        })
    }

    /// The environment map's light as a mirror sphere reflects it onto p (facing shading
    /// normal n), for the lobe light sampling weighs (its 1/π included and its tint not, as
    /// `sample_light`): one of the scene's mirror spheres chosen evenly, a direction drawn
    /// from the map's distribution, the point of the sphere that reflects it to p
    /// (`mirror::point`), both legs unoccluded; in p's solid angle the density is the map's
    /// over the sphere's spread (`mirror::spread`), MIS-weighted against the lobe, which finds
    /// the same paths by scattering into the mirror (`escaped`). Docs: MODEL-NOTES.md, "The
    /// map in a mirror ball" (trace.wgsl: sample_mirror).
    #[allow(clippy::too_many_arguments)]
    fn sample_mirror<const P: u32>(
        &mut self,
        p: Vec3A,
        n: Vec3A,
        n_geo: Vec3A,
        from: u32,
        lobe: Weighed,
        view: Option<(u32, u32)>,
        rng: &mut Rng,
    ) -> Vec3A {
        let Some(map) = self.s.env.as_ref() else {
            return Vec3A::ZERO;
        };
        let count = self.s.reflectors.len();
        let pick = if count > 1 { rng.rand() } else { 0.0 };
        let i = self.s.reflectors[((pick * count as f32) as usize).min(count - 1)];
        let sphere = self.s.spheres[i as usize];
        let c = sphere_center(&sphere);
        // A sphere wholly behind the surface reflects nothing onto it.
        if n.dot(c - p) <= -sphere.radius {
            return Vec3A::ZERO;
        }
        let u = &self.s.u;
        let (u1, u2) = rng.rand2();
        let smp = map.distribution.sample(u1, u2, u.env_rotation);
        if smp.pdf <= 0.0 {
            return Vec3A::ZERO;
        }
        let Some(x) = mirror::point(p, c, sphere.radius, Vec3A::from(smp.dir)) else {
            return Vec3A::ZERO;
        };
        let cos_s = n.dot(x.dir);
        if cos_s <= 0.0 || (self.s.shading_normals() && n_geo.dot(x.dir) <= 0.0) {
            return Vec3A::ZERO;
        }
        let spread = mirror::spread(sphere.radius, x.dist, x.cos_i);
        if spread.is_nan() || spread <= 0.0 {
            return Vec3A::ZERO;
        }
        // To the sphere (the first thing the ray meets must be it), then from its point to
        // the map.
        let to_mirror = Ray {
            origin: offset_ray(p, n_geo),
            dir: x.dir,
        };
        let t_mirror = hit_primitive::<ANY>(self.s, i, &to_mirror, T_FAR);
        if t_mirror <= 0.0 || self.occluded::<P>(&to_mirror, t_mirror, i, from) {
            return Vec3A::ZERO;
        }
        let to_map = Ray {
            origin: offset_ray(p + x.dir * x.dist, x.normal),
            dir: Vec3A::from(smp.dir),
        };
        if self.occluded::<P>(&to_map, T_FAR, NONE, i) {
            return Vec3A::ZERO;
        }
        // What the mirror reflects: the lecture's specular tint, or glTF's Fresnel at the
        // angle of incidence; glass, the chance that `scatter_dielectric` reflects there
        // (Schlick's Fresnel) and its tint.
        let m = &self.s.materials[sphere.material as usize];
        let reflectance = if m.smoothness < 0.0 {
            m.color * schlick(x.cos_i, 1.0 / m.ior)
        } else if self.follows_pbr(m) {
            pbr::mirror_reflectance(&pbr::lobe(m, -x.dir, x.normal, true), x.cos_i)
        } else {
            m.specular_color
        };
        let radiance =
            Vec3A::from_array(map.radiance_at(smp.uv.0, smp.uv.1)) * u.env_intensity * reflectance;
        self.weighed(
            radiance,
            p,
            x.dir,
            cos_s,
            self.mirror_pdf(smp.pdf, spread),
            lobe,
            view,
        )
    }

    /// Primitive `r` where a ray leaving its surface on the side of its normal (`out`) or
    /// against it cannot meet it again, else NONE. A ray leaving a plane, or a convex primitive
    /// outward, cannot (in exact arithmetic: in floating point its test could only find the
    /// surface the ray starts on, which the ray offset is there to avoid), so its test is
    /// skipped. A sphere's normal points inward where its radius is negative (a hollow one).
    #[inline(always)]
    pub(super) fn leaving(&self, r: u32, out: bool) -> u32 {
        match r >> 30 {
            0 => {
                let outward = self.s.spheres[(r & INDEX) as usize].radius > 0.0;
                if out == outward { r } else { NONE }
            }
            2 if !out => NONE,
            _ => r,
        }
    }

    /// Thin-lens camera through the jittered pixel (Shirley, Ray Tracing in One Weekend §13).
    #[inline(always)]
    pub fn camera_ray(&self, x: u32, y: u32, rng: &mut Rng) -> Ray {
        let u = &self.s.u;
        let (jx, jy) = rng.rand2();
        let s = (x as f32 + jx) / u.width as f32;
        let t = (y as f32 + jy) / u.height as f32;
        let target = u.cam_to_corner + s * u.cam_horizontal - t * u.cam_vertical;
        let mut lens = Vec3A::ZERO;
        if self.f.dof && u.lens_radius > 0.0 {
            let p = random_in_disk(rng) * u.lens_radius;
            lens = p.x * u.cam_u + p.y * u.cam_v;
        }
        Ray {
            origin: u.cam_origin + lens,
            dir: (target - lens).normalize(),
        }
    }

    /// Where a ray from `origin`, a point of the camera's lens, along unit `dir` crosses the
    /// focus plane, in pixels (x to the right, y down, as `camera_ray` counts them), and the
    /// density in solid angle with which `camera_ray` draws `dir` from `origin` for that
    /// pixel: uniform over the pixel's rectangle of the plane, so distance² over the cosine
    /// and the rectangle's area (pbrt-v4 §5.4.4, the camera's importance); None behind the
    /// plane (trace.wgsl: pixel_at).
    #[inline(always)]
    fn pixel_at(&self, origin: Vec3A, dir: Vec3A) -> Option<(f32, f32, f32)> {
        let u = &self.s.u;
        let (h, v) = (u.cam_horizontal, u.cam_vertical);
        let centre = u.cam_to_corner + 0.5 * h - 0.5 * v;
        let ahead = centre.normalize();
        let cos = dir.dot(ahead);
        if cos <= 0.0 {
            return None;
        }
        // The lens point relative to the camera's origin lies in the lens plane, square to
        // `ahead`.
        let lens = origin - u.cam_origin;
        let dist = (centre - lens).dot(ahead) / cos;
        let q = lens + dist * dir - u.cam_to_corner;
        let (h2, v2) = (h.length_squared(), v.length_squared());
        let (w, ht) = (u.width as f32, u.height as f32);
        let area = (h2 * v2).sqrt() / (w * ht);
        Some((
            q.dot(h) / h2 * w,
            -q.dot(v) / v2 * ht,
            dist * dist / (cos * area),
        ))
    }

    /// A light sample's estimate for the lobe light sampling weighs (`light_weighted`), or,
    /// from the camera (`view`: the pixel, `sample_view`), for that pixel's camera rays
    /// (`view_weighted`) (trace.wgsl: weighed).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn weighed(
        &self,
        radiance: Vec3A,
        p: Vec3A,
        dir: Vec3A,
        cos_s: f32,
        pl: f32,
        lobe: Weighed,
        view: Option<(u32, u32)>,
    ) -> Vec3A {
        match view {
            Some(px) => self.view_weighted(radiance, p, dir, pl, px),
            None => light_weighted(radiance, dir, cos_s, pl, lobe),
        }
    }

    /// A light sample of density `pl` that reaches the camera's lens point `p` along `dir`,
    /// as an estimate of pixel `px`'s value: none where `dir` is not in the pixel, else
    /// radiance · p_c / pl, weighed by the power heuristic against p_c, the density with
    /// which the pixel's camera rays find `dir` (`pixel_at`): radiance / (p_c/pl + pl/p_c),
    /// which neither square overflows (trace.wgsl: view_weighted).
    #[inline(always)]
    fn view_weighted(
        &self,
        radiance: Vec3A,
        p: Vec3A,
        dir: Vec3A,
        pl: f32,
        px: (u32, u32),
    ) -> Vec3A {
        match self.pixel_at(p, dir) {
            Some((x, y, pc))
                if pc > 0.0 && x.floor() == px.0 as f32 && y.floor() == px.1 as f32 =>
            {
                radiance / (pc / pl + pl / pc)
            }
            _ => Vec3A::ZERO,
        }
    }

    /// The environment map's light that the camera sees in the mirror spheres and through
    /// the glass spheres light sampling samples, for pixel `px` whose camera ray is
    /// `primary`: `sample_mirror` and `sample_lens` from the ray's lens point as from a
    /// surface, their paths counted where they cross the focus plane inside the pixel and
    /// weighed against the pixel's camera rays, which find the same paths (`trace_path` weighs
    /// them at the first hit). The sun's image in a ball is smaller than a pixel: camera rays
    /// find it as fireflies, this in every sample. Only where the pixel may see such a sphere
    /// (`view_meets`). Docs: MODEL-NOTES.md, "The map in a mirror ball" and "The map through a
    /// glass ball" (trace.wgsl: sample_view).
    fn sample_view<const P: u32>(&mut self, px: (u32, u32), primary: &Ray, rng: &mut Rng) -> Vec3A {
        let u = &self.s.u;
        let ahead = (u.cam_to_corner + 0.5 * u.cam_horizontal - 0.5 * u.cam_vertical).normalize();
        let o = primary.origin;
        let mut sum = Vec3A::ZERO;
        // Camera, mirror, map: one scattering.
        if self.f.mirror_nee && u.max_bounces >= 1 && self.view_meets(primary, &self.s.reflectors) {
            sum += self.sample_mirror::<P>(o, ahead, ahead, NONE, Weighed::Cosine, Some(px), rng);
        }
        // Camera, into the glass, (a reflection inside,) out, map: two scatterings (three).
        if self.f.lens_nee && u.max_bounces >= 2 && self.view_meets(primary, &self.s.lenses) {
            let inner = (u.max_bounces >= 3) as u32;
            let lobe = Weighed::Cosine;
            sum += self.sample_lens::<P>(o, ahead, ahead, NONE, lobe, Some(px), inner, rng);
        }
        sum
    }

    /// Whether the pixel of camera ray `primary` may see one of `spheres` (the paths
    /// `sample_view` samples begin on the sphere): some sphere's cone from the ray's lens
    /// point meets the cone of the pixel's rays. Those reach the focus plane within the
    /// pixel's diagonal of the ray's point, and the plane is at least the focus distance
    /// away, so they stay within β of the ray, sin β = diagonal / focus distance. The rest of
    /// the image takes no draw and no solve (trace.wgsl: view_meets).
    #[inline(always)]
    fn view_meets(&self, primary: &Ray, spheres: &[u32]) -> bool {
        let u = &self.s.u;
        let (h, v) = (
            u.cam_horizontal / u.width as f32,
            u.cam_vertical / u.height as f32,
        );
        let focus = (u.cam_to_corner + 0.5 * u.cam_horizontal - 0.5 * u.cam_vertical).length();
        let sin_b = ((h.length_squared() + v.length_squared()).sqrt() / focus).min(1.0);
        let cos_b = (1.0 - sin_b * sin_b).sqrt();
        spheres.iter().any(|&i| {
            let s = &self.s.spheres[i as usize];
            let to = sphere_center(s) - primary.origin;
            let d2 = to.length_squared();
            let r2 = s.radius * s.radius;
            if d2 <= r2 {
                return true;
            }
            // cos of the angle to the centre against cos(α + β), α the sphere's half-angle.
            let (sin_a, cos_a) = ((r2 / d2).sqrt(), (1.0 - r2 / d2).sqrt());
            primary.dir.dot(to) >= d2.sqrt() * (cos_a * cos_b - sin_a * sin_b)
        })
    }

    /// Solid-angle density with which light sampling from `origin` picks the direction that
    /// hit light primitive `hit` at `at`.
    fn light_pdf(&self, hit: Hit, origin: Vec3A, at: Vec3A) -> f32 {
        let i = (hit.r & INDEX) as usize;
        match hit.r >> 30 {
            0 => {
                let s = &self.s.spheres[i];
                let d = sphere_center(s) - origin;
                let dist2 = d.dot(d);
                let r2 = s.radius * s.radius;
                if dist2 <= r2 {
                    return 0.0;
                }
                1.0 / (2.0 * PI * cone_one_minus_cos(r2, dist2))
            }
            1 => {
                let q = &self.s.quads[i];
                let to = at - origin;
                let dist2 = to.dot(to);
                let cos_l = q.normal.dot(to).abs() / dist2.sqrt();
                let area = q.u.cross(q.v).length();
                dist2 / (area * cos_l).max(1e-30)
            }
            _ => 0.0,
        }
    }

    /// Whether light sampling also looks below the surface for `lobe`: glTF's BRDF where it
    /// transmits through a rough boundary, whose density there is known (`pbr::eval_through`;
    /// trace.wgsl: transmits). A smooth one's transmission is a delta, which no light sample
    /// can meet.
    #[inline(always)]
    fn transmits(&self, lobe: Weighed) -> bool {
        self.f.pbr_transmission
            && matches!(lobe, Weighed::Pbr(l) if l.transmission > 0.0 && l.alpha >= pbr::ALPHA_MIN)
    }

    /// The side a light sample toward `dir` (cos_s against the shading normal) leaves its
    /// point on, and the primitive it cannot meet (of `from`'s two, `sample_light`): the
    /// facing geometric normal's side where the lobe reflects, the other where it transmits
    /// (`transmits`) and `dir` lies below both normals; None where the lobe sends nothing
    /// toward `dir` (trace.wgsl: shadow_side).
    #[inline(always)]
    fn shadow_side(
        &self,
        cos_s: f32,
        n_geo: Vec3A,
        dir: Vec3A,
        lobe: Weighed,
        from: (u32, u32),
    ) -> Option<(Vec3A, u32)> {
        let normals = self.s.shading_normals();
        if cos_s > 0.0 && !(normals && n_geo.dot(dir) <= 0.0) {
            return Some((n_geo, from.0));
        }
        if cos_s < 0.0 && self.transmits(lobe) && !(normals && n_geo.dot(dir) >= 0.0) {
            return Some((-n_geo, from.1));
        }
        None
    }

    fn light_weight(&self, l: &GpuLight, p: Vec3A, n: Vec3A) -> f32 {
        let i = (l.prim & INDEX) as usize;
        let (center, r2) = if l.prim >> 30 == 0 {
            let s = &self.s.spheres[i];
            (sphere_center(s), s.radius * s.radius)
        } else {
            let q = &self.s.quads[i];
            (q.q + 0.5 * (q.u + q.v), 0.25 * (q.u + q.v).length_squared())
        };
        let to = center - p;
        let d2 = to.dot(to);
        let cos_t = n.dot(to) / d2.max(1e-30).sqrt();
        l.pmf / d2.max(r2) * (BACKFACE_WEIGHT + cos_t.max(0.0))
    }

    fn pick_light_by_power(&self, u: f32) -> usize {
        let lights = &self.s.lights;
        let (mut lo, mut hi) = (0usize, lights.len() - 1);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if lights[mid].cdf > u {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo
    }

    fn choose_light(&self, u: f32, p: Vec3A, n: Vec3A) -> (usize, f32) {
        let lights = &self.s.lights;
        // One light is chosen for certain (its weight over itself), with no weight to
        // compute: 6 % of cornell's time went to computing it twice.
        if self.s.u.n_lights == 1 {
            return (0, 1.0);
        }
        if self.s.u.n_lights > LOCAL_SELECTION_MAX {
            let i = self.pick_light_by_power(u);
            return (i, lights[i].pmf);
        }
        let total: f32 = lights.iter().map(|l| self.light_weight(l, p, n)).sum();
        let target = u * total;
        let mut acc = 0.0;
        for (i, l) in lights.iter().enumerate() {
            let w = self.light_weight(l, p, n);
            acc += w;
            if acc > target || i + 1 == lights.len() {
                return (i, w / total);
            }
        }
        (0, 0.0)
    }

    fn light_choice_pmf(&self, i: usize, p: Vec3A, n: Vec3A) -> f32 {
        let lights = &self.s.lights;
        if self.s.u.n_lights == 1 {
            return 1.0;
        }
        if self.s.u.n_lights > LOCAL_SELECTION_MAX {
            return lights[i].pmf;
        }
        let total: f32 = lights.iter().map(|l| self.light_weight(l, p, n)).sum();
        self.light_weight(&lights[i], p, n) / total
    }

    /// The light-sampled estimate at p (facing shading normal n) for the lobe light sampling
    /// weighs, MIS-weighted (`light_weighted`: the lecture's lobes with their f·cos included
    /// and their tint not). `n_geo`: the facing geometric normal; the shadow ray leaves on its
    /// side, never into it.
    /// `from`: the primitive p lies on, where a shadow ray leaving on n_geo's side (`.0`) or
    /// through the surface (`.1`) cannot meet it (`leaving`).
    /// `lobe`: glTF's BRDF, the lecture's glossy lobe, or the cosine lobe. Where glTF's BRDF
    /// transmits through a rough surface, a light below the surface is sampled too, its shadow
    /// ray leaving on the other side (`shadow_side`).
    fn sample_light<const P: u32>(
        &mut self,
        p: Vec3A,
        n: Vec3A,
        n_geo: Vec3A,
        from: (u32, u32),
        lobe: Weighed,
        rng: &mut Rng,
    ) -> Vec3A {
        // The environment map with probability env_pick, else one of the scene's lights;
        // one light alone is chosen without a draw.
        let pe = self.env_pick();
        let mut pick = if self.s.u.n_lights + (pe > 0.0) as u32 > 1 {
            rng.rand()
        } else {
            0.0
        };
        if pe > 0.0 && pick < pe {
            return self.sample_env::<P>(p, n, n_geo, from, pe, lobe, rng);
        }
        if pe > 0.0 {
            pick = (pick - pe) / (1.0 - pe);
        }
        let (index, pmf) = self.choose_light(pick, p, n);
        if pmf <= 0.0 {
            return Vec3A::ZERO;
        }
        let light = self.s.lights[index];
        let i = (light.prim & INDEX) as usize;
        let (dir, pdf, material);
        if light.prim >> 30 == 0 {
            let s = &self.s.spheres[i];
            let to = sphere_center(s) - p;
            let dist2 = to.dot(to);
            let r2 = s.radius * s.radius;
            let (u1, u2) = rng.rand2();
            if dist2 <= r2 {
                return Vec3A::ZERO;
            }
            let one_minus = cone_one_minus_cos(r2, dist2);
            let cos_t = 1.0 - u1 * one_minus;
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let (sp, cp) = sin_cos_turns(u2);
            let b = basis(to / dist2.sqrt());
            dir = (b[0] * (sin_t * cp) + b[1] * (sin_t * sp) + b[2] * cos_t).normalize();
            pdf = 1.0 / (2.0 * PI * one_minus);
            material = s.material;
        } else {
            let q = &self.s.quads[i];
            let (a, b) = rng.rand2();
            let x = q.q + a * q.u + b * q.v;
            let to = x - p;
            let dist2 = to.dot(to);
            dir = to / dist2.sqrt();
            let cos_l = q.normal.dot(dir).abs();
            if cos_l < 1e-6 {
                return Vec3A::ZERO;
            }
            pdf = dist2 / (light.area * cos_l);
            material = q.material;
        }
        let cos_s = n.dot(dir);
        let Some((side, from)) = self.shadow_side(cos_s, n_geo, dir, lobe, from) else {
            return Vec3A::ZERO;
        };
        let shadow = Ray {
            origin: offset_ray(p, side),
            dir,
        };
        let t_light = hit_primitive::<ANY>(self.s, light.prim, &shadow, T_FAR);
        if t_light <= 0.0 || self.occluded::<P>(&shadow, t_light, light.prim, from) {
            return Vec3A::ZERO;
        }
        let m = &self.s.materials[material as usize];
        light_weighted(m.color * m.light, dir, cos_s, (1.0 - pe) * pmf * pdf, lobe)
    }

    /// One path: its radiance and the segments it traced. Inlined, as the tests of the
    /// primitives and the scattering are: 7 % more samples/s on `weekend` than calls.
    #[inline(always)]
    ///
    /// `first`: the camera ray's nearest hit where a packet walk has found it already (`Some`
    /// of the (t, reference) or of None for a miss), else None.
    pub fn trace_path<const P: u32, const NEE: bool>(
        &mut self,
        px: (u32, u32),
        primary: Ray,
        mut first: Option<Option<(f32, u32)>>,
        rng: &mut Rng,
    ) -> (Vec3A, u32) {
        let u = self.s.u;
        let mut ray = primary;
        let mut throughput = Vec3A::ONE;
        let mut radiance = Vec3A::ZERO;
        let mut segments = 0;
        let nee = NEE && (u.n_lights > 0 || self.env_pick() > 0.0);
        let mut prev_pdf = 0.0;
        let mut prev_point = ray.origin;
        let mut prev_normal = Vec3A::Y;
        // The last bounce ran no mirror or lens sampler for the direction it drew: drawn
        // through the surface (glTF's transmission), or from inside a volume (`inside`).
        let mut prev_unsampled = false;
        let mut bounce = 0;
        // The primitive the ray leaves, where it cannot meet it again.
        let mut skip = NONE;
        // The ray leaves a mirror sphere that `sample_mirror` samples (`mirror_hit`).
        let mut mirrored = None;
        // The ray is on a path through a glass sphere that `sample_lens` samples (`lens_step`).
        let mut lensed = None;
        // The map in the mirror spheres, seen from the camera (`sample_view`), and the density
        // with which the camera ray was drawn, that weighs its own such paths at the first
        // hit; 0 without.
        let mut view_pdf = 0.0;
        if nee && (self.f.mirror_nee || self.f.lens_nee) {
            radiance += self.sample_view::<P>(px, &primary, rng);
            view_pdf = self
                .pixel_at(primary.origin, primary.dir)
                .map_or(0.0, |v| v.2);
        }
        while bounce <= u.max_bounces {
            segments += 1;
            #[cfg(test)]
            RECORD.with(|r| {
                if let Some(v) = r.borrow_mut().as_mut() {
                    v.push((bounce, ray));
                }
            });
            let found = match first.take() {
                Some(known) => known.map(|(t, r)| Hit { t, r, inst: NONE }),
                None => self.intersect::<P>(&ray, skip),
            };
            let Some(hit) = found else {
                radiance += throughput * self.escaped(ray.dir, bounce, prev_pdf, mirrored, lensed);
                break;
            };
            let (point, material, local) = self.surface_at(hit, &ray);
            // A mirror sphere met from a lobe light sampling weighs: what it reflects from
            // the map next is weighed against `sample_mirror`.
            // The camera ray's density stands for a lobe's at the first hit.
            // A ray drawn through a surface is none that those samplers find (they sample on
            // the side of the normal), nor one drawn inside a volume, where they do not run.
            // Without light sampling (switched off) no sampler finds them: the lobe's paths
            // are the only ones, and weigh 1.
            let drawn = if !nee {
                0.0
            } else if bounce == 0 {
                view_pdf
            } else if prev_unsampled {
                0.0
            } else {
                prev_pdf
            };
            mirrored = self.mirror_hit(hit, &ray, &point, drawn, prev_point);
            lensed = self.lens_step(lensed, hit, &ray, point.normal, drawn, prev_point, None);
            let (textured, mapped) = self.material_at(hit, local, material);
            let m = textured
                .as_ref()
                .unwrap_or(&self.s.materials[material as usize]);
            // Inside a volume's boundary the medium attenuates, by Beer–Lambert's law over the
            // segment's length (KHR_materials_volume; a closed mesh, not nested).
            if self.f.pbr_transmission && m.transmission > 0.0 && ray.dir.dot(point.normal) > 0.0 {
                throughput *= (-m.attenuation * hit.t).exp();
            }
            if self.f.emitters && m.light > 0.0 {
                let mut w = 1.0;
                if nee && prev_pdf > 0.0 && m.light_slot > 0 {
                    let choice = (1.0 - self.env_pick())
                        * self.light_choice_pmf(m.light_slot as usize - 1, prev_point, prev_normal);
                    let pl = choice * self.light_pdf(hit, prev_point, point.position);
                    w = power_heuristic(prev_pdf, pl);
                }
                radiance += throughput * m.color * m.light * w;
                break;
            }
            if bounce == u.max_bounces {
                break;
            }
            let n_out = point.normal;
            let mut sc: Scatter;
            prev_pdf = 0.0;
            prev_unsampled = false;
            if self.f.dielectrics && m.smoothness < 0.0 {
                sc = scatter_dielectric(m, ray.dir, n_out, rng);
                lensed =
                    self.lens_step(lensed, hit, &ray, n_out, prev_pdf, prev_point, Some(sc.dir));
            } else {
                // The lecture's lobes, or glTF's BRDF (cpu::pbr), with one light-sampling
                // call for both (trace.wgsl: path_step).
                let pbr = self.follows_pbr(m);
                // A certain lobe takes no draw.
                let is_spec =
                    !pbr && (m.specular >= 1.0 || (m.specular > 0.0 && rng.rand() < m.specular));
                let front = ray.dir.dot(n_out) < 0.0;
                let n = if front { n_out } else { -n_out };
                // The shading normal, on the side of n.
                let ns = self.shading_normal_at(hit, mapped, local, n_out, n);
                let lobe = pbr.then(|| pbr::lobe(m, -ray.dir, ns, front));
                // Inside a volume's boundary (a solid: closed, not nested) the mirror and lens
                // spheres lie beyond the surface, which the shadow rays on this side meet first:
                // those samplers would find nothing here, and do not run.
                let inside = pbr && !front && m.transmission > 0.0 && !m.thin;
                // The lecture's glossy lobe: the specular one blended with the diffuse
                // direction, without fuzz (`Material::is_glossy`). Taken at a probability
                // below 1, light sampling weighs its mixture with the cosine lobe whichever
                // lobe was drawn (`Weighed::Mixed`).
                let glossy = self.f.gloss_nee
                    && !pbr
                    && m.specular > 0.0
                    && m.smoothness > 0.0
                    && m.smoothness < 1.0
                    && m.absorption == 0.0;
                let mixed = glossy && m.specular < 1.0;
                let gloss = glossy && !mixed;
                // A lobe with a density light sampling can weigh: the Lambertian one, the
                // lecture's specular one at smoothness 0 or glossy, or glTF's but for its
                // mirror and, where it transmits wholly (no diffuse share), its glass; a
                // rough clear coat has one over either.
                let light_lobe = match &lobe {
                    Some(l) => {
                        l.alpha >= pbr::ALPHA_MIN
                            || (l.p_spec < 1.0 && l.transmission < 1.0)
                            || (l.coat > 0.0 && l.coat_alpha >= pbr::ALPHA_MIN)
                    }
                    None => !is_spec || m.smoothness == 0.0 || glossy,
                };
                let weighed = match &lobe {
                    Some(l) => Weighed::Pbr(l),
                    None if mixed => Weighed::Mixed {
                        n: ns,
                        r: reflect(ray.dir, ns),
                        s: m.smoothness,
                        p: m.specular,
                        spec: m.specular_color,
                        diff: m.color,
                    },
                    None if gloss => Weighed::Gloss {
                        n: ns,
                        r: reflect(ray.dir, ns),
                        s: m.smoothness,
                    },
                    None => Weighed::Cosine,
                };
                if nee && light_lobe {
                    let tint = match (&lobe, is_spec) {
                        (Some(_), _) => Vec3A::ONE,
                        (None, _) if mixed => Vec3A::ONE,
                        (None, true) => m.specular_color,
                        (None, false) => m.color,
                    };
                    // The shadow ray leaves on the side of n (or, through a transmitting
                    // surface, the other).
                    let from = self.leaving(hit.r, front);
                    // Used only where a lobe transmits: no lookup in scenes without one.
                    let back = if self.f.pbr_transmission {
                        self.leaving(hit.r, !front)
                    } else {
                        NONE
                    };
                    radiance += throughput
                        * tint
                        * self.sample_light::<P>(point.position, ns, n, (from, back), weighed, rng);
                    // The map in the mirror spheres: its paths scatter here and at the
                    // mirror, and leave it, within the bounces allowed.
                    if self.f.mirror_nee
                        && !inside
                        && !self.s.reflectors.is_empty()
                        && bounce + 2 <= u.max_bounces
                    {
                        radiance += throughput
                            * tint
                            * self.sample_mirror::<P>(
                                point.position,
                                ns,
                                n,
                                from,
                                weighed,
                                None,
                                rng,
                            );
                    }
                    // The map through the glass spheres: its paths scatter here, refract in
                    // and out, and leave, within the bounces allowed.
                    // With a reflection inside, one bounce more.
                    if self.f.lens_nee
                        && !inside
                        && !self.s.lenses.is_empty()
                        && bounce + 3 <= u.max_bounces
                    {
                        let inner = (bounce + 4 <= u.max_bounces) as u32;
                        radiance += throughput
                            * tint
                            * self.sample_lens::<P>(
                                point.position,
                                ns,
                                n,
                                from,
                                weighed,
                                None,
                                inner,
                                rng,
                            );
                    }
                }
                let mut pbr_pdf = 0.0;
                let mut through = false;
                // Light sampling found directions through the surface here too (`transmits`).
                let lit_through = nee && light_lobe && self.transmits(weighed);
                sc = match &lobe {
                    Some(l) => {
                        let s = pbr::sample(l, rng);
                        // A glass-sphere path goes on through glTF's smooth glass by its
                        // deltas alone (`Material::is_lens`).
                        if self.f.lens_nee {
                            lensed = if s.pdf == 0.0 {
                                self.lens_step(
                                    lensed,
                                    hit,
                                    &ray,
                                    n_out,
                                    0.0,
                                    prev_point,
                                    Some(s.dir),
                                )
                            } else {
                                None
                            };
                        }
                        // Where light sampling finds no direction through the surface, a light
                        // the transmitted ray meets counts fully.
                        pbr_pdf = if s.through && !lit_through {
                            0.0
                        } else {
                            s.pdf
                        };
                        through = s.through;
                        Scatter {
                            dir: s.dir,
                            attenuation: s.weight,
                            absorbed: !s.ok,
                        }
                    }
                    None => scatter_surface(m, ray.dir, ns, is_spec, rng),
                };
                // A direction the shading normal allows but that enters the surface (or, drawn
                // through it, leaves it) ends the path.
                let side = sc.dir.dot(n);
                if self.s.shading_normals() && (if through { side >= 0.0 } else { side <= 0.0 }) {
                    sc.absorbed = true;
                }
                if pbr {
                    prev_pdf = pbr_pdf;
                    prev_normal = ns;
                    prev_unsampled = through || inside;
                } else if light_lobe {
                    prev_pdf = lobe_pdf(weighed, sc.dir, ns);
                    prev_normal = ns;
                }
            }
            if sc.absorbed {
                break;
            }
            throughput *= sc.attenuation;
            prev_point = point.position;
            if nee && bounce >= RR_START {
                let q = throughput.max_element().min(RR_MAX_SURVIVAL);
                if rng.rand() >= q {
                    break;
                }
                throughput /= q;
            }
            let out = sc.dir.dot(n_out) > 0.0;
            let side = if out { n_out } else { -n_out };
            skip = self.leaving(hit.r, out);
            ray = Ray {
                origin: offset_ray(point.position, side),
                dir: sc.dir,
            };
            bounce += 1;
        }
        (radiance, segments)
    }
}

#[cfg(target_arch = "x86_64")]
/// What `trace_path` reads at a hit, for the lanes' walk (`cpu::lanes`): the point, its
/// geometric normal (outward), its material, that material's colour there (a texture's where
/// it has one) and the shading normal on the side the ray came from.
pub(super) struct Met {
    pub position: Vec3A,
    pub normal: Vec3A,
    pub material: u32,
    pub color: Vec3A,
    pub shading: Vec3A,
}

#[cfg(target_arch = "x86_64")]
impl Tracer<'_> {
    /// The nearest hit of `ray` but primitive `skip`, its distance and reference, as
    /// `trace_path` finds it (the lanes' walk: a scene of no instances).
    #[inline(always)]
    pub(super) fn nearest(&mut self, ray: &Ray, skip: u32) -> Option<(f32, u32)> {
        self.intersect::<ANY>(ray, skip).map(|h| (h.t, h.r))
    }

    /// `nearest` where the lanes have visited the eight-wide tree's root (`at`): the walk
    /// from the root's inner slots on (`Bvh8::closest_below_root`), the same hit. A scene of
    /// no instances whose tree is eight wide (the lanes' `Root` exists only then).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn nearest_below_root(
        &mut self,
        ray: &Ray,
        skip: u32,
        at: &super::bvh8::AtRoot,
    ) -> Option<(f32, u32)> {
        let s = self.s;
        let b8 = s
            .bvh8
            .as_ref()
            .expect("the lanes' root is an eight-wide tree's");
        let mut skipped = 0;
        let mut leaves = s.leaves(skip, NONE);
        // SAFETY: `bvh8` exists only where the CPU has AVX.
        let hit = unsafe {
            b8.closest_below_root(
                &s.bvh.refs,
                ray,
                at,
                &mut self.tally,
                &mut self.stack8,
                &mut leaves,
                #[inline(always)]
                |r, t| hit_except::<ANY>(s, r, ray, t, skip, &mut skipped),
            )
        };
        self.tally.tests -= skipped + leaves.skipped;
        hit
    }

    /// `trace_path`'s surface at the hit (t, r) of `ray` (`surface_at`, `material_at` and
    /// `shading_normal_at`), for the lanes' walk: a scene of no instances, whose textures
    /// give a lecture material its colour alone.
    #[inline(always)]
    pub(super) fn met(&self, ray: &Ray, t: f32, r: u32) -> Met {
        let hit = Hit { t, r, inst: NONE };
        let (point, material, local) = self.surface_at(hit, ray);
        let (textured, mapped) = self.material_at(hit, local, material);
        let m = textured
            .as_ref()
            .unwrap_or(&self.s.materials[material as usize]);
        let n_out = point.normal;
        let n = if ray.dir.dot(n_out) < 0.0 {
            n_out
        } else {
            -n_out
        };
        Met {
            position: point.position,
            normal: n_out,
            material,
            color: m.color,
            shading: self.shading_normal_at(hit, mapped, local, n_out, n),
        }
    }
}

/// Mirrors and clear glass the guides look through before they give up (the sky's guide).
const GUIDE_SPECULAR_DEPTH: u32 = 4;

impl Tracer<'_> {
    /// The denoiser's guide sample of a camera ray: the albedo and shading normal of the
    /// first surface that is not a perfect mirror or clear glass (`guide_of` in trace.wgsl;
    /// the sky's normal is zero).
    pub fn guide<const P: u32>(&mut self, primary: Ray) -> ([f32; 3], [f32; 3]) {
        let mut ray = primary;
        let mut tint = Vec3A::ONE;
        let mut skip = NONE;
        for depth in 0..=GUIDE_SPECULAR_DEPTH {
            let Some(hit) = self.intersect::<P>(&ray, skip) else {
                return (tint.to_array(), [0.0; 3]);
            };
            let (point, material, local) = self.surface_at(hit, &ray);
            let (textured, mapped) = self.material_at(hit, local, material);
            let m = textured
                .as_ref()
                .unwrap_or(&self.s.materials[material as usize]);
            let n_out = point.normal;
            let front = ray.dir.dot(n_out) < 0.0;
            let n = if front { n_out } else { -n_out };
            if self.f.emitters && m.light > 0.0 {
                return ((tint * m.color).to_array(), n.to_array());
            }
            let last = depth == GUIDE_SPECULAR_DEPTH;
            let dir;
            if self.f.dielectrics && m.smoothness < 0.0 {
                if m.absorption > 0.0 || last {
                    return ((tint * m.color).to_array(), n.to_array());
                }
                let ratio = if front { 1.0 / m.ior } else { m.ior };
                let cos_theta = (-ray.dir).dot(n).min(1.0);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                dir = if ratio * sin_theta <= 1.0 {
                    refract_dir(ray.dir, n, cos_theta, ratio).normalize()
                } else {
                    reflect(ray.dir, n).normalize()
                };
                tint *= m.color;
            } else {
                let ns = self.shading_normal_at(hit, mapped, local, n_out, n);
                if !(m.specular >= 1.0 && m.smoothness >= 1.0 && m.absorption == 0.0) || last {
                    let s = m.specular.clamp(0.0, 1.0);
                    let albedo = tint * m.color.lerp(m.specular_color, s);
                    return (albedo.to_array(), ns.to_array());
                }
                tint *= m.specular_color;
                dir = reflect(ray.dir, ns);
            }
            let out = dir.dot(n_out) > 0.0;
            let side = if out { n_out } else { -n_out };
            skip = self.leaving(hit.r, out);
            ray = Ray {
                origin: offset_ray(point.position, side),
                dir,
            };
        }
        (tint.to_array(), [0.0; 3])
    }
}

#[cfg(test)]
thread_local! {
    /// Tests only: where set, every segment's (bounce, ray) is recorded (the packet
    /// experiment replays them).
    pub(super) static RECORD: std::cell::RefCell<Option<Vec<(u32, Ray)>>> =
        const { std::cell::RefCell::new(None) };
}

/// Whether segments are being recorded (tests only): the paths are then traced one by one,
/// where the recording is, not in lanes (`cpu::lanes`, on x86-64 only).
#[cfg(target_arch = "x86_64")]
pub(super) fn recording() -> bool {
    #[cfg(test)]
    return RECORD.with(|r| r.borrow().is_some());
    #[cfg(not(test))]
    false
}

/// Tests only: every segment (bounce, ray) that scene `name` traces at `w`×`h` and `spp`
/// samples per pixel, in the row loop's order (one thread), and the scene as traced.
/// (Its users, the packet and eight-wide walks, exist on x86-64 only.)
#[cfg(all(test, target_arch = "x86_64"))]
pub(super) fn recorded(
    name: &str,
    w: u32,
    h: u32,
    spp: u32,
) -> (CpuScene, Vec<(u32, super::intersect::Ray)>) {
    use crate::common::FrameSettings;
    use crate::common::layout::DispatchUniforms;
    let scene = crate::scene::Scene::load(name).unwrap();
    let settings = FrameSettings::new(w, h, scene.render.max_bounces, 1);
    let mut engine = super::CpuEngine::new(&scene, &settings);
    let d = DispatchUniforms {
        sample_base: 0,
        sample_count: spp,
        row_offset: 0,
        row_count: h,
        accumulate: 0,
        lanes: 1,
        row_stride: 1,
        _pad: 0,
    };
    // One thread, so that a path's segments are recorded in a row.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let segments = pool.install(|| {
        RECORD.with(|r| *r.borrow_mut() = Some(Vec::new()));
        engine.run(&d, Features::of(&scene));
        RECORD.with(|r| r.borrow_mut().take().unwrap())
    });
    (CpuScene::new(&scene, &settings), segments)
}
