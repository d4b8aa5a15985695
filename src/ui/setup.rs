//! What the preview runs on, decided before the terminal is taken: its options, the backend
//! and scene, the graphics protocol the terminal answers for, and the render settings for
//! the image area.

use super::{detect, graphics};
use crate::common::FrameSettings;
use crate::output::cells::{CellMode, ColorMode};
use crate::render::Backend;
use crate::scene::Scene;
use ratatui::crossterm::terminal;
use ratatui::layout::Rect;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;

/// How the preview reaches the terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Graphics {
    /// Ask the terminal (`detect`): kitty graphics, else sixel, else iTerm2's images by
    /// TERM_PROGRAM, else cells.
    Auto,
    /// Text cells.
    Cells,
    /// The kitty graphics protocol (zlib-compressed RGB).
    Kitty,
    /// Sixel (quantized to the terminal's colour registers).
    Sixel,
    /// iTerm2's inline images (PNG; iTerm2, WezTerm).
    Iterm,
}

/// The preview's options (the command line's `view` flags).
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// A glTF scene's camera by name (`--camera`).
    pub camera: Option<String>,
    /// An environment map for the scene (`--sky`).
    pub sky: Option<std::path::PathBuf>,
    pub scene: Option<String>,
    pub cells: CellMode,
    /// `None`: detect from COLORTERM / TERM.
    pub color: Option<ColorMode>,
    pub graphics: Graphics,
    /// In a graphics mode, trace this fraction of the terminal's pixels each way; `None`:
    /// as many as the backend traces a sample of in [`FIRST_IMAGE`].
    pub scale: Option<f64>,
    pub fps: f64,
    /// Lower the frame rate to stay under this many kilobits per second of output.
    pub max_kbps: Option<f64>,
    /// Trace `n × n` pixels per image pixel and average them (linear light).
    pub supersample: u32,
    pub max_spp: u32,
    /// Stop accumulating where the estimated error reaches this (`--target-error`).
    pub target_error: Option<f64>,
    /// A cell whose colour moved by at most this (per 8-bit channel) is not resent.
    pub threshold: u8,
    pub generic: bool,
    pub denoise: crate::denoise::Mode,
    pub adapter: Option<String>,
    pub log: Option<PathBuf>,
    /// Quit by itself after this long (scripted runs and benchmarks).
    pub exit_after: Option<Duration>,
    /// Print frames drawn and bytes written at exit.
    pub stats: bool,
}

/// The graphics protocol for this terminal (`None`: cells), what the status line calls it
/// (the protocol's name, or `cells`), and why cells where the user may have wanted graphics
/// (for the start-up message and the log: the status line has no room for it). Asks the
/// terminal (raw mode, before the input thread reads stdin) unless the choice is forced.
pub(super) fn choose_graphics(
    opts: &ViewOptions,
) -> (Option<graphics::Encoder>, String, Option<String>) {
    use graphics::{Encoder, Protocol};
    let tmux = std::env::var_os("TMUX").is_some();
    let forced = match opts.graphics {
        Graphics::Cells => return (None, "cells".into(), None),
        Graphics::Kitty => Some(Protocol::Kitty),
        Graphics::Sixel => Some(Protocol::Sixel),
        Graphics::Iterm => Some(Protocol::Iterm),
        Graphics::Auto => None,
    };
    let (passthrough, outer) = if tmux {
        detect::tmux_outer()
    } else {
        (false, None)
    };
    // Outside tmux the terminal answers; inside, tmux would answer for it.
    let answers = if tmux {
        detect::Answers::default()
    } else {
        detect::ask(Duration::from_secs(1))
    };
    tracing::info!("terminal's answers: {answers:?}");
    if let Some((w, h)) = answers.cell {
        let _ = CELL_ANSWER.set((w as f64, h as f64));
    }
    let protocol = match forced {
        Some(p) => Ok(p),
        None if tmux && !passthrough => Err(detect::NoGraphics::TmuxPassthrough),
        None if tmux => match outer.as_deref() {
            Some("xterm-kitty") => Ok(Protocol::Kitty),
            other => Err(detect::NoGraphics::TmuxOuter(other.map(str::to_string))),
        },
        None => detect::choose(&answers, std::env::var("TERM_PROGRAM").ok().as_deref()),
    };
    match protocol {
        Ok(p) => {
            tracing::info!(
                "graphics: {}{}",
                p.name(),
                if tmux { " via tmux" } else { "" }
            );
            let e = Encoder {
                protocol: p,
                tmux,
                colors: answers.colors.unwrap_or(256),
            };
            let note = if tmux {
                format!("{} via tmux", p.name())
            } else {
                p.name().to_string()
            };
            (Some(e), note, None)
        }
        Err(why) => {
            tracing::info!("graphics: cells ({why})");
            // A terminal without graphics is the common case: only the log says why. Inside
            // tmux, or where the terminal did not answer, the start-up message says it too.
            let told = (tmux || !answers.complete).then(|| why.to_string());
            (None, "cells".to_string(), told)
        }
    }
}

