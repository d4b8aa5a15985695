//! The render thread: owns the GPU, keeps it busy with short pipelined submissions of the
//! preview, and renders PNGs in the background on the same device, interleaved with it.
//!
//! Frames never stop the tracing: a frame is made on the GPU by the resolve pass (the small
//! image the terminal shows, and its noise estimate) and read back asynchronously through two
//! staging buffers; the thread takes it once it has landed. A submission is a few
//! milliseconds of work and at most two are queued, so an edit waits behind little: its
//! first round is one sample per pixel, and its frame is requested as soon as that round is
//! queued, whatever the frame rate. Frames of an older state still in flight are dropped.
//!
//! On several devices (`helpers`) this thread's device is the first: it claims samples with
//! the others, and once another device has published its sums, every frame shows them all:
//! on a GPU its resolve pass adds the others' sums (uploaded when they change), elsewhere and
//! for denoised frames the host adds them (the first frame after an edit is this device's
//! alone). If this device fails (a panic on this thread, `render::failure`), the preview
//! starts over on the others, the next one making the frames.

use super::app::Stats;
use super::event::{Event, Frame};
use super::save::SaveError;
use crate::common::FrameSettings;
use crate::common::Resolved;
use crate::output::{Transfer, write_png};
use crate::render::claims::{Claims, Fail};
use crate::render::failure::contained;
use crate::render::frames::Frames;
use crate::render::team::live::Helpers;
use crate::render::{Backend, RenderOptions, Renderer, stages};
use crate::scene::Scene;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// GPU time one preview submission should take: short, so that an edit waits behind little.
const PREVIEW_SUBMISSION: Duration = Duration::from_millis(5);
/// Submissions queued on the GPU at once: one running, one waiting behind it.
const QUEUED: usize = 2;
/// Tracing time given to a background save between preview submissions.
const SAVE_SLICE: Duration = Duration::from_millis(8);
/// How often the render thread looks at the other devices' progress when it has nothing of
/// its own to trace.
const HELPER_POLL: Duration = Duration::from_millis(5);

/// What the UI asks of the render thread.
pub enum Request {
    /// Render this scene at these settings from now on (restarts the accumulation); frames
    /// average `factor × factor` traced pixels per image pixel.
    Scene {
        scene: Box<Scene>,
        settings: FrameSettings,
        factor: u32,
        generation: u64,
    },
    /// Restart the accumulation.
    Reset,
    /// Render `scene` at its own resolution and spp in the background, then write `path`.
    Save { scene: Box<Scene>, path: PathBuf },
    /// Denoise frames in this mode from now on (the accumulation goes on).
    Denoise(crate::denoise::Mode),
    /// Stop; a background save in progress writes what it has.
    Quit,
}

#[derive(Clone, Copy, Debug)]
pub struct WorkerOptions {
    pub fps: f64,
    /// The preview stops accumulating here (and the GPU idles).
    pub max_spp: u32,
    /// Or here, where the raw image's estimated error reaches this (`--target-error`): its
    /// samples are claimed in stages aimed at it (`render::stages`).
    pub target_error: Option<f64>,
    pub generic: bool,
    pub denoise: crate::denoise::Mode,
}

struct SaveJob {
    renderer: Renderer,
    path: PathBuf,
    total: u32,
}

/// What a frame in flight shows.
#[derive(Clone, Copy)]
struct FrameTag {
    generation: u64,
    epoch: u64,
    /// The accumulation has stopped (`--max-spp`, or a stage's end, `--target-error`):
    /// this is the final image, unless the target asks for another stage.
    last: bool,
    spp: u32,
    /// Of `spp`, the samples per pixel the other devices traced.
    helped: u32,
    paths: u64,
}

/// The preview's state since its last reset.
struct Preview {
    renderer: Renderer,
    factor: u32,
    since_reset: Instant,
    /// Paths submitted since the reset.
    paths: u64,
    /// When the last frame was requested, and how many paths it showed.
    last_frame: Option<(Instant, u64)>,
    /// The raw image's estimated error in the last frame (the denoiser's `auto` reads it).
    noise: Option<f64>,
    /// When the last denoised frame was made, and what making it took (denoised frames are
    /// spaced so that the denoiser takes at most a quarter of the time).
    last_denoise: Option<(Instant, Duration)>,
    /// When the last frame of every device's sums was made, and what making it took.
    last_combined: Option<(Instant, Duration)>,
    /// No samples are left for this device to claim (the others may still be tracing).
    exhausted: bool,
    /// Where this stage's samples end: `max_spp`, or with a target error the stage's end.
    stage_end: u32,
    /// The estimate has reached the target error: the accumulation has stopped.
    reached: bool,
    /// The other devices have been told to trace this state (after its first frame, so
    /// that they take nothing from this device's first sample).
    helpers_told: bool,
}

