//! Per-scene specialization. The tracer's WGSL declares one pipeline-overridable boolean per
//! optional feature (`override HAS_DIELECTRICS: bool = true;`, …) and guards that feature's
//! code with it. A scene's pipeline is created with the constants of the features it uses;
//! naga substitutes them before the driver compiles, so `if HAS_DIELECTRICS { … }` becomes
//! `if false { … }` and the driver's dead-code elimination leaves the glass code out of the
//! pipeline. The generic pipeline (`--generic`) sets every feature.

use crate::scene::{Scene, Shape, Sky};

/// A feature name [`Features::parse_list`] does not know.
#[derive(Debug, thiserror::Error)]
#[error(
    "unknown feature `{0}` (expected spheres, quads, boxes, triangles, dielectrics, emitters, \
     nee, dof, sun, textures, cutouts, normal_maps, smooth_normals, env_map, mirror_nee, \
     lens_nee, gloss_nee, pbr, pbr_specular, pbr_transmission, pbr_clearcoat, instances or lecture)"
)]
pub struct UnknownFeature(pub String);

/// The optional parts of the tracer a scene needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Features {
    pub spheres: bool,
    pub quads: bool,
    pub boxes: bool,
    pub triangles: bool,
    pub dielectrics: bool,
    pub emitters: bool,
    /// Next-event estimation: the scene has lights to sample (emissive spheres or quads)
    /// and the settings ask for it.
    pub nee: bool,
    pub dof: bool,
    pub sun: bool,
    /// glTF materials with texture maps.
    pub textures: bool,
    /// Alpha cut-outs (glTF's MASK and BLEND).
    pub cutouts: bool,
    /// Tangent-space normal maps (shading normals).
    pub normal_maps: bool,
    /// Meshes with the file's normals (glTF `NORMAL`, OBJ `vn`), interpolated across each
    /// triangle: smooth shading.
    pub smooth_normals: bool,
    /// An HDR environment map: looked up where rays leave the scene, and sampled by
    /// next-event estimation (with `nee`).
    pub env_map: bool,
    /// Perfect mirror spheres (or clear glass balls, which reflect too) under an environment
    /// map that lights the scene: next-event estimation also samples the map's light as a
    /// mirror ball reflects it (with `nee`; `common::arrays::mirror_spheres`).
    pub mirror_nee: bool,
    /// Clear glass balls under an environment map that lights the scene: next-event
    /// estimation also samples the map's light as the ball refracts it (the sun's caustic;
    /// with `nee`; `common::arrays::lens_spheres`).
    pub lens_nee: bool,
    /// The lecture's glossy lobe (its specular lobe at a smoothness between 0 and 1, without
    /// fuzz) takes light samples, weighed against its density (`cpu::material::gloss_pdf`;
    /// with `nee`).
    pub gloss_nee: bool,
    /// glTF's metallic-roughness BRDF (`model = "pbr"` materials).
    pub pbr: bool,
    /// A pbr material with `KHR_materials_specular` (a specular other than 1 or a coloured
    /// one): without one the lobes carry no coloured f0.
    pub pbr_specular: bool,
    /// A pbr material that transmits (KHR_materials_transmission), with its volume's
    /// refraction and attenuation (KHR_materials_volume).
    pub pbr_transmission: bool,
    /// A pbr material with a clear coat (KHR_materials_clearcoat).
    pub pbr_clearcoat: bool,
    /// A mesh drawn by instances: the BVH's top level holds copies, walked into their
    /// meshes' own trees.
    pub instances: bool,
    /// The lecture's surface lobes (a non-emitting, non-dielectric material of its model):
    /// a scene of glTF materials alone compiles none of them. Without `pbr` too (the
    /// benchmarks' feature lists) the lecture's lobes are what every surface runs.
    pub lecture: bool,
    /// Counts path segments (benchmarks only); not a scene feature.
    pub count_segments: bool,
    /// Walk the BVH (true) or test every primitive (false: for tests and scaling benchmarks).
    pub bvh: bool,
}

impl Features {
    /// Everything on: the generic tracer.
    pub fn generic() -> Features {
        Features {
            spheres: true,
            quads: true,
            boxes: true,
            triangles: true,
            dielectrics: true,
            emitters: true,
            nee: true,
            dof: true,
            sun: true,
            textures: true,
            cutouts: true,
            normal_maps: true,
            smooth_normals: true,
            env_map: true,
            mirror_nee: true,
            lens_nee: true,
            gloss_nee: true,
            pbr: true,
            pbr_specular: true,
            pbr_transmission: true,
            pbr_clearcoat: true,
            instances: true,
            lecture: true,
            count_segments: false,
            bvh: true,
        }
    }

