//! The path loop in vector lanes, one path a lane (sixteen on AVX-512, else eight on AVX2),
//! for scenes of a few primitives (spheres, quads, boxes: at most eight) of the lecture's
//! materials (its lobes, certain or drawn, light sampling weighing the glossy one too, and its
//! glass) under the sky and its sun or an environment map, lit by them and by at most
//! `MAX_LAMPS` lights (not both lights and a map), with or without light sampling; and for
//! scenes of triangles or of more primitives, without lights, by a walk (`Walk`: each lane's
//! ray walks the scalar tracer's tree, and what it meets there is the scalar tracer's):
//! `Tracer::trace_path`'s arithmetic for those scenes, operation for operation in the same
//! order (glam's dot is (x·x′ + y·y′) + z·z′, its cross the textbook one, its normalize a
//! division by the square root, nothing fused), so that each lane's path is the scalar one
//! bit for bit; tested against it on every lane, at both widths. The scalar loop
//! runs one path's dependent chain of divisions and square roots at a time; here a vector's
//! worth run side by side, every primitive tested against all their rays at once (the
//! wavefront of Laine, Karras and Aila, "Megakernels Considered Harmful", HPG 2013, kept in
//! one kernel as Mitsuba 3's LLVM backend keeps it). A lane whose path has ended starts its
//! pixel's next sample (`Lanes::trace`): its sampler and camera ray made in lanes too. The
//! draws are each lane's own sampler's (`cpu::draws`, `Rng`'s in lanes), taken in the order
//! the scalar path takes them. The code is written once over `simd::Isa`. The map runs in lanes
//! (`map`: its coordinates, its distribution's inversions and density, its bilinear lookup),
//! with the scalar tracer's own polynomials for the trigonometry (`trig`, `scene::trig`);
//! the sun's falloff (libm's `powf`) runs lane by lane through the scalar tracer's function,
//! so that it stays its bits. So does light sampling through mirror spheres (`mirror`: the
//! reflection point's Newton steps in lanes, their start through libm lane by lane), from the
//! surfaces and from the camera.
//!
//! The one difference a path can show: where two primitives are hit at the same distance (a
//! ray through the edge two quads share), the scalar walk keeps the one its BVH order tests
//! first, and this the first in the scene's order (spheres, quads, boxes).

use super::draws::Draws;
use super::fixed::FIXED_MAX;
use super::intersect::{NO_HIT, Ray};
use super::scene::CpuScene;
use super::simd::{
    Avx2, Avx512, F, I, Isa, M, MAX_LANES, Make, Row, V3, cross, dot, lanes_of, normalize,
    normalize_or, rows,
};
use super::trace::{ANY, T_FAR, Tracer};
use crate::common::Features;
use crate::common::arrays::{ENV_NONE, ENV_VISIBLE, REF_INDEX};
use crate::scene::envmap::EnvMap;
use glam::Vec3A;
use std::arch::x86_64::{_CMP_EQ_OQ, _CMP_NGE_UQ, _CMP_NLE_UQ, _CMP_NLT_UQ};
use std::array::from_fn;
use std::cell::RefCell;
use std::f32::consts::PI;
use surface::Met;

/// `[e(0), e(1), e(2)]`, written out. The lanes' code takes no closures: one
/// (`std::array::from_fn`'s, `map`'s) is compiled apart from the instruction set that its
/// caller's entry point enables, and its lane operations would be calls, not instructions.
macro_rules! each {
    (|$c:ident| $e:expr) => {
        [
            {
                let $c = 0usize;
                $e
            },
            {
                let $c = 1usize;
                $e
            },
            {
                let $c = 2usize;
                $e
            },
        ]
    };
}

mod map;
mod mirror;
mod surface;
mod trig;

use map::{Tables, map_radiance};
use trig::sin_cos_turns;

/// An entry point: `Lanes::trace_in` for one instruction set, compiled with its features
/// (everything the lanes do is inlined into it; `Isa::new` checks the same features).
macro_rules! entry {
    ($name:ident, $isa:ty, $features:literal, $doc:literal) => {
        #[doc = $doc]
        #[target_feature(enable = $features)]
        fn $name(
            &self,
            s: $isa,
            at: (u32, u32, u32),
            n: usize,
            samples: std::ops::Range<u32>,
            seed: u32,
            done: impl FnMut(usize, u32, Traced),
        ) -> (u64, u64) {
            self.trace_in(s, at, n, samples, seed, done)
        }
    };
}

/// Why a material is left to the scalar loop: glTF's BRDF, or glass where the scene's
/// features leave glass out.
const UNTRACED: &str = "a material the lanes do not trace";

/// The most primitives a scene may have here: their parameters are permuted into the lanes
/// from one register of eight (AVX2's widest permute).
pub const MAX_PRIMITIVES: usize = 8;

/// Russian roulette as `trace_path` plays it (with light sampling only).
const RR_START: u32 = 3;
const RR_MAX_SURVIVAL: f32 = 0.95;

/// No primitive (a lane's index where it hit none, or leaves none behind).
const NONE: i32 = -1;

/// A primitive's kind, as its reference's top bits say.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Sphere = 0,
    Quad = 1,
    Box = 2,
}

type Tables3 = [Row; 3];

/// The scene as the lanes read it: per primitive (in the scene's order, spheres, quads,
/// boxes), its shape's parameters and its material's, as tables that a lane's primitive
/// index permutes. Built per row from the scene (a few primitives: nothing to keep in step
/// with edits).
pub struct Lanes<'a> {
    /// The instruction sets: AVX2 for eight lanes, and AVX-512 for sixteen where the CPU
    /// has it (`None` traces eight).
    narrow: Avx2,
    pub(crate) wide: Option<Avx512>,
    kinds: Vec<Kind>,
    /// Per kind (sphere, quad, box), whether each primitive is of it (1.0 or 0.0).
    of_kind: [Row; 3],
    /// Spheres: the anchor, the anchor normal, |radius| times it (`hit_sphere`'s r·n, the
    /// product of the same two floats), |radius|, 2·|radius|, and whether the radius is
    /// positive (the outside is where the normal points) or negative (the normal turned
    /// inward), as 1.0 or 0.0.
    anchor: Tables3,
    normal: Tables3,
    r_normal: Tables3,
    r: Row,
    two_r: Row,
    outward: Row,
    inward: Row,
    /// Quads: the corner, the edges, the normal and w (`Quad`).
    quad: [Tables3; 5],
    /// Boxes: the centre, the half extents and the three axes.
    center: Tables3,
    half: Tables3,
    axes: [Tables3; 3],
    /// The material: whether it emits (1.0 or 0.0), its colour and light; whether its
    /// specular lobe is certain (`specular` ≥ 1) or drawn (0 < `specular` < 1, with that
    /// probability), its smoothness s and 1 − s, whether s is 0 (light sampling then weighs
    /// its specular lobe too: `trace_path`'s `light_lobe`), the specular lobe's tint, and the
    /// fuzz of its specular lobe or of its glass (`absorption`).
    emits: Row,
    color: Tables3,
    light: Row,
    certain: Row,
    maybe: Row,
    p_spec: Row,
    smooth: Row,
    rough: Row,
    flat: Row,
    spec_color: Tables3,
    fuzz: Row,
    /// The lecture's glossy lobe that light sampling weighs (`trace_path`'s `glossy`: with
    /// glossy light sampling, a specular lobe of smoothness in (0, 1) without fuzz), and
    /// whether it is drawn beside the cosine lobe (`mixed`: specular below 1).
    glossy: Row,
    mixed: Row,
    /// Glass (`scatter_dielectric`): whether the material is, its index of refraction and
    /// 1 / it.
    glass: Row,
    ior: Row,
    inv_ior: Row,
    /// The lights (`GpuLight`), where light sampling runs: at most `MAX_LAMPS`.
    lamps: Vec<Lamp>,
    /// Per primitive, its material's light slot (`Material::light_slot`: 1 + its light's
    /// index, 0 for none).
    slot: Row,
    /// The sky's sun (`Tracer::sky`), where the scene has one.
    sun: Option<Sun>,
    /// The environment map, where the scene has one (then without lights).
    env: Option<Env>,
    /// The mirror spheres through which light sampling also samples the map
    /// (`Tracer::sample_mirror`; their radii are positive, `arrays::mirror_spheres`, so `r`
    /// holds them), and per primitive whether it is one (1.0 or 0.0). None without light
    /// sampling.
    mirrors: Vec<Ball>,
    reflector: Row,
    /// What `Tracer::sample_view` and `Tracer::pixel_at` read of the camera, where the
    /// scene has mirror spheres.
    view: View,
    /// Whether light sampling runs (`trace_path`'s `nee`): a light or the map to sample.
    nee: bool,
    sky_uniform: bool,
    sky_bottom: [f32; 3],
    sky_top: [f32; 3],
    max_bounces: u32,
    camera: Camera,
    /// A scene the lanes do not test whole, where each lane's ray walks the scalar
    /// tracer's tree (then the tables hold the materials, in the scene's order).
    walk: Option<Walk<'a>>,
}

/// A scene of triangles, or of more than `MAX_PRIMITIVES` primitives: each lane's ray walks
/// the scalar tracer's tree (`Tracer::nearest`, `Tracer::occluded`, below the root the lanes
/// test); what it meets there (the surface, a texture's colour, the shading normal) is made
/// in lanes on triangles (`surface`) and the root's spheres, else by the scalar tracer lane
/// by lane (`Tracer::met`); the rest of the path runs in lanes. A lane's walk is one ray's, as
/// Embree's single-ray kernels walk the incoherent rays of a path tracer (Wald et al.,
/// "Embree: A Kernel Framework for Efficient CPU Ray Tracing", SIGGRAPH 2014).
struct Walk<'a> {
    tracer: RefCell<Tracer<'a>>,
    /// Per material of the scene, its row of the tables.
    rows: Vec<i32>,
    /// Whether the scene has shading normals (smooth or mapped): light sampling and the
    /// lobes then read the shading normal, and a direction below the surface ends the path.
    normals: bool,
    /// The tree's root, tested in lanes, where the scalar walk reads an eight-wide tree.
    root: Option<Root>,
    /// Per sphere of the scene (by reference index), 1 where its normal points out (a
    /// positive radius), for `leaving`; one 0 where the scene has none.
    outward: Vec<u32>,
    /// The tables of the surfaces met on triangles, where the scene has triangles.
    triangles: Option<surface::Triangles<'a>>,
}

/// The camera as `Tracer::camera_ray` reads it (`GpuUniforms`): the image's size, the
/// corner, the edges and origin of the view, and the lens (its radius 0 without depth of
/// field).
struct Camera {
    size: [f32; 2],
    corner: [f32; 3],
    horizontal: [f32; 3],
    vertical: [f32; 3],
    origin: [f32; 3],
    u: [f32; 3],
    v: [f32; 3],
    lens_radius: f32,
}

/// The environment map as `Tracer::escaped` and `Tracer::sample_env` read it: the map, its
/// rotation and intensity, the probability that light sampling picks it (`env_pick`: 1 here,
/// where it is the only light, or 0 for a black map), and whether camera rays see it (else
/// they see the sky) and whether anything does (`env_mode`).
struct Env {
    map: std::sync::Arc<EnvMap>,
    rotation: f32,
    intensity: f32,
    pick: f32,
    seen_directly: bool,
    shown: bool,
}

/// A mirror sphere that `Tracer::sample_mirror` samples: its row of the tables, its centre
/// (`sphere_center`) and radius, and what it reflects (its material's specular tint).
struct Ball {
    index: usize,
    center: [f32; 3],
    r: f32,
    tint: [f32; 3],
}

/// The camera as `Tracer::pixel_at` and `Tracer::view_meets` read it, each figure computed
/// by the scalar tracer's expression: the view's centre on the focus plane and its unit
/// direction, the image's edges and their squared lengths, the pixel's area there, and the
/// sine and cosine of the pixel's cone's half-angle.
#[derive(Default)]
struct View {
    centre: [f32; 3],
    ahead: [f32; 3],
    h2: f32,
    v2: f32,
    area: f32,
    sin_b: f32,
    cos_b: f32,
}

impl View {
    /// The figures as `Tracer::pixel_at` and `Tracer::view_meets` compute them from `s`'s
    /// camera.
    fn of(s: &CpuScene) -> View {
        let u = &s.u;
        let (h, v) = (u.cam_horizontal, u.cam_vertical);
        let centre = u.cam_to_corner + 0.5 * h - 0.5 * v;
        let (h2, v2) = (h.length_squared(), v.length_squared());
        let (w, ht) = (u.width as f32, u.height as f32);
        let (ph, pv) = (h / w, v / ht);
        let sin_b = ((ph.length_squared() + pv.length_squared()).sqrt() / centre.length()).min(1.0);
        View {
            centre: centre.to_array(),
            ahead: centre.normalize().to_array(),
            h2,
            v2,
            area: (h2 * v2).sqrt() / (w * ht),
            sin_b,
            cos_b: (1.0 - sin_b * sin_b).sqrt(),
        }
    }
}

/// The sun of the gradient sky: its direction, its radiance and the exponent of its falloff.
struct Sun {
    dir: [f32; 3],
    radiance: [f32; 3],
    size: f32,
}

/// A light that light sampling draws from: its primitive, its shape, its material's colour
/// times its light, and what choosing it among several reads (`Tracer::light_weight`): its
/// power's share, and the centre and radius² of its bounding sphere.
struct Lamp {
    index: usize,
    shape: LampShape,
    radiance: [f32; 3],
    pmf: f32,
    center: [f32; 3],
    r2: f32,
}

/// The most lights the lanes sample (chosen among by `Tracer::choose_light`'s local weights).
pub const MAX_LAMPS: usize = 8;

/// What sampling a light needs of its shape.
enum LampShape {
    /// The centre (`sphere_center`) and radius².
    Sphere { center: [f32; 3], r2: f32 },
    /// The corner, the edges and the normal, and the area (`GpuLight::area`).
    Quad { q: [[f32; 3]; 4], area: f32 },
}

/// One lane's path: its radiance, its segments, and its radiance as the sums' fixed-point
/// words (`fixed::words`; `None` where it is not finite).
pub struct Traced {
    pub radiance: Vec3A,
    pub segments: u32,
    pub words: Option<[u64; 3]>,
    /// Where its sampler stands: the Sobol draws taken (`Rng::taken`) and the stream's state.
    pub taken: u32,
    pub state: u32,
}