/// The cell size the terminal gave in answer to `CSI 16 t`.
pub(super) static CELL_ANSWER: std::sync::OnceLock<(f64, f64)> = std::sync::OnceLock::new();

/// Cell size in pixels (width, height), when the terminal reports it: its answer to
/// `CSI 16 t` (exact), else the window size ioctl (which in xterm includes the border).
pub(super) fn cell_pixels() -> Option<(f64, f64)> {
    if let Some(&c) = CELL_ANSWER.get() {
        return Some(c);
    }
    terminal::window_size().ok().and_then(|ws| {
        (ws.width > 0 && ws.height > 0 && ws.columns > 0 && ws.rows > 0).then(|| {
            // Cells are whole pixels; xterm counts its border in the window's size.
            (
                (ws.width / ws.columns).max(1) as f64,
                (ws.height / ws.rows).max(1) as f64,
            )
        })
    })
}

/// Widest image sent by pixel graphics (bandwidth).
pub(super) const GRAPHICS_MAX_WIDTH: f64 = 960.0;

/// The preview's render settings for an image area of `area` cells.
pub(super) fn preview_settings(
    scene: &Scene,
    mode: CellMode,
    graphics: Option<(graphics::Protocol, f64)>,
    ss: u32,
    nee: bool,
    area: Rect,
) -> Option<FrameSettings> {
    if area.width == 0 || area.height == 0 {
        return None;
    }
    // Without a report, a cell is about twice as tall as wide.
    let (cw, ch) = cell_pixels().unwrap_or((8.0, 16.0));
    let (cols, rows) = (area.width as f64, area.height as f64);
    let (w, h, pixel_aspect) = if let Some((protocol, scale)) = graphics {
        let (pw, ph) = (cols * cw, rows * ch);
        let k = (GRAPHICS_MAX_WIDTH / pw).min(1.0) * scale;
        let mut h = (ph * k).max(1.0) as u32;
        if protocol == graphics::Protocol::Sixel {
            h = graphics::sixel_height(h);
        }
        ((pw * k).max(1.0) as u32, h, 1.0)
    } else {
        let (sx, sy) = mode.subpixels();
        (
            area.width as u32 * sx * ss,
            area.height as u32 * sy * ss,
            (cw / sx as f64) / (ch / sy as f64),
        )
    };
    Some(FrameSettings {
        width: w,
        height: h,
        max_bounces: scene.render.max_bounces,
        seed: scene.render.seed,
        pixel_aspect,
        nee,
    })
}

/// What the preview runs on, decided before the terminal is taken (so that errors print
/// plainly).
pub(super) struct Setup {
    pub(super) scene: Scene,
    /// The devices: the first makes the frames, the others help it trace (`helpers`).
    pub(super) backends: Vec<Backend>,
    /// The adapters as the status line names them.
    pub(super) adapter: String,
    pub(super) color: ColorMode,
    pub(super) cells: CellMode,
}

pub(super) fn setup(opts: &ViewOptions) -> Result<Setup, super::error::ViewError> {
    // The scene loads while the adapter opens (each can take a few hundred milliseconds).
    let (scene, backend) = std::thread::scope(|s| {
        let opening = s.spawn(|| Backend::open_all(opts.adapter.as_deref()));
        let scene = match &opts.scene {
            Some(s) => crate::scene::load_scene(s, opts.camera.as_deref(), opts.sky.as_deref()),
            None => {
                let mut scene = Scene::default_scene();
                match &opts.sky {
                    Some(p) => scene.set_sky_map(p).map(|()| scene),
                    None => Ok(scene),
                }
            }
        };
        let backend = opening
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (scene, backend)
    });
    let scene = scene?;
    if !(std::io::stdout().is_terminal() && std::io::stdin().is_terminal()) {
        return Err(super::error::ViewError::NoTerminal {
            scene: opts.scene.clone().unwrap_or_else(|| "SCENE".into()),
        });
    }
    let backends = backend?;
    for b in &backends {
        b.check_fits(&scene)?;
    }
    let names: Vec<String> = backends.iter().map(Backend::short_name).collect();
    let adapter = names.join(" + ");
    let color = opts.color.unwrap_or_else(|| {
        ColorMode::detect(
            std::env::var("COLORTERM").ok().as_deref(),
            std::env::var("TERM").ok().as_deref(),
        )
    });
    let cells = if color == ColorMode::None && opts.cells != CellMode::Ascii {
        CellMode::Ascii
    } else {
        opts.cells
    };
    Ok(Setup {
        scene,
        backends,
        adapter,
        color,
        cells,
    })
}
