//! The live preview: three threads and one event channel. The input thread reads terminal
//! events, the render thread (`worker`) owns the GPU and sends frames, a signal handler
//! sends SIGTERM/SIGHUP; the UI thread (here) only updates the [`app::App`] and draws, so
//! input never waits on the GPU.

pub mod app;
pub mod detect;
pub mod flow;
pub mod graphics;
pub mod input;
pub mod keys;
pub mod term;
pub mod view;
pub mod worker;

use crate::gpu::FrameSettings;
use crate::output::cells::{self, CellMode, ColorMode};
use crate::output::{LinearImage, Transfer};
use crate::render::Backend;
use crate::scene::Scene;
use app::{App, Effect, Saving};
use ratatui::Terminal;
use ratatui::backend::CrosstermBackend;
use ratatui::crossterm::event::{Event as TermEvent, KeyEventKind};
use ratatui::crossterm::{Command, cursor, queue, terminal};
use ratatui::layout::Rect;
use rayon::prelude::*;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};
use view::Grid;
use worker::{Request, WorkerOptions};

/// Everything that reaches the UI thread.
pub enum Event {
    Input(TermEvent),
    Frame(Box<worker::Frame>),
    SaveProgress {
        done: u32,
        total: u32,
    },
    Saved(Result<String, String>),
    /// SIGTERM, SIGHUP or SIGINT from outside.
    Signal,
    /// The terminal answered a status query (`flow`): everything written before it has
    /// reached the terminal.
    StatusReport(Instant),
}

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
    /// A cell whose colour moved by at most this (per 8-bit channel) is not resent.
    pub threshold: u8,
    pub generic: bool,
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
fn choose_graphics(opts: &ViewOptions) -> (Option<graphics::Encoder>, String, Option<String>) {
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
        None if tmux && !passthrough => {
            Err("tmux: set allow-passthrough on for graphics".to_string())
        }
        None if tmux => match outer.as_deref() {
            Some("xterm-kitty") => Ok(Protocol::Kitty),
            other => Err(format!(
                "tmux in {}: cannot ask it for graphics (--graphics sixel|kitty|iterm)",
                other.unwrap_or("an unknown terminal")
            )),
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
            let told = (tmux || !answers.complete).then_some(why);
            (None, "cells".to_string(), told)
        }
    }
}

/// The cell size the terminal gave in answer to `CSI 16 t`.
static CELL_ANSWER: std::sync::OnceLock<(f64, f64)> = std::sync::OnceLock::new();