impl<'a> Lanes<'a> {
    /// The lanes for `s` traced with features `f`, where they apply: a CPU with AVX2, one to
    /// `MAX_PRIMITIVES` spheres, quads and boxes, every material an emitter, the lecture's
    /// glass, or its surface (lobes certain or drawn, fuzzed or not), at most `MAX_LAMPS`
    /// lights, or a map and no light (with the mirror sampler where the map has mirror
    /// spheres of the lecture's mirrors), and neither glTF's BRDF nor the lens sampler; or a
    /// walk (`Walk`) of any number of spheres, quads, boxes and triangles
    /// (textured, smooth or normal-mapped) of materials that differ in at most
    /// `MAX_PRIMITIVES` ways but for their colour, no emitter, no instance, no light. The
    /// camera rays, a lens's included, are made in lanes too.
    pub fn of(s: &'a CpuScene, f: Features) -> Option<Lanes<'a>> {
        Self::try_of(s, f).ok()
    }

    /// `of`, or why the scene is left to the scalar loop (for `bench`'s report).
    pub fn try_of(s: &'a CpuScene, f: Features) -> Result<Lanes<'a>, &'static str> {
        let narrow = Avx2::new().ok_or("the CPU has no AVX2")?;
        let count = s.spheres.len() + s.quads.len() + s.boxes.len();
        let walks = !s.triangles.is_empty() || count > MAX_PRIMITIVES;
        // Mirror spheres of the lecture's mirrors, sampled under a map, in a scene of a few
        // primitives.
        let mirrored = f.mirror_nee
            && !walks
            && s.lenses.is_empty()
            && s.env.is_some()
            && s.reflectors.iter().all(|&i| {
                let m = s
                    .spheres
                    .get(i as usize)
                    .and_then(|b| s.materials.get(b.material as usize));
                m.is_some_and(|m| !m.pbr && m.smoothness >= 0.0)
            });
        let refused = [
            (f.instances || !s.instances.is_empty(), "instanced meshes"),
            (f.pbr, "glTF's BRDF"),
            (f.lens_nee, "light sampling through glass balls"),
            (
                f.mirror_nee && !mirrored,
                "light sampling through mirror balls of glass or glTF's, or among many primitives",
            ),
            (
                !walks && (f.triangles || f.textures),
                "textures on a few primitives",
            ),
            (count + s.triangles.len() == 0, "an empty scene"),
            (s.u.n_lights as usize > MAX_LAMPS, "more than eight lights"),
            (
                f.env_map && s.env.is_some() && s.u.n_lights > 0,
                "lights and a map together",
            ),
            (
                s.shading_normals() && !walks,
                "shading normals on a few primitives",
            ),
            (
                walks && s.u.n_lights > 0,
                "lights among triangles or many primitives",
            ),
        ];
        if let Some(&(_, why)) = refused.iter().find(|r| r.0) {
            return Err(why);
        }
        // A textured material that may emit is left to the scalar tracer.
        let lit_by_texture = |m: u32| {
            super::texture::record(&s.tex, m).is_some_and(|r| super::texture::may_emit(&s.tex, r))
        };
        if walks && !s.tex.is_empty() && (0..s.materials.len() as u32).any(lit_by_texture) {
            return Err("a texture that emits light");
        }
        let row = [0.0; MAX_LANES];
        let mut l = Lanes {
            narrow,
            wide: Avx512::new().filter(|_| !eight_lanes()),
            kinds: Vec::with_capacity(count),
            of_kind: [row; 3],
            anchor: [row; 3],
            normal: [row; 3],
            r_normal: [row; 3],
            r: row,
            two_r: row,
            outward: row,
            inward: row,
            quad: [[row; 3]; 5],
            center: [row; 3],
            half: [row; 3],
            axes: [[row; 3]; 3],
            emits: row,
            color: [row; 3],
            light: row,
            certain: row,
            maybe: row,
            p_spec: row,
            smooth: row,
            rough: row,
            flat: row,
            spec_color: [row; 3],
            fuzz: row,
            glossy: row,
            mixed: row,
            glass: row,
            ior: row,
            inv_ior: row,
            lamps: Vec::new(),
            slot: row,
            env: s.env.clone().filter(|_| f.env_map).map(|map| Env {
                map,
                rotation: s.u.env_rotation,
                intensity: s.u.env_intensity,
                pick: s.u.env_pick,
                seen_directly: s.u.env_mode == ENV_VISIBLE,
                shown: s.u.env_mode != ENV_NONE,
            }),
            mirrors: Vec::new(),
            reflector: row,
            view: View::default(),
            nee: false,
            sun: f.sun.then(|| Sun {
                dir: s.u.sun_dir.to_array(),
                radiance: s.u.sun_radiance.to_array(),
                size: s.u.sun_size,
            }),
            sky_uniform: s.u.sky_uniform,
            sky_bottom: s.u.sky_bottom.to_array(),
            sky_top: s.u.sky_top.to_array(),
            max_bounces: s.u.max_bounces,
            camera: Camera {
                size: [s.u.width as f32, s.u.height as f32],
                corner: s.u.cam_to_corner.to_array(),
                horizontal: s.u.cam_horizontal.to_array(),
                vertical: s.u.cam_vertical.to_array(),
                origin: s.u.cam_origin.to_array(),
                u: s.u.cam_u.to_array(),
                v: s.u.cam_v.to_array(),
                lens_radius: if f.dof { s.u.lens_radius.max(0.0) } else { 0.0 },
            },
            walk: None,
        };
        let mut materials = Vec::with_capacity(count);
        // The primitives' tables (a walk's tree holds its primitives).
        let (spheres, quads, boxes) = if walks {
            (&[][..], &[][..], &[][..])
        } else {
            (&s.spheres[..], &s.quads[..], &s.boxes[..])
        };
        for (k, sp) in spheres.iter().enumerate() {
            l.put_sphere(k, sp);
            l.kinds.push(Kind::Sphere);
            materials.push(sp.material);
        }
        for q in quads {
            let k = l.kinds.len();
            for (t, v) in l.quad.iter_mut().zip([q.q, q.u, q.v, q.normal, q.w]) {
                for c in 0..3 {
                    t[c][k] = v[c];
                }
            }
            l.kinds.push(Kind::Quad);
            materials.push(q.material);
        }
        for b in boxes {
            let k = l.kinds.len();
            for c in 0..3 {
                l.center[c][k] = b.center[c];
                l.half[c][k] = b.half_extents[c];
                for a in 0..3 {
                    l.axes[a][c][k] = b.axes[a][c];
                }
            }
            l.kinds.push(Kind::Box);
            materials.push(b.material);
        }
        for (k, &kind) in l.kinds.iter().enumerate() {
            l.of_kind[kind as usize][k] = 1.0;
        }
        // A walk's rows are its materials', one row for those that differ in their colour
        // alone (a walk's colour is the hit's).
        let mut rows = Vec::new();
        if walks {
            let mut kept: Vec<Entry> = Vec::new();
            for m in &s.materials {
                let e = Entry::of(m, f).ok_or(UNTRACED)?;
                if e.emits != 0.0 {
                    return Err("emitters among triangles or many primitives");
                }
                let key = Entry {
                    color: [0.0; 3],
                    ..e
                };
                let row = match kept.iter().position(|k| *k == key) {
                    Some(row) => row,
                    None if kept.len() < MAX_PRIMITIVES => {
                        kept.push(key);
                        kept.len() - 1
                    }
                    None => return Err("more than eight kinds of material, colour aside"),
                };
                rows.push(row as i32);
            }
            for (k, e) in kept.iter().enumerate() {
                l.put(k, e);
            }
        }
        for (k, &mat) in materials.iter().enumerate() {
            let m = s.materials.get(mat as usize).ok_or(UNTRACED)?;
            l.put(k, &Entry::of(m, f).ok_or(UNTRACED)?);
        }
        // Light sampling runs where the scene has lights and the settings ask for it
        // (`trace_path`'s `nee`).
        let lights = if f.nee { s.u.n_lights as usize } else { 0 };
        for light in &s.lights[..lights] {
            let i = (light.prim & REF_INDEX) as usize;
            let (index, shape, material, (center, r2)) = match light.prim >> 30 {
                0 => {
                    let sp = &s.spheres[i];
                    let center = super::trace::sphere_center(sp);
                    let r2 = sp.radius * sp.radius;
                    let shape = LampShape::Sphere {
                        center: center.to_array(),
                        r2,
                    };
                    (i, shape, sp.material, (center, r2))
                }
                1 => {
                    let q = &s.quads[i];
                    let corners = [q.q, q.u, q.v, q.normal].map(|v| v.to_array());
                    let shape = LampShape::Quad {
                        q: corners,
                        area: light.area,
                    };
                    // `light_weight`'s bounding sphere of the quad.
                    let bound = (q.q + 0.5 * (q.u + q.v), 0.25 * (q.u + q.v).length_squared());
                    (s.spheres.len() + i, shape, q.material, bound)
                }
                _ => return Err("a light that is neither a sphere nor a quad"),
            };
            let m = &s.materials[material as usize];
            l.lamps.push(Lamp {
                index,
                shape,
                radiance: (m.color * m.light).to_array(),
                pmf: light.pmf,
                center: center.to_array(),
                r2,
            });
        }
        l.nee = f.nee && (!l.lamps.is_empty() || l.env.as_ref().is_some_and(|e| e.pick > 0.0));
        if f.mirror_nee && l.nee {
            for &i in &s.reflectors {
                let b = &s.spheres[i as usize];
                let k = i as usize;
                l.reflector[k] = 1.0;
                l.mirrors.push(Ball {
                    index: k,
                    center: super::trace::sphere_center(b).to_array(),
                    r: b.radius,
                    tint: s.materials[b.material as usize].specular_color.to_array(),
                });
            }
            l.view = View::of(s);
        }
        // The root of the scalar tracer's eight-wide tree, which its walk reads where the
        // settings keep the tree (`Tracer::intersect`).
        let root = match s.bvh8.as_ref().and_then(|b| b.root()) {
            Some(r) if walks && f.bvh => Some(Root::of(&mut l, s, &r, &rows)),
            _ => None,
        };
        l.walk = walks.then(|| Walk {
            tracer: RefCell::new(Tracer::new(s, f)),
            triangles: surface::Triangles::of(s, &rows),
            rows,
            normals: s.shading_normals(),
            root,
            outward: if s.spheres.is_empty() {
                vec![0]
            } else {
                s.spheres
                    .iter()
                    .map(|b| u32::from(b.radius > 0.0))
                    .collect()
            },
        });
        Ok(l)
    }

    /// `Tracer::sample_mirror` for the lanes of `lanes` at points `p` (facing shading normal
    /// `n`, geometric `ng`, leaving primitive `from`), for the lobe light sampling weighs, or
    /// from the camera (`view`: the lanes' columns and the row, `Tracer::sample_view`): one of
    /// the mirror spheres chosen evenly, a direction drawn from the map's distribution, the
    /// sphere's point that reflects it to p (`mirror::point`), both legs unoccluded, weighed
    /// against the lobe (`light_weighted`) or the pixel's camera rays (`view_weighted`);
    /// returns the light (tint not included) and the tests made.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sample_mirror<S: Isa>(
        &self,
        s: S,
        (p, n, ng): (V3<S>, V3<S>, V3<S>),
        from: I<S>,
        lanes: M<S>,
        view: Option<(I<S>, u32)>,
        lobe: (&Lobe<S>, (V3<S>, V3<S>)),
        rng: &mut Draws<S>,
    ) -> (V3<S>, u64) {
        let zero = s.zero();
        let Some(env) = self.env.as_ref() else {
            return ([zero; 3], 0);
        };
        // The sphere: its row, centre, radius and tint.
        let count = self.mirrors.len();
        let slot = if count > 1 {
            (rng.draw(s, lanes) * s.splat(count as f32)).truncate()
        } else {
            s.int(0)
        };
        let (mut index, mut c, mut r, mut tint) = (s.int(NONE), [zero; 3], zero, [zero; 3]);
        for (j, b) in self.mirrors.iter().enumerate() {
            // (The last takes a product rounded up to the count: `min(count − 1)`.)
            let this = if j + 1 == count {
                slot.gt(s.int(j as i32 - 1))
            } else {
                slot.eq(s.int(j as i32))
            };
            index = index.blend(s.int(b.index as i32), this);
            r = r.blend(s.splat(b.r), this);
            for k in 0..3 {
                c[k] = c[k].blend(s.splat(b.center[k]), this);
                tint[k] = tint[k].blend(s.splat(b.tint[k]), this);
            }
        }
        // A sphere wholly behind the surface reflects nothing onto it, and takes no draw.
        let cp: V3<S> = each!(|k| c[k] - p[k]);
        let lanes = lanes.without(dot(n, cp).le(-r));
        let (u1, u2) = rng.draw2(s, lanes);
        let tables = Tables::of(&env.map.distribution);
        let draws = (u1.keep(lanes), u2.keep(lanes));
        let map::Drawn {
            dir: w,
            pdf,
            uv: (u, v),
        } = map::sample(s, &env.map.distribution, &tables, draws, env.rotation);
        let x = mirror::point(s, (p, c, r), w, lanes & pdf.gt(zero));
        let cos_s = dot(n, x.dir);
        let spread = mirror::spread(s, r, x.dist, x.cos_i);
        let mut ok = (x.found & cos_s.gt(zero)) & spread.gt(zero);
        let mut tests = 0;
        if ok.any() {
            // To the sphere (the first thing the ray meets must be it), then from its point
            // to the map.
            let origin = offset_ray(s, p, ng);
            let mut t_mirror = s.splat(NO_HIT);
            for b in &self.mirrors {
                let this = ok & index.eq(s.int(b.index as i32));
                if this.any() {
                    t_mirror = t_mirror.blend(self.hit(s, b.index, origin, x.dir), this);
                }
            }
            ok = ok & t_mirror.gt(zero);
            let skip = (from, index);
            ok = ok.without(self.occluded(s, (origin, x.dir), t_mirror, usize::MAX, skip, ok));
            let at: V3<S> = each!(|k| p[k] + x.dir[k] * x.dist);
            let origin = offset_ray(s, at, x.normal);
            let (none, far) = (s.int(NONE), s.splat(T_FAR));
            ok = ok.without(self.occluded(s, (origin, w), far, usize::MAX, (index, none), ok));
            tests = 2 * (lanes.bits().count_ones() as u64) * self.kinds.len() as u64;
        }
        let l = map_radiance(s, (&env.map, env.intensity), (u, v), ok);
        let radiance = each!(|k| l[k] * tint[k]);
        let pl = self.mirror_pdf(s, pdf, spread);
        let l = match view {
            Some(px) => self.view_weighted(s, radiance, (p, x.dir), pl, px),
            None => light_weighted(s, radiance, (cos_s, x.dir, n), pl, lobe),
        };
        (each!(|k| l[k].keep(ok)), tests)
    }

    /// `Tracer::mirror_pdf`: the density, in solid angle at the point that sees it, with which
    /// `sample_mirror` finds the map's direction of density `pdf` in a mirror sphere of spread
    /// `spread`.
    #[inline(always)]
    fn mirror_pdf<S: Isa>(&self, s: S, pdf: F<S>, spread: F<S>) -> F<S> {
        pdf / (s.splat(self.mirrors.len() as f32) * spread)
    }

    /// `Tracer::sample_view` for the paths starting in lanes `m` (the pixels' columns `x`,
    /// row `y`): the map the camera sees in the mirror spheres, where the pixel may see one
    /// (`view_meets`), and the density with which the camera ray was drawn, which weighs the
    /// same paths found by the ray at its first hit.
    #[inline(always)]
    fn sample_view<S: Isa>(&self, s: S, p: &mut Paths<S>, m: M<S>, (x, y): (I<S>, u32)) {
        let (o, d, zero) = (p.o, p.d, s.zero());
        if self.max_bounces >= 1 {
            let meets = m & self.view_meets(s, o, d);
            if meets.any() {
                let ahead = lit(s, self.view.ahead);
                let cosine = Lobe {
                    gloss: s.mask(0),
                    mixed: s.mask(0),
                    r: [zero; 3],
                    smooth: zero,
                    p: zero,
                };
                let lobe = (&cosine, ([zero; 3], [zero; 3]));
                let at = (o, ahead, ahead);
                let view = Some((x, y));
                let none = s.int(NONE);
                let (l, _) = self.sample_mirror(s, at, none, meets, view, lobe, &mut p.rng);
                for (r, l) in p.radiance.iter_mut().zip(l) {
                    *r = r.blend(*r + l, meets);
                }
            }
        }
        let (_, _, pc, ahead) = self.pixel_at(s, o, d);
        p.view_pdf = p.view_pdf.blend(pc.keep(ahead), m);
    }

    /// `Tracer::pixel_at` in lanes: where the rays from lens points `o` along `d` cross the
    /// focus plane, in pixels, and the density in solid angle with which the pixel's camera
    /// rays find them; the lanes whose rays point ahead of the camera.
    #[inline(always)]
    fn pixel_at<S: Isa>(&self, s: S, o: V3<S>, d: V3<S>) -> (F<S>, F<S>, F<S>, M<S>) {
        let (c, v) = (&self.camera, &self.view);
        let ahead = lit(s, v.ahead);
        let cos = dot(d, ahead);
        let lens: V3<S> = each!(|k| o[k] - s.splat(c.origin[k]));
        let to: V3<S> = each!(|k| s.splat(v.centre[k]) - lens[k]);
        let dist = dot(to, ahead) / cos;
        let q: V3<S> = each!(|k| (lens[k] + dist * d[k]) - s.splat(c.corner[k]));
        let (h, vv) = (lit(s, c.horizontal), lit(s, c.vertical));
        let x = (dot(q, h) / s.splat(v.h2)) * s.splat(c.size[0]);
        let y = (-dot(q, vv) / s.splat(v.v2)) * s.splat(c.size[1]);
        let pc = (dist * dist) / (cos * s.splat(v.area));
        (x, y, pc, cos.gt(s.zero()))
    }

    /// `Tracer::view_weighted` in lanes: a light sample of density `pl` reaching lens points
    /// `o` along `dir`, as an estimate of the lanes' pixels (columns `x`, row `y`): none where
    /// the direction is not in the pixel, else radiance / (p_c/pl + pl/p_c).
    #[inline(always)]
    fn view_weighted<S: Isa>(
        &self,
        s: S,
        radiance: V3<S>,
        (o, dir): (V3<S>, V3<S>),
        pl: F<S>,
        (x, y): (I<S>, u32),
    ) -> V3<S> {
        let (px, py, pc, ahead) = self.pixel_at(s, o, dir);
        let inside = (ahead & pc.gt(s.zero()))
            & map::floor(s, px).cmp::<_CMP_EQ_OQ>(x.to_float())
            & map::floor(s, py).cmp::<_CMP_EQ_OQ>(s.splat(y as f32));
        let w = pc / pl + pl / pc;
        each!(|k| (radiance[k] / w).keep(inside))
    }

    /// `Tracer::view_meets` in lanes: whether the pixels of camera rays (o, d) may see one of
    /// the mirror spheres.
    #[inline(always)]
    fn view_meets<S: Isa>(&self, s: S, o: V3<S>, d: V3<S>) -> M<S> {
        let one = s.splat(1.0);
        let (sin_b, cos_b) = (s.splat(self.view.sin_b), s.splat(self.view.cos_b));
        let mut meets = s.mask(0);
        for b in &self.mirrors {
            let to: V3<S> = each!(|k| s.splat(b.center[k]) - o[k]);
            let d2 = dot(to, to);
            let r2 = s.splat(b.r * b.r);
            let ratio = r2 / d2;
            let (sin_a, cos_a) = (ratio.sqrt(), (one - ratio).sqrt());
            let cone = d2.sqrt() * (cos_a * cos_b - sin_a * sin_b);
            meets = meets | d2.le(r2) | dot(d, to).ge(cone);
        }
        meets
    }

