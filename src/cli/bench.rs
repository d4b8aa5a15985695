//! `termtrace bench`: samples/s and path segments/s of one scene on the chosen adapter, or
//! with `--preview` the live preview's key → frame latency and frame rate in a
//! pseudo-terminal (`measure::preview`).

use super::args::GlobalArgs;
use super::render::rate_text;
use crate::render::Backend;
use crate::render::RenderOptions;
use crate::render::team::Team;
use crate::scene::load_scene;
use clap::Args;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scene file or built-in scene name.
    #[arg(default_value = "weekend")]
    pub scene: String,
    /// Instead of SCENE, a generated field of N random spheres around the weekend scene's
    /// three large ones (for the scaling table).
    #[arg(long, value_name = "N")]
    pub spheres: Option<usize>,
    /// Test every primitive instead of walking the BVH.
    #[arg(long)]
    pub no_bvh: bool,
    /// No light sampling (next-event estimation).
    #[arg(long)]
    pub no_nee: bool,
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Maximum scatterings per path [default: the scene's].
    #[arg(long)]
    pub max_bounces: Option<u32>,
    /// Seconds to measure (after a warm-up).
    #[arg(long, default_value_t = 10.0)]
    pub time: f64,
    /// Seconds of warm-up (pipeline compilation, submission sizing); it goes on until the
    /// tuner has chosen between the specialized and the generic pipeline, for at most a
    /// minute more (a large image on a slow adapter times seconds-long rounds).
    #[arg(long, default_value_t = 2.0)]
    pub warmup: f64,
    /// Measure the generic tracer instead of the specialized one.
    #[arg(long)]
    pub generic: bool,
    /// Compile these features in although the scene does not need them (comma-separated:
    /// spheres, quads, boxes, triangles, dielectrics, emitters, nee, dof, sun), to measure
    /// what each costs.
    #[arg(long, value_name = "LIST", value_parser = crate::common::Features::parse_list)]
    pub with: Option<crate::common::Features>,
    /// Replace the base colour and metallic-roughness maps by one texel of their mean (the
    /// same code, no texel traffic): what those maps cost. Emissive maps stay (their mean
    /// would make the whole surface a lamp).
    #[arg(long)]
    pub mean_textures: bool,
    /// Measure the live preview instead: run it in a pseudo-terminal of --cols × --rows,
    /// type an edit key --presses times and time each until the screen shows the edit.
    #[arg(long)]
    pub preview: bool,
    /// Terminal columns for --preview.
    #[arg(long, default_value_t = 120)]
    pub cols: u16,
    /// Terminal rows for --preview.
    #[arg(long, default_value_t = 40)]
    pub rows: u16,
    /// Key presses to time with --preview.
    #[arg(long, default_value_t = 10)]
    pub presses: usize,
    /// With --preview: seconds the accumulation runs before each press.
    #[arg(long, default_value_t = 0.5)]
    pub settle: f64,
    /// With --preview: a press not shown within this many seconds is a miss.
    #[arg(long, default_value_t = 1.0)]
    pub timeout: f64,
    /// With --preview: the preview's graphics (its --graphics; the harness's emulator draws
    /// text only, so images are measured in bytes and frames, and edits by the status line).
    #[arg(long, value_enum)]
    pub graphics: Option<crate::ui::Graphics>,
    /// With --preview: the preview's frame cap (its --fps).
    #[arg(long)]
    pub fps: Option<f64>,
    /// With --preview: put a model of a link of this many Mbit/s between termtrace and the
    /// terminal (an SSH connection: output read eagerly into --window-kib, leaving at this
    /// rate, arriving --rtt-ms / 2 later; keys and answers take --rtt-ms / 2 back).
    #[arg(long, value_name = "MBIT/S", requires = "preview")]
    pub link_mbps: Option<f64>,
    /// With --preview: run the preview through a real OpenSSH connection (a throw-away sshd
    /// on a loopback port) behind a throttling proxy of --link-mbps and --rtt-ms, instead of
    /// the link model.
    #[arg(long, requires = "preview")]
    pub ssh: bool,
    /// With --link-mbps: the round trip in milliseconds.
    #[arg(long, default_value_t = 0.0, value_name = "MS")]
    pub rtt_ms: f64,
    /// With --link-mbps: the channel window in KiB (OpenSSH's default: 2048).
    #[arg(long, default_value_t = 2048, value_name = "KIB")]
    pub window_kib: usize,
    /// With --preview: the termtrace binary to measure [default: this one].
    #[arg(long, value_name = "PATH")]
    pub exe: Option<std::path::PathBuf>,
}

