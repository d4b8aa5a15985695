//! The scene types of `MODEL.md` on the host and their defaults: what a scene file says after
//! validation.

use super::mesh::Mesh;
use super::texture::TexturedRef;
use glam::{DMat3, DMat4, DVec3, Vec3};
use std::path::Path;
use std::sync::Arc;

/// The pinhole or thin-lens camera of MODEL.md ("Space and camera"); its defaults come
/// from the parameter table (`params`).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub look_from: DVec3,
    pub look_at: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub vfov: f64,
    /// Lens diameter; 0 is a pinhole.
    pub aperture: f64,
    /// Distance to the plane in focus; `None` means `|look_at - look_from|`.
    pub focus_distance: Option<f64>,
}

impl Camera {
    /// The focus distance actually used: the explicit one, or the distance to `look_at`.
    pub fn focus(&self) -> f64 {
        self.focus_distance
            .unwrap_or_else(|| (self.look_at - self.look_from).length())
    }
}

/// The `[render]` table: the settings of a final render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel for `render` when neither `--spp` nor `--time` is given.
    pub spp: u32,
    pub max_bounces: u32,
    pub seed: u32,
}

/// Upper bounds that keep a scene file from asking for absurd work by mistake.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// llvmpipe (the software adapter) ends any shader loop after 65535 iterations; 10000
/// bounces stays well inside that, and far beyond what any scene needs.
pub const MAX_BOUNCES: u32 = 10_000;

/// The optional sun of the gradient sky: `color * intensity * max(dot(direction, dir), 0)^size`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sun {
    /// Direction towards the sun, as written (not necessarily unit length).
    pub direction: DVec3,
    pub color: Vec3,
    pub intensity: f32,
    pub size: f32,
}

/// The sky seen by rays that leave the scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Sky {
    /// `(1-t)*bottom + t*top` with `t = 0.5*(dir.y + 1)`, plus an optional sun.
    Gradient {
        bottom: Vec3,
        top: Vec3,
        sun: Option<Sun>,
    },
    /// One constant radiance in every direction (furnace tests).
    Uniform(Vec3),
}

impl Default for Sky {
    fn default() -> Self {
        Sky::Gradient {
            bottom: Vec3::ONE,
            top: Vec3::new(0.5, 0.7, 1.0),
            sun: None,
        }
    }
}

impl Sky {
    /// Radiance seen along the unit direction `dir` (MODEL.md "Sky"), on the host.
    pub fn radiance(&self, dir: DVec3) -> DVec3 {
        match self {
            Sky::Uniform(c) => c.as_dvec3(),
            Sky::Gradient { bottom, top, sun } => {
                let t = 0.5 * (dir.y + 1.0);
                let mut c = (1.0 - t) * bottom.as_dvec3() + t * top.as_dvec3();
                if let Some(s) = sun {
                    let k = s
                        .direction
                        .normalize()
                        .dot(dir)
                        .max(0.0)
                        .powf(s.size as f64);
                    c += s.color.as_dvec3() * s.intensity as f64 * k;
                }
                c
            }
        }
    }
}

/// An HDR environment map around the scene (`[sky] map = "…"` or `--sky FILE`): it lights
/// the scene, and rays that leave the scene see it (docs/MODEL-NOTES.md "Environment maps").
/// The `[sky]` gradient or uniform colour stays the background that camera rays see where
/// the map is not `visible`.
#[derive(Clone, Debug)]
pub struct Environment {
    /// The file as the scene names it (relative to the scene file), for writing back.
    pub file: String,
    /// The loaded map, shared by every copy of the scene (edits clone the scene).
    pub map: std::sync::Arc<super::envmap::EnvMap>,
    /// A factor on the map's radiance.
    pub intensity: f32,
    /// Degrees about the up axis (+y); positive turns the map's features to the left as seen
    /// from above (counter-clockwise).
    pub rotation: f32,
    /// Whether camera rays see the map (false: they see the `[sky]` background).
    pub visible: bool,
}