    /// Sphere `sp`'s shape in row k of the tables.
    fn put_sphere(&mut self, k: usize, sp: &super::intersect::Sphere) {
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        let r = sp.radius.abs();
        for c in 0..3 {
            self.anchor[c][k] = sp.anchor[c];
            self.normal[c][k] = sp.anchor_normal[c];
            self.r_normal[c][k] = (r * sp.anchor_normal)[c];
        }
        self.r[k] = r;
        self.two_r[k] = 2.0 * r;
        self.outward[k] = flag(sp.radius > 0.0);
        self.inward[k] = flag(sp.radius < 0.0);
    }
}

/// The root of the scalar tracer's eight-wide tree (`Bvh8`), tested in lanes: its boxes
/// against every lane's ray at once, and the spheres of its leaves with `hit_sphere` (the
/// scalar test bit for bit), in the walk's order (leaves first, slot by slot; a nearer hit
/// replaces the best). A lane whose ray enters no other slot nearer than its best hit (an
/// inner node, a leaf of other primitives) ends its walk there: the ground of an outdoor
/// scene, the sky. The others walk on, each on its own, from the root's inner slots they
/// enter (`Tracer::nearest_below_root`, `Tracer::occluded_below_root`: the root is not
/// visited twice), or from the root where a ray enters a leaf of other primitives. So each
/// lane's hit is the scalar walk's, and most rays that miss a model never leave the lanes.
struct Root {
    /// The valid slots, in the walk's order.
    slots: Vec<RootSlot>,
}

/// A slot of the root: its box, and the spheres of a leaf that the lanes test (row of the
/// tables, reference), none where they walk it (an inner node, or a leaf of other
/// primitives or of more spheres than the tables hold).
struct RootSlot {
    /// Its slot in the root node.
    slot: usize,
    min: [f32; 3],
    max: [f32; 3],
    spheres: Vec<RootSphere>,
    leaf: bool,
}

/// A sphere of a root leaf: its row of the lanes' tables, its reference, and what
/// `Tracer::met` reads of it (its material's row in the walk's tables, its colour).
#[derive(Clone, Copy)]
struct RootSphere {
    k: usize,
    r: u32,
    material: i32,
    color: [f32; 3],
}

impl Root {
    /// The root `r` of `s`'s tree, its leaves' spheres put in `l`'s tables from row 0.
    fn of(l: &mut Lanes, s: &CpuScene, r: &super::bvh8::Root, material_rows: &[i32]) -> Root {
        let mut slots = Vec::new();
        let mut rows = 0;
        for slot in (0..8).filter(|&j| r.valid >> j & 1 != 0) {
            let leaf = r.leaves >> slot & 1 != 0;
            let mut spheres = Vec::new();
            if leaf {
                let first = r.child[slot] as usize;
                let refs = &s.bvh.refs[first..first + r.count[slot] as usize];
                if refs.iter().all(|&x| x >> 30 == 0) && rows + refs.len() <= MAX_PRIMITIVES {
                    for &x in refs {
                        let sp = &s.spheres[(x & REF_INDEX) as usize];
                        l.put_sphere(rows, sp);
                        spheres.push(RootSphere {
                            k: rows,
                            r: x,
                            material: material_rows[sp.material as usize],
                            color: s.materials[sp.material as usize].color.to_array(),
                        });
                        rows += 1;
                    }
                }
            }
            slots.push(RootSlot {
                slot,
                min: from_fn(|c| r.min[c][slot]),
                max: from_fn(|c| r.max[c][slot]),
                spheres,
                leaf,
            });
        }
        Root { slots }
    }
}

impl RootSlot {
    /// `Bvh8::slab` of this slot for the rays from `o` of inverse directions `inv`, in
    /// lanes (its operations, in its order): the entry distances, and the lanes that enter
    /// before `t_max`.
    #[inline(always)]
    fn slab<S: Isa>(&self, s: S, (o, inv): (V3<S>, V3<S>), t_max: F<S>) -> (F<S>, M<S>) {
        let t0: V3<S> = each!(|c| (s.splat(self.min[c]) - o[c]) * inv[c]);
        let t1: V3<S> = each!(|c| (s.splat(self.max[c]) - o[c]) * inv[c]);
        let near = (t0[0].min(t1[0]).max(t0[1].min(t1[1]))).max(t0[2].min(t1[2]).max(s.zero()));
        let far = (t0[0].max(t1[0]).min(t0[1].max(t1[1]))).min(t0[2].max(t1[2]).min(t_max));
        (near, near.le(far))
    }
}

/// The lanes whose rays walk the tree from the root's inner slots on (`Walk::closest`),
/// and what the root's visit in lanes gave them: each valid slot's entry distances and the
/// lanes that enter it (as `root.slots`).
struct Below<'a, S: Isa> {
    lanes: M<S>,
    near: &'a [F<S>; 8],
    entered: &'a [M<S>; 8],
    root: &'a Root,
}

impl<S: Isa> Below<'_, S> {
    /// Lane k's visit of the root, for `Tracer::nearest_below_root`: its best hit (t, r)
    /// among the root's leaves (`NONE`: none, t then `T_FAR`), and the inner slots it
    /// enters with their distances (`near`, `entered`: `self`'s, stored by slot).
    #[inline(always)]
    fn at_root(
        &self,
        k: usize,
        (t, r): (f32, i32),
        near: &[[f32; MAX_LANES]; 8],
        entered: &[u32; 8],
    ) -> super::bvh8::AtRoot {
        let mut at = super::bvh8::AtRoot {
            best: (r != NONE).then_some((t, r as u32)),
            t_best: t,
            inner: 0,
            near: [0.0; 8],
        };
        for (j, slot) in self.root.slots.iter().enumerate() {
            if !slot.leaf && entered[j] >> k & 1 != 0 {
                at.inner |= 1 << slot.slot;
                at.near[slot.slot] = near[j][k];
            }
        }
        at
    }
}

/// `intersect::safe_inverse` of directions `d` in lanes: 1 / d, a component below 10⁻³⁰ in
/// magnitude (or NaN) taken as 10⁻³⁰.
#[inline(always)]
fn inverse<S: Isa>(s: S, d: V3<S>) -> V3<S> {
    let tiny = s.splat(1e-30);
    each!(|c| s.splat(1.0) / tiny.blend(d[c], d[c].abs().ge(tiny)))
}

/// A material as the tables hold it (`Lanes::put`): whether it emits, its colour and
/// light; whether its specular lobe is certain or drawn, with what probability, its
/// smoothness s and 1 − s, whether s is 0, the lobe's tint and fuzz; whether light sampling
/// weighs the glossy lobe, alone or mixed; glass and its index; its light slot.
#[derive(Clone, Copy, PartialEq, Default)]
struct Entry {
    emits: f32,
    color: [f32; 3],
    light: f32,
    certain: f32,
    maybe: f32,
    p_spec: f32,
    smooth: f32,
    rough: f32,
    flat: f32,
    spec_color: [f32; 3],
    fuzz: f32,
    glossy: f32,
    mixed: f32,
    glass: f32,
    ior: f32,
    inv_ior: f32,
    slot: f32,
}

impl Entry {
    /// Material `m` traced with features `f`, where the lanes trace it (not glTF's BRDF, nor
    /// a smoothness below 0 without glass).
    fn of(m: &super::scene::Material, f: Features) -> Option<Entry> {
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        if m.pbr {
            return None;
        }
        let mut e = Entry {
            slot: m.light_slot as f32,
            color: m.color.to_array(),
            light: m.light,
            ..Entry::default()
        };
        if f.emitters && m.light > 0.0 {
            // An emitter ends the path where it is met, whatever its other keys.
            e.emits = 1.0;
            return Some(e);
        }
        e.fuzz = m.absorption;
        if f.dielectrics && m.smoothness < 0.0 {
            e.glass = 1.0;
            e.ior = m.ior;
            e.inv_ior = 1.0 / m.ior;
            return Some(e);
        }
        if m.smoothness < 0.0 {
            return None;
        }
        e.spec_color = m.specular_color.to_array();
        e.certain = flag(m.specular >= 1.0);
        e.maybe = flag(m.specular > 0.0 && m.specular < 1.0);
        e.p_spec = m.specular;
        e.smooth = m.smoothness;
        e.rough = 1.0 - m.smoothness;
        e.flat = flag(m.smoothness == 0.0);
        let glossy = f.gloss_nee
            && m.specular > 0.0
            && m.smoothness > 0.0
            && m.smoothness < 1.0
            && m.absorption == 0.0;
        e.glossy = flag(glossy);
        e.mixed = flag(glossy && m.specular < 1.0);
        Some(e)
    }
}

impl Lanes<'_> {
    /// Material entry `e` into row k of the tables.
    fn put(&mut self, k: usize, e: &Entry) {
        for c in 0..3 {
            self.color[c][k] = e.color[c];
            self.spec_color[c][k] = e.spec_color[c];
        }
        self.emits[k] = e.emits;
        self.light[k] = e.light;
        self.certain[k] = e.certain;
        self.maybe[k] = e.maybe;
        self.p_spec[k] = e.p_spec;
        self.smooth[k] = e.smooth;
        self.rough[k] = e.rough;
        self.flat[k] = e.flat;
        self.fuzz[k] = e.fuzz;
        self.glossy[k] = e.glossy;
        self.mixed[k] = e.mixed;
        self.glass[k] = e.glass;
        self.ior[k] = e.ior;
        self.inv_ior[k] = e.inv_ior;
        self.slot[k] = e.slot;
    }
}

