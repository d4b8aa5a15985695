//! The UI thread's state (`Ui`): what it asks of the render thread, and how a frame becomes
//! terminal output (cells, or pixel-graphics bands sized to the link), and what each event
//! does to it.

use super::event::Event;
use super::save::{free_png_path, write_scene};
use super::setup::{GRAPHICS_MAX_WIDTH, ViewOptions, cell_pixels, preview_settings};

use super::app::{App, Effect, Saving};
use super::view::Grid;
use super::worker::Request;
use super::{flow, graphics, keys, view};
use crate::output::Transfer;
use crate::output::cells::{self, ColorMode};
use ratatui::crossterm::event::{Event as TermEvent, KeyEventKind};
use ratatui::layout::Rect;
use std::sync::mpsc::Sender;
use std::time::Duration;

/// The fraction of a band's pixels that must move beyond their noise for the band to be
/// resent (measured on weekend: at 1 % a converging image still resent a band or two of ten
/// every frame, 155 kB/s; at 3 %, 3.2 bands a second, 89 kB/s, as whole images did at 1 %).
pub(super) const BAND_CHANGED: f64 = 0.03;

/// The time one sample per pixel of a graphics preview should take (see `graphics_scale`).
pub(super) const FIRST_IMAGE: Duration = Duration::from_millis(40);

/// An image by pixel graphics may take this many frames' worth of the link's budget
/// (`flow::frame_budget`) before it is sent at fewer pixels, at most `IMAGE_SHRINK` fewer each
/// way.
pub(super) const IMAGE_FRAMES: u64 = 4;
pub(super) const IMAGE_SHRINK: u32 = 4;
/// The first image of an edit, which the user waits for, takes one frame's budget and may be
/// shrunk further (kitty and iTerm2 scale it up; at 8 it is about the cells' own resolution):
/// it arrives about as soon as cells would, and the next images bring the detail.
pub(super) const EDIT_IMAGE_SHRINK: u32 = 8;

/// Frames in a row with almost no change before the image counts as settled.
pub(super) const QUIET_FRAMES: u32 = 15;
/// Time between frames once the image has (nearly) stopped changing.
pub(super) const IDLE_FRAME: Duration = Duration::from_secs(1);

pub(super) struct Ui {
    pub(super) app: App,
    pub(super) opts: ViewOptions,
    pub(super) color: ColorMode,
    /// Pixel graphics, or `None` for cells.
    pub(super) graphics: Option<graphics::Encoder>,
    /// The image last sent by pixel graphics (8-bit sRGB, its size, the area it covered),
    /// against which a new one counts as changed or not.
    pub(super) sent_image: Option<(Vec<u8>, (u32, u32), Rect)>,
    /// The bands of the latest image (`graphics::bands`) that go out by pixel graphics in
    /// this frame.
    pub(super) image_due: Vec<graphics::Band>,
    /// The graphics preview's size has been fitted to the backend's rate.
    pub(super) scale_settled: bool,
    /// Bytes per pixel the last graphics frames took (for shrinking on a slow link).
    pub(super) image_bytes_per_pixel: f64,
    pub(super) grid: Grid,
    pub(super) to_worker: Sender<Request>,
    pub(super) generation: u64,
    pub(super) fresh_image: bool,
    /// A frame that shows an edit arrived: draw it now.
    pub(super) urgent: bool,
    /// The frame being drawn is the first of an edit.
    pub(super) edit_frame: bool,
    /// The image on screen was sent coarser than the link needs (an edit's first): the next
    /// image goes out whole, changed or not.
    pub(super) sent_coarse: bool,
    /// Bands due that did not fit in the last frame's budget: they go in the next frames.
    pub(super) pending_bands: Vec<u32>,
    /// The generation of the last frame taken.
    pub(super) shown_generation: u64,
    /// Frames clocked by the terminal's answers.
    pub(super) flow: flow::Flow,
    /// Output bytes per changed cell, as the last frames measured (for the frame budget).
    pub(super) bytes_per_cell: f64,
    /// Cells the last encoding changed, and those it left for later frames.
    pub(super) cells_changed: usize,
    pub(super) cells_left: usize,
    /// Frames in a row that changed almost nothing.
    pub(super) quiet_frames: u32,
    /// The latest image is final (`--max-spp` reached): every cell that differs is sent.
    pub(super) exact: bool,
    pub(super) quit: bool,
    /// Messages to print once the terminal is restored.
    pub(super) farewell: Vec<String>,
}

impl Ui {
    /// The fraction of the terminal's pixels a graphics preview traces: `--scale`, or so
    /// that one sample of every pixel takes about [`FIRST_IMAGE`] at the rate the backend
    /// last showed (an edit's first image then comes in about that time; the terminal scales
    /// the image up). All of them until a rate is known.
    pub(super) fn graphics_scale(&self, area: Rect) -> f64 {
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
    pub(super) fn settle_graphics_scale(&mut self, area: Rect) {
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

    pub(super) fn send_scene(&mut self, area: Rect) {
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

    pub(super) fn handle(&mut self, ev: Event, area: Rect) {
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
                    Effect::Denoise(mode) => {
                        let _ = self.to_worker.send(Request::Denoise(mode));
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
            Event::DeviceLost(m) => {
                // Said again once the terminal is restored.
                self.farewell.push(m.clone());
                self.app.say(m);
            }
            Event::Signal => self.quit = true,
            Event::StatusReport(at) => self.flow.answered(at),
        }
    }

    pub(super) fn save_png(&mut self) {
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
    pub(super) fn encode(&mut self, area: Rect) {
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