struct Worker {
    backend: Backend,
    opts: WorkerOptions,
    events: Sender<Event>,
    preview: Option<Preview>,
    /// The other devices, and the claims this epoch's samples are shared by.
    helpers: Option<Helpers>,
    claims: Option<Arc<Claims>>,
    /// This device's frame makers and the frames on their way (`render::frames`).
    frames: Frames<FrameTag>,
    /// The UI's number of the scene request being traced.
    generation: u64,
    /// Counts every restart of the accumulation: frames of an older epoch are dropped.
    epoch: u64,
    save: Option<SaveJob>,
    /// The last scene request taken (scene, settings, factor, generation): the scene the
    /// helpers are told to trace, and where the others go on if this device fails, even in
    /// the middle of taking it.
    requested: Option<(Arc<Scene>, FrameSettings, u32, u64)>,
    /// A test's device failure: this device of every claims fails then.
    #[cfg(test)]
    fail: Option<(usize, Fail)>,
}

/// Starts the render thread on the first of `backends` (and a helper on each other); it
/// ends on `Request::Quit` or when either channel closes.
pub fn spawn(
    backends: Vec<Backend>,
    opts: WorkerOptions,
    events: Sender<Event>,
) -> (Sender<Request>, JoinHandle<()>) {
    spawn_failing(backends, opts, events, None)
}

/// `spawn`, with device `fail.0` failing at `fail.1` in every state (a test's device loss;
/// `None` outside tests).
fn spawn_failing(
    mut backends: Vec<Backend>,
    opts: WorkerOptions,
    events: Sender<Event>,
    #[allow(unused_variables, unused_mut)] mut fail: Option<(usize, Fail)>,
) -> (Sender<Request>, JoinHandle<()>) {
    let (tx, rx) = std::sync::mpsc::channel();
    let handle = std::thread::Builder::new()
        .name("render".into())
        .spawn(move || {
            assert!(!backends.is_empty(), "the preview needs a device");
            let mut go_on = None;
            loop {
                let mut w = Worker::new(backends.clone(), opts, events.clone(), fail);
                if let Some((scene, settings, factor, generation)) = go_on.take() {
                    w.set_scene(scene, settings, factor, generation);
                }
                if backends.len() == 1 {
                    return w.run(&rx);
                }
                // On several devices the first one's failure is contained: the preview starts
                // over on the others, from the state it was tracing.
                let why = match contained(|| w.run(&rx)) {
                    Ok(()) => return,
                    Err(why) => why,
                };
                let lost = backends.remove(0).describe();
                tracing::warn!("{lost} failed ({why}); the preview starts over on the others");
                let _ = events.send(Event::DeviceLost(format!(
                    "{lost} failed ({why}); the preview starts over on the other devices"
                )));
                if w.save.take().is_some() {
                    let _ = events.send(Event::Saved(Err(format!(
                        "the save in progress was lost with {lost}; save again"
                    )
                    .into())));
                }
                go_on = w.requested.take();
                // Its helpers end with it; the next worker starts them again.
                drop(w);
                #[cfg(test)]
                {
                    fail = None;
                }
            }
        })
        .expect("spawn the render thread");
    (tx, handle)
}

impl Worker {
    /// A worker on the first of `backends`, with a helper on each other.
    fn new(
        mut backends: Vec<Backend>,
        opts: WorkerOptions,
        events: Sender<Event>,
        #[allow(unused_variables)] fail: Option<(usize, Fail)>,
    ) -> Worker {
        let backend = backends.remove(0);
        let mut w = Worker {
            frames: Frames::new(&backend),
            backend,
            opts,
            events,
            preview: None,
            helpers: None,
            claims: None,
            generation: 0,
            epoch: 0,
            save: None,
            requested: None,
            #[cfg(test)]
            fail,
        };
        if !backends.is_empty() {
            let every = w.frame_interval();
            w.helpers = Some(Helpers::spawn(backends, w.options(), every));
        }
        w
    }