impl Lanes<'_> {
    /// Pixels traced side by side: sixteen on AVX-512, else eight.
    pub fn width(&self) -> usize {
        if self.wide.is_some() {
            Avx512::N
        } else {
            Avx2::N
        }
    }

    /// Traces samples `samples` of the `n` (up to `width()`) pixels of row `y` (of `width`)
    /// from column `x0`, one pixel a lane, as `Tracer::trace_path` traces each path, and
    /// hands each path to `done` when it ends: its lane (the pixel x0 + lane), its sample,
    /// and the path (`Traced`), with seed `seed`'s samplers. A lane whose path ends
    /// starts its pixel's next sample at once (path regeneration: Novák, Havran and
    /// Dachsbacher, "Path Regeneration for Interactive Path Tracing", Eurographics 2010), so
    /// the lanes stay busy while the paths' lengths differ. Returns the tree's nodes visited
    /// (a walk's) and the primitive tests made.
    pub fn trace(
        &self,
        at: (u32, u32, u32),
        n: usize,
        samples: std::ops::Range<u32>,
        seed: u32,
        done: impl FnMut(usize, u32, Traced),
    ) -> (u64, u64) {
        match self.wide {
            // SAFETY: the token says the CPU has AVX-512 F, DQ and BW, `narrow` AVX and AVX2.
            Some(s) => unsafe { self.trace_avx512(s, at, n, samples, seed, done) },
            // SAFETY: the token says the CPU has AVX and AVX2.
            None => unsafe { self.trace_avx2(self.narrow, at, n, samples, seed, done) },
        }
    }

    entry!(
        trace_avx2,
        Avx2,
        "avx,avx2",
        "`trace` compiled for AVX2, eight lanes."
    );
    entry!(
        trace_avx512,
        Avx512,
        "avx,avx2,avx512f,avx512dq,avx512bw",
        "`trace` compiled for AVX-512, sixteen lanes."
    );

    /// `trace` in the lanes of `S`, inlined into the entry point that enables it (as is
    /// everything below).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trace_in<S: Isa>(
        &self,
        s: S,
        (x0, y, width): (u32, u32, u32),
        n: usize,
        samples: std::ops::Range<u32>,
        seed: u32,
        mut done: impl FnMut(usize, u32, Traced),
    ) -> (u64, u64) {
        debug_assert!(n <= S::N);
        let (zero, one) = (s.zero(), s.splat(1.0));
        let pixel = s.ints(&from_fn(|k| (y * width + x0 + k as u32) as i32));
        let column = s.ints(&from_fn(|k| (x0 + k as u32) as i32));
        let mut tests = 0u64;
        let mut p = Paths {
            o: [zero; 3],
            d: [zero, zero, one],
            throughput: [one; 3],
            radiance: [zero; 3],
            segments: s.int(0),
            bounce: s.int(0),
            skip: s.int(NONE),
            prev_pdf: zero,
            prev_point: [zero; 3],
            prev_normal: [zero, one, zero],
            view_pdf: zero,
            mirror_pdf: zero,
            mirror_spread: zero,
            rng: Draws::new(s),
        };
        let mut next = [samples.start; MAX_LANES];
        let mut sample_of = [0i32; MAX_LANES];
        let mut active = 0u32;
        loop {
            // Each idle lane starts its pixel's next sample: its sampler and camera ray.
            let mut starts = 0u32;
            for k in 0..n {
                if active >> k & 1 == 0 && next[k] < samples.end {
                    sample_of[k] = next[k] as i32;
                    next[k] += 1;
                    starts |= 1 << k;
                }
            }
            if starts != 0 {
                let m = s.mask(starts);
                p.rng.start(s, m, pixel, s.ints(&sample_of), seed);
                let (o, d) = self.camera(s, m, column, y, &mut p.rng);
                p.start(s, m, o, d);
                if !self.mirrors.is_empty() {
                    self.sample_view(s, &mut p, m, (column, y));
                }
                active |= starts;
            }
            if active == 0 {
                break;
            }
            let before = active;
            active = self.step(s, &mut p, active, &mut tests);
            let ended = before & !active;
            if ended != 0 {
                let (mut out, mut whole, mut frac) = (
                    [[0.0f32; MAX_LANES]; 3],
                    [[0; MAX_LANES]; 3],
                    [[0; MAX_LANES]; 3],
                );
                let mut finite = s.mask(u32::MAX);
                for c in 0..3 {
                    let r = p.radiance[c];
                    r.store(&mut out[c]);
                    finite = finite & r.abs().lt(s.splat(f32::INFINITY));
                    let (w, f) = fixed_words(s, r);
                    w.store(&mut whole[c]);
                    f.store(&mut frac[c]);
                }
                let (mut segments, mut taken, mut state) =
                    ([0; MAX_LANES], [0; MAX_LANES], [0; MAX_LANES]);
                p.segments.store(&mut segments);
                let (t, st) = p.rng.taken_and_state();
                t.store(&mut taken);
                st.store(&mut state);
                let finite = finite.bits();
                for k in lanes_of(ended) {
                    let words = (finite >> k & 1 != 0).then_some(each!(|c| {
                        (whole[c][k] as u32 as u64) << 32 | frac[c][k] as u32 as u64
                    }));
                    let path = Traced {
                        radiance: Vec3A::new(out[0][k], out[1][k], out[2][k]),
                        segments: segments[k] as u32,
                        words,
                        taken: taken[k] as u32,
                        state: state[k] as u32,
                    };
                    done(k, sample_of[k] as u32, path);
                }
            }
        }
        match &self.walk {
            Some(w) => {
                let tally = std::mem::take(&mut w.tracer.borrow_mut().tally);
                (tally.visits, tests + tally.tests)
            }
            None => (0, tests),
        }
    }

    /// `Tracer::camera_ray` of the lanes of `m`, at columns `x` of row `y`: the jitter in the
    /// pixel, the lens's point where it has one, the ray normalized as glam's `normalize`
    /// (a division by the square root).
    #[inline(always)]
    fn camera<S: Isa>(&self, s: S, m: M<S>, x: I<S>, y: u32, rng: &mut Draws<S>) -> (V3<S>, V3<S>) {
        let c = &self.camera;
        let (jx, jy) = rng.draw2(s, m);
        let sx = (x.to_float() + jx) / s.splat(c.size[0]);
        let ty = (s.splat(y as f32) + jy) / s.splat(c.size[1]);
        let target = each!(|k| (s.splat(c.corner[k]) + sx * s.splat(c.horizontal[k]))
            - ty * s.splat(c.vertical[k]));
        let mut lens = [s.zero(); 3];
        if c.lens_radius > 0.0 {
            // sampling::random_in_disk, scaled by the lens's radius.
            let (u, v) = rng.draw2(s, m);
            let r = u.sqrt();
            let (sin, cos) = sin_cos_turns(s, v);
            let radius = s.splat(c.lens_radius);
            let (px, py) = ((r * cos) * radius, (r * sin) * radius);
            lens = each!(|k| px * s.splat(c.u[k]) + py * s.splat(c.v[k]));
        }
        let origin = each!(|k| s.splat(c.origin[k]) + lens[k]);
        let to = each!(|k| target[k] - lens[k]);
        let len = dot(to, to).sqrt();
        (origin, each!(|k| to[k] / len))
    }

    /// One bounce of the paths in lanes `active` (`trace_path`'s loop body); returns the
    /// lanes whose paths go on.
    #[inline(always)]
    fn step<S: Isa>(&self, s: S, p: &mut Paths<S>, active: u32, tests: &mut u64) -> u32 {
        let zero = s.zero();
        let one = s.splat(1.0);
        let nee = self.nee;
        let Paths {
            o,
            d,
            throughput,
            radiance,
            ..
        } = p;
        let live = s.mask(active);
        p.segments = p.segments.count(live);
        *tests += (active.count_ones() as u64) * self.kinds.len() as u64;
        let (best, index, found) = match &self.walk {
            Some(w) => w.closest(self, s, (*o, *d), p.skip, live),
            None => {
                let (best, index) = self.closest(s, *o, *d, p.skip);
                (best, index, index.gt(s.int(NONE)))
            }
        };
        let missed = live.without(found);
        if missed.any() {
            let sky = match &self.env {
                Some(env) => {
                    let mirrored = (p.mirror_pdf, p.mirror_spread);
                    self.escaped(s, env, *d, missed, p.bounce, (p.prev_pdf, mirrored))
                }
                None => self.sky(s, *d, missed),
            };
            for c in 0..3 {
                let add = radiance[c] + throughput[c] * sky[c];
                radiance[c] = radiance[c].blend(add, missed);
            }
        }
        let mut hit = found & live;
        if !hit.any() {
            return 0;
        }
        // The tables' row (a primitive's; a walk's material), the primitive, the point and
        // geometric normal, and a walk's colour and shading normal.
        let (idx, prim, position, n_out, met) = match &self.walk {
            Some(w) => {
                let m = w.surface(self, s, (*o, *d), (best, index), hit);
                (
                    m.material,
                    index,
                    m.position,
                    m.normal,
                    Some((m.color, m.shading)),
                )
            }
            None => {
                let idx = index.max(s.int(0));
                let (position, n_out) = self.surface(s, *o, *d, best, idx);
                (idx, idx, position, n_out, None)
            }
        };
        // A mirror sphere met from a lobe light sampling weighs, or by the camera ray: what
        // it reflects from the map next is weighed against `sample_mirror` (`mirror_hit`).
        if !self.mirrors.is_empty() {
            let drawn = p.prev_pdf.blend(p.view_pdf, p.bounce.eq(s.int(0)));
            let on = (hit & flagged(s, &self.reflector, idx)) & drawn.gt(zero);
            let cos_i = -dot(*d, n_out);
            let apart: V3<S> = each!(|c| position[c] - p.prev_point[c]);
            let r = F::pick(&self.r, idx);
            let spread = mirror::spread(s, r, dot(apart, apart).sqrt(), cos_i);
            let met = (on & cos_i.gt(zero)) & spread.gt(zero);
            p.mirror_pdf = p.mirror_pdf.blend(drawn.keep(met), hit);
            p.mirror_spread = p.mirror_spread.blend(spread, hit);
        }
        // An emitter: its light, weighed against light sampling where the last lobe's
        // density is known, and the path ends.
        let emits = flagged(s, &self.emits, idx) & hit;
        if emits.any() {
            let mut w = one;
            if nee {
                // Weighed where it is a light (`light_slot`), against the chance that light
                // sampling chose it from the last vertex and drew this point.
                let slot = F::pick(&self.slot, idx);
                let mut pl = self.light_pdf(s, idx, p.prev_point, position);
                if self.lamps.len() > 1 {
                    let (weights, total) = self.light_weights(s, p.prev_point, p.prev_normal);
                    let mut w_slot = zero;
                    for (i, &wi) in weights.iter().enumerate() {
                        w_slot = w_slot.blend(wi, slot.cmp::<_CMP_EQ_OQ>(s.splat(i as f32 + 1.0)));
                    }
                    pl = (w_slot / total) * pl;
                }
                let weigh = p.prev_pdf.gt(zero) & slot.gt(zero);
                w = one.blend(power_heuristic(p.prev_pdf, pl), weigh);
            }
            let (color, light) = (pick3(&self.color, idx), F::pick(&self.light, idx));
            for c in 0..3 {
                let e = ((throughput[c] * color[c]) * light) * w;
                radiance[c] = radiance[c].blend(radiance[c] + e, emits);
            }
            hit = hit.without(emits);
        }
        // The paths at the bounce limit end here.
        let last = p.bounce.eq(s.int(self.max_bounces as i32));
        hit = hit.without(last);
        let on = hit.bits();
        if on == 0 {
            return 0;
        }
        // The facing normal, and the shading normal on its side.
        let front = dot(*d, n_out).lt(zero);
        let nf = each!(|c| (-n_out[c]).blend(n_out[c], front));
        let normals = self.walk.as_ref().is_some_and(|w| w.normals);
        let ns = match met {
            Some((_, shading)) if normals => shading,
            _ => nf,
        };
        let glass = flagged(s, &self.glass, idx) & hit;
        let surface = hit.without(glass);
        // The lobe (`trace_path`'s is_spec): the specular one where it is certain, or drawn
        // with the material's probability; its tint.
        let mut spec = flagged(s, &self.certain, idx) & surface;
        let maybe = flagged(s, &self.maybe, idx) & surface;
        if maybe.any() {
            let u = p.rng.draw(s, maybe);
            spec = spec | (maybe & u.lt(F::pick(&self.p_spec, idx)));
        }
        let color = match met {
            Some((color, _)) => color,
            None => pick3(&self.color, idx),
        };
        let spec_color = pick3(&self.spec_color, idx);
        let tint = each!(|c| color[c].blend(spec_color[c], spec));
        // The lobes light sampling weighs: the diffuse one, the specular one at smoothness 0,
        // and the glossy one, alone or mixed with the diffuse one (`Weighed`).
        let glossy = flagged(s, &self.glossy, idx) & surface;
        let weighs = flagged(s, &self.flat, idx) | glossy;
        let sampled = surface.without(spec.without(weighs));
        // The mirror direction (`reflect(d, n)`): the glossy lobe's axis, the specular lobe's
        // and glass's reflection (about the shading normal, glass's about the geometric one).
        let dn = s.splat(2.0) * dot(*d, ns);
        let reflected: V3<S> = each!(|c| d[c] - dn * ns[c]);
        let mixed = flagged(s, &self.mixed, idx);
        let lobe = Lobe {
            gloss: glossy.without(mixed),
            mixed: glossy & mixed,
            r: reflected,
            smooth: F::pick(&self.smooth, idx),
            p: F::pick(&self.p_spec, idx),
        };
        // Light sampling at the lobes it weighs: the shadow ray leaves on the facing side, and
        // cannot meet the primitive it leaves (`leaving(hit, front)`). The mixture's tints
        // are its own.
        if nee && sampled.any() {
            let from = self.leaving(s, prim, front, sampled);
            let tints = (spec_color, color);
            let at = (position, ns, nf);
            let (l, t) = self.sample_light(s, at, from, sampled, (&lobe, tints), &mut p.rng);
            *tests += t;
            let tint = each!(|c| tint[c].blend(one, lobe.mixed));
            for c in 0..3 {
                let add = (throughput[c] * tint[c]) * l[c];
                radiance[c] = radiance[c].blend(radiance[c] + add, sampled);
            }
            // The map in the mirror spheres: its paths scatter here and at the mirror, and
            // leave it, within the bounces allowed.
            let room = sampled & s.int(self.max_bounces as i32 - 1).gt(p.bounce);
            if !self.mirrors.is_empty() && room.any() {
                let lobe = (&lobe, tints);
                let (l, t) = self.sample_mirror(s, at, from, room, None, lobe, &mut p.rng);
                *tests += t;
                for c in 0..3 {
                    let add = (throughput[c] * tint[c]) * l[c];
                    radiance[c] = radiance[c].blend(radiance[c] + add, room);
                }
            }
        }
        // The lobe's direction (`scatter_surface`): the diffuse one, or blended toward the
        // mirror direction (fuzzed by a second draw where the lobe has fuzz) by the
        // smoothness (`Vec3A::lerp`) and normalized again.
        let (u, v) = p.rng.draw2(s, surface);
        let unit = random_unit_vector(s, u, v);
        let diffuse = normalize_or(s, each!(|c| ns[c] + unit[c]), ns);
        let mut dir = if spec.any() {
            let (smooth, rough) = (lobe.smooth, F::pick(&self.rough, idx));
            let mut mirror = reflected;
            let fuzz = F::pick(&self.fuzz, idx);
            let fuzzed = fuzz.gt(zero) & spec;
            let fuzzy = fuzzed.bits();
            if fuzzy != 0 {
                let (u, v) = p.rng.draw2(s, fuzzed);
                let unit = random_unit_vector(s, u, v);
                let moved = normalize_or(s, each!(|c| mirror[c] + fuzz * unit[c]), ns);
                for c in 0..3 {
                    mirror[c] = mirror[c].blend(moved[c], fuzzed);
                }
            }
            let blend: V3<S> = each!(|c| diffuse[c] * rough + mirror[c] * smooth);
            let specular = normalize_or(s, blend, ns);
            each!(|c| diffuse[c].blend(specular[c], spec))
        } else {
            diffuse
        };
        if glass.any() {
            let mirror = if normals {
                let dn = s.splat(2.0) * dot(*d, nf);
                each!(|c| d[c] - dn * nf[c])
            } else {
                reflected
            };
            let through = self.refract(s, (*d, nf, front), mirror, (idx, glass), &mut p.rng);
            for c in 0..3 {
                dir[c] = dir[c].blend(through[c], glass);
            }
        }
        // Absorbed where dir·n <= 0 (a NaN goes on, as in `scatter_surface`), and with shading
        // normals where the direction enters the surface; glass never.
        let mut stays = dot(dir, ns).cmp::<_CMP_NLE_UQ>(zero);
        if normals {
            stays = stays & dot(dir, nf).cmp::<_CMP_NLE_UQ>(zero);
        }
        let mut kept = (stays & surface) | glass;
        if nee {
            // `lobe_pdf`.
            let cosine = dot(dir, ns).max(zero) / s.splat(PI);
            let mut pdf = cosine;
            if glossy.any() {
                let g = gloss_pdf(s, dir, ns, lobe.r, lobe.smooth);
                let mix = lobe.p * g + (one - lobe.p) * cosine;
                pdf = pdf.blend(g, lobe.gloss).blend(mix, lobe.mixed);
            }
            p.prev_pdf = p.prev_pdf.blend(pdf.keep(sampled), hit);
            for (prev, n) in p.prev_normal.iter_mut().zip(ns) {
                *prev = prev.blend(n, sampled);
            }
        }
        for c in 0..3 {
            throughput[c] = throughput[c].blend(throughput[c] * tint[c], kept);
            p.prev_point[c] = p.prev_point[c].blend(position[c], kept);
        }
        // Russian roulette, with light sampling only, from bounce RR_START.
        if nee {
            let late = p.bounce.gt(s.int(RR_START as i32 - 1));
            let plays = kept & late;
            let playing = plays.bits();
            if playing != 0 {
                let (x, y, z) = (throughput[0], throughput[1], throughput[2]);
                let q = x.max(z).max(y).min(s.splat(RR_MAX_SURVIVAL));
                let u = p.rng.draw(s, plays);
                let lost = plays.without(u.cmp::<_CMP_NGE_UQ>(q));
                kept = kept.without(lost);
                let divided = plays.without(lost);
                for t in throughput.iter_mut() {
                    *t = t.blend(*t / q, divided);
                }
            }
        }
        // The side the ray leaves by, the primitive it cannot meet next (`leaving`), and its
        // origin moved off the surface (`offset_ray`).
        let out = dot(dir, n_out).gt(zero);
        let side = each!(|c| (-n_out[c]).blend(n_out[c], out));
        p.skip = p.skip.blend(self.leaving(s, prim, out, kept), kept);
        let moved = offset_ray(s, position, side);
        for c in 0..3 {
            o[c] = o[c].blend(moved[c], kept);
            d[c] = d[c].blend(dir[c], kept);
        }
        p.bounce = p.bounce.count(kept);
        kept.bits()
    }

    /// The nearest hit of the rays and its primitive (`NONE` for none), primitive `skip`
    /// left out (`hit_except`); the first in the scene's order at equal distances.
    #[inline(always)]
    fn closest<S: Isa>(&self, s: S, o: V3<S>, d: V3<S>, skip: I<S>) -> (F<S>, I<S>) {
        let mut best = s.splat(T_FAR);
        let mut index = s.int(NONE);
        for k in 0..self.kinds.len() {
            let t = self.hit(s, k, o, d);
            let kk = s.int(k as i32);
            let nearer = between(s, t, best).without(skip.eq(kk));
            best = best.blend(t, nearer);
            index = index.blend(kk, nearer);
        }
        (best, index)
    }

    /// Whether each ray meets any primitive but `skip` and `from` before `t_max` (a walk's,
    /// in the lanes of `lanes`).
    #[inline(always)]
    fn occluded<S: Isa>(
        &self,
        s: S,
        (o, d): (V3<S>, V3<S>),
        t_max: F<S>,
        skip: usize,
        (from, also): (I<S>, I<S>),
        lanes: M<S>,
    ) -> M<S> {
        if let Some(w) = &self.walk {
            return w.occluded(self, s, (o, d), t_max, (from, also), lanes);
        }
        let mut blocked = s.mask(0);
        for k in (0..self.kinds.len()).filter(|&k| k != skip) {
            let t = self.hit(s, k, o, d);
            let kk = s.int(k as i32);
            let left = from.eq(kk) | also.eq(kk);
            blocked = blocked | between(s, t, t_max).without(left);
        }
        blocked
    }

    /// Primitive k's distance along the rays (t_max `T_FAR`), or NO_HIT.
    #[inline(always)]
    fn hit<S: Isa>(&self, s: S, k: usize, o: V3<S>, d: V3<S>) -> F<S> {
        match self.kinds[k] {
            Kind::Sphere => self.hit_sphere(s, k, o, d),
            Kind::Quad => self.hit_quad(s, k, o, d),
            Kind::Box => self.hit_box(s, k, o, d),
        }
    }

    /// `hit_sphere` of sphere `k` for the rays.
    #[inline(always)]
    fn hit_sphere<S: Isa>(&self, s: S, k: usize, o: V3<S>, d: V3<S>) -> F<S> {
        let zero = s.zero();
        let r = s.splat(self.r[k]);
        let g: V3<S> = each!(|c| o[c] - s.splat(self.anchor[c][k]));
        let f: V3<S> = each!(|c| g[c] + s.splat(self.r_normal[c][k]));
        let b = dot(f, d);
        let l: V3<S> = each!(|c| f[c] - b * d[c]);
        let ll = dot(l, l).sqrt();
        let disc = (r - ll) * (r + ll);
        let an = column(s, &self.normal, k);
        let c = dot(g, g) + s.splat(self.two_r[k]) * dot(g, an);
        let sq = disc.sqrt();
        let below = b.lt(zero);
        let q = -b - sq.blend(-sq, below);
        let t0 = c / q;
        // f32::min and max: where t0 is NaN, q.
        let near = t0.min(q);
        let far = t0.max(q);
        let no_hit = s.splat(NO_HIT);
        let t = no_hit
            .blend(far, within(s, far))
            .blend(near, within(s, near));
        // Neither a ray that passes the sphere (disc < 0) nor one with q = 0 hits it.
        let fails = disc.lt(zero) | q.cmp::<_CMP_EQ_OQ>(zero);
        t.blend(no_hit, fails)
    }

    /// `hit_quad` of quad `k` for the rays.
    #[inline(always)]
    fn hit_quad<S: Isa>(&self, s: S, k: usize, o: V3<S>, d: V3<S>) -> F<S> {
        let zero = s.zero();
        let one = s.splat(1.0);
        let quad = &self.quad;
        let (q, u, v) = (
            column(s, &quad[0], k),
            column(s, &quad[1], k),
            column(s, &quad[2], k),
        );
        let (n, w) = (column(s, &quad[3], k), column(s, &quad[4], k));
        let denom = dot(n, d);
        let flat = denom.abs().lt(s.splat(1e-20));
        let qo: V3<S> = each!(|c| q[c] - o[c]);
        let t = dot(n, qo) / denom;
        let p: V3<S> = each!(|c| (o[c] + t * d[c]) - q[c]);
        let alpha = dot(w, cross(p, v));
        let beta = dot(w, cross(u, p));
        let inside = (alpha.ge(zero) & alpha.le(one)) & (beta.ge(zero) & beta.le(one));
        let hits = (within(s, t) & inside).without(flat);
        s.splat(NO_HIT).blend(t, hits)
    }

    /// `hit_box` of box `k` for the rays: the slab test in the box's frame.
    #[inline(always)]
    fn hit_box<S: Isa>(&self, s: S, k: usize, o: V3<S>, d: V3<S>) -> F<S> {
        let axes = each!(|a| column(s, &self.axes[a], k));
        let oc: V3<S> = each!(|c| o[c] - s.splat(self.center[c][k]));
        let tiny = s.splat(1e-30);
        // Per axis, the slab's two planes' distances t1 and t2, nearer and farther.
        let slabs: [(F<S>, F<S>); 3] = each!(|a| {
            let lo = dot(oc, axes[a]);
            let ld = dot(d, axes[a]);
            let safe = ld.blend(tiny, ld.abs().lt(tiny));
            let inv = s.splat(1.0) / safe;
            let h = s.splat(self.half[a][k]);
            let t1 = (-h - lo) * inv;
            let t2 = (h - lo) * inv;
            (t1.min(t2), t1.max(t2))
        });
        // glam's max_element and min_element: max(max(x, z), y).
        let (lo, hi) = (each!(|a| slabs[a].0), each!(|a| slabs[a].1));
        let enter = lo[0].max(lo[2]).max(lo[1]);
        let exit = hi[0].min(hi[2]).min(hi[1]);
        let t = exit.blend(enter, enter.gt(s.zero()));
        let hits = within(s, t).without(enter.gt(exit));
        s.splat(NO_HIT).blend(t, hits)
    }

    /// Where the rays hit spheres `idx` (rows of the tables) at `t`: the point moved onto the
    /// surface, and the normal on the side it points to (`intersect::sphere_surface`).
    #[inline(always)]
    fn sphere_surface<S: Isa>(
        &self,
        s: S,
        o: V3<S>,
        d: V3<S>,
        t: F<S>,
        idx: I<S>,
    ) -> (V3<S>, V3<S>) {
        let r = F::pick(&self.r, idx);
        let (an, anc) = (pick3(&self.normal, idx), pick3(&self.anchor, idx));
        let q: V3<S> = each!(|c| (o[c] - anc[c]) + t * d[c]);
        let m: V3<S> = each!(|c| q[c] / r + an[c]);
        let len = dot(m, m).sqrt();
        let n = each!(|c| m[c] / len);
        let h = (dot(q, q) + F::pick(&self.two_r, idx) * dot(q, an)) / (r * len + r);
        let p = each!(|c| anc[c] + (q[c] - h * n[c]));
        let inward = flagged(s, &self.inward, idx);
        (p, each!(|c| n[c].blend(-n[c], inward)))
    }

    /// The point and outward normal of the hits at `t` on primitives `idx` (`surface_at`:
    /// `sphere_surface`, `quad_surface`, `box_surface`), by kind.
    #[inline(always)]
    fn surface<S: Isa>(&self, s: S, o: V3<S>, d: V3<S>, t: F<S>, idx: I<S>) -> (V3<S>, V3<S>) {
        let zero = s.zero();
        let has = |kind: Kind| self.kinds.contains(&kind);
        let mut at = ([zero; 3], [zero; 3]);
        if has(Kind::Sphere) {
            let (p, n) = self.sphere_surface(s, o, d, t, idx);
            put(&mut at, self.is_kind(s, Kind::Sphere, idx), p, n);
        }
        if has(Kind::Quad) {
            let (q, n) = (pick3(&self.quad[0], idx), pick3(&self.quad[3], idx));
            let p: V3<S> = each!(|c| o[c] + t * d[c]);
            let pq = each!(|c| p[c] - q[c]);
            let h = dot(n, pq);
            let on = each!(|c| p[c] - n[c] * h);
            put(&mut at, self.is_kind(s, Kind::Quad, idx), on, n);
        }
        if has(Kind::Box) {
            let (center, half) = (pick3(&self.center, idx), pick3(&self.half, idx));
            let axes = each!(|a| pick3(&self.axes[a], idx));
            let oc: V3<S> = each!(|c| (o[c] + t * d[c]) - center[c]);
            let mut lp: V3<S> = each!(|a| dot(oc, axes[a]));
            let a: V3<S> = each!(|c| (lp[c] / half[c]).abs());
            let on_x = a[0].ge(a[1]) & a[0].ge(a[2]);
            let on_y = a[1].ge(a[2]).without(on_x);
            let on_z = !(on_x | on_y);
            let face = [on_x, on_y, on_z];
            let local: V3<S> = each!(|c| sign(s, lp[c]).keep(face[c]));
            for c in 0..3 {
                lp[c] = lp[c].blend(local[c] * half[c], face[c]);
            }
            let p = each!(|c| {
                let w = center[c] + lp[0] * axes[0][c];
                let w = w + lp[1] * axes[1][c];
                w + lp[2] * axes[2][c]
            });
            let m: V3<S> = each!(|c| {
                (local[0] * axes[0][c] + local[1] * axes[1][c]) + local[2] * axes[2][c]
            });
            let len = dot(m, m).sqrt();
            put(
                &mut at,
                self.is_kind(s, Kind::Box, idx),
                p,
                each!(|c| m[c] / len),
            );
        }
        at
    }

    /// The primitive a ray leaving `idx` on its outer side (`out`) or inner side cannot meet
    /// next (`Tracer::leaving`): a sphere where it leaves the side its normal points to, a
    /// quad always, a box where it leaves outward (a triangle always: a walk's, in the lanes
    /// of `lanes`).
    #[inline(always)]
    fn leaving<S: Isa>(&self, s: S, idx: I<S>, out: M<S>, lanes: M<S>) -> I<S> {
        if let Some(w) = &self.walk {
            return w.leaving(s, idx, out, lanes);
        }
        // (`outward` is 0 but for the spheres.)
        let outward = flagged(s, &self.outward, idx);
        let same = !out.xor(outward);
        let sphere = self.is_kind(s, Kind::Sphere, idx);
        let keeps = self.is_kind(s, Kind::Quad, idx) | (out.without(sphere) | (same & sphere));
        s.int(NONE).blend(idx, keeps)
    }

    /// The density with which light sampling draws the point `at` of primitive `idx` from
    /// `origin`, where it is the light (`Tracer::light_pdf`, the one light chosen for
    /// certain): a sphere's cone, a quad's area; 0 for a box.
    #[inline(always)]
    fn light_pdf<S: Isa>(&self, s: S, idx: I<S>, origin: V3<S>, at: V3<S>) -> F<S> {
        let zero = s.zero();
        let mut pdf = zero;
        if self.kinds.contains(&Kind::Sphere) {
            // sphere_center: anchor − |r|·normal.
            let (anc, an, r) = (
                pick3(&self.anchor, idx),
                pick3(&self.normal, idx),
                F::pick(&self.r, idx),
            );
            let center: V3<S> = each!(|c| anc[c] - r * an[c]);
            let dd: V3<S> = each!(|c| center[c] - origin[c]);
            let dist2 = dot(dd, dd);
            let r2 = r * r;
            let cone = s.splat(1.0) / (s.splat(2.0 * PI) * cone_one_minus_cos(s, r2, dist2));
            let p = cone.blend(zero, dist2.le(r2));
            pdf = pdf.blend(p, self.is_kind(s, Kind::Sphere, idx));
        }
        if self.kinds.contains(&Kind::Quad) {
            let (u, v, n) = (
                pick3(&self.quad[1], idx),
                pick3(&self.quad[2], idx),
                pick3(&self.quad[3], idx),
            );
            let to: V3<S> = each!(|c| at[c] - origin[c]);
            let dist2 = dot(to, to);
            let cos_l = dot(n, to).abs() / dist2.sqrt();
            let uv = cross(u, v);
            let area = dot(uv, uv).sqrt();
            let p = dist2 / (area * cos_l).max(s.splat(1e-30));
            pdf = pdf.blend(p, self.is_kind(s, Kind::Quad, idx));
        }
        pdf
    }

    /// `Tracer::sample_light` at points `p` (facing normal n, leaving primitive `from`) in the
    /// lanes of `lanes`, for the lobe light sampling weighs there: one light of several chosen
    /// by a draw (`choose_light`), the one light, or the map; the MIS-weighted light (its f·cos
    /// included, its tint not), and the primitive tests made.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sample_light<S: Isa>(
        &self,
        s: S,
        (p, n, ng): (V3<S>, V3<S>, V3<S>),
        from: I<S>,
        lanes: M<S>,
        (lobe, (spec, diff)): (&Lobe<S>, (V3<S>, V3<S>)),
        rng: &mut Draws<S>,
    ) -> (V3<S>, u64) {
        let zero = s.zero();
        let one = s.splat(1.0);
        if self.lamps.is_empty() {
            let (u1, u2) = rng.draw2(s, lanes);
            return self.sample_env(s, (p, n, ng), from, lanes, (u1, u2), (lobe, (spec, diff)));
        }
        // One light of several is chosen by a draw (`choose_light`); the lanes whose choice
        // has no weight draw nothing more.
        let several = self.lamps.len() > 1;
        let (chosen, pmf, lanes) = if several {
            let u = rng.draw(s, lanes);
            let (chosen, pmf) = self.choose_light(s, u, p, n);
            (chosen, pmf, lanes.without(pmf.le(zero)))
        } else {
            (s.int(0), one, lanes)
        };
        let (u1, u2) = rng.draw2(s, lanes);
        let (mut dir, mut pdf, mut ok) = ([zero; 3], zero, s.mask(0));
        let (mut radiance, mut index) = ([zero; 3], s.int(NONE));
        for (i, lamp) in self.lamps.iter().enumerate() {
            let this = if several {
                lanes & chosen.eq(s.int(i as i32))
            } else {
                lanes
            };
            if !this.any() {
                continue;
            }
            let (d, pd, good) = self.lamp_sample(s, lamp, p, (u1, u2));
            for c in 0..3 {
                dir[c] = dir[c].blend(d[c], this);
                radiance[c] = radiance[c].blend(s.splat(lamp.radiance[c]), this);
            }
            pdf = pdf.blend(pd, this);
            ok = ok | (good & this);
            index = index.blend(s.int(lamp.index as i32), this);
        }
        let cos_s = dot(n, dir);
        let mut ok = (ok & lanes) & cos_s.gt(zero);
        let mut tests = 0;
        if ok.any() {
            let origin = offset_ray(s, p, n);
            let (t_light, blocked) = if several {
                let mut t_light = s.splat(NO_HIT);
                for (i, lamp) in self.lamps.iter().enumerate() {
                    let this = ok & chosen.eq(s.int(i as i32));
                    if this.any() {
                        t_light = t_light.blend(self.hit(s, lamp.index, origin, dir), this);
                    }
                }
                let skip = (from, index);
                let b = self.occluded(s, (origin, dir), t_light, usize::MAX, skip, ok);
                (t_light, b)
            } else {
                let lamp = &self.lamps[0];
                let t_light = self.hit(s, lamp.index, origin, dir);
                let none = s.int(NONE);
                let b = self.occluded(s, (origin, dir), t_light, lamp.index, (from, none), ok);
                (t_light, b)
            };
            ok = (ok & t_light.gt(zero)).without(blocked);
            tests = (lanes.bits().count_ones() as u64) * self.kinds.len() as u64;
        }
        // (1 − env_pick)·pmf·pdf, the map not picked here.
        let pl = if several { pmf * pdf } else { pdf };
        let l = light_weighted(s, radiance, (cos_s, dir, n), pl, (lobe, (spec, diff)));
        (each!(|c| l[c].keep(ok)), tests)
    }

    /// `Tracer::light_weight` of every light at points `p` (facing shading normal `n`), and
    /// their sum, in the lights' order (`choose_light`'s total).
    #[inline(always)]
    fn light_weights<S: Isa>(&self, s: S, p: V3<S>, n: V3<S>) -> ([F<S>; MAX_LAMPS], F<S>) {
        let zero = s.zero();
        let mut weights = [zero; MAX_LAMPS];
        let mut total = zero;
        for (i, lamp) in self.lamps.iter().enumerate() {
            let to: V3<S> = each!(|c| s.splat(lamp.center[c]) - p[c]);
            let d2 = dot(to, to);
            let cos_t = dot(n, to) / d2.max(s.splat(1e-30)).sqrt();
            let w = (s.splat(lamp.pmf) / d2.max(s.splat(lamp.r2)))
                * (s.splat(super::trace::BACKFACE_WEIGHT) + cos_t.max(zero));
            weights[i] = w;
            total = total + w;
        }
        (weights, total)
    }

    /// `Tracer::choose_light` among several lights with draw `u` at points `p` (facing
    /// shading normal `n`): the light whose running sum of weights first passes u × their
    /// total (the last one else), and its weight's share.
    #[inline(always)]
    fn choose_light<S: Isa>(&self, s: S, u: F<S>, p: V3<S>, n: V3<S>) -> (I<S>, F<S>) {
        let (weights, total) = self.light_weights(s, p, n);
        let target = u * total;
        let mut acc = s.zero();
        let (mut chosen, mut pmf) = (s.int(NONE), s.zero());
        let mut decided = s.mask(0);
        let last = self.lamps.len() - 1;
        for (i, &w) in weights.iter().enumerate().take(self.lamps.len()) {
            acc = acc + w;
            let here = if i == last {
                !decided
            } else {
                acc.gt(target).without(decided)
            };
            chosen = chosen.blend(s.int(i as i32), here);
            pmf = pmf.blend(w / total, here);
            decided = decided | here;
        }
        (chosen, pmf)
    }

    /// A direction toward `lamp` from points `p` with draws (u1, u2) (`Tracer::sample_light`'s
    /// shapes): the direction, its density in solid angle, and where the sample holds (the
    /// point outside the sphere; the quad not seen edge-on).
    #[inline(always)]
    fn lamp_sample<S: Isa>(
        &self,
        s: S,
        lamp: &Lamp,
        p: V3<S>,
        (u1, u2): (F<S>, F<S>),
    ) -> (V3<S>, F<S>, M<S>) {
        let (zero, one) = (s.zero(), s.splat(1.0));
        match &lamp.shape {
            LampShape::Sphere { center, r2 } => {
                let to: V3<S> = each!(|c| s.splat(center[c]) - p[c]);
                let dist2 = dot(to, to);
                let r2 = s.splat(*r2);
                let one_minus = cone_one_minus_cos(s, r2, dist2);
                let cos_t = one - u1 * one_minus;
                let sin_t = (one - cos_t * cos_t).max(zero).sqrt();
                let (sp, cp) = sin_cos_turns(s, u2);
                let root = dist2.sqrt();
                let b = basis(s, each!(|c| to[c] / root));
                let (k0, k1) = (sin_t * cp, sin_t * sp);
                let v: V3<S> = each!(|c| (b[0][c] * k0 + b[1][c] * k1) + b[2][c] * cos_t);
                let len = dot(v, v).sqrt();
                let dir = each!(|c| v[c] / len);
                let pdf = one / (s.splat(2.0 * PI) * one_minus);
                (dir, pdf, dist2.cmp::<_CMP_NLE_UQ>(r2))
            }
            LampShape::Quad { q, area } => {
                let [q, u, v, nl] = [lit(s, q[0]), lit(s, q[1]), lit(s, q[2]), lit(s, q[3])];
                let x: V3<S> = each!(|c| (q[c] + u1 * u[c]) + u2 * v[c]);
                let to: V3<S> = each!(|c| x[c] - p[c]);
                let dist2 = dot(to, to);
                let root = dist2.sqrt();
                let dir = each!(|c| to[c] / root);
                let cos_l = dot(nl, dir).abs();
                let pdf = dist2 / (s.splat(*area) * cos_l);
                (dir, pdf, cos_l.cmp::<_CMP_NLT_UQ>(s.splat(1e-6)))
            }
        }
    }

    /// `Tracer::sample_env` for the lanes of `lanes` at points `p` (facing shading normal `n`,
    /// geometric `ng`, leaving primitive `from`), with draws (u1, u2): a direction from the map's
    /// distribution and the radiance there, lane by lane with the scalar tracer's code
    /// (`Distribution::sample`, `EnvMap::radiance_at`), the shadow ray in lanes, weighed as
    /// `sample_light` weighs; returns the light (tint not included) and the tests made.
    #[inline(always)]
    fn sample_env<S: Isa>(
        &self,
        s: S,
        (p, n, ng): (V3<S>, V3<S>, V3<S>),
        from: I<S>,
        lanes: M<S>,
        (u1, u2): (F<S>, F<S>),
        lobe: (&Lobe<S>, (V3<S>, V3<S>)),
    ) -> (V3<S>, u64) {
        let zero = s.zero();
        let Some(env) = self.env.as_ref() else {
            return ([zero; 3], 0);
        };
        let tables = Tables::of(&env.map.distribution);
        let draws = (u1.keep(lanes), u2.keep(lanes));
        let map::Drawn {
            dir,
            pdf,
            uv: (u, v),
        } = map::sample(s, &env.map.distribution, &tables, draws, env.rotation);
        // Looked up after the shadow rays, where it is not occluded.
        map::prefetch(s, &env.map, (u, v), lanes);
        let cos_s = dot(n, dir);
        let mut ok = (lanes & pdf.gt(zero)) & cos_s.gt(zero);
        // With shading normals, a direction below the geometric surface is not lit
        // (`Tracer::shadow_side`).
        if self.walk.as_ref().is_some_and(|w| w.normals) {
            ok = ok & dot(ng, dir).cmp::<_CMP_NLE_UQ>(zero);
        }
        let mut tests = 0;
        if ok.any() {
            let origin = offset_ray(s, p, ng);
            let (none, far) = (s.int(NONE), s.splat(T_FAR));
            let blocked = self.occluded(s, (origin, dir), far, usize::MAX, (from, none), ok);
            ok = ok.without(blocked);
            tests = (lanes.bits().count_ones() as u64) * self.kinds.len() as u64;
        }
        let radiance = map_radiance(s, (&env.map, env.intensity), (u, v), ok);
        let pl = s.splat(env.pick) * pdf;
        let l = light_weighted(s, radiance, (cos_s, dir, n), pl, lobe);
        (each!(|c| l[c].keep(ok)), tests)
    }

    /// `Tracer::escaped` under the map, for the rays `d` of the lanes of `lanes` that left the
    /// scene at bounce `bounce` after a lobe of density `prev_pdf`: the map, weighed against
    /// light sampling where that could have found the direction, or, where the ray leaves a
    /// mirror sphere met from such a lobe (its density and the sphere's spread: `mirrored`),
    /// against `sample_mirror`; the sky where the map is not seen (by camera rays, where it
    /// is hidden from them).
    #[inline(always)]
    fn escaped<S: Isa>(
        &self,
        s: S,
        env: &Env,
        d: V3<S>,
        lanes: M<S>,
        bounce: I<S>,
        (prev_pdf, (mirror_pdf, spread)): (F<S>, (F<S>, F<S>)),
    ) -> V3<S> {
        let seen = if !env.shown {
            s.mask(0)
        } else if env.seen_directly {
            lanes
        } else {
            lanes & bounce.gt(s.int(0))
        };
        let sky = self.sky(s, d, lanes.without(seen));
        if !seen.any() {
            return sky;
        }
        let weighs = self.nee && env.pick > 0.0;
        let weighed = if weighs {
            seen & prev_pdf.gt(s.zero())
        } else {
            s.mask(0)
        };
        let ((mut u, mut v), nan) = map::coordinates(s, d, env.rotation);
        // The texels asked for first, so that their cache misses overlap the density's gathers.
        map::prefetch(s, &env.map, (u, v), seen);
        let mut w = s.splat(1.0);
        let mirrored = seen.without(weighed) & mirror_pdf.gt(s.zero());
        if (weighed | mirrored).any() {
            let tables = Tables::of(&env.map.distribution);
            let pdf = map::pdf_at(s, &env.map.distribution, &tables, u, v);
            if weighed.any() {
                let pl = s.splat(env.pick) * pdf;
                w = w.blend(power_heuristic(prev_pdf, pl), weighed);
            }
            if mirrored.any() {
                let pm = self.mirror_pdf(s, pdf, spread);
                w = w.blend(power_heuristic(mirror_pdf, pm), mirrored);
            }
        }
        // A direction with a NaN component: the scalar code's coordinates and weight.
        let odd = seen & nan;
        if odd.any() {
            let (mut us, mut vs) = ([0.0; MAX_LANES], [0.0; MAX_LANES]);
            u.store(&mut us);
            v.store(&mut vs);
            let (dirs, mut prev, mut weights) = (rows(d), [0.0; MAX_LANES], [0.0; MAX_LANES]);
            let (mut m_pdf, mut m_spread) = ([0.0; MAX_LANES], [0.0; MAX_LANES]);
            prev_pdf.store(&mut prev);
            w.store(&mut weights);
            mirror_pdf.store(&mut m_pdf);
            spread.store(&mut m_spread);
            for k in lanes_of(odd.bits()) {
                let dir = glam::Vec3::new(dirs[0][k], dirs[1][k], dirs[2][k]);
                let (cu, cv) = crate::scene::envmap_sampling::coordinates(dir, env.rotation);
                (us[k], vs[k]) = (cu, cv);
                weights[k] = 1.0;
                if weighs && prev[k] > 0.0 {
                    let pl = env.pick * env.map.distribution.pdf_at(cu, cv);
                    weights[k] = super::trace::power_heuristic(prev[k], pl);
                } else if m_pdf[k] > 0.0 {
                    // `mirror_pdf`, lane by lane.
                    let count = self.mirrors.len() as f32;
                    let pl = env.map.distribution.pdf_at(cu, cv) / (count * m_spread[k]);
                    weights[k] = super::trace::power_heuristic(m_pdf[k], pl);
                }
            }
            (u, v, w) = (s.load(&us), s.load(&vs), s.load(&weights));
        }
        let l = map_radiance(s, (&env.map, env.intensity), (u, v), seen);
        each!(|c| sky[c].blend(l[c] * w, seen))
    }

    /// `scatter_dielectric`'s direction for the rays `d` meeting glass in the lanes of `glass`
    /// (facing normal `n`, from the front where `front`; `reflected` is `reflect(d, n)`):
    /// reflected by total internal reflection or with Schlick's probability, else refracted
    /// (a ratio of exactly 1 lets the ray through, and draws nothing), then fuzzed where the
    /// glass has absorption.
    #[inline(always)]
    fn refract<S: Isa>(
        &self,
        s: S,
        (d, n, front): (V3<S>, V3<S>, M<S>),
        reflected: V3<S>,
        (idx, glass): (I<S>, M<S>),
        rng: &mut Draws<S>,
    ) -> V3<S> {
        let (zero, one) = (s.zero(), s.splat(1.0));
        let ratio = F::pick(&self.ior, idx).blend(F::pick(&self.inv_ior, idx), front);
        let back = each!(|c| -d[c]);
        let cos_t = dot(back, n).min(one);
        let sin_t = (one - cos_t * cos_t).max(zero).sqrt();
        let mut dir = d;
        let bends = glass.without(ratio.cmp::<_CMP_EQ_OQ>(one));
        if bends.any() {
            let u = rng.draw(s, bends);
            // Schlick's reflectance (`material::schlick`).
            let r0 = (one - ratio) / (one + ratio);
            let r0 = r0 * r0;
            let x = one - cos_t;
            let x2 = x * x;
            let fresnel = r0 + (one - r0) * ((x2 * x2) * x);
            let reflects = (ratio * sin_t).gt(one) | fresnel.gt(u);
            // `reflect(d, n).normalize()` and `refract_dir(d, n, cos_t, ratio).normalize()`.
            let mirror = normalize(reflected);
            let perp: V3<S> = each!(|c| ratio * (d[c] + cos_t * n[c]));
            let k = -((one - dot(perp, perp)).abs().sqrt());
            let bent = normalize(each!(|c| perp[c] + k * n[c]));
            for c in 0..3 {
                dir[c] = dir[c].blend(bent[c].blend(mirror[c], reflects), bends);
            }
        }
        let fuzz = F::pick(&self.fuzz, idx);
        let fuzzed = glass & fuzz.gt(zero);
        if fuzzed.any() {
            let (u, v) = rng.draw2(s, fuzzed);
            let unit = random_unit_vector(s, u, v);
            let moved = normalize_or(s, each!(|c| dir[c] + fuzz * unit[c]), dir);
            for c in 0..3 {
                dir[c] = dir[c].blend(moved[c], fuzzed);
            }
        }
        dir
    }

    /// The lanes whose primitive `idx` is of `kind`.
    #[inline(always)]
    fn is_kind<S: Isa>(&self, s: S, kind: Kind, idx: I<S>) -> M<S> {
        flagged(s, &self.of_kind[kind as usize], idx)
    }

    /// The sky in directions d, for the lanes of `lanes`: uniform, or the gradient with its
    /// sun where it has one (`Tracer::sky`; the sun's falloff is libm's `powf`, lane by lane).
    #[inline(always)]
    fn sky<S: Isa>(&self, s: S, d: V3<S>, lanes: M<S>) -> V3<S> {
        if self.sky_uniform {
            return each!(|c| s.splat(self.sky_bottom[c]));
        }
        let one = s.splat(1.0);
        let t = s.splat(0.5) * (d[1] + one);
        let below = one - t;
        let mut sky = each!(|c| below * s.splat(self.sky_bottom[c]) + t * s.splat(self.sky_top[c]));
        if let Some(sun) = &self.sun {
            let cz = dot(lit(s, sun.dir), d).max(s.zero());
            let lit_by = (cz.gt(s.zero()) & lanes).bits();
            if lit_by != 0 {
                let mut x = [0.0; MAX_LANES];
                cz.store(&mut x);
                for k in lanes_of(lit_by) {
                    x[k] = x[k].powf(sun.size);
                }
                let falloff = s.load(&x);
                let on = s.mask(lit_by);
                for (c, v) in sky.iter_mut().enumerate() {
                    *v = v.blend(*v + s.splat(sun.radiance[c]) * falloff, on);
                }
            }
        }
        sky
    }
}

