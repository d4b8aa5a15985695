//! `termtrace check`: validates scene files and prints what each contains.

use crate::gpu::Features;
use crate::scene::{Scene, Sky};
use clap::Args;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scene files or built-in scene names.
    #[arg(required = true)]
    pub scenes: Vec<String>,
}

pub fn run(a: CheckArgs) -> anyhow::Result<ExitCode> {
    let mut failed = 0;
    for name in &a.scenes {
        match Scene::load(name) {
            Ok(s) => println!("{}", summary(&s)),
            Err(e) => {
                failed += 1;
                eprintln!("error: {name}: invalid scene\n{e}\n");
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

/// A few lines describing a valid scene.
pub fn summary(s: &Scene) -> String {
    let c = &s.camera;
    let r = &s.render;
    let n = s.counts();
    let mut kinds = [0usize; 4];
    for o in &s.objects {
        let m = &o.material;
        let k = if m.is_emitter() {
            3
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
    format!(
        "{}: ok\n  camera     from {} to {}, vfov {}°, aperture {}, focus distance {}\n  \
         render     {}x{}, {} spp, max_bounces {}, seed {}\n  sky        {}\n  \
         objects    {} ({} spheres, {} quads, {} boxes, {} meshes of {} triangles)\n  \
         materials  {} Lambertian, {} glossy/metal, {} dielectric, {} emitters; {} named\n  \
         tracer     {}",
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
        s.materials.len(),
        Features::of(s).summary(),
    )
}