    /// Nothing at all: the sky-only tracer.
    pub fn none() -> Features {
        Features {
            spheres: false,
            quads: false,
            boxes: false,
            triangles: false,
            dielectrics: false,
            emitters: false,
            nee: false,
            dof: false,
            sun: false,
            textures: false,
            cutouts: false,
            normal_maps: false,
            smooth_normals: false,
            env_map: false,
            mirror_nee: false,
            lens_nee: false,
            gloss_nee: false,
            pbr: false,
            pbr_specular: false,
            pbr_transmission: false,
            pbr_clearcoat: false,
            instances: false,
            lecture: false,
            count_segments: false,
            bvh: false,
        }
    }

    /// Features named in a comma-separated list (`quads,nee`), as [`Features::summary`]
    /// spells them; for benchmarks that add features one at a time.
    pub fn parse_list(list: &str) -> Result<Features, UnknownFeature> {
        let mut f = Features::none();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let flag = match name {
                "spheres" => &mut f.spheres,
                "quads" => &mut f.quads,
                "boxes" => &mut f.boxes,
                "triangles" => &mut f.triangles,
                "dielectrics" => &mut f.dielectrics,
                "emitters" => &mut f.emitters,
                "nee" => &mut f.nee,
                "dof" => &mut f.dof,
                "sun" => &mut f.sun,
                "textures" => &mut f.textures,
                "cutouts" => &mut f.cutouts,
                "normal_maps" => &mut f.normal_maps,
                "smooth_normals" => &mut f.smooth_normals,
                "env_map" => &mut f.env_map,
                "mirror_nee" => &mut f.mirror_nee,
                "lens_nee" => &mut f.lens_nee,
                "gloss_nee" => &mut f.gloss_nee,
                "pbr" => &mut f.pbr,
                "pbr_specular" => &mut f.pbr_specular,
                "pbr_transmission" => &mut f.pbr_transmission,
                "pbr_clearcoat" => &mut f.pbr_clearcoat,
                "instances" => &mut f.instances,
                "lecture" => &mut f.lecture,
                _ => return Err(UnknownFeature(name.to_string())),
            };
            *flag = true;
        }
        Ok(f)
    }

    /// Exactly what `scene` uses.
    pub fn of(scene: &Scene) -> Features {
        let mut f = Features {
            dof: scene.camera.aperture > 0.0,
            sun: matches!(&scene.sky, Sky::Gradient { sun: Some(s), .. } if s.intensity > 0.0),
            bvh: true,
            env_map: scene.environment.is_some(),
            nee: scene.environment.as_ref().is_some_and(|e| e.lights()),
            ..Features::none()
        };
        for o in &scene.objects {
            match &o.shape {
                Shape::Sphere { .. } => f.spheres = true,
                Shape::Quad { .. } => f.quads = true,
                Shape::Box { .. } => f.boxes = true,
                Shape::Mesh {
                    mesh, instances, ..
                } => {
                    f.triangles = true;
                    f.instances |= !instances.is_empty();
                    // Glass refracts about the geometric normal: only surfaces shade smooth.
                    f.smooth_normals |= !mesh.normals.is_empty() && !o.material.is_dielectric();
                }
            }
            f.dielectrics |= o.material.is_dielectric();
            // An emissive pbr material still needs the BRDF where its emissive map is dark.
            f.pbr |= o.material.is_pbr();
            let specular_maps = o.material.textured.as_ref().is_some_and(|t| {
                t.0.extensions.specular.is_some() || t.0.extensions.specular_color.is_some()
            });
            f.pbr_specular |= o.material.is_pbr()
                && (o.material.specular != 1.0
                    || specular_maps
                    || o.material
                        .specular_color
                        .is_some_and(|c| c != glam::Vec3::ONE));
            f.pbr_transmission |= o.material.is_pbr() && o.material.transmission > 0.0;
            f.pbr_clearcoat |= o.material.is_pbr() && o.material.clearcoat > 0.0;
            // (A textured emitter's dark texels are surfaces too.)
            f.lecture |= !o.material.is_pbr()
                && !o.material.is_dielectric()
                && (!o.material.is_emitter() || o.material.textured.is_some());
            f.emitters |= o.material.is_emitter();
            if let Some(t) = &o.material.textured
                && !o.material.is_dielectric()
                && matches!(o.shape, Shape::Mesh { .. })
            {
                f.textures = true;
                f.cutouts |= t.0.cuts_out();
                f.normal_maps |= t.0.normal.is_some();
            }
            f.nee |= o.material.is_emitter()
                && matches!(o.shape, Shape::Sphere { .. } | Shape::Quad { .. });
            f.gloss_nee |= o.material.is_glossy();
        }
        f.gloss_nee &= f.nee;
        f.lens_nee = !crate::common::arrays::lens_spheres(scene, true).is_empty();
        // A glass ball reflects the map too.
        f.mirror_nee = f.lens_nee || !crate::common::arrays::mirror_spheres(scene, true).is_empty();
        f
    }

    /// `self` with everything `other` has as well.
    pub fn union(self, other: Features) -> Features {
        Features {
            spheres: self.spheres | other.spheres,
            quads: self.quads | other.quads,
            boxes: self.boxes | other.boxes,
            triangles: self.triangles | other.triangles,
            dielectrics: self.dielectrics | other.dielectrics,
            emitters: self.emitters | other.emitters,
            nee: self.nee | other.nee,
            dof: self.dof | other.dof,
            sun: self.sun | other.sun,
            textures: self.textures | other.textures,
            cutouts: self.cutouts | other.cutouts,
            normal_maps: self.normal_maps | other.normal_maps,
            smooth_normals: self.smooth_normals | other.smooth_normals,
            env_map: self.env_map | other.env_map,
            mirror_nee: self.mirror_nee | other.mirror_nee,
            lens_nee: self.lens_nee | other.lens_nee,
            gloss_nee: self.gloss_nee | other.gloss_nee,
            pbr: self.pbr | other.pbr,
            pbr_specular: self.pbr_specular | other.pbr_specular,
            pbr_transmission: self.pbr_transmission | other.pbr_transmission,
            pbr_clearcoat: self.pbr_clearcoat | other.pbr_clearcoat,
            instances: self.instances | other.instances,
            lecture: self.lecture | other.lecture,
            count_segments: self.count_segments | other.count_segments,
            bvh: self.bvh | other.bvh,
        }
    }

    /// True if `self` has every feature `needed` has.
    pub fn covers(&self, needed: &Features) -> bool {
        self.union(*needed) == *self
    }

    /// The pipeline-overridable constants of `shaders/trace.wgsl`.
    pub fn constants(&self) -> Vec<(&'static str, f64)> {
        let b = |x: bool| if x { 1.0 } else { 0.0 };
        vec![
            ("HAS_SPHERES", b(self.spheres)),
            ("HAS_QUADS", b(self.quads)),
            ("HAS_BOXES", b(self.boxes)),
            ("HAS_TRIANGLES", b(self.triangles)),
            ("HAS_DIELECTRICS", b(self.dielectrics)),
            ("HAS_EMITTERS", b(self.emitters)),
            ("HAS_NEE", b(self.nee)),
            ("HAS_DOF", b(self.dof)),
            ("HAS_SUN", b(self.sun)),
            ("HAS_TEXTURES", b(self.textures)),
            ("HAS_CUTOUTS", b(self.cutouts)),
            ("HAS_NORMAL_MAPS", b(self.normal_maps)),
            ("HAS_SMOOTH_NORMALS", b(self.smooth_normals)),
            ("HAS_ENV_MAP", b(self.env_map)),
            ("HAS_MIRROR_NEE", b(self.mirror_nee)),
            ("HAS_LENS_NEE", b(self.lens_nee)),
            ("HAS_GLOSS_NEE", b(self.gloss_nee)),
            ("HAS_PBR", b(self.pbr)),
            ("HAS_PBR_SPECULAR", b(self.pbr_specular)),
            ("HAS_PBR_TRANSMISSION", b(self.pbr_transmission)),
            ("HAS_PBR_CLEARCOAT", b(self.pbr_clearcoat)),
            ("HAS_INSTANCES", b(self.instances)),
            ("HAS_LECTURE", b(self.lecture)),
            ("COUNT_SEGMENTS", b(self.count_segments)),
            ("USE_BVH", b(self.bvh)),
        ]
    }

    /// Short list for logs and benchmarks: `spheres+dielectrics+dof`.
    pub fn summary(&self) -> String {
        let names = [
            (self.spheres, "spheres"),
            (self.quads, "quads"),
            (self.boxes, "boxes"),
            (self.triangles, "triangles"),
            (self.dielectrics, "dielectrics"),
            (self.emitters, "emitters"),
            (self.nee, "nee"),
            (self.dof, "dof"),
            (self.sun, "sun"),
            (self.textures, "textures"),
            (self.cutouts, "cutouts"),
            (self.normal_maps, "normal_maps"),
            (self.smooth_normals, "smooth_normals"),
            (self.env_map, "env_map"),
            (self.mirror_nee, "mirror_nee"),
            (self.lens_nee, "lens_nee"),
            (self.gloss_nee, "gloss_nee"),
            (self.pbr, "pbr"),
            (self.pbr_specular, "pbr_specular"),
            (self.pbr_transmission, "pbr_transmission"),
            (self.pbr_clearcoat, "pbr_clearcoat"),
            (self.instances, "instances"),
        ];
        let on: Vec<&str> = names.iter().filter(|(b, _)| *b).map(|(_, n)| *n).collect();
        if on.is_empty() {
            "sky only".into()
        } else {
            on.join("+")
        }
    }
}