    /// Time between frame requests: half the UI's frame time, so that a fresh frame is
    /// waiting at each of its draws (a frame is small: reading it back costs little).
    fn frame_interval(&self) -> Duration {
        Duration::from_secs_f64(0.5 / self.opts.fps.max(1.0))
    }

    fn options(&self) -> RenderOptions {
        RenderOptions {
            generic: self.opts.generic,
            submission: PREVIEW_SUBMISSION,
            compile_in_background: true,
            first_look: true,
            ..Default::default()
        }
    }

    /// Samples per pixel and paths the other devices have published since the last restart.
    fn helper_progress(&self) -> (u32, u64) {
        self.helpers
            .as_ref()
            .map_or((0, 0), |h| h.progress(self.epoch))
    }

    /// Whether the preview's accumulation is short of `max_spp` (on every device together),
    /// with `helped` samples of the other devices (`helper_progress`, read once for each
    /// decision: a helper may publish between two reads, and a frame tagged as not the last
    /// that showed every sample left the preview waiting for a last frame forever).
    fn preview_busy(&self, helped: u32) -> bool {
        self.preview
            .as_ref()
            .is_some_and(|p| p.renderer.samples().saturating_add(helped) < p.stage_end)
    }

    /// Whether this thread's device has samples to trace.
    fn preview_tracing(&self, helped: u32) -> bool {
        self.preview_busy(helped) && self.preview.as_ref().is_some_and(|p| !p.exhausted)
    }

    fn frames_pending(&self) -> bool {
        self.frames.pending()
    }

    /// Whether the preview holds samples that no frame has shown yet (from its first look
    /// on; later frames may show a round in progress, as its rows land).
    fn unshown(&self, (helped, helper_paths): (u32, u64)) -> bool {
        self.preview.as_ref().is_some_and(|p| {
            (p.renderer.has_image() || helped > 0)
                && p.last_frame
                    .is_none_or(|(_, shown)| shown != p.paths + helper_paths)
        })
    }

    fn run(&mut self, rx: &Receiver<Request>) {
        loop {
            self.check_helpers();
            // Wait when there is nothing to do; otherwise take what has arrived.
            let mut requests = Vec::new();
            let progress = self.helper_progress();
            let idle = !self.preview_tracing(progress.0)
                && !self.frames_pending()
                && !self.unshown(progress)
                && self.save.is_none();
            if idle && self.preview_busy(progress.0) {
                // The other devices are still tracing: look at them again shortly.
                match rx.recv_timeout(HELPER_POLL) {
                    Ok(r) => requests.push(r),
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => return self.finish_save(),
                }
            } else if idle {
                match rx.recv() {
                    Ok(r) => requests.push(r),
                    Err(_) => return,
                }
            }
            loop {
                match rx.try_recv() {
                    Ok(r) => requests.push(r),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return self.finish_save(),
                }
            }
            // Of several scene updates only the last matters.
            let last_scene = requests
                .iter()
                .rposition(|r| matches!(r, Request::Scene { .. }));
            for (i, r) in requests.into_iter().enumerate() {
                match r {
                    Request::Scene { .. } if Some(i) != last_scene => {}
                    Request::Scene {
                        scene,
                        settings,
                        factor,
                        generation,
                    } => self.set_scene(Arc::from(scene), settings, factor, generation),
                    Request::Reset => self.reset(),
                    Request::Denoise(mode) => {
                        self.opts.denoise = mode;
                        // Show the change at once, even when the accumulation has stopped.
                        if let Some(p) = &mut self.preview {
                            p.last_frame = None;
                        }
                    }
                    Request::Save { scene, path } => self.start_save(&scene, path),
                    Request::Quit => return self.finish_save(),
                }
            }
            if self.preview_tracing(self.helper_progress().0)
                && let Some(p) = &mut self.preview
            {
                p.renderer.wait(QUEUED - 1);
                match p.renderer.submit(p.stage_end) {
                    Some(paths) => p.paths += paths,
                    None => p.exhausted = true,
                }
            }
            self.request_frame();
            if !self.deliver_frames() {
                return self.finish_save();
            }
            if self.save.is_some() {
                self.step_save();
            }
        }
    }

