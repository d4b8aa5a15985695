//! The scene file grammar of MODEL.md ("A scene file, spelled out"): TOML → [`Scene`].

use super::error::Malformed;
use super::error::SceneError;
use super::gltf::Instancing;
use super::model::*;
use super::params::{self, Param};
use super::reader::{Sink, Table};
use glam::{DMat4, DVec3, Vec3};
use std::path::Path;
use toml::de::DeTable;

const TOP_KEYS: &[&str] = &[
    "camera",
    "render",
    "sky",
    "materials",
    "sphere",
    "quad",
    "box",
    "mesh",
    "gltf",
];
const CAMERA_KEYS: &[&str] = &[
    "look_from",
    "look_at",
    "up",
    "vfov",
    "aperture",
    "focus_distance",
];
const RENDER_KEYS: &[&str] = &["width", "height", "spp", "max_bounces", "seed"];
const SKY_KEYS: &[&str] = &[
    "bottom",
    "top",
    "uniform",
    "sun",
    "map",
    "intensity",
    "rotation",
    "visible",
];
const SUN_KEYS: &[&str] = &["direction", "color", "intensity", "size"];
const SPHERE_KEYS: &[&str] = &["center", "radius"];
const QUAD_KEYS: &[&str] = &["q", "u", "v"];
const BOX_KEYS: &[&str] = &["center", "half_extents", "rotation"];
const MESH_KEYS: &[&str] = &["file", "translate", "rotation", "scale"];
const GLTF_KEYS: &[&str] = &[
    "file",
    "translate",
    "rotation",
    "scale",
    "camera",
    "instancing",
    "materials",
];
/// The keys of a material: its colours and the numbers the parameter table declares.
fn material_keys() -> Vec<&'static str> {
    let mut keys = vec!["model", "color"];
    keys.extend(params::material_keys().map(|(_, k)| k));
    keys.extend([
        "specular_color",
        "thin_walled",
        "attenuation_color",
        "attenuation_distance",
    ]);
    keys
}

/// Keys every object table takes besides its shape and material keys.
const OBJECT_KEYS: &[&str] = &["name", "material"];

/// Parses and validates a scene; every problem found is reported, not just the first.
pub(super) fn parse(src: &str, origin: &str) -> Result<Scene, SceneError> {
    let sink = Sink::new(origin, src);
    let doc = match DeTable::parse(src) {
        Ok(d) => d,
        Err(e) => {
            let span = e.span().unwrap_or(0..0);
            sink.error(
                span,
                String::new(),
                format!("TOML syntax error: {}", e.message().trim()),
                None,
            );
            return Err(SceneError::Invalid(sink.into_diagnostics()));
        }
    };
    let root = Table::new(&sink, doc.get_ref(), 0..0, "scene".to_string(), TOP_KEYS);
    let scene = read_scene(&root, origin);
    let diags = sink.into_diagnostics();
    if diags.is_empty() {
        Ok(scene)
    } else {
        Err(SceneError::Invalid(diags))
    }
}

