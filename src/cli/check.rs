//! `termtrace check`: validates scene files and prints what each contains.

use crate::common::Features;
use crate::scene::{Scene, Sky};
use clap::Args;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scene files or built-in scene names.
    #[arg(required_unless_present = "stress")]
    pub scenes: Vec<String>,
    /// Run the extreme scenes and the double-precision comparisons instead; one row per case.
    #[arg(long)]
    pub stress: bool,
    /// Samples per pixel of each extreme render (with --stress).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
}

pub fn run(a: CheckArgs, g: &super::args::GlobalArgs) -> anyhow::Result<ExitCode> {
    if a.stress {
        return stress(&a, g);
    }
    let mut failed = 0;
    for name in &a.scenes {
        let loaded = crate::scene::load_scene(name, g.camera.as_deref(), g.sky.as_deref());
        match loaded {
            Ok(s) => println!("{}", summary(&s)),
            Err(e) => {
                failed += 1;
                // Most errors name the file themselves; a sky map's names the map.
                if matches!(e, crate::scene::SceneError::Sky(_)) {
                    eprintln!("error: {name}: {e}\n");
                } else {
                    eprintln!("error: {e}\n");
                }
            }
        }
    }
    if failed > 0 {
        eprintln!("{failed} of {} scenes are invalid", a.scenes.len());
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

fn v3(v: glam::DVec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

fn c3(v: glam::Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// A material's colour and every number the parameter table declares for it.
fn material_values(m: &crate::scene::Material) -> String {
    let mut parts = vec![
        format!("model {}", m.model.name()),
        format!("color {}", c3(m.color)),
    ];
    for (p, key) in
        crate::scene::params::material_keys().filter(|(p, _)| p.applies_to(Some(m.model)))
    {
        if let Some(v) = crate::scene::params::material_value(p, m) {
            parts.push(format!("{key} {v}"));
        }
    }
    parts.join(", ")
}

/// A few lines describing a valid scene.
pub fn summary(s: &Scene) -> String {
    let c = &s.camera;
    let r = &s.render;
    let n = s.counts();
    let mut kinds = [0usize; 5];
    for o in &s.objects {
        let m = &o.material;
        let k = if m.is_emitter() {
            3
        } else if m.is_pbr() {
            4
        } else if m.is_dielectric() {
            2
        } else if m.smoothness > 0.0 && m.specular > 0.0 {
            1
        } else {
            0
        };
        kinds[k] += 1;
    }
    let sky = match &s.sky {
        Sky::Uniform(u) => format!("uniform {}", c3(*u)),
        Sky::Gradient { bottom, top, sun } => format!(
            "gradient {} to {}, {}",
            c3(*bottom),
            c3(*top),
            match sun {
                Some(sun) if sun.intensity > 0.0 => format!(
                    "sun towards {} intensity {} size {}",
                    v3(sun.direction),
                    sun.intensity,
                    sun.size
                ),
                _ => "no sun".into(),
            }
        ),
    };
    let gltf: String = s
        .gltf
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let objects = s.objects.iter().filter(|o| o.gltf == Some(i)).count();
            let left_out: String = g
                .left_out
                .iter()
                .map(|l| format!("\n  left out   {}: {l}", g.file))
                .collect();
            format!(
                "\n  model      {}: {objects} objects, {} materials{left_out}",
                g.file,
                g.materials.len()
            )
        })
        .collect();
    let named: String = s
        .materials
        .iter()
        .map(|(name, m)| format!("\n  material   {name}: {}", material_values(m)))
        .collect();
    let env = s.environment.as_ref().map_or(String::new(), environment);
    let tex = crate::common::textures::words(s).map_or(String::new(), |w| {
        let frames = w[crate::common::textures::FRAMES] as usize;
        let mib = |words: usize| words as f64 * 4.0 / (1 << 20) as f64;
        format!(
            "\n  textures   {:.1} MiB of texture words (texels and coordinates{})",
            mib(w.len()),
            if frames > 0 {
                format!(
                    ", {:.1} MiB of them normal maps' shading frames",
                    mib(w.len() - frames)
                )
            } else {
                String::new()
            }
        )
    });
    let instanced = if n.instances > 0 {
        format!(
            "; {} instances draw {} triangles",
            n.instances, n.drawn_triangles
        )
    } else {
        String::new()
    };
    format!(
        "{}: ok\n  camera     from {} to {}, vfov {}°, aperture {}, focus distance {}\n  \
         render     {}x{}, {} spp, max_bounces {}, seed {}\n  sky        {}\n  \
         objects    {} ({} spheres, {} quads, {} boxes, {} meshes of {} triangles{instanced})\n  \
         materials  {} Lambertian, {} glossy/metal, {} dielectric, {} emitters, {} pbr; {} named{named}\n  \
         tracer     {}{env}{gltf}{tex}",
        s.origin,
        v3(c.look_from),
        v3(c.look_at),
        c.vfov,
        c.aperture,
        c.focus(),
        r.width,
        r.height,
        r.spp,
        r.max_bounces,
        r.seed,
        sky,
        s.objects.len(),
        n.spheres,
        n.quads,
        n.boxes,
        n.meshes,
        n.triangles,
        kinds[0],
        kinds[1],
        kinds[2],
        kinds[3],
        kinds[4],
        s.materials.len(),
        Features::of(s).summary(),
    )
}

/// Samples per pixel of the accumulation-drift row: a million frames.
const DRIFT_SPP: u32 = 1_000_000;

fn stress(a: &CheckArgs, g: &super::args::GlobalArgs) -> anyhow::Result<ExitCode> {
    use crate::common::FrameSettings;
    use crate::gpu::GpuContext;
    use crate::stability::{self, FURNACE_BOUNCES, FURNACE_SKY};
    use std::sync::Arc;
    let ctx = Arc::new(GpuContext::new(g.adapter.as_deref())?);
    println!("stress check on {}", ctx.adapter_name());
    println!(
        "{:<66} {:>8} {:>12} {:>12} {:>7}  result",
        "case", "invalid", "furnace err", "worst rel", "rays"
    );
    let mut failed = 0;
    let mut print = |row: &stability::StressRow| {
        println!(
            "{:<66} {:>8} {:>12} {:>12.2e} {:>7}  {}",
            row.case,
            row.invalid,
            row.furnace.map_or("–".into(), |e| format!("{e:.2e}")),
            row.probe.worst,
            row.probe.count,
            if row.pass() { "pass" } else { "FAIL" }
        );
        if !row.pass() {
            failed += 1;
        }
    };
    let (w, h) = (48, 27);
    // The worst deviation of `scene`'s white furnace from its sky.
    let furnace = |scene: &Scene| {
        let fs = FrameSettings::new(w, h, FURNACE_BOUNCES, 1);
        let white = stability::white_furnace(scene, FURNACE_SKY);
        let (_, img) = stability::render_counting(&ctx, &white, fs, a.spp);
        stability::furnace_error(&img, FURNACE_SKY)
    };
    for (name, text) in crate::scene::EXTREME_SCENES {
        let scene = Scene::from_toml(text, &format!("builtin:{name}"))?;
        let s = FrameSettings::new(w, h, scene.render.max_bounces, 1);
        let (invalid, _) = stability::render_counting(&ctx, &scene, s, a.spp);
        let furnace = stability::furnace_applies(name).then(|| furnace(&scene));
        let probe = stability::run_probes(&ctx, &[stability::scene_category(&scene, 7)]).remove(0);
        print(&stability::StressRow {
            case: name.to_string(),
            invalid,
            furnace,
            probe,
        });
    }
    for (name, scene) in stability::meshes::cases() {
        let s = FrameSettings::new(w, h, 12, 1);
        let (invalid, _) = stability::render_counting(&ctx, &scene, s, a.spp);
        print(&stability::StressRow {
            case: name,
            invalid,
            furnace: Some(furnace(&scene)),
            probe: stability::ProbeResult::none(),
        });
    }
    for probe in stability::run_probes(&ctx, &stability::categories(11)) {
        print(&stability::StressRow {
            case: probe.name.clone(),
            invalid: 0,
            furnace: None,
            probe,
        });
    }
    let drift = stability::accumulation_drift(&ctx, DRIFT_SPP);
    print(&stability::StressRow {
        case: format!("furnace sphere after {DRIFT_SPP} accumulated frames"),
        invalid: drift.invalid,
        furnace: Some(drift.error),
        probe: stability::ProbeResult::none(),
    });
    if failed > 0 {
        println!("{failed} cases failed");
        return Ok(ExitCode::FAILURE);
    }
    println!("every case passed");
    Ok(ExitCode::SUCCESS)
}

/// The environment map's line: its file and size, what the tracers hold, its brightest texel
/// and where it lies, and the share of the light in its brightest 0.1 % of texels (a sun).
fn environment(e: &crate::scene::Environment) -> String {
    use crate::common::envmap::{direction, luminance};
    let m = &e.map;
    let texels = m.texels();
    let sin = |y: usize| (std::f64::consts::PI * (y as f64 + 0.5) / m.height as f64).sin();
    let weights: Vec<f64> = texels
        .iter()
        .enumerate()
        .map(|(i, t)| luminance(*t) as f64 * sin(i / m.width as usize))
        .collect();
    let total: f64 = weights.iter().sum();
    let (brightest, _) = texels
        .iter()
        .enumerate()
        .max_by(|a, b| luminance(*a.1).total_cmp(&luminance(*b.1)))
        .expect("a map has texels");
    let mut sorted = weights.clone();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let top = sorted[..sorted.len().div_ceil(1000)].iter().sum::<f64>();
    let (x, y) = (brightest as u32 % m.width, brightest as u32 / m.width);
    let d = direction(
        (x as f32 + 0.5) / m.width as f32,
        (y as f32 + 0.5) / m.height as f32,
        e.rotation.to_radians(),
    );
    format!(
        "\n  env map    {} ({}×{}, {:.1} MiB as traced), intensity {}, rotation {}°, {}; \
         brightest texel {:.3e} at ({x}, {y}), towards [{:.2}, {:.2}, {:.2}]; the brightest \
         0.1 % of texels send {:.0} % of its light",
        e.file,
        m.width,
        m.height,
        m.bytes() as f64 / (1 << 20) as f64,
        e.intensity,
        e.rotation,
        if e.visible {
            "visible"
        } else {
            "not seen by the camera"
        },
        luminance(texels[brightest]),
        d.x,
        d.y,
        d.z,
        if total > 0.0 {
            100.0 * top / total
        } else {
            0.0
        }
    )
}
