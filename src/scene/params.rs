//! One declaration per adjustable parameter — the lecture's material, the camera, the render
//! settings — with its name, range, steps, default, unit and doc. From this table come the
//! scene file's keys and range checks (`parse`), write-back (`write`), the preview's key
//! bindings, clamps, status line and `?` help (`ui`), `check`'s summary and the README's key
//! table (`tests/params.rs` fails when they differ). docs/PARAMETERS.md says how to add one.

use super::color::{linear_to_srgb, srgb_to_linear};
use super::model::{
    Camera, DEFAULT_COLOR, MAX_BOUNCES, Material, MaterialModel, RenderSettings, Scene,
};
use glam::DVec3;

/// The values a parameter may take: `[lo, hi]`, either end open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub lo: f64,
    pub hi: f64,
    pub lo_open: bool,
    pub hi_open: bool,
}

impl Range {
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Range {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
        }
    }

    /// `[lo, ∞)`.
    pub const fn at_least(lo: f64) -> Range {
        Range::closed(lo, f64::MAX)
    }

    /// `(lo, ∞)`.
    pub const fn above(lo: f64) -> Range {
        Range {
            lo_open: true,
            ..Range::at_least(lo)
        }
    }

    /// `(lo, hi)`.
    pub const fn open(lo: f64, hi: f64) -> Range {
        Range {
            lo,
            hi,
            lo_open: true,
            hi_open: true,
        }
    }

    pub fn contains(&self, x: f64) -> bool {
        let above = if self.lo_open {
            x > self.lo
        } else {
            x >= self.lo
        };
        let below = if self.hi_open {
            x < self.hi
        } else {
            x <= self.hi
        };
        above && below
    }

    /// The range as a scene file's error states it: `between -1 and 1`, `at least 0`,
    /// `greater than 0`, `strictly between 0 and 180`.
    pub fn describe(&self) -> String {
        let (lo, hi) = (self.lo, self.hi);
        match (self.lo_open, self.hi == f64::MAX, self.hi_open) {
            (false, true, _) => format!("at least {lo}"),
            (true, true, _) => format!("greater than {lo}"),
            (false, false, false) => format!("between {lo} and {hi}"),
            (true, false, true) => format!("strictly between {lo} and {hi}"),
            (true, false, false) => format!("greater than {lo} and at most {hi}"),
            (false, false, true) => format!("at least {lo} and less than {hi}"),
        }
    }

    /// `x` brought into the range; an open end is kept `margin` inside (the preview's keys
    /// stop a fine step short of it).
    pub fn clamp(&self, x: f64, margin: f64) -> f64 {
        let lo = if self.lo_open {
            self.lo + margin
        } else {
            self.lo
        };
        let hi = if self.hi_open {
            self.hi - margin
        } else {
            self.hi
        };
        x.max(lo).min(hi)
    }
}

/// How the preview's `+ - ] [` keys change a value by the fine or the coarse step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// `± fine` or `± coarse`, kept on the 0.001 grid.
    Add,
    /// Added to the sRGB-encoded value (the one shown), kept on the 0.001 grid.
    Srgb,
    /// `× fine` or `× coarse` up, `÷` down.
    Mul,
    /// A thin lens's aperture: `× fine` / `× coarse` from a non-zero value; from a pinhole
    /// the first step up opens it to [`LENS_OPEN_FINE`] (or [`LENS_OPEN_COARSE`]) of the focus
    /// distance, and a step down below [`LENS_CLOSE`] of it closes it to a pinhole.
    Lens,
    /// Whole numbers: `± 1` fine, `× 2` / `÷ 2` coarse.
    Count,
}

/// Fractions of the focus distance at which [`Step::Lens`] opens and closes the aperture.
pub const LENS_OPEN_FINE: f64 = 0.002;
pub const LENS_OPEN_COARSE: f64 = 0.02;
pub const LENS_CLOSE: f64 = 1e-4;

/// Where a parameter's value lives.
#[derive(Clone, Copy)]
pub enum Access {
    /// A number of the selected object's material (the lecture's model).
    Material {
        get: fn(&Material) -> f32,
        set: fn(&mut Material, f32),
    },
    /// One channel (0 red, 1 green, 2 blue) of the material's linear colour, shown and
    /// stepped sRGB-encoded.
    Channel(usize),
    /// A value of the scene as a whole (camera, render settings).
    Scene {
        get: fn(&Scene) -> f64,
        set: fn(&mut Scene, f64),
    },
}