    fn set_scene(
        &mut self,
        scene: Arc<Scene>,
        settings: FrameSettings,
        factor: u32,
        generation: u64,
    ) {
        tracing::debug!("scene request {generation}");
        self.requested = Some((scene.clone(), settings, factor, generation));
        match &mut self.preview {
            Some(p) => {
                p.renderer.set_scene(&scene, settings);
                p.factor = factor;
            }
            None => {
                self.preview = Some(Preview {
                    renderer: Renderer::new(self.backend.clone(), &scene, settings, self.options()),
                    factor,
                    since_reset: Instant::now(),
                    paths: 0,
                    last_frame: None,
                    noise: None,
                    last_denoise: None,
                    last_combined: None,
                    exhausted: false,
                    stage_end: self.opts.max_spp,
                    reached: false,
                    helpers_told: false,
                })
            }
        }
        self.generation = generation;
        self.restart_clock();
    }

    fn reset(&mut self) {
        if let Some(p) = &mut self.preview {
            p.renderer.reset();
        }
        self.restart_clock();
    }

    /// After any restart of the accumulation; frames in flight show the old one and are
    /// dropped when they land.
    fn restart_clock(&mut self) {
        self.epoch += 1;
        self.frames.clear_extra();
        let first_end = stages::first_end(self.opts.target_error, self.opts.max_spp);
        if let Some(p) = &mut self.preview {
            p.stage_end = first_end;
            p.reached = false;
            p.since_reset = Instant::now();
            p.paths = 0;
            p.last_frame = None;
            p.noise = None;
            p.last_denoise = None;
            p.exhausted = false;
            p.helpers_told = false;
            p.last_combined = None;
            // On several devices: new claims, this device first to take from them (the
            // others start after the first frame: `tell_helpers`).
            if let Some(h) = &self.helpers {
                let claims = Arc::new(Claims::new(0..first_end, 1 + h.len()));
                #[cfg(test)]
                if let Some((device, when)) = self.fail {
                    claims.fail_when(device, when);
                }
                p.renderer.share(claims.clone(), 0);
                self.claims = Some(claims);
            }
        }
    }

    /// Takes out the other devices that failed, tells the UI, and has the devices left
    /// trace the samples they had claimed (given back to the claims).
    fn check_helpers(&mut self) {
        let Some(h) = &mut self.helpers else { return };
        let failed = h.take_failed();
        if failed.is_empty() {
            return;
        }
        for (device, why) in failed {
            tracing::warn!("{device} failed ({why}); the preview goes on without it");
            let _ = self.events.send(Event::DeviceLost(format!(
                "{device} failed ({why}); the other devices trace its samples"
            )));
        }
        h.resume(self.epoch);
        // Its sums are left out of the frames from now on.
        self.frames.clear_extra();
        if let Some(p) = &mut self.preview {
            p.exhausted = false;
        }
    }

    /// Sets the other devices tracing the current state, once.
    fn tell_helpers(&mut self) {
        let (Some(p), Some(h), Some((scene, ..)), Some(claims)) = (
            &mut self.preview,
            &self.helpers,
            &self.requested,
            &self.claims,
        ) else {
            return;
        };
        if !p.helpers_told {
            h.trace(scene, p.renderer.settings(), claims, self.epoch);
            p.helpers_told = true;
        }
    }

