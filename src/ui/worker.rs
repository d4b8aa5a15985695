//! The render thread: owns the GPU, traces the preview a frame's time at a time, and renders
//! PNGs in the background on the same device, interleaved with the preview.

use super::Event;
use super::app::Stats;
use crate::gpu::{FrameSettings, GpuContext};
use crate::output::{LinearImage, Transfer, write_png};
use crate::render::{RenderOptions, Renderer};
use crate::scene::Scene;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Share of a frame spent tracing.
const TRACE_SHARE: f64 = 0.6;

/// What the UI asks of the render thread.
pub enum Request {
    /// Render this scene at these settings from now on (restarts the accumulation).
    Scene {
        scene: Box<Scene>,
        settings: FrameSettings,
        generation: u64,
    },
    /// Restart the accumulation.
    Reset,
    /// Render `scene` at its own resolution and spp in the background, then write `path`.
    Save { scene: Box<Scene>, path: PathBuf },
    /// Stop; a background save in progress writes what it has.
    Quit,
}

/// One preview frame.
pub struct Frame {
    pub image: LinearImage,
    pub stats: Stats,
    /// The `Request::Scene` this frame renders.
    pub generation: u64,
}

#[derive(Clone, Copy, Debug)]
pub struct WorkerOptions {
    pub fps: f64,
    /// The preview stops accumulating here (and the GPU idles).
    pub max_spp: u32,
    pub generic: bool,
}

struct SaveJob {
    renderer: Renderer,
    path: PathBuf,
    total: u32,
}

struct Worker {
    ctx: Arc<GpuContext>,
    opts: WorkerOptions,
    events: Sender<Event>,
    preview: Option<Renderer>,
    generation: u64,
    since_reset: Instant,
    paths: u64,
    save: Option<SaveJob>,
}

/// Starts the render thread; it ends on `Request::Quit` or when either channel closes.
pub fn spawn(
    ctx: Arc<GpuContext>,
    opts: WorkerOptions,
    events: Sender<Event>,
) -> (Sender<Request>, JoinHandle<()>) {
    let (tx, rx) = std::sync::mpsc::channel();
    let handle = std::thread::Builder::new()
        .name("render".into())
        .spawn(move || {
            let mut w = Worker {
                ctx,
                opts,
                events,
                preview: None,
                generation: 0,
                since_reset: Instant::now(),
                paths: 0,
                save: None,
            };
            w.run(rx);
        })
        .expect("spawn the render thread");
    (tx, handle)
}

impl Worker {
    /// Tracing time per preview frame: most of a frame, leaving room for the readback and
    /// the encoding so that frames keep up with `--fps`.
    fn frame_time(&self) -> Duration {
        Duration::from_secs_f64(TRACE_SHARE / self.opts.fps.max(1.0))
    }

    fn options(&self) -> RenderOptions {
        RenderOptions {
            generic: self.opts.generic,
            submission: self.frame_time(),
            compile_in_background: true,
            ..Default::default()
        }
    }

    fn preview_busy(&self) -> bool {
        self.preview
            .as_ref()
            .is_some_and(|r| r.samples() < self.opts.max_spp)
    }

    fn run(&mut self, rx: Receiver<Request>) {
        loop {
            // Wait when there is nothing to trace; otherwise take what has arrived.
            let mut requests = Vec::new();
            if !self.preview_busy() && self.save.is_none() {
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
                        generation,
                    } => self.set_scene(&scene, settings, generation),
                    Request::Reset => {
                        if let Some(p) = &mut self.preview {
                            p.reset();
                        }
                        self.since_reset = Instant::now();
                        self.paths = 0;
                    }
                    Request::Save { scene, path } => self.start_save(&scene, path),
                    Request::Quit => return self.finish_save(),
                }
            }
            let budget = if self.save.is_some() {
                self.frame_time() / 2
            } else {
                self.frame_time()
            };
            if self.preview_busy() && !self.step_preview(budget) {
                return self.finish_save();
            }
            if self.save.is_some() {
                self.step_save(budget);
            }
        }
    }

    fn set_scene(&mut self, scene: &Scene, settings: FrameSettings, generation: u64) {
        match &mut self.preview {
            Some(r) => r.set_scene(scene, settings),
            None => {
                self.preview = Some(Renderer::new(
                    self.ctx.clone(),
                    scene,
                    settings,
                    self.options(),
                ))
            }
        }
        self.generation = generation;
        self.since_reset = Instant::now();
        self.paths = 0;
    }

    /// Traces for `budget` and sends the frame; false when the UI has gone.
    fn step_preview(&mut self, budget: Duration) -> bool {
        let Some(r) = &mut self.preview else {
            return true;
        };
        self.paths += r.step(budget, self.opts.max_spp).paths;
        let snap = r.snapshot();
        let elapsed = self.since_reset.elapsed();
        let s = r.settings();
        let frame = Frame {
            image: snap.image(),
            stats: Stats {
                width: s.width,
                height: s.height,
                spp: r.samples(),
                samples_per_second: self.paths as f64 / elapsed.as_secs_f64().max(1e-9),
                elapsed,
                noise: snap.noise_estimate(),
                invalid: snap.invalid_samples(),
            },
            generation: self.generation,
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
            submission: self.frame_time() / 2,
            ..self.options()
        };
        self.save = Some(SaveJob {
            renderer: Renderer::new(self.ctx.clone(), scene, settings, options),
            path,
            total: scene.render.spp,
        });
    }

    fn step_save(&mut self, budget: Duration) {
        let Some(job) = &mut self.save else { return };
        job.renderer.step(budget, job.total);
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
                    .map_err(|e| e.to_string());
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
            .map_err(|e| e.to_string());
        let _ = self.events.send(Event::Saved(result));
    }
}