impl Walk<'_> {
    /// The nearest hits of the rays (o, d) of the lanes of `lanes`, primitive `skip` left
    /// out (`Tracer::nearest`): the root in lanes (`Root`), then lane by lane for the rays
    /// that walk on; the distances, the primitives, and the lanes that hit.
    #[inline(always)]
    fn closest<S: Isa>(
        &self,
        l: &Lanes,
        s: S,
        (o, d): (V3<S>, V3<S>),
        skip: I<S>,
        lanes: M<S>,
    ) -> (F<S>, I<S>, M<S>) {
        let Some(root) = &self.root else {
            let (t, r) = (s.splat(T_FAR), s.int(NONE));
            return self.walked(s, (o, d), skip, lanes, (t, r), None);
        };
        let inv = inverse(s, d);
        let far = s.splat(T_FAR);
        let (mut best, mut index) = (far, s.int(NONE));
        let (mut leafy, mut tests) = (s.mask(0), 0);
        let mut near = [far; 8];
        let mut entered = [s.mask(0); 8];
        for (j, slot) in root.slots.iter().enumerate() {
            (near[j], entered[j]) = slot.slab(s, (o, inv), far);
            entered[j] = entered[j] & lanes;
        }
        // The leaves first, slot by slot, as `bvh::Walk::visit`.
        for (j, slot) in root.slots.iter().enumerate() {
            if !slot.leaf || !entered[j].any() {
                continue;
            }
            if slot.spheres.is_empty() {
                leafy = leafy | entered[j];
                continue;
            }
            for &RootSphere { k, r, .. } in &slot.spheres {
                let t = l.hit_sphere(s, k, o, d);
                let rr = s.int(r as i32);
                let take = (entered[j] & within(s, t)).without(skip.eq(rr)) & t.lt(best);
                best = best.blend(t, take);
                index = index.blend(rr, take);
                tests += (entered[j].without(skip.eq(rr))).bits().count_ones() as u64;
            }
        }
        // Then the inner nodes nearer than the best hit: walked, from the root's inner
        // slots on where the lanes have tested all the leaves a ray enters, else from the
        // root (a leaf of other primitives: the scalar walk tests the leaves in slot order).
        let mut inner = s.mask(0);
        for (j, slot) in root.slots.iter().enumerate() {
            if !slot.leaf {
                inner = inner | (entered[j] & near[j].lt(best));
            }
        }
        let walked = leafy | inner;
        let below = inner.without(leafy);
        {
            let tally = &mut self.tracer.borrow_mut().tally;
            tally.visits += lanes.without(leafy).bits().count_ones() as u64;
            tally.tests += tests;
        }
        let below = Below {
            lanes: below,
            near: &near,
            entered: &entered,
            root,
        };
        self.walked(s, (o, d), skip, walked, (best, index), Some(below))
    }

    /// `closest`'s lanes of `lanes` walked on their own (`Tracer::nearest`; those of
    /// `below` from the root's inner slots on, their best hit so far (t, r)): their hits
    /// replace (t, r) there; and the lanes that hit.
    #[inline(always)]
    fn walked<S: Isa>(
        &self,
        s: S,
        (o, d): (V3<S>, V3<S>),
        skip: I<S>,
        lanes: M<S>,
        (t, r): (F<S>, I<S>),
        below: Option<Below<'_, S>>,
    ) -> (F<S>, I<S>, M<S>) {
        let (mut t, mut r) = (t, r);
        if lanes.any() {
            let (o, d) = (rows(o), rows(d));
            let mut skips = [0; MAX_LANES];
            skip.store(&mut skips);
            let (mut ts, mut refs) = ([0.0; MAX_LANES], [NONE; MAX_LANES]);
            t.store(&mut ts);
            r.store(&mut refs);
            let (mut near, mut entered) = ([[0.0; MAX_LANES]; 8], [0u32; 8]);
            let below_bits = below.as_ref().map_or(0, |b| b.lanes.bits());
            if let Some(b) = below.as_ref().filter(|_| below_bits != 0) {
                for j in 0..b.root.slots.len() {
                    b.near[j].store(&mut near[j]);
                    entered[j] = b.entered[j].bits();
                }
            }
            let mut tracer = self.tracer.borrow_mut();
            for k in lanes_of(lanes.bits()) {
                let ray = ray_of(&o, &d, k);
                let hit = match below.as_ref().filter(|_| below_bits >> k & 1 != 0) {
                    Some(b) => {
                        let at = b.at_root(k, (ts[k], refs[k]), &near, &entered);
                        tracer.nearest_below_root(&ray, skips[k] as u32, &at)
                    }
                    None => tracer.nearest(&ray, skips[k] as u32),
                };
                (ts[k], refs[k]) = match hit {
                    Some(hit) => (hit.0, hit.1 as i32),
                    None => (T_FAR, NONE),
                };
            }
            (t, r) = (s.load(&ts), s.ints(&refs));
        }
        // (A triangle's reference is negative as an i32: its kind is in the top bits.)
        let found = !r.eq(s.int(NONE));
        (t.keep(found), r, found)
    }

    /// What the rays (o, d) of the lanes of `lanes` met at (t, r) (`Tracer::met`): a root
    /// leaf's sphere in lanes (its surface, its material's row and colour, the facing normal
    /// for shading: `met` of a sphere, which has no texture and no shading normal of its
    /// own), the rest lane by lane.
    #[inline(always)]
    fn surface<S: Isa>(
        &self,
        l: &Lanes,
        s: S,
        (o, d): (V3<S>, V3<S>),
        (t, r): (F<S>, I<S>),
        lanes: M<S>,
    ) -> Met<S> {
        let zero = s.zero();
        let mut m = Met {
            material: s.int(0),
            position: [zero; 3],
            normal: [zero; 3],
            color: [zero; 3],
            shading: [zero; 3],
        };
        let mut rest = lanes;
        if let Some(root) = &self.root {
            let (mut row, mut on) = (s.int(0), s.mask(0));
            for sp in root.slots.iter().flat_map(|slot| slot.spheres.iter()) {
                let this = r.eq(s.int(sp.r as i32)) & lanes;
                row = row.blend(s.int(sp.k as i32), this);
                m.material = m.material.blend(s.int(sp.material), this);
                m.color = each!(|c| m.color[c].blend(s.splat(sp.color[c]), this));
                on = on | this;
            }
            if on.any() {
                let (p, n) = l.sphere_surface(s, o, d, t, row);
                let facing = dot(d, n).lt(zero);
                m.position = each!(|c| p[c].keep(on));
                m.normal = each!(|c| n[c].keep(on));
                m.shading = each!(|c| (-n[c]).blend(n[c], facing).keep(on));
                rest = rest.without(on);
            }
        }
        // Triangles in lanes, where `surface` covers them.
        if let Some(tris) = &self.triangles {
            let on = rest & r.shr(30).eq(s.int(3));
            if on.any() {
                let index = r.and(s.int(REF_INDEX as i32));
                let (met, slow) = tris.met(s, (o, d), t, index, on);
                let done = on.without(slow);
                m.material = m.material.blend(met.material, done);
                m.position = each!(|c| m.position[c].blend(met.position[c], done));
                m.normal = each!(|c| m.normal[c].blend(met.normal[c], done));
                m.color = each!(|c| m.color[c].blend(met.color[c], done));
                m.shading = each!(|c| m.shading[c].blend(met.shading[c], done));
                rest = rest.without(done);
            }
        }
        if !rest.any() {
            return m;
        }
        let (o, d) = (rows(o), rows(d));
        let (mut ts, mut refs) = ([0.0; MAX_LANES], [0; MAX_LANES]);
        t.store(&mut ts);
        r.store(&mut refs);
        let mut material = [0; MAX_LANES];
        m.material.store(&mut material);
        let (mut position, mut normal) = (rows(m.position), rows(m.normal));
        let (mut color, mut shading) = (rows(m.color), rows(m.shading));
        let tracer = self.tracer.borrow();
        for k in lanes_of(rest.bits()) {
            let met = tracer.met(&ray_of(&o, &d, k), ts[k], refs[k] as u32);
            material[k] = self.rows[met.material as usize];
            for c in 0..3 {
                position[c][k] = met.position[c];
                normal[c][k] = met.normal[c];
                color[c][k] = met.color[c];
                shading[c][k] = met.shading[c];
            }
        }
        Met {
            material: s.ints(&material),
            position: each!(|c| s.load(&position[c])),
            normal: each!(|c| s.load(&normal[c])),
            color: each!(|c| s.load(&color[c])),
            shading: each!(|c| s.load(&shading[c])),
        }
    }

    /// Whether the rays (o, d) of the lanes of `lanes` meet any primitive but `from` and
    /// `also` before `t_max` (`Tracer::occluded`): the root in lanes (`Root`; any blocker
    /// ends a shadow ray's walk), then lane by lane for the rays that enter another slot.
    #[inline(always)]
    fn occluded<S: Isa>(
        &self,
        l: &Lanes,
        s: S,
        (o, d): (V3<S>, V3<S>),
        t_max: F<S>,
        (from, also): (I<S>, I<S>),
        lanes: M<S>,
    ) -> M<S> {
        let (mut blocked, mut walked) = (s.mask(0), lanes);
        // By lane, the root's slots it enters that the lanes do not test (the root visited:
        // the scalar walk goes on below it).
        let mut rest = None;
        if let Some(root) = &self.root {
            let inv = inverse(s, d);
            walked = s.mask(0);
            let mut tests = 0;
            let mut slots = [0u32; MAX_LANES];
            for slot in &root.slots {
                let entered = slot.slab(s, (o, inv), t_max).1 & lanes;
                if !entered.any() {
                    continue;
                }
                if slot.spheres.is_empty() {
                    walked = walked | entered;
                    for k in lanes_of(entered.bits()) {
                        slots[k] |= 1 << slot.slot;
                    }
                    continue;
                }
                for &RootSphere { k, r, .. } in &slot.spheres {
                    let rr = s.int(r as i32);
                    let hits = between(s, l.hit_sphere(s, k, o, d), t_max);
                    blocked = blocked | (entered & hits).without(from.eq(rr) | also.eq(rr));
                    tests += entered.bits().count_ones() as u64;
                }
            }
            walked = walked.without(blocked);
            let tally = &mut self.tracer.borrow_mut().tally;
            tally.visits += lanes.bits().count_ones() as u64;
            tally.tests += tests;
            rest = Some(slots);
        }
        if !walked.any() {
            return blocked;
        }
        let (o, d) = (rows(o), rows(d));
        let (mut far, mut froms, mut alsos) = ([0.0; MAX_LANES], [0; MAX_LANES], [0; MAX_LANES]);
        t_max.store(&mut far);
        from.store(&mut froms);
        also.store(&mut alsos);
        let mut hit = 0;
        let mut tracer = self.tracer.borrow_mut();
        for k in lanes_of(walked.bits()) {
            let ray = ray_of(&o, &d, k);
            let (also, from) = (alsos[k] as u32, froms[k] as u32);
            let blocks = match &rest {
                Some(slots) => tracer.occluded_below_root(&ray, far[k], (also, from), slots[k]),
                None => tracer.occluded::<ANY>(&ray, far[k], also, from),
            };
            if blocks {
                hit |= 1 << k;
            }
        }
        blocked | s.mask(hit)
    }

    /// `Tracer::leaving` of primitives `r` on their outer side (`out`) or inner side, in the
    /// lanes of `lanes` (`NONE` in the others).
    #[inline(always)]
    fn leaving<S: Isa>(&self, s: S, r: I<S>, out: M<S>, lanes: M<S>) -> I<S> {
        // A reference's kind is in its top two bits: 0 a sphere, 2 a triangle.
        let kind = r.shr(30);
        let sphere = kind.eq(s.int(0));
        let index = r.and(s.int(REF_INDEX as i32)).blend(s.int(0), !sphere);
        let outward = I::gather(&self.outward, index).eq(s.int(1));
        let none = sphere.without(!out.xor(outward)) | kind.eq(s.int(2)).without(out);
        s.int(NONE).blend(r, lanes.without(none))
    }
}

