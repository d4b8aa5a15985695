//! The progressive renderer: owns the GPU passes and buffers of one scene, advances the
//! accumulation in watchdog-safe submissions, and resets it on any change (the lecture's
//! `should_accumulate`).

mod schedule;
mod snapshot;

pub use schedule::Schedule;
pub use snapshot::{ErrorEstimate, REL_MSE_EPSILON, Snapshot};

use crate::gpu::layout::DispatchUniforms;
use crate::gpu::timer::GpuTimer;
use crate::gpu::trace::TraceDispatch;
use crate::gpu::{Accumulation, Features, FrameSettings, GpuContext, SceneBuffers, TracePass};
use crate::scene::Scene;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How a renderer specializes and sizes its work.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    /// Use the generic pipeline instead of one specialized for the scene.
    pub generic: bool,
    /// Count path segments (for benchmarks).
    pub count_segments: bool,
    /// Test every primitive instead of walking the BVH (tests, scaling benchmarks).
    pub no_bvh: bool,
    /// Time every pass on the GPU (timestamp queries, where the adapter has them).
    pub gpu_timing: bool,
    /// Wall time one submission should take.
    pub submission: Duration,
    /// Never wait for a new pipeline: trace with the generic one (same image) while the
    /// specialized one compiles in the background (the live preview).
    pub compile_in_background: bool,
    /// Features compiled in beyond what the scene needs (benchmarks of one feature's cost).
    pub extra: Option<Features>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            generic: false,
            count_segments: false,
            no_bvh: false,
            gpu_timing: false,
            submission: Duration::from_millis(100),
            compile_in_background: false,
            extra: None,
        }
    }
}

/// What one call of [`Renderer::step`] did.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepStats {
    /// Paths traced (pixels × samples).
    pub paths: u64,
    pub submissions: u32,
    pub elapsed: Duration,
    /// Time the passes took on the GPU, when timed.
    pub gpu_seconds: f64,
}

/// Where the current round is: samples `[base, base + k)` of rows below `next_row` are done.
#[derive(Clone, Copy, Debug, Default)]
struct Round {
    k: u32,
    next_row: u32,
}

pub struct Renderer {
    ctx: Arc<GpuContext>,
    trace: TracePass,
    scene: SceneBuffers,
    accum: Accumulation,
    bind_group: wgpu::BindGroup,
    settings: FrameSettings,
    options: RenderOptions,
    features: Features,
    schedule: Schedule,
    /// Samples per pixel of every completed round since the last reset.
    samples: u32,
    round: Option<Round>,
    /// The next round restarts the sums (`should_accumulate = 0`).
    fresh: bool,
    timer: Option<GpuTimer>,
}

impl Renderer {
    pub fn new(
        ctx: Arc<GpuContext>,
        scene: &Scene,
        settings: FrameSettings,
        options: RenderOptions,
    ) -> Renderer {
        let device = &ctx.device;
        let mut trace = TracePass::new(device);
        let features = Self::features_for(scene, &options, &settings);
        trace.prepare(device, features);
        if options.compile_in_background {
            // The fallback for the feature sets edits will introduce.
            let generic = Features {
                count_segments: options.count_segments,
                bvh: !options.no_bvh,
                ..Features::generic()
            };
            trace.prepare_in_background(device, generic);
        }
        let buffers = SceneBuffers::new(device, scene, &settings);
        let accum = Accumulation::new(device, settings.width, settings.height);
        let bind_group = trace.bind_group(device, &buffers, &accum);
        accum.reset_counters(&ctx.queue);
        let timer = if options.gpu_timing {
            GpuTimer::new(&ctx)
        } else {
            None
        };
        Renderer {
            timer,
            trace,
            scene: buffers,
            accum,
            bind_group,
            settings,
            options,
            features,
            schedule: Schedule::new(options.submission),
            samples: 0,
            round: None,
            fresh: true,
            ctx,
        }
    }