impl PartialEq for Environment {
    fn eq(&self, o: &Environment) -> bool {
        self.file == o.file
            && (std::sync::Arc::ptr_eq(&self.map, &o.map) || self.map == o.map)
            && self.intensity == o.intensity
            && self.rotation == o.rotation
            && self.visible == o.visible
    }
}

impl Environment {
    /// The map of `file` (as written) at `path`, with the defaults: intensity 1, no rotation,
    /// visible.
    pub fn load(file: &str, path: &Path) -> Result<Environment, super::envmap::EnvMapError> {
        Ok(Self::with_defaults(
            file,
            super::envmap::EnvMap::load(path)?,
        ))
    }

    /// `map`, named `file`, with intensity 1, no rotation, visible.
    fn with_defaults(file: &str, map: super::envmap::EnvMap) -> Environment {
        Environment {
            file: file.to_string(),
            map: std::sync::Arc::new(map),
            intensity: 1.0,
            rotation: 0.0,
            visible: true,
        }
    }

    /// A built-in scene's map, from the binary (`BUILTIN_MAPS`).
    pub fn builtin(file: &str) -> Result<Environment, super::envmap::EnvMapError> {
        let (_, bytes) = super::BUILTIN_MAPS
            .iter()
            .find(|(n, _)| *n == file)
            .ok_or_else(|| super::envmap::EnvMapError::NoBuiltin(file.to_string()))?;
        Ok(Self::with_defaults(
            file,
            super::envmap::EnvMap::from_bytes(bytes, file)?,
        ))
    }

    /// Whether the map sends any light: its texels are not all black and its intensity is
    /// above zero (a dark map is looked up but never sampled).
    pub fn lights(&self) -> bool {
        self.intensity > 0.0 && self.map.distribution.integral > 0.0
    }
}

/// glTF's GGX α (roughness²) below which a pbr lobe is a perfect mirror, on both tracers
/// (`cpu::pbr::ALPHA_MIN`, `PBR_ALPHA_MIN` in shaders/common/pbr.wgsl).
pub const PBR_MIRROR_ALPHA: f32 = 1e-4;

/// The lecture's four material parameters plus `ior` and `specular_color` (MODEL.md table);
/// each number's range, steps and default are declared once in `params`.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Albedo, emission colour or glass tint; linear.
    pub color: Vec3,
    /// 0 Lambertian … 1 mirror; < 0 dielectric.
    pub smoothness: f32,
    /// The lecture's "Absorption = Fuzz": radius of the random unit vector added to reflections.
    pub absorption: f32,
    /// Probability that a bounce takes the specular lobe.
    pub specular: f32,
    /// Emission strength; radiance = `color * light`.
    pub light: f32,
    /// Index of refraction, used when `smoothness < 0`.
    pub ior: f32,
    /// Tint of specular bounces; `None` means the same as `color`.
    pub specular_color: Option<Vec3>,
    /// Which material model the surface follows: the lecture's, or glTF's metallic-roughness
    /// BRDF (`color` is then the base colour, `ior` the dielectric's index).
    pub model: MaterialModel,
    /// glTF's metallic factor (0 dielectric … 1 metal); the `pbr` model's.
    pub metallic: f32,
    /// glTF's perceptual roughness (α = roughness²); the `pbr` model's.
    pub roughness: f32,
    /// KHR_materials_transmission's factor: the share of the dielectric base that passes
    /// through the surface; the `pbr` model's.
    pub transmission: f32,
    /// How a transmitting pbr material's light passes: a thin wall, or a volume's boundary
    /// (KHR_materials_volume).
    pub volume: Volume,
    /// KHR_materials_clearcoat's factor and roughness: a clear coat of ior 1.5 over the
    /// material; the `pbr` model's.
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    /// A glTF material's texture maps, mapped onto the other fields at each hit (`None`: the
    /// fields as they are).
    pub textured: Option<TexturedRef>,
}