/// Cell size in pixels (width, height), when the terminal reports it: its answer to
/// `CSI 16 t` (exact), else the window size ioctl (which in xterm includes the border).
fn cell_pixels() -> Option<(f64, f64)> {
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
const GRAPHICS_MAX_WIDTH: f64 = 960.0;

/// The preview's render settings for an image area of `area` cells.
fn preview_settings(
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

/// `dir/NAME.edited.toml` beside a scene file, `./NAME.edited.toml` for a built-in scene.
pub fn edited_scene_path(scene: &Scene) -> PathBuf {
    let name = format!("{}.edited.toml", scene.short_name());
    match Path::new(&scene.origin).parent() {
        Some(dir) if !scene.origin.starts_with("builtin:") => dir.join(name),
        _ => PathBuf::from(name),
    }
}

/// The first of `NAME.png`, `NAME-1.png`, … that does not exist yet.
pub fn free_png_path(scene: &Scene) -> PathBuf {
    let stem = scene.short_name();
    (0..)
        .map(|i| match i {
            0 => PathBuf::from(format!("{stem}.png")),
            i => PathBuf::from(format!("{stem}-{i}.png")),
        })
        .find(|p| !p.exists())
        .expect("some name is free")
}

/// Writes the edited scene; an existing file of that name is kept as `….bak` first.
pub fn write_scene(scene: &Scene) -> Result<String, String> {
    let path = edited_scene_path(scene);
    let mut note = String::new();
    if path.exists() {
        let backup = PathBuf::from(format!("{}.bak", path.display()));
        std::fs::rename(&path, &backup)
            .map_err(|e| format!("cannot back up {}: {e}", path.display()))?;
        note = format!(" (the previous one is now {})", backup.display());
    }
    crate::output::write::write_text(&path, &crate::scene::to_toml(scene))
        .map_err(|e| e.to_string())?;
    // A built-in scene's meshes live in the binary: write them beside the scene, so that the
    // file loads on its own.
    if scene.origin.starts_with("builtin:") {
        let dir = path.parent().unwrap_or(Path::new("."));
        for o in &scene.objects {
            if let crate::scene::Shape::Mesh { file, .. } = &o.shape
                && let Some((_, text)) = crate::scene::BUILTIN_FILES.iter().find(|(n, _)| n == file)
            {
                let target = dir.join(file);
                if !target.exists() {
                    if let Some(d) = target.parent() {
                        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
                    }
                    crate::output::write::write_text(&target, text).map_err(|e| e.to_string())?;
                    note.push_str(&format!(" and {}", target.display()));
                }
            }
        }
    }
    Ok(format!("wrote {}{note}", path.display()))
}

/// The fraction of a band's pixels that must move beyond their noise for the band to be
/// resent (measured on weekend: at 1 % a converging image still resent a band or two of ten
/// every frame, 155 kB/s; at 3 %, 3.2 bands a second, 89 kB/s, as whole images did at 1 %).
const BAND_CHANGED: f64 = 0.03;

/// The time one sample per pixel of a graphics preview should take (see `graphics_scale`).
const FIRST_IMAGE: Duration = Duration::from_millis(40);

/// An image by pixel graphics may take this many frames' worth of the link's budget
/// (`flow::frame_budget`) before it is sent at fewer pixels, at most `IMAGE_SHRINK` fewer each
/// way.
const IMAGE_FRAMES: u64 = 4;
const IMAGE_SHRINK: u32 = 4;
/// The first image of an edit, which the user waits for, takes one frame's budget and may be
/// shrunk further (kitty and iTerm2 scale it up; at 8 it is about the cells' own resolution):
/// it arrives about as soon as cells would, and the next images bring the detail.
const EDIT_IMAGE_SHRINK: u32 = 8;

/// Frames in a row with almost no change before the image counts as settled.
const QUIET_FRAMES: u32 = 15;
/// Time between frames once the image has (nearly) stopped changing.
const IDLE_FRAME: Duration = Duration::from_secs(1);

struct Ui {
    app: App,
    opts: ViewOptions,
    color: ColorMode,
    /// Pixel graphics, or `None` for cells.
    graphics: Option<graphics::Encoder>,
    /// The image last sent by pixel graphics (8-bit sRGB, its size, the area it covered),
    /// against which a new one counts as changed or not.
    sent_image: Option<(Vec<u8>, (u32, u32), Rect)>,
    /// The bands of the latest image (`graphics::bands`) that go out by pixel graphics in
    /// this frame.
    image_due: Vec<graphics::Band>,
    /// The graphics preview's size has been fitted to the backend's rate.
    scale_settled: bool,
    /// Bytes per pixel the last graphics frames took (for shrinking on a slow link).
    image_bytes_per_pixel: f64,
    grid: Grid,
    to_worker: Sender<Request>,
    generation: u64,
    fresh_image: bool,
    /// A frame that shows an edit arrived: draw it now.
    urgent: bool,
    /// The frame being drawn is the first of an edit.
    edit_frame: bool,
    /// The image on screen was sent coarser than the link needs (an edit's first): the next
    /// image goes out whole, changed or not.
    sent_coarse: bool,
    /// Bands due that did not fit in the last frame's budget: they go in the next frames.
    pending_bands: Vec<u32>,
    /// The generation of the last frame taken.
    shown_generation: u64,
    /// Frames clocked by the terminal's answers.
    flow: flow::Flow,
    /// Output bytes per changed cell, as the last frames measured (for the frame budget).
    bytes_per_cell: f64,
    /// Cells the last encoding changed, and those it left for later frames.
    cells_changed: usize,
    cells_left: usize,
    /// Frames in a row that changed almost nothing.
    quiet_frames: u32,
    /// The latest image is final (`--max-spp` reached): every cell that differs is sent.
    exact: bool,
    quit: bool,
    /// Messages to print once the terminal is restored.
    farewell: Vec<String>,
}

impl Ui {
    /// The fraction of the terminal's pixels a graphics preview traces: `--scale`, or so
    /// that one sample of every pixel takes about [`FIRST_IMAGE`] at the rate the backend
    /// last showed (an edit's first image then comes in about that time; the terminal scales
    /// the image up). All of them until a rate is known.
    fn graphics_scale(&self, area: Rect) -> f64 {
        if let Some(s) = self.opts.scale {
            return s;
        }
        let rate = self.app.stats.samples_per_second;
        let (cw, ch) = cell_pixels().unwrap_or((8.0, 16.0));
        let pixels = (area.width as f64 * cw).min(GRAPHICS_MAX_WIDTH) * area.height as f64 * ch;
        if rate <= 0.0 || pixels <= 0.0 {
            return 1.0;
        }
        (rate * FIRST_IMAGE.as_secs_f64() / pixels)
            .sqrt()
            .clamp(0.25, 1.0)
    }

    /// Once the backend's rate is known (its first frames), a graphics preview started at
    /// every pixel of the terminal restarts at the size `graphics_scale` picks, if that is
    /// much smaller: from then on an edit's first image comes in about [`FIRST_IMAGE`].
    fn settle_graphics_scale(&mut self, area: Rect) {
        if self.scale_settled || self.graphics.is_none() || self.opts.scale.is_some() {
            return;
        }
        let s = &self.app.stats;
        if s.spp < 1
            || s.samples_per_second <= 0.0
            || s.elapsed < Duration::from_millis(100)
            || self.sent_image.is_none()
        {
            return;
        }
        self.scale_settled = true;
        let (image, _) = view::split(area);
        let k = self.graphics_scale(image);
        if k * k < 0.66 {
            tracing::info!("graphics: tracing {k:.2} of the terminal's pixels each way");
            self.send_scene(area);
        }
    }

    fn send_scene(&mut self, area: Rect) {
        let (image, _) = view::split(area);
        let s = preview_settings(
            &self.app.scene,
            self.app.cells,
            self.graphics
                .map(|g| (g.protocol, self.graphics_scale(image))),
            self.opts.supersample,
            self.app.nee,
            image,
        );
        if let Some(settings) = s {
            tracing::info!(
                "preview image {}x{} ({})",
                settings.width,
                settings.height,
                self.graphics.map_or("cells", |g| g.protocol.name())
            );
            self.generation += 1;
            let _ = self.to_worker.send(Request::Scene {
                scene: Box::new(self.app.scene.clone()),
                settings,
                // Cells average `--ss` traced pixels each way (graphics show every pixel).
                factor: if self.graphics.is_some() {
                    1
                } else {
                    self.opts.supersample
                },
                generation: self.generation,
            });
        }
    }

    fn handle(&mut self, ev: Event, area: Rect) {
        match ev {
            Event::Input(TermEvent::Key(k)) if k.kind != KeyEventKind::Release => {
                let Some(action) = keys::action(k) else {
                    return;
                };
                // What a key changes on screen is drawn at once.
                self.urgent = true;
                match self.app.apply(action) {
                    Effect::None => {}
                    Effect::SceneChanged | Effect::Relayout => {
                        tracing::debug!("key: scene changed");
                        self.send_scene(area)
                    }
                    Effect::Reset => {
                        let _ = self.to_worker.send(Request::Reset);
                    }
                    Effect::SavePng => self.save_png(),
                    Effect::WriteScene => match write_scene(&self.app.scene) {
                        Ok(m) => self.app.say(m),
                        Err(e) => self.app.say(format!("error: {e}")),
                    },
                    Effect::Quit => self.quit = true,
                }
            }
            Event::Input(TermEvent::Resize(..)) => self.send_scene(area),
            Event::Input(_) => {}
            Event::Frame(f) => {
                if f.generation == self.generation {
                    // The first frame of an edit is drawn at once, not at the next slot.
                    self.urgent |=
                        f.stats.spp < self.app.stats.spp || self.shown_generation != f.generation;
                    self.shown_generation = f.generation;
                    self.app.stats = f.stats;
                    self.app.image = Some(f.image);
                    self.app.image_sigma = f.sigma;
                    self.exact = f.last;
                    self.fresh_image = true;
                    self.settle_graphics_scale(area);
                }
            }
            Event::SaveProgress { done, total } => {
                if let Some(s) = &mut self.app.saving {
                    s.done = done;
                    s.total = total;
                }
            }
            Event::Saved(r) => {
                self.app.saving = None;
                let m = r.unwrap_or_else(|e| format!("error: {e}"));
                if self.quit {
                    self.farewell.push(m.clone());
                }
                self.app.say(m);
            }
            Event::Signal => self.quit = true,
            Event::StatusReport(at) => self.flow.answered(at),
        }
    }

    fn save_png(&mut self) {
        if let Some(s) = &self.app.saving {
            let m = format!("already saving {}", s.path);
            self.app.say(m);
            return;
        }
        let path = free_png_path(&self.app.scene);
        self.app.saving = Some(Saving {
            path: path.display().to_string(),
            done: 0,
            total: self.app.scene.render.spp,
        });
        let _ = self.to_worker.send(Request::Save {
            scene: Box::new(self.app.scene.clone()),
            path,
        });
    }

    /// Re-encodes the grid from the latest image if a new one came.
    fn encode(&mut self, area: Rect) {
        if !self.fresh_image {
            self.cells_changed = 0;
            return;
        }
        let (image, _) = view::split(area);
        let Some(img) = &self.app.image else { return };
        if let Some(g) = self.graphics {
            // The image goes out by the graphics protocol; the cells under it stay blank.
            let blank = cells::Cell {
                glyph: ' ',
                fg: cells::CellColor::Default,
                bg: cells::CellColor::Default,
            };
            let n = image.width as usize * image.height as usize;
            self.grid
                .update(image.width, image.height, vec![blank; n], 0);
            // A band is resent only when it changed beyond its own noise (the final image:
            // at all), or the area moved; a settled image then costs nothing.
            let rgb = img.to_rgb8(Transfer::Srgb).into_raw();
            let base = if self.exact { 0 } else { self.opts.threshold };
            let same_layout = self
                .sent_image
                .as_ref()
                .is_some_and(|(_, size, at)| *size == (img.width, img.height) && *at == image);
            let t =
                same_layout.then(|| graphics::pixel_thresholds(img, &self.app.image_sigma, base));
            let row_bytes = 3 * img.width as usize;
            let all = graphics::bands(g.protocol, image.height);
            let mut due = Vec::new();
            // Pixels that moved beyond their noise, over the whole image.
            let mut moved = 0.0;
            for (index, band) in all.iter().enumerate() {
                let rows = graphics::band_pixels(img.height, image.height, *band);
                let (a, b) = (rows.start as usize, rows.end as usize);
                let changed = match (&self.sent_image, &t) {
                    (Some((old, ..)), Some(t)) => graphics::changed_fraction(
                        &old[a * row_bytes..b * row_bytes],
                        &rgb[a * row_bytes..b * row_bytes],
                        &t[a * img.width as usize..b * img.width as usize],
                    ),
                    _ => 1.0,
                };
                moved += changed * (b - a) as f64;
                let owed = self.sent_coarse || self.pending_bands.contains(&(index as u32));
                if changed > BAND_CHANGED || (self.exact && changed > 0.0) || owed {
                    due.push((index as u32, *band));
                }
            }
            match &mut self.sent_image {
                Some((old, ..)) if same_layout => {
                    for (_, band) in &due {
                        let r = graphics::band_pixels(img.height, image.height, *band);
                        let bytes = r.start as usize * row_bytes..r.end as usize * row_bytes;
                        old[bytes.clone()].copy_from_slice(&rgb[bytes]);
                    }
                }
                _ => self.sent_image = Some((rgb, (img.width, img.height), image)),
            }
            // For the frame pacing, the share of the image that moved (not the bands sent):
            // a band resent now and then for its last noise lets the preview settle.
            self.cells_changed = if due.is_empty() {
                0
            } else {
                ((moved / img.height.max(1) as f64 * n as f64).ceil() as usize).max(1)
            };
            self.image_due = due;
            self.pending_bands.clear();
            self.cells_left = 0;
            return;
        }
        // The render thread sends the image already averaged down to the cells' pixels.
        let encoded = cells::encode(img, self.app.cells, self.color);
        let (sx, sy) = self.app.cells.subpixels();
        let (cols, rows) = ((img.width / sx) as u16, (img.height / sy) as u16);
        // On a slow link a frame carries what fits in its budget, the cells that changed
        // most first; the rest follow in the next frames.
        let limit = self.flow.frame_budget().map_or(usize::MAX, |bytes| {
            (bytes as f64 / self.bytes_per_cell).max(1.0) as usize
        });
        let thresholds = match self.color {
            // The final image goes out exactly: what stays on screen is the render.
            _ if self.exact => vec![0; encoded.len()],
            ColorMode::Truecolor => cells::noise_thresholds(
                img,
                &self.app.image_sigma,
                self.app.cells,
                self.opts.threshold,
            ),
            _ => vec![self.opts.threshold; encoded.len()],
        };
        let (changed, left) = self
            .grid
            .update_at_most(cols, rows, encoded, &thresholds, limit);
        self.cells_changed = changed;
        self.cells_left = left;
    }
}

/// What the preview runs on, decided before the terminal is taken (so that errors print
/// plainly).
struct Setup {
    scene: Scene,
    backend: Backend,
    /// The adapter as the status line names it.
    adapter: String,
    color: ColorMode,
    cells: CellMode,
}

fn setup(opts: &ViewOptions) -> anyhow::Result<Setup> {
    let scene = match &opts.scene {
        Some(s) => crate::scene::load_scene(s)?,
        None => Scene::default_scene(),
    };
    anyhow::ensure!(
        std::io::stdout().is_terminal() && std::io::stdin().is_terminal(),
        "the live preview needs a terminal on stdin and stdout; \
         for files use `termtrace render {} -o out.png`",
        opts.scene.as_deref().unwrap_or("SCENE")
    );
    let backend = Backend::open(opts.adapter.as_deref())?;
    // `llvmpipe (LLVM 15.0.6, 256 bits)` → `llvmpipe (Vulkan)`: the status line is short.
    let adapter = match &backend {
        Backend::Gpu(ctx) => {
            let short = ctx.info.name.split(" (").next().unwrap_or(&ctx.info.name);
            format!("{short} ({:?})", ctx.info.backend)
        }
        Backend::Cpu => format!("CPU ({})", crate::cpu::threads()),
    };
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
        backend,
        adapter,
        color,
        cells,
    })
}

