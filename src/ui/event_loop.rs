//! The UI thread's loop: events in, frames paced by the terminal's answers, drawn, and the
//! run's figures (`--stats`) at the end.

use super::event::Event;
use super::screen::*;
use super::setup::{GRAPHICS_MAX_WIDTH, cell_pixels};

use super::worker::Request;
use super::{app, flow, graphics, term, view};
use crate::output::LinearImage;
use crate::output::cells::{self};
use ratatui::Terminal;
use ratatui::backend::CrosstermBackend;
use ratatui::crossterm::event::Event as TermEvent;
use ratatui::crossterm::{Command, cursor, queue, terminal};
use ratatui::layout::Rect;
use rayon::prelude::*;
use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

pub(super) type Term = Terminal<CrosstermBackend<term::CountingWriter>>;

/// Frames drawn and bytes written over a run (`--stats`).
pub(super) struct History {
    pub(super) started: Instant,
    pub(super) frames: u64,
    /// (seconds since start, bytes written so far, frames so far) after every frame.
    pub(super) points: Vec<(f64, u64, u64)>,
}

impl Ui {
    /// Handles events and draws until the user quits; frames are drawn at most at `--fps`
    /// (and `--max-kbps`), except the first frame of an edit, which is drawn at once.
    pub(super) fn event_loop(
        &mut self,
        terminal: &mut Term,
        rx: &Receiver<Event>,
        bytes: &AtomicU64,
    ) -> Result<History, super::error::ViewError> {
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
    pub(super) fn pace_image(
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
    pub(super) fn draw(
        &mut self,
        terminal: &mut Term,
        area: Rect,
    ) -> Result<Rect, super::error::ViewError> {
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
    pub(super) fn shutdown(&mut self, worker: std::thread::JoinHandle<()>, rx: &Receiver<Event>) {
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
pub(super) fn image_sequences(
    g: graphics::Encoder,
    img: &LinearImage,
    image: Rect,
    due: &[graphics::Band],
    (w, mut h): (u32, u32),
    k: u32,
) -> Result<(String, f64), std::fmt::Error> {
    if g.protocol == graphics::Protocol::Sixel {
        h = graphics::sixel_height(h);
    }
    // The bands are separate images: encoded (sRGB, compression) on every core at once.
    let parts = due
        .par_iter()
        .map(|&(index, band)| -> Result<(String, f64), std::fmt::Error> {
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
        .collect::<Result<Vec<_>, _>>()?;
    let sent_pixels = parts.iter().map(|p| p.1).sum();
    let seq = parts.into_iter().map(|p| p.0).collect();
    Ok((seq, sent_pixels))
}

/// `--stats`: frames and bytes over the run, and over its last quarter (when the noise has
/// fallen, so fewer cells change).
pub(super) fn print_stats(h: &History, total: u64, stats: &app::Stats) {
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
    if stats.helped > 0 {
        eprintln!(
            "preview: {} of the {} spp traced by the devices after the first",
            stats.helped, stats.spp
        );
    }
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