/// What lies behind a transmitting pbr surface (KHR_materials_volume).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Volume {
    /// A thin wall: light passes without bending (glTF's reading of a material without
    /// KHR_materials_volume or of thickness 0). Else the surface bounds a volume: it
    /// refracts, and the medium inside attenuates.
    pub thin_walled: bool,
    /// The colour white light takes after `attenuation_distance` inside (linear).
    pub attenuation_color: Vec3,
    /// Scene units; infinite: a clear medium.
    pub attenuation_distance: f32,
}

impl Default for Volume {
    /// A clear solid: what a scene file's transmitting material is unless it says otherwise.
    fn default() -> Self {
        Volume {
            thin_walled: false,
            attenuation_color: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
        }
    }
}

impl Volume {
    /// Beer–Lambert's attenuation coefficient per scene unit, −ln(colour) / distance (0 for a
    /// clear medium; a black channel absorbs within 10⁻⁶ of the distance).
    pub fn coefficient(&self) -> Vec3 {
        if self.thin_walled || !self.attenuation_distance.is_finite() {
            return Vec3::ZERO;
        }
        let c = self.attenuation_color.clamp(Vec3::splat(1e-6), Vec3::ONE);
        -c.map(f32::ln) / self.attenuation_distance
    }
}

/// The material models a surface can follow.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MaterialModel {
    /// MODEL.md's: smoothness, absorption (fuzz), specular probability, glass below 0.
    #[default]
    Lecture,
    /// glTF 2.0's metallic-roughness BRDF (its Appendix B; docs/MODEL-NOTES.md, "pbr").
    Pbr,
}

impl MaterialModel {
    /// The model as a scene file names it (`model = "pbr"`).
    pub fn name(self) -> &'static str {
        match self {
            MaterialModel::Lecture => "lecture",
            MaterialModel::Pbr => "pbr",
        }
    }

    /// The model of that name.
    pub fn named(name: &str) -> Option<MaterialModel> {
        [MaterialModel::Lecture, MaterialModel::Pbr]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// Default albedo of MODEL.md for non-dielectrics.
pub const DEFAULT_COLOR: Vec3 = Vec3::new(0.8, 0.8, 0.8);
/// Default tint of dielectrics.
pub const DEFAULT_GLASS_COLOR: Vec3 = Vec3::ONE;

impl Material {
    pub fn is_dielectric(&self) -> bool {
        self.model == MaterialModel::Lecture && self.smoothness < 0.0
    }
    pub fn is_pbr(&self) -> bool {
        self.model == MaterialModel::Pbr
    }
    pub fn is_emitter(&self) -> bool {
        self.light > 0.0
    }
    /// A perfect mirror, which light sampling looks through at the map where it is a sphere
    /// (`common::arrays::mirror_spheres`): the lecture's (specular 1, smoothness 1, no fuzz),
    /// or glTF's smooth lobe (roughness² below [`PBR_MIRROR_ALPHA`]) where it reflects
    /// (metallic, or a specular weight) and neither transmits nor has a clear coat; not
    /// emitting, untextured.
    pub fn is_mirror(&self) -> bool {
        let mirror = if self.is_pbr() {
            self.roughness * self.roughness < PBR_MIRROR_ALPHA
                && (self.metallic > 0.0 || self.specular > 0.0)
                && self.transmission == 0.0
                && self.clearcoat == 0.0
        } else {
            !self.is_dielectric()
                && self.specular >= 1.0
                && self.smoothness >= 1.0
                && self.absorption == 0.0
        };
        mirror && !self.is_emitter() && self.textured.is_none()
    }
    /// A clear glass ball the map's light is sampled through (`common::arrays::lens_spheres`):
    /// the lecture's dielectric without fuzz, or glTF's smooth transmitting volume
    /// (roughness² below [`PBR_MIRROR_ALPHA`], transmission above 0, not metal through and
    /// through, no clear coat, not a thin wall; its medium may attenuate); denser than air
    /// (ior above 1), neither emitting nor textured.
    pub fn is_lens(&self) -> bool {
        let lens = if self.is_pbr() {
            self.roughness * self.roughness < PBR_MIRROR_ALPHA
                && self.transmission > 0.0
                && self.metallic < 1.0
                && self.clearcoat == 0.0
                && !self.volume.thin_walled
        } else {
            self.is_dielectric() && self.absorption == 0.0
        };
        lens && self.ior > 1.0 && !self.is_emitter() && self.textured.is_none()
    }
    /// The lecture's glossy lobe: a specular lobe (specular > 0) blended with the diffuse
    /// direction (smoothness strictly between 0 and 1) and without fuzz, which light sampling
    /// weighs by its density (`cpu::material::gloss_pdf`).
    pub fn is_glossy(&self) -> bool {
        self.model == MaterialModel::Lecture
            && !self.is_emitter()
            && self.specular > 0.0
            && self.smoothness > 0.0
            && self.smoothness < 1.0
            && self.absorption == 0.0
    }
    /// The specular tint actually used.
    pub fn specular_tint(&self) -> Vec3 {
        self.specular_color.unwrap_or(self.color)
    }
}

/// The geometry of one object (MODEL.md "Primitives").
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A negative radius keeps the geometry of `|radius|` and flips the normal inward.
    Sphere { center: DVec3, radius: f64 },
    /// Corner `q`, edges `u` and `v`; two-sided.
    Quad { q: DVec3, u: DVec3, v: DVec3 },
    /// Box with Euler `rotation` in degrees, applied X then Y then Z.
    Box {
        center: DVec3,
        half_extents: DVec3,
        rotation: DVec3,
    },
    /// Triangles from an OBJ file, scaled, then rotated (Euler XYZ, degrees), then moved.
    Mesh {
        /// The file as the scene names it.
        file: String,
        mesh: Arc<Mesh>,
        translate: DVec3,
        rotation: DVec3,
        scale: DVec3,
        /// Where the mesh is drawn more than once: one world-from-mesh transform per copy,
        /// applied after `translate`, `rotation` and `scale` (glTF nodes that share a mesh,
        /// `EXT_mesh_gpu_instancing`). Empty: once, in place. The tracers store the triangles
        /// once and walk a two-level BVH (docs/MODEL-NOTES.md, "Instancing").
        instances: Arc<Vec<DMat4>>,
    },
}