    /// Requests a frame when one is due: the first of a new state as soon as its first
    /// round is queued, later ones at the frame rate, and a last one when tracing stops.
    fn request_frame(&mut self) {
        let interval = self.frame_interval();
        let progress = self.helper_progress();
        let (helped, helper_paths) = progress;
        let busy = self.preview_busy(helped);
        let unshown = self.unshown(progress);
        let Some(p) = &mut self.preview else { return };
        let spp = p.renderer.samples() + helped;
        let due = match p.last_frame {
            _ if !unshown => false,
            None => true,
            Some(_) if !busy => true,
            Some((at, _)) => at.elapsed() >= interval,
        };
        if !due {
            return;
        }
        let shown = p.paths + helper_paths;
        let tag = FrameTag {
            generation: self.generation,
            epoch: self.epoch,
            last: !busy,
            spp,
            helped,
            paths: shown,
        };
        // Denoised frames need a sample in each half of every pixel; once the accumulation
        // stops (`--max-spp`, the target error), `auto` shows the final, unbiased image. A
        // stage's end that may be followed by another is not the end.
        let staged =
            self.opts.target_error.is_some() && !p.reached && p.stage_end < self.opts.max_spp;
        let denoise = self.opts.denoise.wants(p.noise)
            && spp >= 2
            && (busy || staged || self.opts.denoise == crate::denoise::Mode::On);
        if denoise
            && let Some((at, took)) = p.last_denoise
            && busy
            && at.elapsed() < 3 * took
        {
            return;
        }
        // On several devices, once another has published: every device's sums added (by the
        // GPU's resolve pass, after an upload, or on the host); such frames are spaced so that
        // making them takes at most a quarter of the time (at a large size the upload or the
        // host's work costs more than the tracer's submissions).
        if helper_paths > 0
            && busy
            && let Some((at, took)) = p.last_combined
            && at.elapsed() < 3 * took
        {
            return;
        }
        let combining = Instant::now();
        let parts = self
            .helpers
            .as_ref()
            .map_or(Vec::new(), |h| h.contributions(self.epoch));
        let combined = !parts.is_empty();
        if denoise {
            // The guides are made once per edit: not part of a frame's cost.
            p.renderer.make_guides();
        }
        let start = Instant::now();
        let requested = self
            .frames
            .request(&mut p.renderer, &parts, denoise, p.factor, tag);
        #[cfg(test)]
        if requested.uploaded
            && let Some(c) = &self.claims
        {
            c.note_upload();
        }
        if !requested.made {
            return;
        }
        if denoise {
            p.last_denoise = Some((Instant::now(), start.elapsed()));
        }
        if combined {
            p.last_combined = Some((Instant::now(), combining.elapsed()));
            tracing::debug!(
                "frame of every device's sums made in {:.1} ms",
                combining.elapsed().as_secs_f64() * 1e3
            );
        }
        tracing::debug!(
            "frame requested at {spp} spp, {:.1} ms after the reset",
            p.since_reset.elapsed().as_secs_f64() * 1e3
        );
        p.last_frame = Some((Instant::now(), shown));
        self.tell_helpers();
    }

    /// Sends every frame that has landed; false when the UI has gone.
    fn deliver_frames(&mut self) -> bool {
        if !self.frames_pending() {
            return true;
        }
        if let Some((tag, resolved)) = self.frames.take_host()
            && !self.send_frame(tag, resolved)
        {
            return false;
        }
        // Nothing else to do: wait for the frame rather than spin.
        let block = !self.preview_busy(self.helper_progress().0) && self.save.is_none();
        self.frames
            .take_landed(block)
            .into_iter()
            .all(|(tag, resolved)| self.send_frame(tag, resolved))
    }

    /// Sends a frame of the current state (one of an older epoch is dropped); false when the
    /// UI has gone.
    fn send_frame(&mut self, tag: FrameTag, resolved: Resolved) -> bool {
        let Some(p) = &mut self.preview else {
            return true;
        };
        if tag.epoch != self.epoch {
            return true;
        }
        p.noise = resolved.noise.or(p.noise);
        // The end of a stage (`--target-error`): stop there, or trace on to the next.
        let mut last = tag.last;
        if let Some(target) = self.opts.target_error
            && tag.last
            && !p.reached
            && tag.spp >= p.stage_end
        {
            match stages::next(p.stage_end, p.noise, target, self.opts.max_spp) {
                stages::Next::Reached => {
                    tracing::debug!("target error reached at {} spp", p.stage_end);
                    p.reached = true;
                    // A denoised frame was not the final one (`auto` ends on the raw image):
                    // one more frame of the same samples is.
                    if resolved.denoised.is_some() && self.opts.denoise != crate::denoise::Mode::On
                    {
                        last = false;
                        p.last_frame = None;
                    }
                }
                stages::Next::Exhausted => {}
                stages::Next::To(end) => {
                    tracing::debug!("at {} spp, the next stage ends at {end}", p.stage_end);
                    p.stage_end = end;
                    p.exhausted = false;
                    last = false;
                    if let Some(c) = &self.claims {
                        c.extend(end);
                    }
                    if let Some(h) = &self.helpers {
                        h.resume(self.epoch);
                    }
                }
            }
        }
        let elapsed = p.since_reset.elapsed();
        tracing::debug!(
            "frame at {} spp delivered {:.1} ms after the reset ({} by the other devices)",
            tag.spp,
            elapsed.as_secs_f64() * 1e3,
            tag.helped
        );
        let s = p.renderer.settings();
        let frame = Frame {
            image: resolved.image,
            sigma: resolved.sigma,
            last,
            stats: Stats {
                width: s.width,
                height: s.height,
                spp: tag.spp,
                samples_per_second: tag.paths as f64 / elapsed.as_secs_f64().max(1e-9),
                elapsed,
                noise: resolved.noise,
                denoised: resolved.denoised,
                doubt: resolved.doubt,
                invalid: resolved.invalid,
                helped: tag.helped,
                reached: p.reached && last,
            },
            generation: tag.generation,
        };
        self.events.send(Event::Frame(Box::new(frame))).is_ok()
    }

