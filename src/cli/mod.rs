//! The command line: `termtrace [SCENE]` (the live preview) and its subcommands.

mod adapters;
mod args;
mod bench;
mod check;
mod converge;
mod leave;
mod merge;
mod render;

use crate::output::cells::{CellMode, ColorMode};
use crate::ui::{Graphics, ViewOptions};
pub use args::GlobalArgs;
use args::{positive, scale};
use clap::{Args, Parser, Subcommand};
use std::process::ExitCode;

/// A GPU path tracer whose live preview is drawn in the terminal.
#[derive(Parser, Debug)]
#[command(name = "termtrace", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    global: GlobalArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Open the live preview (the default command).
    View(ViewArgs),
    /// Render a scene to PNG (and linear EXR) headless.
    Render(render::RenderArgs),
    /// Validate scene files and print a summary of each (--stress: the stability report).
    Check(check::CheckArgs),
    /// Merge the shards of a render (`render --shard I/K`, `.tta` files) into its image, bit
    /// for bit the image of the whole render.
    Merge(merge::MergeArgs),
    /// List the GPU adapters this machine offers, best first.
    Adapters,
    /// Measure samples/s and path segments/s on the chosen adapter.
    Bench(bench::BenchArgs),
    /// Measure how fast the error falls against a reference: CSV, plot, fitted slope.
    Converge(converge::ConvergeArgs),
}

/// `termtrace [SCENE]` and `termtrace view [SCENE]`.
#[derive(Args, Debug, Clone, PartialEq)]
pub struct ViewArgs {
    /// Scene file, or the name of a built-in scene; the built-in showcase when omitted.
    pub scene: Option<String>,
    /// How pixels become cells.
    #[arg(long, value_enum, default_value_t = CellMode::Half)]
    pub cells: CellMode,
    /// Colours: truecolor, 256 (dithered palette) or none [default: from COLORTERM/TERM].
    #[arg(long, value_enum)]
    pub color: Option<ColorMode>,
    /// Pixel graphics: `auto` asks the terminal (also over SSH) and falls back to cells;
    /// inside tmux it needs `allow-passthrough on`. The status line says which and why.
    #[arg(long, value_enum, default_value_t = Graphics::Auto)]
    pub graphics: Graphics,
    /// With pixel graphics, trace this fraction of the terminal's pixels each way (less
    /// work and bandwidth; the image is scaled up) [default: what the backend traces a
    /// sample of every pixel of in 40 ms, at most all]
    #[arg(long, value_parser = scale)]
    pub scale: Option<f64>,
    /// Most frames per second drawn.
    #[arg(long, default_value_t = 30.0, value_parser = positive)]
    pub fps: f64,
    /// Lower the frame rate to keep output under this many kilobits per second.
    #[arg(long, value_name = "KBPS", value_parser = positive)]
    pub max_kbps: Option<f64>,
    /// Trace N×N pixels per preview pixel and average them in linear light.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub ss: u32,
    /// The preview stops accumulating (and leaves the GPU idle) at this many samples per pixel.
    #[arg(long, default_value_t = 16384, value_parser = clap::value_parser!(u32).range(1..))]
    pub max_spp: u32,
    /// Stop accumulating where the estimated relative RMSE reaches this (0.05 = 5 %; at most
    /// --max-spp): samples are traced in stages aimed at it, as `render --target-error`
    /// does, and the status line says `target reached`. Every edit starts over.
    #[arg(long, value_name = "E", value_parser = positive)]
    pub target_error: Option<f64>,
    /// A cell whose colour moved by at most this much (0-255 per channel) is not resent.
    #[arg(long, default_value_t = 2)]
    pub threshold: u8,
    /// Use the generic tracer instead of one specialized for the scene.
    #[arg(long)]
    pub generic: bool,
    /// Denoise the preview (guided by albedo and normal; tile by tile the raw image wherever
    /// that is estimated better): `auto` while the raw image's estimated error is above 1 %
    /// and the accumulation goes on (the final image at --max-spp is the raw one), `on`
    /// always, `off` never. The `d` key switches it off and on.
    #[arg(long, value_enum, default_value_t = crate::denoise::Mode::Auto)]
    pub denoise: crate::denoise::Mode,
    /// Quit after this many seconds (scripted runs, benchmarks).
    #[arg(long, value_name = "SECONDS", value_parser = positive)]
    pub exit_after: Option<f64>,
    /// Print frames drawn and bytes written when the preview ends.
    #[arg(long)]
    pub stats: bool,
}

fn init_logging(g: &GlobalArgs, to_stderr: bool) -> anyhow::Result<()> {
    let level = match g.verbose {
        _ if g.quiet => tracing::Level::ERROR,
        0 => tracing::Level::WARN,
        1 => tracing::Level::INFO,
        _ => tracing::Level::DEBUG,
    };
    let builder = tracing_subscriber::fmt().with_max_level(level);
    if let Some(path) = &g.log {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| anyhow::anyhow!("cannot open log file {}: {e}", path.display()))?;
        builder
            .with_ansi(false)
            .with_writer(std::sync::Mutex::new(file))
            .init();
    } else if to_stderr {
        builder.with_writer(std::io::stderr).init();
    }
    Ok(())
}

