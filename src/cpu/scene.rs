//! The scene as the CPU tracer reads it: the very arrays the GPU gets
//! (`common::arrays::Primitives`, `scene_uniforms`, the same BVH), converted to SIMD
//! vectors (`glam::Vec3A`), with the BVH collapsed to four children per node (`cpu::bvh`),
//! and where the CPU has AVX to eight (`cpu::bvh8`).

use super::bvh::Bvh4;
#[cfg(target_arch = "x86_64")]
use super::bvh8::Bvh8;
use super::intersect::{Cuboid, Instance, Quad, Sphere, Triangle};
use crate::common::FrameSettings;
use crate::common::arrays::{Primitives, REF_INDEX, geometry_hash, gpu_bvh, scene_uniforms};
use crate::common::layout::{GpuLight, GpuMaterial, MODEL_PBR, SceneUniforms};
use crate::scene::Scene;
use crate::scene::envmap::EnvMap;
use glam::{DVec3, Vec3A, Vec4};
use std::sync::Arc;

fn v(a: [f32; 3]) -> Vec3A {
    Vec3A::from_array(a)
}

#[derive(Clone, Copy, Debug)]
pub struct Material {
    pub color: Vec3A,
    pub specular_color: Vec3A,
    pub smoothness: f32,
    pub absorption: f32,
    pub specular: f32,
    pub light: f32,
    pub ior: f32,
    pub light_slot: u32,
    pub metallic: f32,
    pub roughness: f32,
    /// glTF's metallic-roughness BRDF (`cpu::pbr`) rather than the lecture's lobes.
    pub pbr: bool,
    /// pbr: KHR_materials_transmission's factor, and whether the surface is a thin wall
    /// (else a volume's boundary, with its medium's attenuation per unit).
    pub transmission: f32,
    pub thin: bool,
    pub attenuation: Vec3A,
    /// pbr: KHR_materials_clearcoat's factor and perceptual roughness.
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
}

/// The uniforms the tracer reads per sample, as vectors.
#[derive(Clone, Copy, Debug)]
pub struct Uniforms {
    pub cam_origin: Vec3A,
    pub cam_to_corner: Vec3A,
    pub cam_horizontal: Vec3A,
    pub cam_vertical: Vec3A,
    pub cam_u: Vec3A,
    pub cam_v: Vec3A,
    pub lens_radius: f32,
    pub sky_uniform: bool,
    pub sky_bottom: Vec3A,
    pub sky_top: Vec3A,
    pub sun_dir: Vec3A,
    pub sun_size: f32,
    pub sun_radiance: Vec3A,
    pub width: u32,
    pub height: u32,
    pub max_bounces: u32,
    pub seed: u32,
    pub n_lights: u32,
    pub n_mirrors: u32,
    pub primitives: u32,
    pub env_rotation: f32,
    pub env_intensity: f32,
    pub env_pick: f32,
    /// `SceneUniforms::env_mode`.
    pub env_mode: u32,
}

impl Uniforms {
    fn of(u: &SceneUniforms) -> Uniforms {
        Uniforms {
            cam_origin: v(u.cam_origin),
            cam_to_corner: v(u.cam_to_corner),
            cam_horizontal: v(u.cam_horizontal),
            cam_vertical: v(u.cam_vertical),
            cam_u: v(u.cam_u),
            cam_v: v(u.cam_v),
            lens_radius: u.lens_radius,
            sky_uniform: u.sky_uniform != 0,
            sky_bottom: v(u.sky_bottom),
            sky_top: v(u.sky_top),
            sun_dir: v(u.sun_dir),
            sun_size: u.sun_size,
            sun_radiance: v(u.sun_radiance),
            width: u.width,
            height: u.height,
            max_bounces: u.max_bounces,
            seed: u.seed,
            n_lights: u.n_lights,
            n_mirrors: u.n_mirrors,
            primitives: u.n_spheres + u.n_quads + u.n_boxes + u.n_triangles,
            env_rotation: u.env_rotation,
            env_intensity: u.env_intensity,
            env_pick: u.env_pick,
            env_mode: u.env_mode,
        }
    }
}

impl Material {
    /// The material as the CPU tracer reads it, from the GPU's mirror.
    pub fn of(m: &GpuMaterial) -> Material {
        Material {
            color: v(m.color),
            specular_color: v(m.specular_color),
            smoothness: m.smoothness,
            absorption: m.absorption,
            specular: m.specular,
            light: m.light,
            ior: m.ior,
            light_slot: m.light_slot,
            metallic: m.metallic,
            roughness: m.roughness,
            pbr: m.model == MODEL_PBR,
            transmission: m.transmission,
            thin: m.thin != 0,
            attenuation: v(m.attenuation),
            clearcoat: m.clearcoat,
            clearcoat_roughness: m.clearcoat_roughness,
        }
    }
}