/// Lane k's ray of origins `o` and directions `d` (by component).
#[inline(always)]
fn ray_of(o: &[Row; 3], d: &[Row; 3], k: usize) -> Ray {
    Ray {
        origin: Vec3A::new(o[0][k], o[1][k], o[2][k]),
        dir: Vec3A::new(d[0][k], d[1][k], d[2][k]),
    }
}

/// The glossy lobe light sampling weighs (`Weighed::Gloss` and `Weighed::Mixed`) at a bounce:
/// the lanes where it is alone and where it is mixed with the cosine lobe, the mirror
/// direction, the smoothness and the mixture's probability.
struct Lobe<S: Isa> {
    gloss: M<S>,
    mixed: M<S>,
    r: V3<S>,
    smooth: F<S>,
    p: F<S>,
}

/// The paths in flight, one a lane: what `Tracer::trace_path` keeps between bounces.
struct Paths<S: Isa> {
    o: V3<S>,
    d: V3<S>,
    throughput: V3<S>,
    radiance: V3<S>,
    segments: I<S>,
    bounce: I<S>,
    /// The primitive the ray leaves, where it cannot meet it again.
    skip: I<S>,
    /// The last bounce's lobe density where light sampling weighs it (else 0), and where it
    /// was drawn: what an emitter met next is weighed against.
    prev_pdf: F<S>,
    prev_point: V3<S>,
    prev_normal: V3<S>,
    /// Where mirror spheres are sampled: the density with which the camera ray was drawn
    /// (`Tracer::pixel_at`), which weighs the first hit; and where the ray leaves a mirror
    /// sphere met from a lobe light sampling weighs (`Tracer::mirror_hit`), that lobe's
    /// density (else 0) and the sphere's spread there.
    view_pdf: F<S>,
    mirror_pdf: F<S>,
    mirror_spread: F<S>,
    /// The paths' samplers.
    rng: Draws<S>,
}