    fn start_save(&mut self, scene: &Scene, path: PathBuf) {
        let settings = FrameSettings::new(
            scene.render.width,
            scene.render.height,
            scene.render.max_bounces,
            scene.render.seed,
        );
        let options = RenderOptions {
            submission: SAVE_SLICE,
            first_look: false,
            ..self.options()
        };
        self.save = Some(SaveJob {
            renderer: Renderer::new(self.backend.clone(), scene, settings, options),
            path,
            total: scene.render.spp,
        });
    }

    fn step_save(&mut self) {
        let Some(job) = &mut self.save else { return };
        job.renderer.step(SAVE_SLICE, job.total);
        let done = job.renderer.samples();
        let _ = self.events.send(Event::SaveProgress {
            done,
            total: job.total,
        });
        if done >= job.total {
            let job = self.save.take().expect("a save job");
            let image = job.renderer.snapshot().image();
            let events = self.events.clone();
            // Encoding a large PNG takes a while: not on the render thread.
            std::thread::spawn(move || {
                let result = write_png(&job.path, &image, Transfer::Srgb, false)
                    .map(|()| format!("saved {} ({} spp)", job.path.display(), job.total))
                    .map_err(|e| SaveError(e.to_string()));
                let _ = events.send(Event::Saved(result));
            });
        }
    }