impl Shape {
    /// The kind of primitive as the scene file spells its table.
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Sphere { .. } => "sphere",
            Shape::Quad { .. } => "quad",
            Shape::Box { .. } => "box",
            Shape::Mesh { .. } => "mesh",
        }
    }

    /// A mesh's triangles in world space, every instance's in turn (empty for other shapes).
    pub fn world_triangles(&self) -> Vec<[DVec3; 3]> {
        match self {
            Shape::Mesh {
                mesh,
                translate,
                rotation,
                scale,
                instances,
                ..
            } => {
                use rayon::prelude::*;
                let r = euler_xyz(*rotation);
                let f = |p: DVec3| *translate + r * (*scale * p);
                if instances.is_empty() {
                    return mesh.triangles.par_iter().map(|t| t.map(f)).collect();
                }
                instances
                    .par_iter()
                    .flat_map_iter(|m| {
                        mesh.triangles
                            .iter()
                            .map(|t| t.map(|p| m.transform_point3(f(p))))
                    })
                    .collect()
            }
            _ => Vec::new(),
        }
    }

    /// How many times the shape is drawn: a mesh's instances, else 1.
    pub fn copies(&self) -> usize {
        match self {
            Shape::Mesh { instances, .. } => instances.len().max(1),
            _ => 1,
        }
    }
}

/// Rotation matrix of a box's Euler angles (degrees), applied X then Y then Z: `Rz * Ry * Rx`.
pub fn euler_xyz(degrees: DVec3) -> DMat3 {
    let r = degrees * (std::f64::consts::PI / 180.0);
    DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
}

/// One object: a shape with its own (flattened) material.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// Optional `name = "..."` from the file, shown by the preview.
    pub name: Option<String>,
    pub shape: Shape,
    pub material: Material,
    /// The named material the object started from, kept so the scene can be written back
    /// (for an object from a glTF file: its glTF material's key, see [`GltfPlacement`]).
    pub material_name: Option<String>,
    /// The [`Scene::gltf`] placement the object was imported from; such an object is written
    /// back as its placement, not on its own.
    pub gltf: Option<usize>,
}