pub struct CpuScene {
    pub u: Uniforms,
    pub materials: Vec<Material>,
    pub spheres: Vec<Sphere>,
    pub quads: Vec<Quad>,
    pub boxes: Vec<Cuboid>,
    pub triangles: Vec<Triangle>,
    pub lights: Vec<GpuLight>,
    /// The mirror spheres light sampling reflects the map in: indices into `spheres`
    /// (`common::arrays::mirror_spheres`, which follow the lights in `Primitives::lights`).
    pub mirrors: Vec<u32>,
    /// The glass spheres light sampling refracts the map through, likewise
    /// (`common::arrays::lens_spheres`, which follow the mirror spheres).
    pub lenses: Vec<u32>,
    /// The spheres light sampling reflects the map in: the mirror spheres, then the glass
    /// ones (their outer surface reflects as Fresnel says).
    pub reflectors: Vec<u32>,
    /// Copies of instanced meshes, whose trees follow the top level in `bvh`.
    pub instances: Vec<Instance>,
    /// Triangles the top level names (an instanced mesh's follow them).
    pub top_triangles: usize,
    pub bvh: Bvh4,
    /// The BVH collapsed to eight-wide nodes, for the single-ray walk on a CPU with AVX.
    #[cfg(target_arch = "x86_64")]
    pub bvh8: Option<Bvh8>,
    /// A scene of a few quads and boxes: all of them tested at once instead of the walk.
    #[cfg(target_arch = "x86_64")]
    pub few: Option<super::few::Few>,
    /// The triangles by component in the order of the tree's references, for the leaves
    /// tested eight at a time (`cpu::tri8`), where the tree is eight wide.
    #[cfg(target_arch = "x86_64")]
    pub tri8: Option<super::tri8::Tri8>,
    /// The texture words (`common::textures`; empty when no material has maps), and whether
    /// any material cuts out.
    pub tex: Vec<u32>,
    pub cutouts: bool,
    /// Some material has a normal map (the shading-normal code runs).
    pub normal_maps: bool,
    /// Some mesh has the file's normals (smooth shading; texture.wgsl's HAS_SMOOTH_NORMALS).
    pub smooth_normals: bool,
    /// The environment map, where the scene has one (its CDFs and texels as the GPU's).
    pub env: Option<Arc<EnvMap>>,
    tex_key: Vec<usize>,
    /// Nodes of the BVH, and the seconds its build took.
    pub node_count: usize,
    pub build_seconds: f64,
    /// As on the GPU (`SceneBuffers`): positions are relative to this floating origin, kept
    /// while the geometry is unchanged so that the BVH can be kept too.
    origin: DVec3,
    geometry: u64,
    nee: bool,
}

impl CpuScene {
    pub fn new(scene: &Scene, s: &FrameSettings) -> CpuScene {
        let origin = scene.camera.look_at;
        let p = Primitives::of(scene, origin, s.nee);
        let t = std::time::Instant::now();
        let (nodes, refs, instances) = gpu_bvh(&p);
        let bvh = Bvh4::new(&nodes, refs);
        #[cfg(target_arch = "x86_64")]
        let bvh8 = std::arch::is_x86_feature_detected!("avx").then(|| Bvh8::new(&bvh));
        let build_seconds = t.elapsed().as_secs_f64();
        let mut c = CpuScene {
            u: Uniforms::of(&scene_uniforms(scene, s, origin)),
            materials: Vec::new(),
            spheres: Vec::new(),
            quads: Vec::new(),
            boxes: Vec::new(),
            triangles: Vec::new(),
            lights: Vec::new(),
            mirrors: Vec::new(),
            reflectors: Vec::new(),
            lenses: Vec::new(),
            instances: instances
                .iter()
                .map(|i| Instance {
                    object_from_world: i.object_from_world.map(Vec4::from_array),
                    world_from_object: i.world_from_object.map(Vec4::from_array),
                    root: i.root,
                })
                .collect(),
            top_triangles: p.top_triangles,
            tex: Vec::new(),
            cutouts: false,
            normal_maps: false,
            smooth_normals: false,
            env: scene.environment.as_ref().map(|e| e.map.clone()),
            tex_key: Vec::new(),
            bvh,
            #[cfg(target_arch = "x86_64")]
            bvh8,
            #[cfg(target_arch = "x86_64")]
            few: None,
            #[cfg(target_arch = "x86_64")]
            tri8: None,
            node_count: nodes.len(),
            build_seconds,
            origin,
            geometry: geometry_hash(scene),
            nee: s.nee,
        };
        c.take(&p);
        c.take_textures(scene);
        c.take_few();
        #[cfg(target_arch = "x86_64")]
        {
            c.tri8 = c
                .bvh8
                .as_ref()
                .and_then(|_| super::tri8::Tri8::new(&c.bvh.refs, &c.triangles));
        }
        c
    }

