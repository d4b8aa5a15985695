//! What every subcommand shares: the global options and the value parsers.

use crate::output::{ImageFile, Transfer, check_writable};
use clap::Args;
use std::path::{Path, PathBuf};

/// Options every command takes.
#[derive(Args, Debug, Clone)]
pub struct GlobalArgs {
    /// Where to trace: `cpu-native` (the native CPU tracer), or a GPU adapter by part of its
    /// name, a backend (vulkan, gl, metal, dx12), a type (cpu, discrete, integrated) or its
    /// number in `termtrace adapters`. Default: the best GPU; the native CPU tracer where the
    /// best adapter is a software one or there is none. `view`, `render`, `bench` and `converge`
    /// also trace on several at once, sharing the samples: `all` (every hardware GPU) or a list
    /// (`0,1`, `vulkan,cpu-native`).
    #[arg(long, global = true, env = "TERMTRACE_ADAPTER", value_name = "NAME")]
    pub adapter: Option<String>,
    /// Threads of the native CPU tracer and of the host's parallel work (on a shared machine,
    /// fewer than its cores). Default: one per core.
    #[arg(long, global = true, env = "TERMTRACE_THREADS", value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub threads: Option<u32>,
    /// The camera of a glTF scene (`.gltf`, `.glb`) by name. Default: its first camera, or
    /// one that frames the model when it has none.
    #[arg(long, global = true, value_name = "NAME")]
    pub camera: Option<String>,
    /// Light the scene with this HDR environment map (an equirectangular Radiance `.hdr` or
    /// OpenEXR file), for any scene, glTF and OBJ included; it replaces the map of a scene
    /// that has one and keeps its intensity, rotation and visibility.
    #[arg(long, global = true, value_name = "FILE")]
    pub sky: Option<PathBuf>,
    /// Write logs to this file.
    #[arg(long, global = true, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// More detail in the logs (-v info, -vv debug).
    #[arg(short, long, global = true, action = clap::ArgAction::Count, conflicts_with = "quiet")]
    pub verbose: u8,
    /// No progress bars, and errors alone in the logs (no warnings).
    #[arg(short, long, global = true)]
    pub quiet: bool,
}

/// The frame options `render` and `converge` share: the scene's `[render]` values,
/// overridden.
#[derive(Args, Debug, Clone, Copy, Default)]
pub struct FrameArgs {
    /// Image width [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=crate::scene::MAX_IMAGE_SIDE as i64))]
    pub width: Option<u32>,
    /// Image height [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=crate::scene::MAX_IMAGE_SIDE as i64))]
    pub height: Option<u32>,
    /// Random seed [default: the scene's]; the same seed gives the same image on one adapter
    /// (`converge`: its first run's; the next runs count up from it).
    #[arg(long)]
    pub seed: Option<u32>,
    /// Maximum scatterings per path [default: the scene's].
    #[arg(long, value_parser = clap::value_parser!(u32).range(..=crate::scene::MAX_BOUNCES as i64))]
    pub max_bounces: Option<u32>,
}

impl FrameArgs {
    /// The frame settings of `scene` with these overrides.
    pub fn settings(&self, scene: &crate::scene::Scene) -> crate::common::FrameSettings {
        crate::common::FrameSettings::new(
            self.width.unwrap_or(scene.render.width),
            self.height.unwrap_or(scene.render.height),
            self.max_bounces.unwrap_or(scene.render.max_bounces),
            self.seed.unwrap_or(scene.render.seed),
        )
    }
}

/// The image options `render` and `merge` share.
#[derive(Args, Debug, Clone)]
pub struct ImageArgs {
    /// Also write the linear radiance as 32-bit float OpenEXR (a name ending in `.exr`).
    #[arg(long, value_name = "EXR")]
    pub exr: Option<PathBuf>,
    /// Write a 16-bit PNG.
    #[arg(long)]
    pub png16: bool,
    /// Transfer function of the PNG.
    #[arg(long, value_enum, default_value_t = Transfer::Srgb)]
    pub transfer: Transfer,
}

impl ImageArgs {
    /// Refuses, before any work, what does not fit an image of `kind` written to `out`:
    /// `--png16` for an OpenEXR file, an `--exr` name that is not one, an unwritable `--exr`.
    pub fn check(&self, out: &Path, kind: ImageFile) -> anyhow::Result<()> {
        if kind == ImageFile::Exr && self.png16 {
            anyhow::bail!(
                "--png16 asks for a 16-bit PNG, but {} is an OpenEXR file (32-bit float)",
                out.display()
            );
        }
        if let Some(exr) = &self.exr {
            // A name without an extension is a PNG's (`ImageFile::of`).
            if ImageFile::of(exr)? != ImageFile::Exr {
                anyhow::bail!(
                    "--exr {}: the OpenEXR file's name must end in .exr",
                    exr.display()
                );
            }
            check_writable(exr)?;
        }
        Ok(())
    }
}

/// A fraction in (0, 1] (`--scale`).
pub(super) fn scale(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x > 0.0 && x <= 1.0 => Ok(x),
        _ => Err(format!("`{s}` is not a fraction in (0, 1]")),
    }
}

/// A finite number above zero.
pub(super) fn positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("`{s}` is not a positive number")),
    }
}