    /// On quit: a save in progress writes what it has accumulated, so nothing is lost.
    fn finish_save(&mut self) {
        let Some(job) = self.save.take() else { return };
        let done = job.renderer.samples();
        if done == 0 {
            return;
        }
        let image = job.renderer.snapshot().image();
        let result = write_png(&job.path, &image, Transfer::Srgb, false)
            .map(|()| {
                format!(
                    "saved {} with {done} of {} spp (quit before it finished)",
                    job.path.display(),
                    job.total
                )
            })
            .map_err(|e| SaveError(e.to_string()));
        let _ = self.events.send(Event::Saved(result));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::LinearImage;

    /// Runs a preview of cornell at `size` to `max_spp` on `backends`, with `edits` scene
    /// requests sent after the first frame (the last one counts), and returns its final
    /// frame's image and spp.
    fn final_frame(backends: Vec<Backend>, max_spp: u32, edits: &[Scene]) -> (LinearImage, Stats) {
        let off = crate::denoise::Mode::Off;
        let run = frames(backends, (64, 48), max_spp, edits, off, None);
        assert!(run.lost.is_empty(), "{:?}", run.lost);
        (run.image, run.stats)
    }

    /// What a preview run ended on, and what it showed and said on the way.
    struct Run {
        image: LinearImage,
        stats: Stats,
        /// Some frame with samples of the other devices in it was denoised.
        denoised_helped: bool,
        /// What the UI was told of devices lost.
        lost: Vec<String>,
    }

    /// As `final_frame`, in denoiser `mode`, with device `fail.0` failing at `fail.1` in
    /// every state.
    fn frames(
        backends: Vec<Backend>,
        size: (u32, u32),
        max_spp: u32,
        edits: &[Scene],
        denoise: crate::denoise::Mode,
        fail: Option<(usize, Fail)>,
    ) -> Run {
        let opts = WorkerOptions {
            fps: 30.0,
            max_spp,
            target_error: None,
            generic: false,
            denoise,
        };
        frames_with(backends, size, opts, edits, fail)
    }

    /// As `frames`, with the worker's options `opts`.
    fn frames_with(
        backends: Vec<Backend>,
        size: (u32, u32),
        opts: WorkerOptions,
        edits: &[Scene],
        fail: Option<(usize, Fail)>,
    ) -> Run {
        let scene = Scene::load("cornell").unwrap();
        let settings = FrameSettings::new(size.0, size.1, scene.render.max_bounces, 1);
        let (events, rx) = std::sync::mpsc::channel();
        let (tx, handle) = spawn_failing(backends, opts, events, fail);
        let mut generation = 1;
        let send = |scene: &Scene, generation| {
            tx.send(Request::Scene {
                scene: Box::new(scene.clone()),
                settings,
                factor: 1,
                generation,
            })
            .unwrap();
        };
        send(&scene, generation);
        let mut edits = edits.iter();
        let mut denoised_helped = false;
        let mut lost = Vec::new();
        let last = loop {
            let f = match rx.recv_timeout(Duration::from_secs(120)).expect("a frame") {
                Event::Frame(f) => f,
                Event::DeviceLost(m) => {
                    lost.push(m);
                    continue;
                }
                _ => continue,
            };
            if f.generation != generation {
                continue;
            }
            denoised_helped |= f.stats.denoised.is_some() && f.stats.helped > 0;
            if let Some(e) = edits.next() {
                generation += 1;
                send(e, generation);
                continue;
            }
            if f.last {
                break f;
            }
        };
        tx.send(Request::Quit).unwrap();
        handle.join().unwrap();
        Run {
            image: last.image,
            stats: last.stats,
            denoised_helped,
            lost,
        }
    }

    #[test]
    fn a_preview_with_a_target_error_stops_near_it() {
        // cornell at 64×48 reaches a 10 % estimate near 100 spp (16 000 at most). The stages
        // (`render::stages`) end where the estimate should reach the target, each at most
        // twice the last: the estimate the preview stops at is at or below the target, and
        // not far below (a stage that overshot ten times in samples would read about 0.3 of
        // it; 0.5 leaves room for the estimate's own noise). On one device, on two sharing
        // the claims (extended stage by stage), and after an edit, which starts over.
        let target = 0.10;
        let mut edited = Scene::load("cornell").unwrap();
        edited.camera.vfov += 5.0;
        for backends in [vec![Backend::Cpu], vec![Backend::Cpu, Backend::Cpu]] {
            for denoise in [crate::denoise::Mode::Off, crate::denoise::Mode::Auto] {
                let opts = WorkerOptions {
                    fps: 30.0,
                    max_spp: 16_000,
                    target_error: Some(target),
                    generic: false,
                    denoise,
                };
                let edits = std::slice::from_ref(&edited);
                let run = frames_with(backends.clone(), (64, 48), opts, edits, None);
                let s = run.stats;
                let noise = s.noise.expect("an estimate");
                let what = format!(
                    "{} devices, {denoise:?}: {noise} at {} spp",
                    backends.len(),
                    s.spp
                );
                eprintln!("{what}");
                assert!(s.reached, "{what}: not reached");
                assert!(noise <= target && noise >= 0.5 * target, "{what}");
                assert!(s.spp > 4 && s.spp < 1000, "{what}");
                // The final frame is the raw image, as at --max-spp.
                assert!(s.denoised.is_none(), "{what}: the final frame is denoised");
            }
        }
    }

    #[test]
    fn a_preview_on_two_devices_ends_on_one_devices_image() {
        // Two CPU tracers compute alike: the frames made from both devices' sums added end on
        // the image one device makes, bit for bit, also after an edit that restarts the
        // shared claims mid-way. 128 spp at 64×48 (a third of a second on 2 cores), so that
        // the second device is running before the first has traced them all.
        let mut edited = Scene::load("cornell").unwrap();
        edited.camera.vfov += 5.0;
        let (one, stats) = final_frame(vec![Backend::Cpu], 128, std::slice::from_ref(&edited));
        assert_eq!((stats.spp, stats.helped), (128, 0));
        let (two, stats) = final_frame(vec![Backend::Cpu, Backend::Cpu], 128, &[edited.clone()]);
        assert_eq!(stats.spp, 128);
        assert!(
            (1..128).contains(&stats.helped),
            "both devices traced: {} of 128 spp by the second",
            stats.helped
        );
        assert_eq!(one.pixels, two.pixels);
        let (unedited, _) = final_frame(vec![Backend::Cpu], 128, &[]);
        assert_ne!(one.pixels, unedited.pixels, "the edit shows");
    }

    #[test]
    fn a_gpu_and_the_cpu_tracer_share_a_preview() {
        // A GPU (the software adapter) makes the frames, the CPU tracer helps: their sums are
        // added by the GPU's resolve pass, or on the host for denoised frames, and the
        // preview ends at its samples.
        let gpu = Backend::open(Some("vulkan")).expect(
            "the software adapter (lavapipe): apt-get install mesa-vulkan-drivers libvulkan1",
        );
        for mode in [crate::denoise::Mode::Off, crate::denoise::Mode::On] {
            let run = frames(
                vec![gpu.clone(), Backend::Cpu],
                (24, 16),
                24,
                &[],
                mode,
                None,
            );
            let (image, stats) = (run.image, run.stats);
            assert!(run.lost.is_empty(), "{:?}", run.lost);
            assert_eq!(stats.spp, 24);
            assert!(
                (1..24).contains(&stats.helped),
                "{} spp helped",
                stats.helped
            );
            assert_eq!(run.denoised_helped, mode == crate::denoise::Mode::On);
            assert!(image.pixels.iter().flatten().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn a_device_lost_mid_preview_leaves_the_image_whole() {
        // Two CPU tracers, the second failing at its second claim (its renderer panics, as
        // one waiting on a lost GPU does), with an edit after the first frame: the UI is
        // told, the first device traces what the second had claimed, and the preview still
        // ends on one device's image, bit for bit.
        let mut edited = Scene::load("cornell").unwrap();
        edited.camera.vfov += 5.0;
        // 512 spp, so that the second device asks for its second claim before the first has
        // claimed them all.
        let (one, _) = final_frame(vec![Backend::Cpu], 512, std::slice::from_ref(&edited));
        let off = crate::denoise::Mode::Off;
        let two = vec![Backend::Cpu, Backend::Cpu];
        let edits = [edited.clone()];
        let fail = Some((1, Fail::After(1)));
        let Run {
            image, stats, lost, ..
        } = frames(two, (64, 48), 512, &edits, off, fail);
        assert_eq!(
            (stats.spp, stats.helped),
            (512, 0),
            "the first device traced all"
        );
        assert_eq!(lost.len(), 1, "{lost:?}");
        assert!(lost[0].contains("injected"), "{}", lost[0]);
        assert_eq!(image.pixels, one.pixels);
    }

    #[test]
    fn the_first_device_lost_mid_preview_hands_the_preview_over() {
        // Two CPU tracers, the first (the one making the frames) failing at its second claim,
        // and at its first (before any frame, the others not started yet): the UI is told
        // once, and the preview starts over on the second device from the state it was
        // tracing, and ends on one device's image, bit for bit.
        let (one, _) = final_frame(vec![Backend::Cpu], 256, &[]);
        let off = crate::denoise::Mode::Off;
        for after in [1, 0] {
            let two = vec![Backend::Cpu, Backend::Cpu];
            let fail = Some((0, Fail::After(after)));
            let Run {
                image, stats, lost, ..
            } = frames(two, (64, 48), 256, &[], off, fail);
            assert_eq!((stats.spp, stats.helped), (256, 0));
            assert_eq!(lost.len(), 1, "{lost:?}");
            assert!(lost[0].contains("starts over"), "{}", lost[0]);
            assert_eq!(image.pixels, one.pixels);
        }
    }

    #[test]
    fn a_helper_lost_after_its_sums_reached_the_gpu_is_left_out() {
        // The software adapter makes the frames, the CPU tracer helps and fails at its first
        // claim after the render thread uploaded its sums to the resolve pass: those sums
        // must be dropped there (`clear_extra`), or every later frame would add them to
        // samples the adapter traced again. The image is the adapter's alone, bit for bit.
        // 24×16 pixels at 384 spp: the helper is still claiming when its sums are first
        // uploaded (a frame interval after it starts).
        let gpu = Backend::open(Some("vulkan")).expect(
            "the software adapter (lavapipe): apt-get install mesa-vulkan-drivers libvulkan1",
        );
        let off = crate::denoise::Mode::Off;
        let (size, spp) = ((24, 16), 384);
        let alone = frames(vec![gpu.clone()], size, spp, &[], off, None).image;
        let fail = Some((1, Fail::AfterUpload));
        let Run {
            image, stats, lost, ..
        } = frames(vec![gpu, Backend::Cpu], size, spp, &[], off, fail);
        assert_eq!((stats.spp, stats.helped), (spp, 0));
        assert_eq!(lost.len(), 1, "{lost:?}");
        let differ = (image.pixels.iter().zip(&alone.pixels)).filter(|(a, b)| a != b);
        let differ = differ.count();
        assert_eq!(
            differ,
            0,
            "{differ} of {} pixels differ",
            alone.pixels.len()
        );
    }
}