impl<S: Isa> Paths<S> {
    /// New paths in lanes `m` along camera rays (o, d).
    #[inline(always)]
    fn start(&mut self, s: S, m: M<S>, o: V3<S>, d: V3<S>) {
        let (zero, one) = (s.zero(), s.splat(1.0));
        let up = [zero, one, zero];
        for c in 0..3 {
            self.o[c] = self.o[c].blend(o[c], m);
            self.d[c] = self.d[c].blend(d[c], m);
            self.throughput[c] = self.throughput[c].blend(one, m);
            self.radiance[c] = self.radiance[c].blend(zero, m);
            self.prev_point[c] = self.prev_point[c].blend(o[c], m);
            self.prev_normal[c] = self.prev_normal[c].blend(up[c], m);
        }
        self.segments = self.segments.blend(s.int(0), m);
        self.bounce = self.bounce.blend(s.int(0), m);
        self.skip = self.skip.blend(s.int(NONE), m);
        self.prev_pdf = self.prev_pdf.blend(zero, m);
        self.view_pdf = self.view_pdf.blend(zero, m);
        self.mirror_pdf = self.mirror_pdf.blend(zero, m);
    }
}

/// Whether `TERMTRACE_CPU_LANES=8` asks for eight lanes where sixteen could run (to
/// compare the widths on one machine: BENCHMARKS.md).
fn eight_lanes() -> bool {
    static EIGHT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *EIGHT.get_or_init(|| std::env::var("TERMTRACE_CPU_LANES").is_ok_and(|v| v.trim() == "8"))
}

/// Primitive k's entries of three tables, in every lane.
#[inline(always)]
fn column<S: Isa>(s: S, t: &Tables3, k: usize) -> V3<S> {
    [s.splat(t[0][k]), s.splat(t[1][k]), s.splat(t[2][k])]
}

/// A 3-vector in every lane.
#[inline(always)]
fn lit<S: Isa>(s: S, v: [f32; 3]) -> V3<S> {
    [s.splat(v[0]), s.splat(v[1]), s.splat(v[2])]
}

/// Point and normal `(p, n)` replace `into`'s in the lanes of `mask`.
#[inline(always)]
fn put<S: Isa>(into: &mut (V3<S>, V3<S>), mask: M<S>, p: V3<S>, n: V3<S>) {
    for c in 0..3 {
        into.0[c] = into.0[c].blend(p[c], mask);
        into.1[c] = into.1[c].blend(n[c], mask);
    }
}

/// The lanes whose entry `idx` of a table of flags (1.0 or 0.0) is set.
#[inline(always)]
fn flagged<S: Isa>(s: S, t: &Row, idx: I<S>) -> M<S> {
    F::pick(t, idx).gt(s.zero())
}

/// Each lane's entry `idx` of three tables.
#[inline(always)]
fn pick3<S: Isa>(t: &Tables3, idx: I<S>) -> V3<S> {
    [
        F::pick(&t[0], idx),
        F::pick(&t[1], idx),
        F::pick(&t[2], idx),
    ]
}

/// WGSL's sign(): −1, 0 or 1 (`intersect::sign`).
#[inline(always)]
fn sign<S: Isa>(s: S, x: F<S>) -> F<S> {
    let zero = s.zero();
    zero.blend(s.splat(1.0), x.gt(zero))
        .blend(s.splat(-1.0), x.lt(zero))
}

/// t in (0, t_max): a hit the tests count (`hit_except`, `occluded`).
#[inline(always)]
fn between<S: Isa>(s: S, t: F<S>, t_max: F<S>) -> M<S> {
    t.gt(s.zero()) & t.lt(t_max)
}

/// t in (0, T_FAR).
#[inline(always)]
fn within<S: Isa>(s: S, t: F<S>) -> M<S> {
    between(s, t, s.splat(T_FAR))
}

/// a² / (a² + b²).
#[inline(always)]
fn power_heuristic<S: Isa>(a: F<S>, b: F<S>) -> F<S> {
    let a2 = a * a;
    a2 / (a2 + b * b)
}

/// 1 − cos of the cone a sphere of radius² r2 fills seen from distance² dist2.
#[inline(always)]
fn cone_one_minus_cos<S: Isa>(s: S, r2: F<S>, dist2: F<S>) -> F<S> {
    let sin2 = r2 / dist2;
    let root = (s.splat(1.0) - sin2).max(s.zero()).sqrt();
    sin2 / (s.splat(1.0) + root)
}

/// `sampling::basis` (Duff et al. 2017) in lanes.
#[inline(always)]
fn basis<S: Isa>(s: S, n: V3<S>) -> [V3<S>; 3] {
    let one = s.splat(1.0);
    let sg = s.splat(-1.0).blend(one, n[2].ge(s.zero()));
    let a = s.splat(-1.0) / (sg + n[2]);
    let b = (n[0] * n[1]) * a;
    [
        [one + ((sg * n[0]) * n[0]) * a, sg * b, (-sg) * n[0]],
        [b, sg + (n[1] * n[1]) * a, -n[1]],
        n,
    ]
}

/// `fixed::words` in lanes: the whole part and the fraction of each lane's value clamped
/// to [0, FIXED_MAX] (for a finite value the same words: a −0.0 that `f32::clamp` keeps and
/// `max` makes +0.0 gives 0 either way).
#[inline(always)]
fn fixed_words<S: Isa>(s: S, x: F<S>) -> (I<S>, I<S>) {
    let c = x.max(s.zero()).min(s.splat(FIXED_MAX));
    let whole = c.truncate_unsigned();
    // c − trunc(c) is `c - whole as f32`: the whole part is an f32 exactly.
    let frac = ((c - c.trunc()) * s.splat(4294967296.0)).truncate_unsigned();
    (whole, frac)
}

/// `light_weighted` in lanes: `radiance` arriving from `dir` (cos_s against the shading
/// normal `n`), drawn with density `pl`, times the lobe's f·cos, weighed by the power heuristic
/// against the lobe's density: the cosine lobe's (cos_s/π, its tint the caller's), the glossy
/// one's, or their mixture's with each lobe's tint (`spec`, `diff`).
#[inline(always)]
fn light_weighted<S: Isa>(
    s: S,
    radiance: V3<S>,
    (cos_s, dir, n): (F<S>, V3<S>, V3<S>),
    pl: F<S>,
    (lobe, (spec, diff)): (&Lobe<S>, (V3<S>, V3<S>)),
) -> V3<S> {
    // The cosine lobe: radiance · (cos_s/π / pl · w(pl, cos_s/π)).
    let cosine = cos_s / s.splat(PI);
    let f = (cosine / pl) * power_heuristic(pl, cosine);
    let mut l = each!(|c| radiance[c] * f);
    let glossy = lobe.gloss | lobe.mixed;
    if glossy.any() {
        // The glossy lobe: radiance · (g / pl · w(pl, g)); the mixture: radiance ·
        // (spec·pg + diff·pd) · (w(pl, pg + pd) / pl), pg = p·g and pd = (1 − p)·cos_s/π.
        let g = gloss_pdf(s, dir, n, lobe.r, lobe.smooth);
        let fg = (g / pl) * power_heuristic(pl, g);
        let (pg, pd) = (lobe.p * g, (s.splat(1.0) - lobe.p) * cosine);
        let w = power_heuristic(pl, pg + pd) / pl;
        for c in 0..3 {
            let mixed = (radiance[c] * (spec[c] * pg + diff[c] * pd)) * w;
            l[c] = l[c]
                .blend(radiance[c] * fg, lobe.gloss)
                .blend(mixed, lobe.mixed);
        }
    }
    l
}

/// `material::gloss_pdf` in lanes: the density of the lecture's glossy lobe of smoothness
/// `sm` about mirror direction `r` (shading normal `n`) at direction `w`.
#[inline(always)]
fn gloss_pdf<S: Isa>(s: S, w: V3<S>, n: V3<S>, r: V3<S>, sm: F<S>) -> F<S> {
    use super::material::DISC_ROUNDING;
    let zero = s.zero();
    let t = s.splat(1.0) - sm;
    let c = dot(w, r);
    let x = cross(w, r);
    let disc = t * t - (sm * sm) * dot(x, x);
    // 0 where disc is NaN or at most −DISC_ROUNDING.
    let valid = disc.gt(s.splat(-DISC_ROUNDING));
    let q = disc.max(s.splat(DISC_ROUNDING * DISC_ROUNDING)).sqrt();
    let (l1, l2) = (sm * c + q, sm * c - q);
    let d1 = dot(each!(|k| l1 * w[k] - sm * r[k]), n) / t;
    let d2 = dot(each!(|k| l2 * w[k] - sm * r[k]), n) / t;
    let t1 = ((d1 * l1) * l1).keep(l1.gt(zero) & d1.gt(zero));
    let t2 = ((d2 * l2) * l2).keep(l2.gt(zero) & d2.gt(zero));
    ((t1 + t2) / ((s.splat(PI) * t) * q)).keep(valid)
}

/// `sampling::random_unit_vector` from its draws u and v.
#[inline(always)]
fn random_unit_vector<S: Isa>(s: S, u: F<S>, v: F<S>) -> V3<S> {
    let one = s.splat(1.0);
    let z = one - s.splat(2.0) * u;
    let r = (one - z * z).max(s.zero()).sqrt();
    let (sin, cos) = sin_cos_turns(s, v);
    [r * cos, r * sin, z]
}