/// Reads the terminal's input on its own thread, so that input never waits on drawing:
/// keys, and the answers to the status queries that clock frames (`input`). Window size
/// changes come from SIGWINCH.
fn spawn_input(tx: Sender<Event>) -> std::io::Result<()> {
    use std::io::Read;
    let keys = tx.clone();
    std::thread::Builder::new()
        .name("input".into())
        .spawn(move || {
            let mut parser = input::Parser::default();
            let mut buf = [0u8; 4096];
            let stdin = std::io::stdin();
            loop {
                let n = match stdin.lock().read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                let now = Instant::now();
                for i in parser.feed(&buf[..n]) {
                    let ev = match i {
                        input::Input::Key(k) => Event::Input(TermEvent::Key(k)),
                        input::Input::StatusReport => Event::StatusReport(now),
                    };
                    if keys.send(ev).is_err() {
                        return;
                    }
                }
            }
        })?;
    #[cfg(unix)]
    {
        let mut signals = signal_hook::iterator::Signals::new([signal_hook::consts::SIGWINCH])?;
        std::thread::Builder::new()
            .name("resize".into())
            .spawn(move || {
                for _ in signals.forever() {
                    let Ok((w, h)) = terminal::size() else {
                        continue;
                    };
                    if tx.send(Event::Input(TermEvent::Resize(w, h))).is_err() {
                        break;
                    }
                }
            })?;
    }
    Ok(())
}