/// A glTF file placed in a scene (`[[gltf]]`, or the file itself when opened directly):
/// its objects are imported with the transform scale, then rotation (Euler XYZ, degrees),
/// then translation, like a mesh's.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfPlacement {
    /// The file as the scene names it (relative to the scene file).
    pub file: String,
    pub translate: DVec3,
    pub rotation: DVec3,
    pub scale: DVec3,
    /// How the file's repeated meshes are stored (`instancing`: auto, always, never).
    pub instancing: super::gltf_instances::Instancing,
    /// Each glTF material's key (its name, `#INDEX` when unnamed) and the material it maps to
    /// as the file gives it, before the scene's overrides: writing back writes each material
    /// whose objects differ from this as an override.
    pub materials: Vec<(String, Material)>,
    /// What of the file is not rendered, each once ("the extension KHR_materials_clearcoat
    /// (optional; not read)", a primitive without triangles): logged when it is read, and
    /// listed by `check`.
    pub left_out: Vec<String>,
}

impl Object {
    /// A label for lists and status lines: the object's name, else `sphere #3`.
    pub fn label(&self, index_in_kind: usize) -> String {
        match &self.name {
            Some(n) => n.clone(),
            None => format!("{} #{}", self.shape.kind(), index_in_kind + 1),
        }
    }
}

/// Objects by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub spheres: usize,
    pub quads: usize,
    pub boxes: usize,
    pub meshes: usize,
    /// Triangles stored (an instanced mesh's once).
    pub triangles: usize,
    /// Triangles drawn (an instanced mesh's once per instance).
    pub drawn_triangles: usize,
    /// Copies of instanced meshes.
    pub instances: usize,
}

/// A validated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Where the scene came from: a path, or `builtin:NAME`.
    pub origin: String,
    pub camera: Camera,
    pub render: RenderSettings,
    pub sky: Sky,
    /// An HDR environment map, where the scene has one.
    pub environment: Option<Environment>,
    /// The `[materials.NAME]` tables, as written (kept for writing the scene back).
    pub materials: Vec<(String, Material)>,
    pub objects: Vec<Object>,
    /// The glTF files the scene places (their objects are in `objects`).
    pub gltf: Vec<GltfPlacement>,
}

impl Scene {
    /// Short name for titles: file stem or built-in name.
    pub fn short_name(&self) -> String {
        let o = self.origin.strip_prefix("builtin:").unwrap_or(&self.origin);
        Path::new(o)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| o.to_string())
    }

    /// Objects with the index each has among the objects of its kind (for labels).
    pub fn labels(&self) -> Vec<String> {
        let mut counts = std::collections::HashMap::new();
        self.objects
            .iter()
            .map(|o| {
                let k = counts.entry(o.shape.kind()).or_insert(0usize);
                *k += 1;
                o.label(*k - 1)
            })
            .collect()
    }

    /// The objects in the order the tracers store their triangles (`common::arrays`): meshes
    /// drawn once (and the other shapes), then instanced meshes.
    pub fn triangle_order(&self) -> impl Iterator<Item = &Object> {
        let instanced = |o: &&Object| matches!(&o.shape, Shape::Mesh { instances, .. } if !instances.is_empty());
        self.objects
            .iter()
            .filter(move |o| !instanced(o))
            .chain(self.objects.iter().filter(instanced))
    }

    /// How many objects of each kind, and triangles in all meshes.
    pub fn counts(&self) -> Counts {
        let mut c = Counts::default();
        for o in &self.objects {
            match &o.shape {
                Shape::Sphere { .. } => c.spheres += 1,
                Shape::Quad { .. } => c.quads += 1,
                Shape::Box { .. } => c.boxes += 1,
                Shape::Mesh {
                    mesh, instances, ..
                } => {
                    c.meshes += 1;
                    c.triangles += mesh.triangles.len();
                    c.drawn_triangles += mesh.triangles.len() * o.shape.copies();
                    c.instances += instances.len();
                }
            }
        }
        c
    }
}