/// `intersect::offset_ray` in lanes (Wächter and Binder, Ray Tracing Gems ch. 6).
#[inline(always)]
fn offset_ray<S: Isa>(s: S, p: V3<S>, n: V3<S>) -> V3<S> {
    use super::intersect::{OFFSET_FLOAT_SCALE, OFFSET_INT_SCALE, OFFSET_ORIGIN};
    each!(|c| {
        let of_i = (s.splat(OFFSET_INT_SCALE) * n[c]).truncate();
        let near = p[c] + s.splat(OFFSET_FLOAT_SCALE) * n[c];
        let negative = s.int(0).blend(s.int(-1), p[c].lt(s.zero()));
        let step = of_i.xor(negative) - negative;
        let far = (p[c].to_bits() + step).float_of_bits();
        let small = p[c].abs().lt(s.splat(OFFSET_ORIGIN));
        far.blend(near, small)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::FrameSettings;
    use crate::cpu::fixed;
    use crate::cpu::rng::{GROUP, Rng};
    use crate::cpu::trace::{ANY, Tracer};
    use crate::scene::Scene;

    /// Eight spheres: a hollow one (negative radius) behind the others, Lambertian and
    /// specular lobes at smoothness 0, 0.3 and 1 and a fuzzed one, a lens, a uniform sky, and few bounces, so
    /// that paths end at the bounce limit, by a miss and by absorption.
    const SHELL: &str = r##"
[camera]
look_from = [0, 0.4, 2.5]
look_at = [0, 0, -1]
vfov = 70
aperture = 0.1
focus_distance = 3.0
[render]
max_bounces = 3
[sky]
uniform = [0.6, 0.7, 0.9]
[[sphere]]
center = [0, 0, -12]
radius = -8
color = "#c0c0c0"
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#80a060"
[[sphere]]
center = [-1.1, 0, -1]
radius = 0.5
color = "#d04040"
[[sphere]]
center = [0, 0, -1]
radius = 0.5
color = "#e0e0e0"
specular = 1
smoothness = 1
[[sphere]]
center = [1.1, 0, -1]
radius = 0.5
color = "#4060d0"
specular = 1
smoothness = 0.3
[[sphere]]
center = [0.5, 0.8, -1.8]
radius = 0.3
color = "#a0a0a0"
specular = 1
smoothness = 0.7
absorption = 0.4
[[sphere]]
center = [-0.5, 0.9, -2.2]
radius = 0.35
color = "#f0d080"
[[sphere]]
center = [0, -0.3, 0.2]
radius = 0.2
color = "#606060"
"##;

    /// Glass under a sun and a lamp: a solid ball, a hollow one (a sphere of negative radius
    /// inside), an index-matched one (ior 1: no draw) and a frosted one; lobes drawn with a
    /// probability (one at smoothness 0, one glossy: light sampling weighs both, the glossy
    /// one mixed with the diffuse lobe), a box of a certain glossy lobe; a quad lamp; enough
    /// bounces for paths through the glass.
    const GLASSY: &str = r##"
[camera]
look_from = [0, 0.5, 2.6]
look_at = [0, 0.1, -1]
vfov = 60
[render]
max_bounces = 6
[sky]
bottom = [1.0, 1.0, 1.0]
top = [0.5, 0.7, 1.0]
sun = { direction = [-0.5, 0.8, 0.4], color = [1.0, 0.95, 0.85], intensity = 6, size = 40 }
[materials.glass]
color = [0.95, 0.95, 0.95]
smoothness = -1
ior = 1.5
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#80a060"
specular = 0.3
smoothness = 0
[[sphere]]
center = [-1.1, 0, -1]
radius = 0.5
material = "glass"
[[sphere]]
center = [-1.1, 0, -1]
radius = -0.4
material = "glass"
[[sphere]]
center = [0, 0, -1.2]
radius = 0.5
material = "glass"
ior = 1.0
color = [0.9, 0.7, 0.7]
[[sphere]]
center = [1.1, 0, -1]
radius = 0.5
material = "glass"
absorption = 0.2
ior = 2.4
[[sphere]]
center = [0.5, 0.9, -1.9]
radius = 0.35
color = "#d04040"
specular = 0.4
smoothness = 0.8
[[box]]
center = [0, -0.4, 0.3]
half_extents = [0.3, 0.1, 0.2]
color = "#c0c0a0"
specular = 1
smoothness = 0.6
[[quad]]
q = [-0.5, 2.0, -1.5]
u = [1, 0, 0]
v = [0, 0, 1]
color = [1, 0.9, 0.8]
light = 4
"##;

    /// Under the shipped map, hidden from the camera (which sees the gradient sky) and turned:
    /// glossy lobes alone and mixed, a fuzzed specular lobe, a frosted glass box (a perfect
    /// mirror ball or a glass ball would bring the mirror or lens sampler).
    const MAPPED: &str = r##"
[camera]
look_from = [0, 0.7, 2.6]
look_at = [0, 0.1, -1.2]
vfov = 55
[render]
max_bounces = 6
[sky]
map = "scenes/maps/quarry_01_1k.hdr"
rotation = 130
intensity = 0.8
visible = false
bottom = [0.9, 0.9, 0.9]
top = [0.3, 0.5, 0.9]
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#8a8a84"
[[sphere]]
center = [-1.1, 0, -1]
radius = 0.5
color = "#3a6fb5"
[[sphere]]
center = [0, 0, -1.3]
radius = 0.5
color = "#d0200c"
specular = 0.2
smoothness = 0.9
[[sphere]]
center = [1.1, 0, -1]
radius = 0.5
color = "#e0c080"
specular = 1
smoothness = 0.7
[[sphere]]
center = [0.6, 0.7, -2.2]
radius = 0.4
color = [0.9, 0.9, 0.9]
specular = 1
smoothness = 0.98
absorption = 0.1
[[box]]
center = [0, -0.35, 0.2]
half_extents = [0.3, 0.15, 0.2]
smoothness = -1
ior = 1.5
absorption = 0.1
"##;

    /// Three lights of unequal power chosen among by light sampling (two spheres, one small
    /// and bright, and a quad), a glowing box that is no light (its light is met, never
    /// sampled), glossy lobes mixed and alone, glass, a dark sky.
    const LAMPS: &str = r##"
[camera]
look_from = [0, 0.8, 2.8]
look_at = [0, 0.1, -1]
vfov = 60
[render]
max_bounces = 6
[sky]
uniform = [0.02, 0.02, 0.04]
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#8a8a84"
[[sphere]]
center = [-1.0, 0.1, -1.2]
radius = 0.4
color = "#d0200c"
specular = 0.3
smoothness = 0.8
[[sphere]]
center = [0.2, 0, -1.4]
radius = 0.5
smoothness = -1
ior = 1.5
[[sphere]]
center = [1.1, 0, -1.1]
radius = 0.45
color = "#e0c080"
specular = 1
smoothness = 0.6
[[sphere]]
center = [-0.4, 0.9, -0.6]
radius = 0.08
color = [1.0, 0.7, 0.4]
light = 40
[[sphere]]
center = [0.9, 1.2, -2.2]
radius = 0.3
color = [0.6, 0.8, 1.0]
light = 3
[[quad]]
q = [-0.6, 2.2, -1.8]
u = [1.2, 0, 0]
v = [0, 0, 0.8]
color = [1, 1, 1]
light = 2
[[box]]
center = [0, -0.4, 0.2]
half_extents = [0.25, 0.1, 0.15]
color = [0.2, 1.0, 0.3]
light = 2
"##;

    /// A walk (`Walk`): more than `MAX_PRIMITIVES` spheres, a quad and a box, of the
    /// lecture's materials (glass, glossy lobes alone and mixed, fuzz) on triangles too: a
    /// smooth icosphere, glass of smooth normals, and a glTF file's normal-mapped quads given
    /// a glossy lecture material; under the map, seen directly. Two large spheres of
    /// different materials (the ground, a glossy backdrop) stand in the tree's root, which
    /// the lanes test themselves (`Root`).
    const WALKED: &str = r##"
[camera]
look_from = [0, 0.9, 3.2]
look_at = [0, 0.3, -0.8]
vfov = 60
[render]
max_bounces = 6
[sky]
map = "scenes/maps/quarry_01_1k.hdr"
rotation = 40
[materials.ground]
color = "#8a8a84"
[materials.clay]
color = "#3a6fb5"
[materials.glass]
color = [0.95, 0.95, 0.95]
smoothness = -1
ior = 1.5
[materials.gloss]
color = "#d0200c"
specular = 0.3
smoothness = 0.8
[materials.metal]
color = [0.9, 0.8, 0.6]
specular = 1
smoothness = 0.6
[materials.fuzz]
color = [0.8, 0.8, 0.8]
specular = 1
smoothness = 0.95
absorption = 0.2
[[sphere]]
center = [0, -100.5, -1]
radius = 100
material = "ground"
[[sphere]]
center = [0, 2, -60]
radius = 20
material = "gloss"
[[sphere]]
center = [-1.6, -0.3, -1.5]
radius = 0.2
material = "clay"
[[sphere]]
center = [-1.1, -0.3, -1.5]
radius = 0.2
material = "gloss"
[[sphere]]
center = [-0.6, -0.3, -1.5]
radius = 0.2
material = "metal"
[[sphere]]
center = [-0.1, -0.3, -1.5]
radius = 0.2
material = "fuzz"
[[sphere]]
center = [0.4, -0.3, -1.5]
radius = 0.2
material = "fuzz"
[[sphere]]
center = [0.9, -0.3, -1.5]
radius = 0.2
material = "clay"
[[sphere]]
center = [1.4, -0.3, -1.5]
radius = 0.2
material = "gloss"
[[sphere]]
center = [-1.3, -0.35, -0.6]
radius = 0.15
material = "clay"
[[sphere]]
center = [1.3, -0.35, -0.6]
radius = -0.15
material = "metal"
[[quad]]
q = [-2, -0.5, -2.6]
u = [4, 0, 0]
v = [0, 2, 0]
material = "clay"
[[box]]
center = [0, -0.4, 0.3]
half_extents = [0.3, 0.1, 0.2]
material = "glass"
[[mesh]]
file = "scenes/meshes/icosphere.obj"
translate = [-0.6, 0.3, -0.9]
scale = 0.3
material = "metal"
[[mesh]]
file = "scenes/meshes/icosphere.obj"
translate = [0.6, 0.3, -0.9]
scale = 0.3
material = "glass"
[[gltf]]
file = "tests/gltf/NormalTangentMirrorTest/NormalTangentMirrorTest.glb"
translate = [0, 0.75, -2.0]
scale = 1.2
instancing = "never"
[gltf.materials.Material]
model = "lecture"
color = [0.9, 0.9, 0.9]
specular = 0.5
smoothness = 0.7
"##;

    /// A shipped scene, or one of the test scenes `SHELL`, `GLASSY`, `MAPPED` and `LAMPS`.
    fn scene(name: &str) -> Scene {
        match name {
            "shell" => Scene::from_toml(SHELL, "shell").unwrap(),
            "glassy" => Scene::from_toml(GLASSY, "glassy").unwrap(),
            "mapped" => Scene::from_toml(MAPPED, "mapped").unwrap(),
            "lamps" => Scene::from_toml(LAMPS, "lamps").unwrap(),
            "walked" => Scene::from_toml(WALKED, "walked").unwrap(),
            _ => Scene::load(name).unwrap(),
        }
    }

    /// Every path the lanes trace (samples 5 to 40 of every pixel: three groups of
    /// samplers) against `Tracer::trace_path`'s, bit for bit: radiance, segments, and where
    /// its sampler's stream stands after it. Returns the paths compared and those that
    /// differ.
    fn compare(scene: &Scene, f: Features, w: u32, h: u32, wide: bool) -> (u64, u64) {
        let samples = 5..40;
        let settings = FrameSettings::new(w, h, scene.render.max_bounces.min(8), 5);
        let s = CpuScene::new(scene, &settings);
        let Some(mut lanes) = Lanes::of(&s, f) else {
            assert!(
                !std::arch::is_x86_feature_detected!("avx2"),
                "no lanes for the scene"
            );
            return (0, 0);
        };
        if !wide {
            lanes.wide = None;
        } else if lanes.wide.is_none() {
            eprintln!("no AVX-512 here: sixteen lanes not compared");
            return (0, 0);
        }
        let width = lanes.width();
        let mut t = Tracer::new(&s, f);
        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
        let (mut paths, mut differ) = (0, 0);
        for y in 0..h {
            for x0 in (0..w).step_by(width) {
                let n = (w - x0).min(width as u32) as usize;
                let mut got = std::collections::HashMap::new();
                let done = |x: usize, sample: u32, path: Traced| {
                    let (radiance, segments) = (path.radiance, path.segments);
                    let words = radiance
                        .is_finite()
                        .then(|| fixed::words(radiance.to_array()));
                    assert_eq!(path.words, words, "the words of {radiance}");
                    let pixel = y * w + x0 + x as u32;
                    let mut rng = Rng::resumed(pixel, sample, s.u.seed, path.taken, path.state);
                    let after = (rng.taken(), rng.rand().to_bits());
                    got.insert((x, sample), (bits(radiance), segments, after));
                };
                lanes.trace((x0, y, w), n, samples.clone(), s.u.seed, done);
                assert_eq!(got.len(), n * samples.len());
                for sample in samples.clone() {
                    for x in 0..n {
                        // The pixel's sampler, made in its group of eight as `trace_row`
                        // makes it.
                        let first = x0 + (x / GROUP * GROUP) as u32;
                        let pixels: [u32; GROUP] = from_fn(|k| y * w + first + k as u32);
                        let rng = &mut Rng::group(&pixels, sample, s.u.seed, 3)[x % GROUP];
                        let px = (x0 + x as u32, y);
                        let ray = t.camera_ray(px.0, y, rng);
                        let (radiance, segments) = if f.nee {
                            t.trace_path::<ANY, true>(px, ray, None, rng)
                        } else {
                            t.trace_path::<ANY, false>(px, ray, None, rng)
                        };
                        let want = (
                            bits(radiance),
                            segments,
                            (rng.taken(), rng.rand().to_bits()),
                        );
                        let lanes = got[&(x, sample)];
                        if lanes != want && differ < 3 {
                            eprintln!("{px:?}, sample {sample}: {lanes:?} against {want:?}");
                        }
                        differ += (lanes != want) as u64;
                        paths += 1;
                    }
                }
            }
        }
        (paths, differ)
    }

    #[test]
    fn lanes_trace_the_scalar_paths_bit_for_bit() {
        let mut cases = vec![];
        for name in [
            "shell",
            "basic",
            "metal",
            "fuzz",
            "dof",
            "dielectric",
            "specular",
        ] {
            let scene = scene(name);
            cases.push((name, Features::of(&scene), scene));
        }
        for name in [
            "lamp",
            "cornell",
            "glassy",
            "showcase",
            "mapped",
            "outdoor",
            "lamps",
            "emissive",
            "walked",
            "mesh",
            "benches/peer/map-dog.toml",
            "benches/peer/map-mirror.toml",
        ] {
            let scene = scene(name);
            let f = Features::of(&scene);
            cases.push((name, Features { nee: false, ..f }, scene.clone()));
            cases.push((name, f, scene));
        }
        for (name, f, scene) in &cases {
            for wide in [false, true] {
                let (paths, differ) = compare(scene, *f, 36, 20, wide);
                eprintln!(
                    "{name} (light sampling {}, {} lanes): {differ} of {paths} paths differ",
                    f.nee,
                    if wide { 16 } else { 8 }
                );
                assert!(paths == 0 || paths == 36 * 20 * 35);
                assert_eq!(differ, 0);
            }
        }
    }

    /// The words of `fixed_words` in lanes at both widths against `fixed::words`, at the
    /// edges: zeros of both signs, subnormals, values with fraction bits below 2⁻³², the
    /// whole parts about 2^24 and 2^31 (AVX2 converts signed), the clamp's ends and past.
    fn words_in<S: Isa>(s: S) {
        let values = [
            0.0,
            -0.0,
            1.0e-45,
            f32::MIN_POSITIVE,
            1e-30,
            1e-10,
            2.3283064e-10,
            0.1,
            0.5,
            0.99999994,
            1.0,
            1.5,
            3.75,
            16777215.5,
            16777216.0,
            2147483520.0,
            2147483648.0,
            2147483904.0,
            3e9,
            4294967040.0,
            4294967296.0,
            5e9,
            1e38,
            -3.0,
            -1e-20,
            123456.79,
            7.0e-8,
            0.33333334,
            65535.996,
            8388607.5,
            1e9,
            2.5e9,
        ];
        for chunk in values.chunks(S::N) {
            let mut row = [0.0f32; MAX_LANES];
            row[..chunk.len()].copy_from_slice(chunk);
            let (w, f) = fixed_words(s, s.load(&row));
            let (mut whole, mut frac) = ([0; MAX_LANES], [0; MAX_LANES]);
            w.store(&mut whole);
            f.store(&mut frac);
            for (k, &x) in chunk.iter().enumerate() {
                let lanes = (whole[k] as u32 as u64) << 32 | frac[k] as u32 as u64;
                assert_eq!(lanes, fixed::words([x; 3])[0], "{x:e} in {} lanes", S::N);
            }
        }
    }

    #[test]
    fn lanes_make_the_sums_words_as_the_scalar_tracer() {
        if let Some(s) = Avx2::new() {
            words_in(s);
        }
        if let Some(s) = Avx512::new() {
            words_in(s);
        }
    }

    #[test]
    fn lanes_trace_what_they_can_and_leave_out_the_rest() {
        let settings = FrameSettings::new(16, 16, 8, 1);
        let has = std::arch::is_x86_feature_detected!("avx2");
        // Many materials (more than `MAX_PRIMITIVES` kinds), the lens sampler (and glass
        // among the mirror sampler's spheres), glTF's BRDF.
        let kinds = "more than eight kinds of material, colour aside";
        for (name, reason) in [
            ("weekend", kinds),
            ("spheres", kinds),
            ("outdoor-caustics", "light sampling through glass balls"),
            ("pbr", "glTF's BRDF"),
        ] {
            let scene = scene(name);
            let s = CpuScene::new(&scene, &settings);
            let why = Lanes::try_of(&s, Features::of(&scene)).err();
            assert_eq!(
                why,
                Some(if has { reason } else { "the CPU has no AVX2" }),
                "{name}"
            );
        }
        for name in [
            "shell",
            "glassy",
            "basic",
            "metal",
            "fuzz",
            "dof",
            "lamp",
            "cornell",
            "dielectric",
            "specular",
            "showcase",
            "outdoor",
            "mapped",
            "lamps",
            "emissive",
            "walked",
            "mesh",
            "benches/peer/map-dog.toml",
            "benches/peer/map-mirror.toml",
        ] {
            let scene = scene(name);
            let s = CpuScene::new(&scene, &settings);
            assert_eq!(Lanes::of(&s, Features::of(&scene)).is_some(), has, "{name}");
        }
    }
}
