//! [`Scene`] → TOML text in the grammar of MODEL.md, so that an edited scene can be saved and
//! loaded back to the same scene.

use super::color::to_hex_exact;
use super::params;
use super::*;
use glam::{DVec3, Vec3};
use std::fmt::Write;

fn num(x: f64) -> String {
    format!("{x}")
}

fn v3(v: DVec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

fn col(c: Vec3) -> String {
    to_hex_exact(c)
        .map(|h| format!("\"{h}\""))
        .unwrap_or_else(|| format!("[{}, {}, {}]", c.x, c.y, c.z))
}

/// The material keys of `m` that differ from what `base` already gives.
fn material_lines(out: &mut String, m: &Material, base: &Material) {
    let default_color = if m.is_dielectric() {
        DEFAULT_GLASS_COLOR
    } else {
        DEFAULT_COLOR
    };
    // A base without a name resolves its colour by the dielectric rule too.
    let base_color = if base == &Material::default() {
        default_color
    } else {
        base.color
    };
    if m.color != base_color {
        let _ = writeln!(out, "color = {}", col(m.color));
    }
    if m.model != base.model {
        let _ = writeln!(out, "model = {:?}", m.model.name());
    }
    for (p, key) in params::material_keys().filter(|(p, _)| p.applies_to(Some(m.model))) {
        let (v, b) = (
            params::material_value(p, m),
            params::material_value(p, base),
        );
        if let (Some(v), true) = (v, v != b) {
            let _ = writeln!(out, "{key} = {v}");
        }
    }
    if m.specular_color != base.specular_color
        && let Some(s) = m.specular_color
    {
        let _ = writeln!(out, "specular_color = {}", col(s));
    }
    let (v, b) = (&m.volume, &base.volume);
    if m.is_pbr() {
        if v.thin_walled != b.thin_walled {
            let _ = writeln!(out, "thin_walled = {}", v.thin_walled);
        }
        if v.attenuation_color != b.attenuation_color {
            let _ = writeln!(out, "attenuation_color = {}", col(v.attenuation_color));
        }
        if v.attenuation_distance != b.attenuation_distance && v.attenuation_distance.is_finite() {
            let _ = writeln!(out, "attenuation_distance = {}", v.attenuation_distance);
        }
    }
}

/// Writes `scene` as a scene file.
pub fn to_toml(scene: &Scene) -> String {
    let mut o = String::new();
    let c = &scene.camera;
    let _ = writeln!(o, "# termtrace scene (written from {})\n", scene.origin);
    let _ = writeln!(o, "[camera]");
    let _ = writeln!(o, "look_from = {}", v3(c.look_from));
    let _ = writeln!(o, "look_at = {}", v3(c.look_at));
    let _ = writeln!(o, "up = {}", v3(c.up));
    let _ = writeln!(o, "vfov = {}", num(c.vfov));
    let _ = writeln!(o, "aperture = {}", num(c.aperture));
    if let Some(f) = c.focus_distance {
        let _ = writeln!(o, "focus_distance = {}", num(f));
    }
    let r = &scene.render;
    let _ = writeln!(o, "\n[render]");
    let _ = writeln!(o, "width = {}\nheight = {}", r.width, r.height);
    let _ = writeln!(
        o,
        "spp = {}\nmax_bounces = {}\nseed = {}",
        r.spp, r.max_bounces, r.seed
    );
    let _ = writeln!(o, "\n[sky]");
    match &scene.sky {
        Sky::Uniform(u) => {
            let _ = writeln!(o, "uniform = {}", col(*u));
        }
        Sky::Gradient { bottom, top, sun } => {
            let _ = writeln!(o, "bottom = {}\ntop = {}", col(*bottom), col(*top));
            if let Some(s) = sun {
                let _ = writeln!(
                    o,
                    "sun = {{ direction = {}, color = {}, intensity = {}, size = {} }}",
                    v3(s.direction),
                    col(s.color),
                    s.intensity,
                    s.size
                );
            }
        }
    }
    if let Some(e) = &scene.environment {
        let _ = writeln!(o, "map = {}", toml::Value::String(e.file.clone()));
        let _ = writeln!(
            o,
            "intensity = {}\nrotation = {}\nvisible = {}",
            e.intensity, e.rotation, e.visible
        );
    }
    for (name, m) in &scene.materials {
        let _ = writeln!(o, "\n[materials.{name}]");
        material_lines(&mut o, m, &Material::default());
    }
    let named = |n: &Option<String>| -> Material {
        n.as_ref()
            .and_then(|n| scene.materials.iter().find(|(k, _)| k == n))
            .map(|(_, m)| m.clone())
            .unwrap_or_default()
    };
    for obj in scene.objects.iter().filter(|o| o.gltf.is_none()) {
        let _ = writeln!(o, "\n[[{}]]", obj.shape.kind());
        if let Some(n) = &obj.name {
            let _ = writeln!(o, "name = {n:?}");
        }
        match &obj.shape {
            Shape::Sphere { center, radius } => {
                let _ = writeln!(o, "center = {}\nradius = {}", v3(*center), num(*radius));
            }
            Shape::Quad { q, u, v } => {
                let _ = writeln!(o, "q = {}\nu = {}\nv = {}", v3(*q), v3(*u), v3(*v));
            }
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                let _ = writeln!(
                    o,
                    "center = {}\nhalf_extents = {}\nrotation = {}",
                    v3(*center),
                    v3(*half_extents),
                    v3(*rotation)
                );
            }
            Shape::Mesh {
                file,
                translate,
                rotation,
                scale,
                ..
            } => {
                let _ = writeln!(
                    o,
                    "file = {file:?}\ntranslate = {}\nrotation = {}\nscale = {}",
                    v3(*translate),
                    v3(*rotation),
                    v3(*scale)
                );
            }
        }
        if let Some(n) = &obj.material_name {
            let _ = writeln!(o, "material = {n:?}");
        }
        material_lines(&mut o, &obj.material, &named(&obj.material_name));
    }
    for (i, g) in scene.gltf.iter().enumerate() {
        let _ = writeln!(o, "\n[[gltf]]\nfile = {:?}", g.file);
        let _ = writeln!(
            o,
            "translate = {}\nrotation = {}\nscale = {}",
            v3(g.translate),
            v3(g.rotation),
            v3(g.scale)
        );
        if g.instancing != Default::default() {
            let _ = writeln!(o, "instancing = {:?}", g.instancing.name());
        }
        // A material whose objects differ from the file's is written as an override of the
        // keys that differ (the preview edits every object of a glTF material as one).
        for (key, imported) in &g.materials {
            let current = scene
                .objects
                .iter()
                .find(|ob| ob.gltf == Some(i) && ob.material_name.as_deref() == Some(key));
            if let Some(ob) = current
                && ob.material != *imported
            {
                let _ = writeln!(o, "\n[gltf.materials.{key:?}]");
                material_lines(&mut o, &ob.material, imported);
            }
        }
    }
    o
}