/// The groups the preview's key help and status line show together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    Material,
    /// A pbr material's own numbers (its colour, light and ior are shared).
    Pbr,
    Colour,
    Camera,
}

impl Group {
    /// The key help's words around the group's names: `adjust the colour's red, green, blue
    /// (sRGB)`.
    pub fn help(self, names: &str) -> String {
        match self {
            Group::Colour => format!("adjust the colour's {names} (sRGB)"),
            // Short: five names fit an 80-column help.
            Group::Pbr => format!("adjust pbr {names}"),
            _ => format!("adjust {names}"),
        }
    }
}

/// One adjustable parameter, declared once.
pub struct ParamSpec {
    /// Its name in the preview and, for a material's, its key in a scene file.
    pub name: &'static str,
    /// Its short label in the status line.
    pub label: &'static str,
    /// How the key help names it (`focus distance`).
    pub help: &'static str,
    /// The scene file's table and key that set it, where one does (`[camera] vfov`).
    pub toml: Option<(&'static str, &'static str)>,
    pub range: Range,
    pub fine: f64,
    pub coarse: f64,
    pub step: Step,
    /// The value where a scene is silent (`None`: derived, as the focus distance is from
    /// `look_at`).
    pub default: Option<f64>,
    pub unit: &'static str,
    /// The key that makes it the one `+ - ] [` adjust (a key may serve one parameter of
    /// each material model).
    pub key: char,
    /// The material model it belongs to (`None`: every model's, or not a material's).
    pub model: Option<MaterialModel>,
    pub group: Group,
    /// One line of doc.
    pub doc: &'static str,
    pub access: Access,
}