fn read_scene(root: &Table, origin: &str) -> Scene {
    let camera = root
        .table("camera", "[camera]".into(), CAMERA_KEYS)
        .map(|t| read_camera(&t))
        .unwrap_or_default();
    let render = root
        .table("render", "[render]".into(), RENDER_KEYS)
        .map(|t| read_render(&t))
        .unwrap_or_default();
    let sky_table = root.table("sky", "[sky]".into(), SKY_KEYS);
    let sky = sky_table.as_ref().map(read_sky).unwrap_or_default();
    let environment = sky_table.as_ref().and_then(|t| read_environment(t, origin));

    let materials: Vec<(String, MaterialPatch)> = root
        .named_tables("materials", &material_keys())
        .into_iter()
        .map(|(name, t)| {
            let patch = MaterialPatch::read(&t);
            patch.check_model(&t, patch.model.unwrap_or_default());
            (name, patch)
        })
        .collect();

    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        [extra, &material_keys(), OBJECT_KEYS].concat()
    };
    let mut objects = Vec::new();
    for t in root.array_of_tables("sphere", &with(SPHERE_KEYS)) {
        objects.push(read_object(&t, &materials, read_sphere(&t)));
    }
    for t in root.array_of_tables("quad", &with(QUAD_KEYS)) {
        objects.push(read_object(&t, &materials, read_quad(&t)));
    }
    for t in root.array_of_tables("box", &with(BOX_KEYS)) {
        objects.push(read_object(&t, &materials, read_box(&t)));
    }
    for t in root.array_of_tables("mesh", &with(MESH_KEYS)) {
        objects.push(read_object(&t, &materials, read_mesh(&t, origin)));
    }
    let mut objects: Vec<Object> = objects.into_iter().flatten().collect();
    let mut gltf = Vec::new();
    let mut camera = camera;
    for t in root.array_of_tables("gltf", GLTF_KEYS) {
        let Some((placement, imported, cam)) = read_gltf(&t, origin, gltf.len()) else {
            continue;
        };
        if let Some(cam) = cam {
            if root.has("camera") {
                t.error(
                    "camera",
                    "the scene has a [camera] too",
                    Some("keep one: the [camera] table, or this glTF camera".into()),
                );
            } else {
                camera = cam;
            }
        }
        objects.extend(imported);
        gltf.push(placement);
    }

    Scene {
        origin: origin.to_string(),
        camera,
        render,
        sky,
        environment,
        gltf,
        materials: materials
            .into_iter()
            .map(|(n, p)| (n, p.resolve()))
            .collect(),
        objects,
    }
}

fn read_camera(t: &Table) -> Camera {
    let d = Camera::default();
    let cam = Camera {
        look_from: t.vec3("look_from").unwrap_or(d.look_from),
        look_at: t.vec3("look_at").unwrap_or(d.look_at),
        up: t.vec3("up").unwrap_or(d.up),
        vfov: t.param("camera", "vfov").unwrap_or(d.vfov),
        aperture: t.param("camera", "aperture").unwrap_or(d.aperture),
        focus_distance: t.param("camera", "focus_distance"),
    };
    let view = cam.look_at - cam.look_from;
    if view.length() == 0.0 {
        t.error(
            "look_at",
            "`look_at` is the same point as `look_from`",
            Some("the camera needs a direction to look in".into()),
        );
    } else if cam.up.cross(view).length() <= 1e-9 * cam.up.length() * view.length() {
        t.error(
            "up",
            "`up` is zero or parallel to the viewing direction",
            Some("choose an `up` that is not along look_at - look_from, e.g. [0, 1, 0]".into()),
        );
    }
    cam
}

fn read_render(t: &Table) -> RenderSettings {
    let d = RenderSettings::default();
    RenderSettings {
        width: t.u32_in("width", 1, MAX_IMAGE_SIDE).unwrap_or(d.width),
        height: t.u32_in("height", 1, MAX_IMAGE_SIDE).unwrap_or(d.height),
        spp: t.u32_in("spp", 1, u32::MAX).unwrap_or(d.spp),
        max_bounces: t
            .param("render", "max_bounces")
            .map_or(d.max_bounces, |b| b as u32),
        seed: t.u32_in("seed", 0, u32::MAX).unwrap_or(d.seed),
    }
}

fn read_sky(t: &Table) -> Sky {
    if let Some(u) = t.color("uniform") {
        for k in ["bottom", "top", "sun"] {
            if t.has(k) {
                t.error(
                    k,
                    format!("`{k}` cannot be combined with `uniform`"),
                    Some("a uniform sky is one constant radiance; remove one of them".into()),
                );
            }
        }
        return Sky::Uniform(u);
    }
    let Sky::Gradient {
        bottom: db,
        top: dt,
        ..
    } = Sky::default()
    else {
        unreachable!("the default sky is a gradient")
    };
    let sun = t
        .table("sun", "[sky] sun".into(), SUN_KEYS)
        .and_then(|s| read_sun(&s));
    Sky::Gradient {
        bottom: t.color("bottom").unwrap_or(db),
        top: t.color("top").unwrap_or(dt),
        sun,
    }
}

