//! `termtrace bench`: samples/s and path segments/s of one scene on the chosen adapter.

use super::render::{frame_settings, rate_text};
use super::{GlobalArgs, load_scene};
use crate::gpu::GpuContext;
use crate::render::{RenderOptions, Renderer};
use clap::Args;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Scene file or built-in scene name.
    #[arg(default_value = "weekend")]
    pub scene: String,
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
    /// Seconds of warm-up (pipeline compilation, submission sizing).
    #[arg(long, default_value_t = 2.0)]
    pub warmup: f64,
    /// Measure the generic tracer instead of the specialized one.
    #[arg(long)]
    pub generic: bool,
}

pub fn run(a: BenchArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.time > 0.0 && a.warmup >= 0.0,
        "--time must be positive, --warmup non-negative"
    );
    let scene = load_scene(&a.scene)?;
    let settings = frame_settings(&scene, Some(a.width), Some(a.height), a.max_bounces, None);
    let ctx = Arc::new(GpuContext::new(g.adapter.as_deref())?);
    let options = RenderOptions {
        generic: a.generic,
        count_segments: true,
        ..Default::default()
    };
    let compile = Instant::now();
    let mut r = Renderer::new(ctx.clone(), &scene, settings, options);
    let compile = compile.elapsed();
    let warm = Instant::now();
    while warm.elapsed().as_secs_f64() < a.warmup {
        r.step(Duration::from_millis(200), u32::MAX);
    }
    r.reset();
    let start = Instant::now();
    let mut paths = 0u64;
    while start.elapsed().as_secs_f64() < a.time {
        paths += r.step(Duration::from_millis(250), u32::MAX).paths;
    }
    let secs = start.elapsed().as_secs_f64();
    let snap = r.snapshot();
    let segments = snap.data.segments;
    println!("adapter      {}", ctx.adapter_name());
    println!(
        "scene        {} at {}x{}, max_bounces {}, tracer {} ({})",
        scene.short_name(),
        settings.width,
        settings.height,
        settings.max_bounces,
        if a.generic { "generic" } else { "specialized" },
        r.features().summary()
    );
    println!(
        "pipeline     created in {:.0} ms",
        compile.as_secs_f64() * 1e3
    );
    println!(
        "measured     {:.1} s, {} spp complete, {} paths",
        secs,
        r.samples(),
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
    println!("invalid      {}", snap.invalid_samples());
    Ok(ExitCode::SUCCESS)
}