    fn features_for(scene: &Scene, o: &RenderOptions, s: &FrameSettings) -> Features {
        let mut f = if o.generic {
            Features::generic()
        } else {
            Features::of(scene)
        };
        f.nee &= s.nee || o.generic;
        if let Some(extra) = o.extra {
            f = f.union(extra);
        }
        f.count_segments = o.count_segments;
        f.bvh = !o.no_bvh;
        f
    }

    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }
    pub fn settings(&self) -> FrameSettings {
        self.settings
    }
    pub fn features(&self) -> Features {
        self.features
    }
    /// Samples per pixel of every completed round since the last reset.
    pub fn samples(&self) -> u32 {
        self.samples
    }
    /// Whether passes are timed on the GPU.
    pub fn gpu_timed(&self) -> bool {
        self.timer.is_some()
    }

    /// Nodes in the BVH and the seconds its last build took.
    pub fn bvh_stats(&self) -> (usize, f64) {
        (self.scene.node_count, self.scene.build_seconds)
    }

    /// GPU memory held by the accumulation.
    pub fn accumulation_bytes(&self) -> u64 {
        self.accum.gpu_bytes()
    }

    /// Starts the accumulation afresh on the next submission.
    pub fn reset(&mut self) {
        self.samples = 0;
        self.round = None;
        self.fresh = true;
        self.accum.reset_counters(&self.ctx.queue);
    }

    /// The generic pipeline with this renderer's own switches (segment counting, BVH).
    fn generic_features(&self) -> Features {
        Features {
            count_segments: self.options.count_segments,
            bvh: !self.options.no_bvh,
            ..Features::generic()
        }
    }

    /// The pipeline the next submission uses: the scene's own when compiled, else (when
    /// compiling in the background) the generic one, which renders the same image.
    fn pipeline_features(&mut self) -> Features {
        if self.trace.ready(self.features) {
            return self.features;
        }
        let generic = self.generic_features();
        if self.options.compile_in_background && self.trace.ready(generic) {
            return generic;
        }
        self.trace.prepare(&self.ctx.device, self.features);
        self.features
    }

    /// Replaces the scene (and settings); resizes the accumulation if needed; resets.
    pub fn set_scene(&mut self, scene: &Scene, settings: FrameSettings) {
        let device = &self.ctx.device;
        self.features = Self::features_for(scene, &self.options, &settings);
        if self.options.compile_in_background {
            self.trace.prepare_in_background(device, self.features);
        } else {
            self.trace.prepare(device, self.features);
        }
        let mut rebind = self.scene.update(device, &self.ctx.queue, scene, &settings);
        if (settings.width, settings.height) != (self.settings.width, self.settings.height) {
            self.accum = Accumulation::new(device, settings.width, settings.height);
            rebind = true;
        }
        self.settings = settings;
        if rebind {
            self.bind_group = self.trace.bind_group(device, &self.scene, &self.accum);
        }
        self.reset();
    }

    /// Traces for about `budget` (at least one submission), never past `max_samples` per
    /// pixel. Returns what was done; `samples()` advances when a round completes.
    pub fn step(&mut self, budget: Duration, max_samples: u32) -> StepStats {
        let start = Instant::now();
        let mut stats = StepStats::default();
        let (w, h) = (self.settings.width, self.settings.height);
        let features = self.pipeline_features();
        while self.samples < max_samples {
            let round = match self.round {
                Some(r) => r,
                None => Round {
                    k: self
                        .schedule
                        .samples_per_round(w, h, max_samples - self.samples),
                    next_row: 0,
                },
            };
            let rows = self.schedule.rows(w, round.k, h - round.next_row);
            let d = DispatchUniforms {
                sample_base: self.samples,
                sample_count: round.k,
                row_offset: round.next_row,
                row_count: rows,
                accumulate: u32::from(!self.fresh),
                _pad: [0; 3],
            };
            let t = Instant::now();
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("trace.submission"),
                });
            self.trace.encode(
                &self.ctx.queue,
                &mut enc,
                &TraceDispatch {
                    features,
                    bind_group: &self.bind_group,
                    width: w,
                    uniforms: d,
                    timer: self.timer.as_ref(),
                },
            );
            if let Some(t) = &self.timer {
                t.resolve(&mut enc);
            }
            self.ctx.queue.submit([enc.finish()]);
            self.ctx
                .device
                .poll(wgpu::PollType::wait_indefinitely())
                .expect("the GPU stopped answering");
            if let Some(t) = &self.timer {
                stats.gpu_seconds += t.read_seconds(&self.ctx);
            }
            let paths = w as u64 * rows as u64 * round.k as u64;
            self.schedule.observe(paths, t.elapsed());
            stats.paths += paths;
            stats.submissions += 1;
            let next_row = round.next_row + rows;
            if next_row >= h {
                self.samples += round.k;
                self.round = None;
                self.fresh = false;
            } else {
                self.round = Some(Round {
                    k: round.k,
                    next_row,
                });
            }
            if start.elapsed() >= budget {
                break;
            }
        }
        stats.elapsed = start.elapsed();
        stats
    }

    /// Renders until every pixel has `spp` samples.
    pub fn render_spp(&mut self, spp: u32) {
        while self.samples < spp {
            self.step(Duration::from_secs(1), spp);
        }
    }

    /// Reads the accumulation back.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            width: self.settings.width,
            height: self.settings.height,
            data: self.accum.read(&self.ctx),
            samples: self.samples,
        }
    }
}