/// Mesa's implicit `VK_LAYER_MESA_device_select` layer only reorders devices for programs
/// that take the first one (termtrace ranks adapters itself), and on a machine without a
/// display it prints `XDG_RUNTIME_DIR is invalid` on stderr, over the preview. Disable it
/// unless the user set `NODEVICE_SELECT` themselves. Call before any thread starts.
pub fn quiet_vulkan_layers() {
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: called first thing in `main`, before any other thread exists.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

/// Refuses a scene or preview options before a subcommand (`termtrace --cells quadrant render
/// x`): they belong to the preview alone.
fn check_view_args(cli: Cli) -> Result<Cli, String> {
    if cli.command.is_some() {
        let none = Cli::parse_from(["termtrace"]).view;
        if cli.view != none {
            return Err("a scene and preview options go after `view`, or alone: \
                        `termtrace [SCENE] [OPTIONS]`"
                .into());
        }
    }
    Ok(cli)
}

/// Runs the command line; the binary's `main` is this.
pub fn main() -> ExitCode {
    let cli = match check_view_args(Cli::parse()) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(n) = cli.global.threads {
        // Before anything runs on rayon's global pool, which this sizes.
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::FAILURE;
        }
    }
    let is_view = matches!(cli.command, None | Some(Command::View(_)));
    if !is_view {
        // A command whose output is piped into `head` ends quietly when the reader has gone,
        // as Unix tools do, instead of panicking on a broken pipe.
        #[cfg(unix)]
        // SAFETY: SIG_DFL installs no handler; it only restores the default disposition.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    if let Err(e) = init_logging(&cli.global, !is_view) {
        eprintln!("error: {}", chain(&e));
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        None => view(cli.view, &cli.global),
        Some(Command::View(v)) => view(v, &cli.global),
        Some(Command::Render(a)) => render::run(a, &cli.global),
        Some(Command::Check(a)) => check::run(a, &cli.global),
        Some(Command::Merge(a)) => merge::run(a),
        Some(Command::Adapters) => adapters::run(),
        Some(Command::Bench(a)) => bench::run(a, &cli.global),
        Some(Command::Converge(a)) => converge::run(a, &cli.global),
    };
    let code = match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", chain(&e));
            ExitCode::FAILURE
        }
    };
    leave::finish(code)
}

/// An error and its causes on one line, each cause left out where a message above already
/// says it (a library error's message often quotes its source: "cannot read x: No such
/// file").
fn chain(e: &anyhow::Error) -> String {
    let mut out = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !out.contains(&c) {
            out.push_str(": ");
            out.push_str(&c);
        }
    }
    out
}

fn view(a: ViewArgs, g: &GlobalArgs) -> anyhow::Result<ExitCode> {
    crate::ui::run(ViewOptions {
        camera: g.camera.clone(),
        sky: g.sky.clone(),
        scene: a.scene,
        cells: a.cells,
        color: a.color,
        graphics: a.graphics,
        scale: a.scale,
        fps: a.fps,
        max_kbps: a.max_kbps,
        supersample: a.ss,
        max_spp: a.max_spp,
        target_error: a.target_error,
        threshold: a.threshold,
        generic: a.generic,
        denoise: a.denoise,
        adapter: g.adapter.clone(),
        log: g.log.clone(),
        exit_after: a.exit_after.map(std::time::Duration::from_secs_f64),
        stats: a.stats,
    })
    .map_err(Into::into)
}

/// Loads the scene a command names (a file, or a built-in name).
#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("termtrace").chain(args.iter().copied()))
    }

    #[test]
    fn global_options_go_before_or_after_the_subcommand() {
        for args in [
            &["-v", "render", "basic"][..],
            &["render", "basic", "-v"],
            &["--adapter", "cpu", "render", "basic"],
        ] {
            let cli = parse(args).unwrap_or_else(|e| panic!("{args:?}: {e}"));
            assert!(matches!(cli.command, Some(Command::Render(_))), "{args:?}");
        }
        let cli = parse(&["-v", "render", "basic"]).unwrap();
        assert_eq!(cli.global.verbose, 1);
    }

    #[test]
    fn a_scene_alone_opens_the_preview() {
        let cli = parse(&["weekend", "--cells", "sextant"]).unwrap();
        assert!(cli.command.is_none());
        assert_eq!(cli.view.scene.as_deref(), Some("weekend"));
        assert_eq!(cli.view.cells, CellMode::Sextant);
        assert!(parse(&[]).unwrap().view.scene.is_none());
        let cli = parse(&["view", "cornell"]).unwrap();
        assert!(
            matches!(cli.command, Some(Command::View(v)) if v.scene.as_deref() == Some("cornell"))
        );
    }

    #[test]
    fn preview_options_do_not_mix_with_other_commands() {
        let err = parse(&["--cells", "quadrant", "render", "basic"]).map(check_view_args);
        assert!(matches!(err, Ok(Err(_))), "{err:?}");
    }
}