/// `[sky] map = "file.hdr"` with its `intensity`, `rotation` and `visible`; the map is read
/// (relative to the scene file) and its distribution built here, so that a broken map is an
/// error at its line.
fn read_environment(t: &Table, origin: &str) -> Option<Environment> {
    let intensity = t.f64_in("intensity", 0.0, 1e30);
    let rotation = t.f64("rotation");
    let visible = t.boolean("visible");
    let Some(file) = t.string("map") else {
        for k in ["intensity", "rotation", "visible"] {
            if t.has(k) {
                t.error(
                    k,
                    format!("`{k}` belongs to an environment map, and [sky] has no `map`"),
                    Some("add `map = \"sky.hdr\"` (a Radiance .hdr or OpenEXR file)".into()),
                );
            }
        }
        return None;
    };
    let loaded = if origin.starts_with("builtin:") {
        Environment::builtin(&file)
    } else {
        let path = Path::new(origin)
            .parent()
            .unwrap_or(Path::new("."))
            .join(&file);
        Environment::load(&file, &path)
    };
    match loaded {
        Ok(mut env) => {
            env.intensity = intensity.unwrap_or(1.0) as f32;
            env.rotation = rotation.unwrap_or(0.0) as f32;
            env.visible = visible.unwrap_or(true);
            Some(env)
        }
        Err(e) => {
            t.error("map", e.to_string(), None);
            None
        }
    }
}

fn read_sun(t: &Table) -> Option<Sun> {
    let direction = t.vec3("direction").unwrap_or(DVec3::new(-0.4, 0.7, -0.6));
    if direction.length() == 0.0 {
        t.error("direction", "the sun direction is zero", None);
        return None;
    }
    Some(Sun {
        direction,
        color: t.color("color").unwrap_or(Vec3::ONE),
        intensity: t.f64_in("intensity", 0.0, f64::MAX).unwrap_or(0.0) as f32,
        size: t.f64_in("size", 0.0, f64::MAX).unwrap_or(100.0) as f32,
    })
}

/// Material keys as given in one table; `None` where the table is silent.
#[derive(Clone, Default)]
struct MaterialPatch {
    model: Option<MaterialModel>,
    color: Option<Vec3>,
    /// The numbers of the parameter table, by parameter.
    numbers: Vec<(Param, f32)>,
    specular_color: Option<Vec3>,
    volume: VolumePatch,
}

/// KHR_materials_volume's keys as given in one table (`Volume`'s fields).
#[derive(Clone, Copy, Default)]
struct VolumePatch {
    thin_walled: Option<bool>,
    attenuation_color: Option<Vec3>,
    attenuation_distance: Option<f32>,
}

impl VolumePatch {
    fn read(t: &Table) -> VolumePatch {
        VolumePatch {
            thin_walled: t.boolean("thin_walled"),
            attenuation_color: t.color("attenuation_color"),
            attenuation_distance: t.f64_above("attenuation_distance", 0.0).map(|d| d as f32),
        }
    }

    fn over(&self, base: &VolumePatch) -> VolumePatch {
        VolumePatch {
            thin_walled: self.thin_walled.or(base.thin_walled),
            attenuation_color: self.attenuation_color.or(base.attenuation_color),
            attenuation_distance: self.attenuation_distance.or(base.attenuation_distance),
        }
    }

    fn of(v: &Volume) -> VolumePatch {
        VolumePatch {
            thin_walled: Some(v.thin_walled),
            attenuation_color: Some(v.attenuation_color),
            attenuation_distance: Some(v.attenuation_distance),
        }
    }

    fn resolve(&self) -> Volume {
        let d = Volume::default();
        Volume {
            thin_walled: self.thin_walled.unwrap_or(d.thin_walled),
            attenuation_color: self.attenuation_color.unwrap_or(d.attenuation_color),
            attenuation_distance: self.attenuation_distance.unwrap_or(d.attenuation_distance),
        }
    }
}