pub fn run(a: BenchArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.time > 0.0 && a.warmup >= 0.0,
        "--time must be positive, --warmup non-negative"
    );
    if a.preview {
        return run_preview(&a, g);
    }
    let prepare = Instant::now();
    let scene = match a.spheres {
        Some(n) => crate::scene::generate::sphere_field(n, 2024),
        None => load_scene(&a.scene, g.camera.as_deref(), g.sky.as_deref())?,
    };
    let scene = if a.mean_textures {
        with_mean_textures(&scene)
    } else {
        scene
    };
    let settings = crate::common::FrameSettings {
        nee: !a.no_nee,
        ..super::args::FrameArgs {
            width: Some(a.width),
            height: Some(a.height),
            max_bounces: a.max_bounces,
            seed: None,
        }
        .settings(&scene)
    };
    let backends = Backend::open_all(g.adapter.as_deref())?;
    for b in &backends {
        b.check_fits(&scene)?;
    }
    let options = RenderOptions {
        generic: a.generic,
        count_segments: true,
        no_bvh: a.no_bvh,
        gpu_timing: true,
        extra: a.with,
        ..Default::default()
    };
    let mut team = Team::new(&backends, &scene, settings, options, 0..u32::MAX);
    let prepare = prepare.elapsed();
    let warm = Instant::now();
    // Warm up for --warmup, and on until every tuner has chosen (at most a minute more).
    team.run(
        Duration::from_millis(200),
        Some(warm + Duration::from_secs_f64(a.warmup + 60.0)),
        |t| warm.elapsed().as_secs_f64() < a.warmup || t.tuning(),
    );
    team.restart(0..u32::MAX);
    let start = Instant::now();
    team.run(
        Duration::from_millis(250),
        Some(start + Duration::from_secs_f64(a.time)),
        |_| true,
    );
    let (paths, gpu_seconds) = (team.paths(), team.gpu_seconds());
    let secs = start.elapsed().as_secs_f64();
    let snap = team.snapshot();
    let segments = snap.data.segments;
    let r = team.first();
    println!("adapter      {}", team.describe());
    println!(
        "scene        {} at {}x{}, max_bounces {}, tracer {} ({})",
        match a.spheres {
            Some(n) => format!("{n} random spheres"),
            None => scene.short_name(),
        },
        settings.width,
        settings.height,
        settings.max_bounces,
        if a.generic {
            "generic"
        } else if a.with.is_some() {
            "specialized+extra"
        } else {
            "specialized"
        },
        r.features().summary()
    );
    let n = scene.counts();
    let (nodes, build) = r.bvh_stats();
    println!(
        "primitives   {} ({} spheres, {} quads, {} boxes, {} triangles); {}",
        n.spheres + n.quads + n.boxes + n.triangles,
        n.spheres,
        n.quads,
        n.boxes,
        n.triangles,
        if a.no_bvh {
            "no BVH: every primitive tested".to_string()
        } else {
            format!(
                "BVH of {nodes} node{} built in {:.0} ms",
                if nodes == 1 { "" } else { "s" },
                build * 1e3
            )
        }
    );
    println!(
        "prepared     in {:.2} s (scene, BVH, pipeline, buffers)",
        prepare.as_secs_f64()
    );
    println!(
        "measured     {:.1} s, {} spp complete, {} paths",
        secs,
        team.samples(),
        paths
    );
    println!(
        "samples/s    {:.4e}  ({})",
        paths as f64 / secs,
        rate_text(paths as f64 / secs)
    );
    println!("segments/s   {:.4e}", segments as f64 / secs);
    println!(
        "segments     {:.2} per path",
        segments as f64 / paths.max(1) as f64
    );
    let on_cpu = matches!(r.backend(), Backend::Cpu);
    if r.gpu_timed() && gpu_seconds > 0.0 {
        // With several devices, per device: their GPU seconds over their wall seconds.
        let n = team.len() as f64;
        println!(
            "gpu time     {:.1} s of passes ({:.0} % of wall{}): {:.4e} samples/s, {:.4e} segments/s",
            gpu_seconds,
            100.0 * gpu_seconds / (secs * n),
            if team.len() > 1 {
                " on each device"
            } else {
                ""
            },
            n * paths as f64 / gpu_seconds,
            n * segments as f64 / gpu_seconds
        );
    } else if on_cpu {
        println!("gpu time     none (the native CPU tracer: the wall time above is its time)");
    } else {
        println!("gpu time     not measured (no timestamp queries on this adapter)");
    }
    if segments > 0 && !a.no_bvh {
        let per = |x: u64| x as f64 / segments as f64;
        println!(
            "traversal    {:.1} BVH nodes visited and {:.1} primitives tested per segment (shadow rays included)",
            per(snap.data.node_visits),
            per(snap.data.primitive_tests)
        );
    }
    match r.tuned() {
        Some((chosen, (special, generic))) => println!(
            "pipeline     {} chosen by measurement: {:.2} ns/path specialized, {:.2} ns/path generic \
             (the generic one only if 3 % faster)",
            if chosen == r.features() {
                "specialized"
            } else {
                "generic"
            },
            special * 1e9,
            generic * 1e9
        ),
        None if !a.generic && a.with.is_none() && on_cpu => {
            println!("pipeline     specialized (the CPU tracer does not time the generic one)")
        }
        None if !a.generic && a.with.is_none() => {
            println!("pipeline     specialized (the same as the generic one, or not yet timed)")
        }
        None => {}
    }
    if let Some(how) = r.path_loop() {
        println!("cpu loop     {how}");
    }
    println!("invalid      {}", snap.invalid_samples());
    drop(r);
    if team.len() > 1 {
        for s in team.shares() {
            if let Some(why) = &s.failed {
                println!("device       failed ({why}): {}", s.device);
                continue;
            }
            println!(
                "device       {:.4e} samples/s, {:.1} % of the samples ({} claims): {}",
                s.paths as f64 / secs,
                100.0 * s.paths as f64 / paths.max(1) as f64,
                s.ranges.len(),
                s.device
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `bench --preview`: the preview in a pseudo-terminal (`measure::preview`).
fn run_preview(a: &BenchArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.settle >= 0.0 && a.timeout > 0.0,
        "--settle must be non-negative, --timeout positive"
    );
    // Frames/s are measured while converging: never stop accumulating on a fast GPU.
    let mut args = vec!["--max-spp".to_string(), u32::MAX.to_string()];
    if let Some(adapter) = &g.adapter {
        args.extend(["--adapter".to_string(), adapter.clone()]);
    }
    if let Some(g) = a.graphics {
        use clap::ValueEnum;
        let name = g
            .to_possible_value()
            .expect("a named value")
            .get_name()
            .to_string();
        args.extend(["--graphics".to_string(), name]);
    }
    if let Some(fps) = a.fps {
        args.extend(["--fps".to_string(), fps.to_string()]);
    }
    if a.generic {
        args.push("--generic".to_string());
    }
    // `--log FILE -v` logs the preview's own start-up and work, to FILE.preview.
    if let Some(log) = &g.log {
        let mut to = log.clone().into_os_string();
        to.push(".preview");
        args.extend(["--log".to_string(), to.to_string_lossy().into_owned()]);
        args.extend((0..g.verbose).map(|_| "-v".to_string()));
    }
    let mut b = crate::measure::preview::PreviewBench {
        exe: match &a.exe {
            Some(p) => p.clone(),
            None => std::env::current_exe()?,
        },
        scene: a.scene.clone(),
        cols: a.cols,
        rows: a.rows,
        presses: a.presses,
        settle: Duration::from_secs_f64(a.settle),
        timeout: Duration::from_secs_f64(a.timeout),
        window: Duration::from_secs_f64(a.time),
        args,
        link: a.link_mbps.map(|mbps| crate::measure::preview::Link {
            bits_per_second: mbps * 1e6,
            rtt: Duration::from_secs_f64(a.rtt_ms / 1e3),
            window: a.window_kib << 10,
        }),
        command: None,
        answer_gate: None,
    };
    // Kept alive while the preview runs through it.
    let _ssh = if a.ssh {
        let link = crate::measure::ssh_link::SshLink::start(
            a.link_mbps.unwrap_or(1000.0) * 1e6,
            Duration::from_secs_f64(a.rtt_ms / 1e3),
        )?;
        let mut remote = vec![
            "env".to_string(),
            "TERM=xterm-256color".to_string(),
            "COLORTERM=truecolor".to_string(),
            b.exe_path()?.display().to_string(),
            "view".to_string(),
            b.scene.clone(),
        ];
        remote.extend(b.args.iter().cloned());
        b.command = Some(link.command(&remote));
        // The proxy is the link: no model on top of it.
        b.link = None;
        Some(link)
    } else {
        None
    };
    let report = b.run()?;
    crate::measure::preview::print(&b, &report);
    Ok(ExitCode::SUCCESS)
}

/// `scene` with its base colour and metallic-roughness maps replaced by one texel of their
/// mean (`bench --mean-textures`): the same materials and code, without those texel fetches.
fn with_mean_textures(scene: &crate::scene::Scene) -> crate::scene::Scene {
    use crate::scene::texture::{Texture, Textured, TexturedRef};
    use std::sync::Arc;
    let mut out = scene.clone();
    let mut done: Vec<(*const Textured, TexturedRef)> = Vec::new();
    for o in &mut out.objects {
        let Some(t) = &o.material.textured else {
            continue;
        };
        let key = Arc::as_ptr(&t.0);
        let new = match done.iter().find(|(k, _)| *k == key) {
            Some((_, n)) => n.clone(),
            None => {
                let mean = |m: &Option<Arc<Texture>>| m.as_ref().map(|t| Arc::new(t.mean()));
                let n = TexturedRef(Arc::new(Textured {
                    base_color: mean(&t.0.base_color),
                    metallic_roughness: mean(&t.0.metallic_roughness),
                    // The emissive map stays: under the model's rule it decides where the
                    // surface emits (an emitter ends a path), and its mean would make the whole
                    // surface a lamp, another scene.
                    emissive: t.0.emissive.clone(),
                    normal: mean(&t.0.normal),
                    extensions: t.0.extensions.clone(),
                    ..*t.0
                }));
                done.push((key, n.clone()));
                n
            }
        };
        o.material.textured = Some(new);
    }
    out
}