type Term = Terminal<CrosstermBackend<term::CountingWriter>>;

/// Frames drawn and bytes written over a run (`--stats`).
struct History {
    started: Instant,
    frames: u64,
    /// (seconds since start, bytes written so far, frames so far) after every frame.
    points: Vec<(f64, u64, u64)>,
}

impl Ui {
    /// Handles events and draws until the user quits; frames are drawn at most at `--fps`
    /// (and `--max-kbps`), except the first frame of an edit, which is drawn at once.
    fn event_loop(
        &mut self,
        terminal: &mut Term,
        rx: &Receiver<Event>,
        bytes: &AtomicU64,
    ) -> anyhow::Result<History> {
        let mut area = Rect::from((
            (0, 0).into(),
            terminal
                .size()
                .map(|s| (s.width, s.height))
                .unwrap_or((80, 24))
                .into(),
        ));
        self.send_scene(area);
        let mut history = History {
            started: Instant::now(),
            frames: 0,
            points: Vec::new(),
        };
        let min_frame = Duration::from_secs_f64(1.0 / self.opts.fps.max(1.0));
        let mut next_draw = Instant::now();
        let mut dirty = true;
        while !self.quit {
            let wait = next_draw
                .saturating_duration_since(Instant::now())
                .max(Duration::from_millis(if dirty { 0 } else { 250 }));
            match rx.recv_timeout(wait) {
                Ok(ev) => {
                    // Take whatever else is queued before drawing.
                    for ev in std::iter::once(ev).chain(rx.try_iter()) {
                        if let Event::Input(TermEvent::Resize(w, h)) = ev {
                            area = Rect::new(0, 0, w, h);
                        }
                        self.handle(ev, area);
                    }
                    dirty = true;
                }
                Err(RecvTimeoutError::Timeout) => dirty = true,
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if self
                .opts
                .exit_after
                .is_some_and(|t| history.started.elapsed() >= t)
            {
                self.quit = true;
            }
            self.flow.tick(Instant::now());
            let budget_kbps = self.opts.max_kbps.unwrap_or(flow::FALLBACK_KBPS);
            self.app.link = self.flow.status(budget_kbps);
            // A frame waits for the terminal's answer to an earlier one (the answer is an
            // event, which wakes this loop).
            if self.quit
                || !dirty
                || (Instant::now() < next_draw && !self.urgent)
                || !self.flow.can_send()
            {
                continue;
            }
            if self.urgent {
                tracing::debug!(
                    "drawing the first frame of generation {}",
                    self.shown_generation
                );
            }
            if self.urgent {
                self.quiet_frames = 0;
            }
            self.edit_frame = self.urgent;
            self.urgent = false;
            let before = bytes.load(Ordering::Relaxed);
            area = self.draw(terminal, area)?;
            history.frames += 1;
            dirty = false;
            if self.opts.stats {
                history.points.push((
                    history.started.elapsed().as_secs_f64(),
                    bytes.load(Ordering::Relaxed),
                    history.frames,
                ));
            }
            let sent = bytes.load(Ordering::Relaxed) - before;
            self.flow.sent(Instant::now(), sent);
            tracing::debug!(
                "frame of {sent} bytes: {} cells changed, {} left, budget {:?}, {} unanswered, {:?}",
                self.cells_changed,
                self.cells_left,
                self.flow.frame_budget(),
                self.flow.unanswered(),
                self.flow.status(0.0)
            );
            if self.cells_changed > 64 {
                // Up at once, down slowly: a settled image's cells are cheap (neighbours share
                // colours), an edit's noisy ones are not, and its frame must not overshoot.
                let b = sent as f64 / self.cells_changed as f64;
                self.bytes_per_cell = b.max(0.9 * self.bytes_per_cell + 0.1 * b);
            }
            if self.cells_left > 0 {
                // The rest of the image goes in the next frames.
                self.fresh_image = true;
                dirty = true;
            }
            // An image that has (nearly) stopped changing: for QUIET_FRAMES frames fewer than
            // 1 % of its cells moved beyond the threshold, the noise's last flicker. It and
            // the status line are then redrawn once a second (a converged preview costs
            // almost nothing), until a key or an edit's frame.
            if self.cells_changed * 100 < self.grid.cells.len() {
                self.quiet_frames += 1;
            } else {
                self.quiet_frames = 0;
            }
            let idle = if self.quiet_frames >= QUIET_FRAMES {
                IDLE_FRAME
            } else {
                Duration::ZERO
            };
            // `--max-kbps` caps the rate; a terminal that does not answer gets a budget.
            let kbps = match self.flow.mode() {
                flow::Mode::Budget => Some(budget_kbps),
                _ => self.opts.max_kbps,
            };
            let budget = kbps.map_or(Duration::ZERO, |kbps| {
                Duration::from_secs_f64(sent as f64 * 8.0 / (kbps * 1000.0))
            });
            next_draw = Instant::now() + min_frame.max(budget).max(idle);
        }
        Ok(history)
    }

    /// The size at which this frame's image bands go (the full size and the shrink factor
    /// `k`), and which of the due bands go now. Kitty and iTerm2 scale the image over the
    /// cells; sixel pixels are the screen's, so a sixel image is resampled to the area's
    /// pixels. On a slow link fewer pixels (for kitty and iTerm2 scaled back up, for sixel a
    /// smaller image) and only the bands that fit in one frame's budget, the rest in the next
    /// frames, so that a key's frame never waits behind a whole image in the link; an edit's
    /// first image goes whole in one frame's budget, coarser, and the next one whole again.
    /// The final image goes out whole, once.
    fn pace_image(
        &mut self,
        g: graphics::Encoder,
        (width, height): (u32, u32),
        image: Rect,
    ) -> ((u32, u32), u32) {
        let full = match (g.protocol, cell_pixels()) {
            (graphics::Protocol::Sixel, Some((cw, _))) => {
                let w = (image.width as f64 * cw).min(GRAPHICS_MAX_WIDTH) as u32;
                (w, (w as f64 * height as f64 / width as f64) as u32)
            }
            _ => (width, height),
        };
        if self.exact {
            self.sent_coarse = false;
            return (full, 1);
        }
        let budget = self.flow.frame_budget();
        let shrink = |frames: u64, most: u32| {
            graphics::shrink_for(
                full.0 as u64 * full.1 as u64,
                self.image_bytes_per_pixel,
                budget.map(|b| b * frames),
                most,
            )
        };
        let usual = shrink(IMAGE_FRAMES, IMAGE_SHRINK);
        let edit = self.edit_frame && g.protocol != graphics::Protocol::Sixel;
        let k = if edit {
            shrink(1, EDIT_IMAGE_SHRINK)
        } else {
            usual
        };
        self.sent_coarse = k > usual;
        if let Some(budget) = budget
            && !edit
        {
            let per_pixel = self.image_bytes_per_pixel / (k * k) as f64;
            let (now, later) = graphics::fit_bands(
                std::mem::take(&mut self.image_due),
                |band| {
                    let rows = graphics::band_pixels(height, image.height, band);
                    (rows.end - rows.start) as f64 * full.0 as f64 * per_pixel
                },
                budget as f64,
            );
            self.image_due = now;
            self.pending_bands = later;
            self.cells_left = self.pending_bands.len();
        }
        (full, k)
    }

    /// Draws one frame as one synchronized update; returns the area drawn.
    fn draw(&mut self, terminal: &mut Term, area: Rect) -> anyhow::Result<Rect> {
        self.image_due.clear();
        self.encode(area);
        let graphics_frame = self.graphics.filter(|_| !self.image_due.is_empty());
        self.fresh_image = false;
        queue!(terminal.backend_mut(), terminal::BeginSynchronizedUpdate)?;
        let completed =
            terminal.draw(|f| view::draw(&self.app, &self.grid, f.area(), f.buffer_mut()))?;
        let area = completed.area;
        if let Some(g) = graphics_frame
            && let Some(traced) = self.app.image.as_ref().map(|i| (i.width, i.height))
        {
            let (image, _) = view::split(area);
            let (full, k) = self.pace_image(g, traced, image);
            let img = self.app.image.as_ref().expect("an image to draw");
            let size = ((full.0 / k).max(1), (full.1 / k).max(1));
            let (seq, sent_pixels) = image_sequences(g, img, image, &self.image_due, size, k)?;
            let per_pixel = seq.len() as f64 / sent_pixels.max(1.0);
            self.image_bytes_per_pixel = 0.5 * self.image_bytes_per_pixel + 0.5 * per_pixel;
            terminal.backend_mut().write_all(seq.as_bytes())?;
        }
        queue!(terminal.backend_mut(), terminal::EndSynchronizedUpdate)?;
        // The status query that clocks the next frames (`flow`).
        let out = terminal.backend_mut();
        out.write_all(flow::QUERY)?;
        out.flush()?;
        Ok(area)
    }

    /// Stops the render thread (a background save in progress writes what it has) and keeps
    /// what it said, to print once the terminal is restored.
    fn shutdown(&mut self, worker: std::thread::JoinHandle<()>, rx: &Receiver<Event>) {
        let _ = self.to_worker.send(Request::Quit);
        let _ = worker.join();
        for ev in rx.try_iter() {
            if let Event::Saved(r) = ev {
                self.farewell
                    .push(r.unwrap_or_else(|e| format!("error: {e}")));
            }
        }
    }
}

/// The sequences that send `due` bands of `img` over the image area `image`, the whole image
/// being `(w, h)` pixels when sent (`k`: the shrink factor), and the pixels they carry.
fn image_sequences(
    g: graphics::Encoder,
    img: &LinearImage,
    image: Rect,
    due: &[graphics::Band],
    (w, mut h): (u32, u32),
    k: u32,
) -> anyhow::Result<(String, f64)> {
    if g.protocol == graphics::Protocol::Sixel {
        h = graphics::sixel_height(h);
    }
    // The bands are separate images: encoded (sRGB, compression) on every core at once.
    let parts = due
        .par_iter()
        .map(|&(index, band)| -> anyhow::Result<(String, f64)> {
            // The band's rows of the traced image, at the size to send.
            let rows = graphics::band_pixels(img.height, image.height, band);
            let part;
            let src = if rows == (0..img.height) {
                img
            } else {
                part = graphics::crop_rows(img, rows);
                &part
            };
            let bh = if src.height == img.height {
                h
            } else {
                (src.height / k).max(1)
            };
            let resized;
            let sent = if (w, bh) == (src.width, src.height) {
                src
            } else if src.width % w == 0 && src.height % bh == 0 && src.width / w == src.height / bh
            {
                resized = cells::downsample(src, src.width / w);
                &resized
            } else {
                resized = graphics::resample(src, w, bh);
                &resized
            };
            let mut seq = String::new();
            cursor::MoveTo(image.x, image.y + band.0).write_ansi(&mut seq)?;
            seq.push_str(&g.band(sent, image.width, band.1, index));
            Ok((seq, sent.width as f64 * sent.height as f64))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let sent_pixels = parts.iter().map(|p| p.1).sum();
    let seq = parts.into_iter().map(|p| p.0).collect();
    Ok((seq, sent_pixels))
}

/// `--stats`: frames and bytes over the run, and over its last quarter (when the noise has
/// fallen, so fewer cells change).
fn print_stats(h: &History, total: u64, stats: &app::Stats) {
    let secs = h.started.elapsed().as_secs_f64();
    eprintln!(
        "preview: {} frames in {secs:.1} s ({:.1} fps), {total} bytes ({:.1} kB/s), {} spp at {}x{}",
        h.frames,
        h.frames as f64 / secs,
        total as f64 / secs / 1000.0,
        stats.spp,
        stats.width,
        stats.height,
    );
    if let Some(&(t0, b0, f0)) = h.points.iter().find(|p| p.0 >= 0.75 * secs)
        && let Some(&(t1, b1, f1)) = h.points.last()
        && t1 > t0
    {
        eprintln!(
            "preview: last quarter {:.1} fps, {:.1} kB/s",
            (f1 - f0) as f64 / (t1 - t0),
            (b1 - b0) as f64 / (t1 - t0) / 1000.0
        );
    }
}

/// Opens the preview; returns when the user quits.
pub fn run(opts: ViewOptions) -> anyhow::Result<ExitCode> {
    let setup = setup(&opts)?;
    let (tx, rx) = std::sync::mpsc::channel::<Event>();
    let signal_tx = tx.clone();
    let _ = ctrlc::set_handler(move || {
        let _ = signal_tx.send(Event::Signal);
    });
    let guard = term::TerminalGuard::enter(opts.log.as_deref())?;
    let (graphics, graphics_note, graphics_why) = choose_graphics(&opts);
    if let Some(g) = graphics {
        term::set_clear(g.clear());
    }
    spawn_input(tx.clone())?;
    let (to_worker, worker) = worker::spawn(
        setup.backend,
        WorkerOptions {
            fps: opts.fps,
            max_spp: opts.max_spp,
            generic: opts.generic,
        },
        tx,
    );
    let bytes = Arc::new(AtomicU64::new(0));
    let mut terminal = Terminal::new(CrosstermBackend::new(term::CountingWriter::new(
        bytes.clone(),
    )))?;
    let mut ui = Ui {
        app: App::new(setup.scene, setup.adapter, setup.cells),
        opts: opts.clone(),
        color: setup.color,
        graphics,
        sent_image: None,
        image_due: Vec::new(),
        scale_settled: false,
        image_bytes_per_pixel: 1.0,
        grid: Grid::default(),
        to_worker,
        generation: 0,
        fresh_image: false,
        urgent: false,
        edit_frame: false,
        sent_coarse: false,
        pending_bands: Vec::new(),
        shown_generation: 0,
        flow: flow::Flow::default(),
        bytes_per_cell: 40.0,
        cells_changed: 0,
        cells_left: 0,
        quiet_frames: 0,
        exact: false,
        quit: false,
        farewell: Vec::new(),
    };
    // Why there are no pixel graphics, where the user may have wanted them.
    if let Some(why) = graphics_why {
        ui.app.say(format!("graphics: cells ({why})"));
    }
    ui.app.graphics = graphics_note;
    let history = ui.event_loop(&mut terminal, &rx, &bytes);
    ui.shutdown(worker, &rx);
    drop(terminal);
    drop(guard);
    for m in &ui.farewell {
        eprintln!("{m}");
    }
    let history = history?;
    if opts.stats {
        print_stats(&history, bytes.load(Ordering::Relaxed), &ui.app.stats);
    }
    Ok(ExitCode::SUCCESS)
}