impl MaterialPatch {
    fn read(t: &Table) -> MaterialPatch {
        let model = t.string("model").and_then(|name| {
            let model = MaterialModel::named(&name);
            if model.is_none() {
                t.error(
                    "model",
                    format!("unknown material model `{name}`"),
                    Some("`lecture` (MODEL.md's, the default) or `pbr` (glTF's)".into()),
                );
            }
            model
        });
        MaterialPatch {
            model,
            color: t.color("color"),
            numbers: params::material_keys()
                .filter_map(|(p, key)| Some((p, t.param("material", key)? as f32)))
                .collect(),
            specular_color: t.color("specular_color"),
            volume: VolumePatch::read(t),
        }
    }

    /// Reports each number given in `t` that belongs to another model than `model`.
    fn check_model(&self, t: &Table, model: MaterialModel) {
        for (p, key) in params::material_keys() {
            if self.number(p).is_some() && !p.applies_to(Some(model)) {
                t.error(
                    key,
                    format!(
                        "`{key}` belongs to another material model than `{}`",
                        model.name()
                    ),
                    Some(format!(
                        "a `{}` material takes {}",
                        model.name(),
                        params::material_keys()
                            .filter(|(q, _)| q.applies_to(Some(model)))
                            .map(|(_, k)| format!("`{k}`"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )),
                );
            }
        }
        if model != MaterialModel::Pbr {
            let v = &self.volume;
            for (key, given) in [
                ("thin_walled", v.thin_walled.is_some()),
                ("attenuation_color", v.attenuation_color.is_some()),
                ("attenuation_distance", v.attenuation_distance.is_some()),
            ] {
                if given {
                    t.error(
                        key,
                        format!("`{key}` belongs to the `pbr` model (with `transmission`)"),
                        Some("add `model = \"pbr\"`".into()),
                    );
                }
            }
        }
    }

    fn number(&self, p: Param) -> Option<f32> {
        self.numbers.iter().find(|(q, _)| *q == p).map(|(_, v)| *v)
    }

    /// `self` over `base`: keys given here win.
    fn over(&self, base: &MaterialPatch) -> MaterialPatch {
        MaterialPatch {
            model: self.model.or(base.model),
            color: self.color.or(base.color),
            numbers: params::material_keys()
                .filter_map(|(p, _)| Some((p, self.number(p).or(base.number(p))?)))
                .collect(),
            specular_color: self.specular_color.or(base.specular_color),
            volume: self.volume.over(&base.volume),
        }
    }

    /// Every key of a complete material.
    fn of(m: &Material) -> MaterialPatch {
        MaterialPatch {
            model: Some(m.model),
            color: Some(m.color),
            numbers: params::material_keys()
                .filter_map(|(p, _)| Some((p, params::material_value(p, m)?)))
                .collect(),
            specular_color: m.specular_color,
            volume: VolumePatch::of(&m.volume),
        }
    }

    /// Fills the defaults of MODEL.md; a dielectric's default colour is white.
    fn resolve(&self) -> Material {
        let mut m = Material {
            model: self.model.unwrap_or_default(),
            ..Material::default()
        };
        for (p, v) in &self.numbers {
            params::set_material_value(*p, &mut m, *v);
        }
        m.color = self.color.unwrap_or(if m.is_dielectric() {
            DEFAULT_GLASS_COLOR
        } else {
            DEFAULT_COLOR
        });
        m.specular_color = self.specular_color;
        m.volume = self.volume.resolve();
        m
    }
}

fn read_object(
    t: &Table,
    named: &[(String, MaterialPatch)],
    shape: Option<Shape>,
) -> Option<Object> {
    let inline = MaterialPatch::read(t);
    let material_name = t.string("material");
    let base = match &material_name {
        None => MaterialPatch::default(),
        Some(n) => match named.iter().find(|(k, _)| k == n) {
            Some((_, p)) => p.clone(),
            None => {
                let names: Vec<&str> = named.iter().map(|(k, _)| k.as_str()).collect();
                let help = match super::reader::suggest(n, &names) {
                    Some(s) => format!("did you mean `{s}`?"),
                    None if names.is_empty() => "define it in a [materials.NAME] table".to_string(),
                    None => format!("defined materials: {}", names.join(", ")),
                };
                t.error("material", format!("no material named `{n}`"), Some(help));
                MaterialPatch::default()
            }
        },
    };
    let merged = inline.over(&base);
    inline.check_model(t, merged.model.unwrap_or_default());
    Some(Object {
        name: t.string("name"),
        shape: shape?,
        material: merged.resolve(),
        material_name,
        gltf: None,
    })
}

/// A required key: reports its absence.
fn required<T>(t: &Table, key: &str, v: Option<T>) -> Option<T> {
    if v.is_none() && !t.has(key) {
        t.error_table(format!("missing key `{key}`"), None);
    }
    v
}

fn read_sphere(t: &Table) -> Option<Shape> {
    let center = required(t, "center", t.vec3("center"));
    let radius = required(t, "radius", t.f64("radius"));
    if radius == Some(0.0) {
        t.error(
            "radius",
            "a sphere of radius 0 has no surface",
            Some("use a positive radius, or a negative one for an inward normal".into()),
        );
        return None;
    }
    Some(Shape::Sphere {
        center: center?,
        radius: radius?,
    })
}

fn read_quad(t: &Table) -> Option<Shape> {
    let q = required(t, "q", t.vec3("q"));
    let u = required(t, "u", t.vec3("u"));
    let v = required(t, "v", t.vec3("v"));
    let (q, u, v) = (q?, u?, v?);
    let area = u.cross(v).length();
    if area <= 1e-12 * u.length_squared().max(v.length_squared()) || area == 0.0 {
        t.error(
            "v",
            "the quad has zero area: `u` and `v` are zero or parallel",
            Some("`u` and `v` are the two edges from corner `q`; they must span a plane".into()),
        );
        return None;
    }
    Some(Shape::Quad { q, u, v })
}

fn read_box(t: &Table) -> Option<Shape> {
    let center = required(t, "center", t.vec3("center"));
    let half = required(t, "half_extents", t.vec3("half_extents"));
    let rotation = t.vec3("rotation").unwrap_or(DVec3::ZERO);
    if let Some(h) = half
        && h.min_element() <= 0.0
    {
        t.error(
            "half_extents",
            "every half extent of a box must be greater than 0",
            None,
        );
        return None;
    }
    Some(Shape::Box {
        center: center?,
        half_extents: half?,
        rotation,
    })
}

/// The text of a mesh file: beside the scene file, or among the built-in files for a
/// built-in scene.
fn mesh_source(file: &str, origin: &str) -> Result<String, Malformed> {
    if origin.starts_with("builtin:") {
        return super::BUILTIN_FILES
            .iter()
            .find(|(n, _)| *n == file)
            .map(|(_, s)| s.to_string())
            .ok_or_else(|| Malformed(format!("no built-in file `{file}`")));
    }
    let base = std::path::Path::new(origin)
        .parent()
        .unwrap_or(std::path::Path::new("."));
    let path = base.join(file);
    std::fs::read_to_string(&path)
        .map_err(|e| Malformed(format!("cannot read {}: {e}", path.display())))
}

fn read_mesh(t: &Table, origin: &str) -> Option<Shape> {
    let file = required(t, "file", t.string("file"))?;
    let translate = t.vec3("translate").unwrap_or(DVec3::ZERO);
    let rotation = t.vec3("rotation").unwrap_or(DVec3::ZERO);
    let scale = t.scale("scale").unwrap_or(DVec3::ONE);
    if scale.abs().min_element() == 0.0 {
        t.error("scale", "a mesh scale of 0 flattens it", None);
        return None;
    }
    let mesh = mesh_source(&file, origin).and_then(|text| super::mesh::parse_obj(&text));
    match mesh {
        Ok(mesh) => Some(Shape::Mesh {
            file,
            mesh: std::sync::Arc::new(mesh),
            translate,
            rotation,
            scale,
            instances: Default::default(),
        }),
        Err(e) => {
            t.error("file", format!("mesh `{file}`: {e}"), None);
            None
        }
    }
}

/// A `[[gltf]]` table: the file's objects placed by the table's transform, its materials with
/// the table's `[gltf.materials.KEY]` overrides, and its camera when `camera` names one.
fn read_gltf(
    t: &Table,
    origin: &str,
    index: usize,
) -> Option<(GltfPlacement, Vec<Object>, Option<Camera>)> {
    let file = required(t, "file", t.string("file"))?;
    let translate = t.vec3("translate").unwrap_or(DVec3::ZERO);
    let rotation = t.vec3("rotation").unwrap_or(DVec3::ZERO);
    let scale = t.scale("scale").unwrap_or(DVec3::ONE);
    if scale.abs().min_element() == 0.0 {
        t.error("scale", "a glTF scale of 0 flattens it", None);
        return None;
    }
    if origin.starts_with("builtin:") {
        t.error("file", "a built-in scene cannot place glTF files", None);
        return None;
    }
    let camera_name = t.string("camera");
    let instancing = match t.string("instancing") {
        None => Instancing::default(),
        Some(name) => match Instancing::named(&name) {
            Some(i) => i,
            None => {
                t.error(
                    "instancing",
                    format!("unknown instancing `{name}`"),
                    Some(format!("expected one of {}", Instancing::NAMES.join(", "))),
                );
                return None;
            }
        },
    };
    let path = std::path::Path::new(origin)
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(&file);
    let place = placement_matrix(translate, rotation, scale);
    let imported =
        match super::files::import_model(&path, place, camera_name.as_deref(), instancing) {
            Ok(i) => i,
            Err(e) => {
                let kind = if super::files::is_obj(&path) {
                    "OBJ"
                } else {
                    "glTF"
                };
                t.error("file", format!("{kind} `{file}`: {}", e.message), None);
                return None;
            }
        };
    imported.log_left_out(&path.display().to_string());
    let overrides = t.named_tables("materials", &material_keys());
    let keys: Vec<&str> = imported.materials.iter().map(|(k, _)| k.as_str()).collect();
    // Each override read once, so that a bad value is reported once (not once per object).
    let patches: Vec<(&str, MaterialPatch)> = overrides
        .iter()
        .map(|(name, o)| (name.as_str(), MaterialPatch::read(o)))
        .collect();
    for ((name, o), (_, patch)) in overrides.iter().zip(&patches) {
        // An override speaks its material's model (a glTF material's is pbr).
        if let Some((_, m)) = imported.materials.iter().find(|(k, _)| k == name) {
            patch.check_model(o, patch.model.unwrap_or(m.model));
        }
        if !keys.contains(&name.as_str()) {
            let help = match super::reader::suggest(name, &keys) {
                Some(s) => format!("did you mean `{s}`?"),
                None => format!("its materials: {}", keys.join(", ")),
            };
            o.error_table(format!("`{file}` has no material `{name}`"), Some(help));
        }
    }
    let apply = |key: &str, m: &Material| -> Material {
        match patches.iter().find(|(n, _)| *n == key) {
            Some((_, patch)) => Material {
                textured: m.textured.clone(),
                ..patch.over(&MaterialPatch::of(m)).resolve()
            },
            None => m.clone(),
        }
    };
    let objects = imported
        .objects
        .into_iter()
        .map(|mut o| {
            if let Some(key) = &o.material_name {
                o.material = apply(key, &o.material);
            }
            o.gltf = Some(index);
            o
        })
        .collect();
    let camera = if camera_name.is_some() {
        imported.camera
    } else {
        None
    };
    Some((
        GltfPlacement {
            file,
            translate,
            rotation,
            scale,
            instancing,
            materials: imported.materials,
            left_out: imported.skipped,
        },
        objects,
        camera,
    ))
}

/// A placement's transform: scale, then rotation (Euler XYZ, degrees), then translation.
pub(super) fn placement_matrix(translate: DVec3, rotation: DVec3, scale: DVec3) -> DMat4 {
    DMat4::from_translation(translate)
        * DMat4::from_mat3(euler_xyz(rotation))
        * DMat4::from_scale(scale)
}