/// Every parameter, in the preview's order (`m` goes to the next).
pub static PARAMS: [ParamSpec; 17] = [
    ParamSpec {
        name: "smoothness",
        label: "smooth",
        help: "smoothness",
        toml: Some(("material", "smoothness")),
        range: Range::closed(-1.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: '1',
        model: Some(MaterialModel::Lecture),
        group: Group::Material,
        doc: "0 Lambertian … 1 mirror; below 0 a dielectric (glass)",
        access: Access::Material {
            get: |m| m.smoothness,
            set: |m, v| m.smoothness = v,
        },
    },
    ParamSpec {
        name: "absorption",
        label: "absorb",
        help: "absorption",
        toml: Some(("material", "absorption")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: '2',
        model: Some(MaterialModel::Lecture),
        group: Group::Material,
        doc: "the lecture's fuzz: radius of the random vector added to reflected and refracted rays",
        access: Access::Material {
            get: |m| m.absorption,
            set: |m, v| m.absorption = v,
        },
    },
    ParamSpec {
        name: "specular",
        label: "spec",
        help: "specular",
        toml: Some(("material", "specular")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(1.0),
        unit: "",
        key: '3',
        model: None,
        group: Group::Material,
        doc: "the lecture's probability that a bounce takes the specular lobe; in the pbr \
              model KHR_materials_specular's specularFactor, the strength of the dielectric's \
              specular layer (its f0 colour: `specular_color`)",
        access: Access::Material {
            get: |m| m.specular,
            set: |m, v| m.specular = v,
        },
    },
    ParamSpec {
        name: "light",
        label: "light",
        help: "light",
        toml: Some(("material", "light")),
        range: Range::at_least(0.0),
        fine: 0.1,
        coarse: 1.0,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: '4',
        model: None,
        group: Group::Material,
        doc: "emission strength: the surface emits colour × light",
        access: Access::Material {
            get: |m| m.light,
            set: |m, v| m.light = v,
        },
    },
    ParamSpec {
        name: "ior",
        label: "ior",
        help: "ior",
        toml: Some(("material", "ior")),
        range: Range::above(0.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(1.5),
        unit: "",
        key: '5',
        model: None,
        group: Group::Material,
        doc: "index of refraction: the lecture's dielectric's (smoothness below 0); a pbr \
              material's Fresnel f0 and, where it transmits, its refraction",
        access: Access::Material {
            get: |m| m.ior,
            set: |m, v| m.ior = v,
        },
    },
    ParamSpec {
        name: "metallic",
        label: "metal",
        help: "metallic",
        toml: Some(("material", "metallic")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: '1',
        model: Some(MaterialModel::Pbr),
        group: Group::Pbr,
        doc: "glTF's metallic factor: 0 a dielectric (diffuse base under a Fresnel coat) … 1 a metal",
        access: Access::Material {
            get: |m| m.metallic,
            set: |m, v| m.metallic = v,
        },
    },
    ParamSpec {
        name: "roughness",
        label: "rough",
        help: "roughness",
        toml: Some(("material", "roughness")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.5),
        unit: "",
        key: '2',
        model: Some(MaterialModel::Pbr),
        group: Group::Pbr,
        doc: "glTF's perceptual roughness (GGX α = roughness²): 0 a mirror … 1 matte",
        access: Access::Material {
            get: |m| m.roughness,
            set: |m, v| m.roughness = v,
        },
    },
    ParamSpec {
        name: "transmission",
        label: "trans",
        help: "transmission",
        toml: Some(("material", "transmission")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: 't',
        model: Some(MaterialModel::Pbr),
        group: Group::Pbr,
        doc: "KHR_materials_transmission's factor: the share of the dielectric base that \
              passes through, tinted by the colour (a rough dielectric; `thin_walled`, \
              `attenuation_color` and `attenuation_distance` say what lies behind)",
        access: Access::Material {
            get: |m| m.transmission,
            set: |m, v| m.transmission = v,
        },
    },
    ParamSpec {
        name: "clearcoat",
        label: "coat",
        help: "coat",
        toml: Some(("material", "clearcoat")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: 'o',
        model: Some(MaterialModel::Pbr),
        group: Group::Pbr,
        doc: "KHR_materials_clearcoat's factor: the strength of a clear coat (ior 1.5) over \
              the material",
        access: Access::Material {
            get: |m| m.clearcoat,
            set: |m, v| m.clearcoat = v,
        },
    },
    ParamSpec {
        name: "clearcoat_roughness",
        label: "coat rough",
        help: "coat roughness",
        toml: Some(("material", "clearcoat_roughness")),
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Add,
        default: Some(0.0),
        unit: "",
        key: 'O',
        model: Some(MaterialModel::Pbr),
        group: Group::Pbr,
        doc: "KHR_materials_clearcoat's roughness (GGX α = roughness²): 0 a polished coat",
        access: Access::Material {
            get: |m| m.clearcoat_roughness,
            set: |m, v| m.clearcoat_roughness = v,
        },
    },
    channel("red", "r", '6', 0),
    channel("green", "g", '7', 1),
    channel("blue", "b", '8', 2),
    ParamSpec {
        name: "aperture",
        label: "aperture",
        help: "aperture",
        toml: Some(("camera", "aperture")),
        range: Range::at_least(0.0),
        fine: 1.1,
        coarse: 1.5,
        step: Step::Lens,
        default: Some(0.0),
        unit: "scene units",
        key: '9',
        model: None,
        group: Group::Camera,
        doc: "lens diameter; 0 is a pinhole",
        access: Access::Scene {
            get: |s| s.camera.aperture,
            set: |s, v| s.camera.aperture = v,
        },
    },
    ParamSpec {
        name: "focus",
        label: "focus",
        help: "focus distance",
        toml: Some(("camera", "focus_distance")),
        range: Range::above(0.0),
        fine: 1.02,
        coarse: 1.2,
        step: Step::Mul,
        default: None,
        unit: "scene units",
        key: '0',
        model: None,
        group: Group::Camera,
        doc: "distance to the plane in focus; by default the distance to look_at",
        access: Access::Scene {
            get: |s| s.camera.focus(),
            set: |s, v| s.camera.focus_distance = Some(v),
        },
    },
    ParamSpec {
        name: "bounces",
        label: "bounces",
        help: "max bounces",
        toml: Some(("render", "max_bounces")),
        range: Range::closed(0.0, MAX_BOUNCES as f64),
        fine: 1.0,
        coarse: 2.0,
        step: Step::Count,
        default: Some(10.0),
        unit: "",
        key: 'b',
        model: None,
        group: Group::Camera,
        doc: "the longest path, in bounces",
        access: Access::Scene {
            get: |s| s.render.max_bounces as f64,
            set: |s, v| s.render.max_bounces = v as u32,
        },
    },
    ParamSpec {
        name: "fov",
        label: "fov",
        help: "field of view",
        toml: Some(("camera", "vfov")),
        range: Range::open(0.0, 180.0),
        fine: 1.0,
        coarse: 10.0,
        step: Step::Add,
        default: Some(60.0),
        unit: "degrees",
        key: 'v',
        model: None,
        group: Group::Camera,
        doc: "vertical field of view",
        access: Access::Scene {
            get: |s| s.camera.vfov,
            set: |s, v| s.camera.vfov = v,
        },
    },
];

/// A channel of the material's colour.
const fn channel(name: &'static str, label: &'static str, key: char, i: usize) -> ParamSpec {
    ParamSpec {
        name,
        label,
        help: name,
        toml: None,
        range: Range::closed(0.0, 1.0),
        fine: 0.01,
        coarse: 0.1,
        step: Step::Srgb,
        default: None,
        unit: "sRGB",
        key,
        model: None,
        group: Group::Colour,
        doc: "a channel of the colour (albedo, emission colour or glass tint), sRGB-encoded",
        access: Access::Channel(i),
    }
}

/// A parameter: an index into [`PARAMS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Param(usize);

impl Param {
    /// Every parameter, in order.
    pub fn all() -> impl Iterator<Item = Param> {
        (0..PARAMS.len()).map(Param)
    }

    /// The parameter of that name; panics on an unknown one (a programming error).
    pub fn named(name: &str) -> Param {
        Param::all()
            .find(|p| p.spec().name == name)
            .unwrap_or_else(|| panic!("no parameter `{name}`"))
    }

    /// The parameter whose key is `c` (the lecture's model's where a key serves each model).
    pub fn by_key(c: char) -> Option<Param> {
        Param::all().find(|p| p.spec().key == c)
    }

    /// Whether it is a parameter of a material of `model` (or of the scene).
    pub fn applies_to(self, model: Option<MaterialModel>) -> bool {
        match (self.spec().model, model) {
            (None, _) => true,
            (Some(own), Some(m)) => own == m,
            (Some(_), None) => false,
        }
    }

    /// The parameter on the same key for a material of `model`: `1` is smoothness for the
    /// lecture's model and metallic for pbr.
    pub fn for_model(self, model: Option<MaterialModel>) -> Param {
        if self.applies_to(model) {
            return self;
        }
        Param::all()
            .find(|p| p.spec().key == self.spec().key && p.applies_to(model))
            .unwrap_or(self)
    }

    pub fn spec(self) -> &'static ParamSpec {
        &PARAMS[self.0]
    }

    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// A parameter of the selected object's material (the others belong to the scene).
    pub fn is_material(self) -> bool {
        !matches!(self.spec().access, Access::Scene { .. })
    }

    pub fn next(self) -> Param {
        Param((self.0 + 1) % PARAMS.len())
    }

    /// The value as the preview shows it (a colour channel sRGB-encoded); `None` for a
    /// material's parameter when no object is selected.
    pub fn value(self, scene: &Scene, selected: Option<&Material>) -> Option<f64> {
        if self.is_material() && !self.applies_to(selected.map(|m| m.model)) {
            return None;
        }
        Some(match self.spec().access {
            Access::Material { get, .. } => get(selected?) as f64,
            Access::Channel(i) => linear_to_srgb(selected?.color[i] as f64),
            Access::Scene { get, .. } => get(scene),
        })
    }

    /// One step of the preview's keys on a material: up or down, fine or coarse, clamped to
    /// the range. Returns whether the material changed.
    pub fn adjust_material(self, m: &mut Material, up: bool, coarse: bool) -> bool {
        let s = self.spec();
        if !self.applies_to(Some(m.model)) {
            return false;
        }
        let before = m.clone();
        let step = signed_step(s, up, coarse);
        match s.access {
            Access::Material { get, set } => {
                let v = snap(get(m) + step as f32) as f64;
                set(m, s.range.clamp(v, s.fine) as f32);
            }
            Access::Channel(i) => {
                let encoded = linear_to_srgb(m.color[i] as f64) as f32 + step as f32;
                let v = s.range.clamp(snap(encoded) as f64, s.fine);
                m.color[i] = srgb_to_linear(v) as f32;
            }
            Access::Scene { .. } => unreachable!("{} is no material parameter", s.name),
        }
        *m != before
    }

    /// One step of the preview's keys on a scene-wide parameter (camera, render settings).
    pub fn adjust_scene(self, scene: &mut Scene, up: bool, coarse: bool) {
        let s = self.spec();
        let Access::Scene { get, set } = s.access else {
            unreachable!("{} is a material parameter", s.name)
        };
        let v = get(scene);
        let k = if coarse { s.coarse } else { s.fine };
        let next = match s.step {
            Step::Add | Step::Srgb => v + signed_step(s, up, coarse),
            Step::Mul if up => v * k,
            Step::Mul => v / k,
            Step::Lens => {
                let focus = scene.camera.focus();
                let open = if coarse {
                    LENS_OPEN_COARSE
                } else {
                    LENS_OPEN_FINE
                };
                match (v <= 0.0, up) {
                    (true, true) => focus * open,
                    (true, false) => 0.0,
                    (false, true) => v * k,
                    (false, false) if v / k < focus * LENS_CLOSE => 0.0,
                    (false, false) => v / k,
                }
            }
            Step::Count => {
                let b = v as u32;
                (match (up, coarse) {
                    (true, false) => b.saturating_add(1),
                    (false, false) => b.saturating_sub(1),
                    (true, true) => b.saturating_mul(2).max(1),
                    (false, true) => b / 2,
                }) as f64
            }
        };
        set(scene, s.range.clamp(next, s.fine));
    }
}

fn signed_step(s: &ParamSpec, up: bool, coarse: bool) -> f64 {
    let d = if coarse { s.coarse } else { s.fine };
    if up { d } else { -d }
}

/// Rounds away float noise from repeated steps (0.1 + 0.01 + … stays on the 0.001 grid).
fn snap(x: f32) -> f32 {
    (x * 1000.0).round() / 1000.0
}

/// The material parameters a scene file sets by name (the colours are read as colours).
pub fn material_keys() -> impl Iterator<Item = (Param, &'static str)> {
    Param::all().filter_map(|p| match p.spec().toml {
        Some(("material", key)) => Some((p, key)),
        _ => None,
    })
}

/// The parameter a scene file sets with `key` in `[table]`.
pub fn for_toml(table: &str, key: &str) -> Param {
    Param::all()
        .find(|p| p.spec().toml == Some((table, key)))
        .unwrap_or_else(|| panic!("no parameter for [{table}] {key}"))
}

/// The declared default of a parameter that has one.
fn default_of(name: &str) -> f64 {
    Param::named(name)
        .spec()
        .default
        .unwrap_or_else(|| panic!("{name} has no declared default"))
}

/// A number of a material by its parameter.
pub fn material_value(p: Param, m: &Material) -> Option<f32> {
    match p.spec().access {
        Access::Material { get, .. } => Some(get(m)),
        _ => None,
    }
}

/// Sets a number of a material by its parameter.
pub fn set_material_value(p: Param, m: &mut Material, v: f32) {
    if let Access::Material { set, .. } = p.spec().access {
        set(m, v)
    }
}

// The defaults of MODEL.md's tables, from the declarations above.

impl Default for Material {
    fn default() -> Self {
        let mut m = Material {
            color: DEFAULT_COLOR,
            smoothness: 0.0,
            absorption: 0.0,
            specular: 0.0,
            light: 0.0,
            ior: 0.0,
            specular_color: None,
            model: MaterialModel::Lecture,
            metallic: 0.0,
            roughness: 0.0,
            transmission: 0.0,
            volume: super::model::Volume::default(),
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            textured: None,
        };
        for (p, _) in material_keys() {
            set_material_value(p, &mut m, default_of(p.name()) as f32);
        }
        m
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            look_from: DVec3::new(0.0, 0.0, 0.0),
            look_at: DVec3::new(0.0, 0.0, -1.0),
            up: DVec3::Y,
            vfov: default_of("fov"),
            aperture: default_of("aperture"),
            focus_distance: None,
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 360,
            spp: 256,
            max_bounces: default_of("bounces") as u32,
            seed: 1,
        }
    }
}

/// The key help's lines for the parameters: the keys of each group and what they adjust
/// (`1 2 3 4 5` → `adjust smoothness, absorption, specular, light, ior`).
pub fn help_lines() -> Vec<(String, String)> {
    let mut lines: Vec<(Group, Vec<char>, Vec<&str>)> = Vec::new();
    for p in Param::all() {
        let s = p.spec();
        match lines.last_mut() {
            Some((g, keys, names)) if *g == s.group => {
                keys.push(s.key);
                names.push(s.help);
            }
            _ => lines.push((s.group, vec![s.key], vec![s.help])),
        }
    }
    lines
        .into_iter()
        .map(|(g, keys, names)| {
            let keys: Vec<String> = keys.iter().map(char::to_string).collect();
            (keys.join(" "), g.help(&names.join(", ")))
        })
        .collect()
}

/// The parameters' reference as a Markdown table (docs/PARAMETERS.md holds it, checked by
/// `tests/params.rs`).
pub fn reference_table() -> String {
    let mut t = String::from(
        "| parameter | scene file | range | default | steps (fine / coarse) | key | what it is |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for p in Param::all() {
        let s = p.spec();
        let file = match s.toml {
            None => "`color` (a channel)".to_string(),
            Some(("material", key)) => format!("`{key}` (a material's key)"),
            Some((table, key)) => format!("`[{table}] {key}`"),
        };
        let default = s.default.map_or("–".to_string(), |d| d.to_string());
        let unit = if s.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", s.unit)
        };
        let steps = match s.step {
            Step::Add | Step::Srgb => format!("± {} / ± {}", s.fine, s.coarse),
            Step::Mul => format!("× {} / × {}", s.fine, s.coarse),
            Step::Lens => format!(
                "× {} / × {}; from 0 to {} / {} of the focus distance",
                s.fine, s.coarse, LENS_OPEN_FINE, LENS_OPEN_COARSE
            ),
            Step::Count => "± 1 / × 2".to_string(),
        };
        let key = match s.model {
            Some(m) => format!("`{}` ({})", s.key, m.name()),
            None => format!("`{}`", s.key),
        };
        t += &format!(
            "| {} | {file} | {}{unit} | {default} | {steps} | {key} | {} |\n",
            s.name,
            s.range.describe(),
            s.doc
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_keys_are_unique() {
        for a in Param::all() {
            for b in Param::all().filter(|b| *b != a) {
                assert_ne!(a.spec().name, b.spec().name);
                // One key, one parameter for each material model.
                let overlap = match (a.spec().model, b.spec().model) {
                    (Some(x), Some(y)) => x == y,
                    _ => true,
                };
                assert!(!overlap || a.spec().key != b.spec().key, "{}", a.name());
                assert!(a.spec().toml.is_none() || a.spec().toml != b.spec().toml);
            }
        }
    }

    #[test]
    fn defaults_lie_in_their_ranges() {
        for p in Param::all() {
            if let Some(d) = p.spec().default {
                assert!(p.spec().range.contains(d), "{}", p.name());
            }
        }
        assert_eq!(Material::default().ior, 1.5);
        assert_eq!(Material::default().specular, 1.0);
        assert_eq!(Camera::default().vfov, 60.0);
        assert_eq!(RenderSettings::default().max_bounces, 10);
    }

    #[test]
    fn ranges_describe_and_clamp() {
        assert_eq!(Range::closed(-1.0, 1.0).describe(), "between -1 and 1");
        assert_eq!(Range::at_least(0.0).describe(), "at least 0");
        assert_eq!(Range::above(0.0).describe(), "greater than 0");
        assert_eq!(
            Range::open(0.0, 180.0).describe(),
            "strictly between 0 and 180"
        );
        assert!(!Range::above(0.0).contains(0.0));
        assert!(Range::at_least(0.0).contains(0.0));
        assert_eq!(Range::above(0.0).clamp(-3.0, 0.01), 0.01);
        assert_eq!(Range::open(0.0, 180.0).clamp(200.0, 1.0), 179.0);
    }

    #[test]
    fn ior_steps_stop_a_fine_step_above_zero_and_have_no_upper_clamp() {
        let ior = Param::named("ior");
        let mut m = Material {
            ior: 0.05,
            ..Material::default()
        };
        for _ in 0..10 {
            ior.adjust_material(&mut m, false, true);
        }
        assert_eq!(m.ior, 0.01);
        m.ior = 9.95;
        ior.adjust_material(&mut m, true, true);
        assert_eq!(m.ior, 10.05, "the range is ior > 0, as MODEL.md says");
    }
}