    /// How the eight-wide walks test their leaves (`cpu::tri8`): triangles eight at a time,
    /// but where a material cuts out (its texture test is the scalar one's), and `skip` and
    /// `from` left out.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub fn leaves(&self, skip: u32, from: u32) -> super::tri8::Leaves<'_> {
        super::tri8::Leaves {
            tris: self.tri8.as_ref().filter(|_| !self.cutouts),
            skip,
            from,
            skipped: 0,
        }
    }

    /// The test of every primitive at once, where the scene is a few quads and boxes.
    fn take_few(&mut self) {
        #[cfg(target_arch = "x86_64")]
        {
            self.few = self
                .bvh8
                .as_ref()
                .and_then(|b8| super::few::Few::of(b8, &self.bvh.refs, &self.quads, &self.boxes));
        }
    }

    /// Whether shading normals can differ from the geometric one (a normal map or smooth
    /// shading): then a direction below the geometric surface is refused.
    #[inline(always)]
    pub fn shading_normals(&self) -> bool {
        self.normal_maps || self.smooth_normals
    }

    /// The texture words, as the GPU gets them.
    fn take_textures(&mut self, scene: &Scene) {
        self.tex = crate::common::textures::words(scene).unwrap_or_default();
        self.tex_key = crate::common::textures::material_key(scene);
        let f = crate::common::Features::of(scene);
        self.cutouts = f.cutouts;
        self.normal_maps = f.normal_maps;
        self.smooth_normals = f.smooth_normals;
    }

    /// Brings the scene up to date; the BVH is kept when the geometry is unchanged (as the
    /// GPU's `SceneBuffers::update` does).
    pub fn update(&mut self, scene: &Scene, s: &FrameSettings) {
        if geometry_hash(scene) != self.geometry || s.nee != self.nee {
            *self = CpuScene::new(scene, s);
            return;
        }
        // The geometry is unchanged: the triangles stay (10⁶ of them take 0.2 s to make), and
        // so do the trees, `few` and `tri8`, made of the same primitives.
        let p = Primitives::without_meshes(scene, self.origin, s.nee);
        self.u = Uniforms::of(&scene_uniforms(scene, s, self.origin));
        self.env = scene.environment.as_ref().map(|e| e.map.clone());
        let triangles = std::mem::take(&mut self.triangles);
        self.take(&p);
        self.triangles = triangles;
        // The texture words are made again only when the textured materials changed; an edit
        // of their factors rewrites the records alone (as `SceneBuffers::update` does).
        let key = crate::common::textures::material_key(scene);
        if key != self.tex_key {
            self.take_textures(scene);
        } else if let Some((at, records)) = crate::common::textures::record_words(scene) {
            self.tex[at..at + records.len()].copy_from_slice(&records);
        }
    }

    fn take(&mut self, p: &Primitives) {
        self.materials = p.materials.iter().map(Material::of).collect();
        self.spheres = p
            .spheres
            .iter()
            .map(|s| Sphere {
                anchor: v(s.anchor),
                anchor_normal: v(s.anchor_normal),
                radius: s.radius,
                material: s.material,
            })
            .collect();
        self.quads = p
            .quads
            .iter()
            .map(|q| Quad {
                q: v(q.q),
                u: v(q.u),
                v: v(q.v),
                normal: v(q.normal),
                w: v(q.w),
                material: q.material,
            })
            .collect();
        self.boxes = p
            .boxes
            .iter()
            .map(|b| Cuboid {
                center: v(b.center),
                half_extents: v(b.half_extents),
                axes: [v(b.axis_x), v(b.axis_y), v(b.axis_z)],
                material: b.material,
            })
            .collect();
        self.triangles = p
            .triangles
            .iter()
            .map(|t| Triangle {
                v0: v(t.v0),
                e1: v(t.e1),
                e2: v(t.e2),
                material: t.material,
            })
            .collect();
        let n = self.u.n_lights as usize;
        self.lights = p.lights[..n].to_vec();
        let m = n + self.u.n_mirrors as usize;
        self.mirrors = p.lights[n..m].iter().map(|l| l.prim & REF_INDEX).collect();
        self.lenses = p.lights[m..].iter().map(|l| l.prim & REF_INDEX).collect();
        self.reflectors = p.lights[n..].iter().map(|l| l.prim & REF_INDEX).collect();
    }
}
