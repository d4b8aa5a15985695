//! The progressive renderer: owns the GPU passes and buffers of one scene, advances the
//! accumulation in watchdog-safe submissions, and resets it on any change (the lecture's
//! `should_accumulate`).
//!
//! Submissions are pipelined: [`Renderer::submit`] queues one and returns at once, and
//! [`Renderer::wait`] lets at most a given number stay in flight, so the GPU has the next
//! one before it finishes the last. A small image fills the GPU by tracing several samples
//! of each pixel in parallel ("lanes", see `fn trace` in trace.wgsl), whose exact
//! fixed-point sums the reduce pass adds up: the image is the same bit for bit.

mod schedule;
mod snapshot;
pub mod tune;

pub use schedule::Schedule;
pub use snapshot::{ErrorEstimate, REL_MSE_EPSILON, Snapshot};

use crate::gpu::layout::DispatchUniforms;
use crate::gpu::reduce::ReducePass;
use crate::gpu::timer::GpuTimer;
use crate::gpu::trace::TraceDispatch;
use crate::gpu::{Accumulation, Features, FrameSettings, GpuContext, SceneBuffers, TracePass};
use crate::scene::Scene;
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Invocations a dispatch should have to fill a large GPU: an H100/H200 holds about 270 000
/// resident threads (132 SMs × 2048); twice that evens out the paths' unequal lengths.
/// Lanes are added until a submission has about this many.
pub const LANE_INVOCATIONS: u64 = 1 << 19;

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
    /// Samples of a pixel traced in parallel, at most: `None` chooses by the adapter (on a
    /// GPU enough lanes to fill it, see [`LANE_INVOCATIONS`]; on a CPU adapter, whose few
    /// cores a small image already fills, one); `Some(n)` uses up to `n` (tests).
    pub lanes: Option<u32>,
    /// The first round after a reset traces the even rows, then the odd ones, so that a
    /// first image (every other row, the rows between filled in for display) exists in half
    /// the time of a whole sample per pixel (the preview on a slow adapter).
    pub first_look: bool,
    /// Always trace with the scene's specialized pipeline, never measure it against the
    /// generic one (`tune`); tests that compare the two use it.
    pub no_tune: bool,
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
            lanes: None,
            first_look: false,
            no_tune: false,
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
    /// 1: submissions take contiguous rows from `next_row` on; n > 1: each takes every n-th
    /// row from `next_row` (the first look), and the round ends when `next_row` reaches n.
    stride: u32,
}

/// A submission the GPU has not finished.
struct InFlight {
    index: wgpu::SubmissionIndex,
    features: Features,
    paths: u64,
    submitted: Instant,
}

pub struct Renderer {
    ctx: Arc<GpuContext>,
    trace: TracePass,
    scene: SceneBuffers,
    accum: Accumulation,
    bind_group: wgpu::BindGroup,
    reduce: ReducePass,
    reduce_bind_group: wgpu::BindGroup,
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
    in_flight: VecDeque<InFlight>,
    /// Timing the specialized pipeline against the generic one, until one is chosen.
    tune: Option<tune::Tune>,
    /// When the GPU last finished a submission (as seen by `wait`).
    last_done: Instant,
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
        let accum = Accumulation::new(
            device,
            settings.width,
            settings.height,
            Self::scratch_slots(&ctx, &options, &settings),
        );
        let bind_group = trace.bind_group(device, &buffers, &accum);
        let reduce = ReducePass::new(device);
        let reduce_bind_group =
            reduce.bind_group(device, &buffers, trace.dispatch_buffer(), &accum);
        accum.reset_counters(&ctx.queue);
        let timer = if options.gpu_timing {
            GpuTimer::new(&ctx)
        } else {
            None
        };
        let mut r = Renderer {
            timer,
            trace,
            scene: buffers,
            accum,
            bind_group,
            reduce,
            reduce_bind_group,
            settings,
            options,
            features,
            schedule: Schedule::new(options.submission),
            samples: 0,
            round: None,
            fresh: true,
            ctx,
            in_flight: VecDeque::new(),
            tune: None,
            last_done: Instant::now(),
        };
        r.retune();
        r
    }

    /// Starts timing the specialized pipeline against the generic one, where they differ.
    fn retune(&mut self) {
        let generic = self.generic_features();
        self.tune = (!self.options.generic
            && !self.options.no_tune
            && self.options.extra.is_none()
            && self.features != generic)
            .then(|| tune::Tune::new(self.features, generic));
    }

    /// The tuner's outcome: the pipeline chosen and the seconds per path measured of the
    /// (specialized, generic) ones; `None` while measuring or when there was no choice.
    pub fn tuned(&self) -> Option<(Features, (f64, f64))> {
        let t = self.tune.as_ref()?;
        Some((t.chosen()?, t.measured()))
    }

    /// Lane-pixels of scratch: none where one lane per pixel is all a dispatch needs.
    fn scratch_slots(ctx: &GpuContext, o: &RenderOptions, s: &FrameSettings) -> u64 {
        let pixels = s.width as u64 * s.height as u64;
        match o.lanes {
            Some(n) if n > 1 => pixels * n as u64,
            Some(_) => 0,
            None if ctx.is_software() || 2 * pixels > LANE_INVOCATIONS => 0,
            None => LANE_INVOCATIONS,
        }
    }

    /// Lanes per pixel of a submission of `rows` rows at `k` samples per pixel.
    fn lanes(&self, rows: u32, k: u32) -> u32 {
        let pixels = self.settings.width as u64 * rows as u64;
        let fit = self.accum.scratch_slots / pixels.max(1);
        let wanted = match self.options.lanes {
            Some(n) => n as u64,
            None => LANE_INVOCATIONS.div_ceil(pixels.max(1)),
        };
        let lanes = fit.min(wanted).min(k as u64);
        if lanes < 2 { 1 } else { lanes as u32 }
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

    /// The pipeline the next submission uses: the tuner's pick (or the scene's own) when
    /// compiled; else, when compiling in the background, whichever of the scene's own and the
    /// generic one is ready (they render the same image); else compiled now.
    fn pipeline_features(&mut self) -> Features {
        let want = self.tune.as_ref().map_or(self.features, tune::Tune::next);
        if self.trace.ready(want) {
            return want;
        }
        if self.options.compile_in_background {
            self.trace.prepare_in_background(&self.ctx.device, want);
            for f in [self.features, self.generic_features()] {
                if self.trace.ready(f) {
                    return f;
                }
            }
        }
        self.trace.prepare(&self.ctx.device, want);
        want
    }

    /// Replaces the scene (and settings); resizes the accumulation if needed; resets.
    pub fn set_scene(&mut self, scene: &Scene, settings: FrameSettings) {
        let features = Self::features_for(scene, &self.options, &settings);
        if features != self.features {
            self.features = features;
            self.retune();
        }
        let device = &self.ctx.device;
        if self.options.compile_in_background {
            self.trace.prepare_in_background(device, self.features);
        } else {
            self.trace.prepare(device, self.features);
        }
        let mut rebind = self.scene.update(device, &self.ctx.queue, scene, &settings);
        if (settings.width, settings.height) != (self.settings.width, self.settings.height) {
            self.accum = Accumulation::new(
                device,
                settings.width,
                settings.height,
                Self::scratch_slots(&self.ctx, &self.options, &settings),
            );
            rebind = true;
        }
        self.settings = settings;
        if rebind {
            self.bind_group = self.trace.bind_group(device, &self.scene, &self.accum);
            self.reduce_bind_group = self.reduce.bind_group(
                device,
                &self.scene,
                self.trace.dispatch_buffer(),
                &self.accum,
            );
        }
        self.reset();
    }

    /// Queues the next submission (part of a round: some rows at `k` samples per pixel) and
    /// returns the paths it traces, without waiting for the GPU; `None` once every pixel has
    /// `max_samples`. `samples()` advances when a round's last submission is queued: work
    /// submitted later (a readback) sees it complete.
    pub fn submit(&mut self, max_samples: u32) -> Option<u64> {
        if self.samples >= max_samples {
            return None;
        }
        let (w, h) = (self.settings.width, self.settings.height);
        let features = self.pipeline_features();
        let round = match self.round {
            Some(r) => r,
            // The first round after a reset takes one sample, so that a first image exists
            // as soon as possible.
            None if self.fresh => Round {
                k: 1,
                next_row: 0,
                stride: if self.options.first_look { 2 } else { 1 },
            },
            None => Round {
                k: self
                    .schedule
                    .samples_per_round(w, h, max_samples - self.samples),
                next_row: 0,
                stride: 1,
            },
        };
        let rows = if round.stride > 1 {
            (h - round.next_row).div_ceil(round.stride)
        } else {
            self.schedule.rows(w, round.k, h - round.next_row)
        };
        let lanes = self.lanes(rows, round.k);
        let d = DispatchUniforms {
            sample_base: self.samples,
            sample_count: round.k,
            row_offset: round.next_row,
            row_count: rows,
            accumulate: u32::from(!self.fresh),
            lanes,
            row_stride: round.stride,
            _pad: 0,
        };
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
        if lanes > 1 {
            self.reduce
                .encode(&mut enc, &self.reduce_bind_group, w * rows);
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        let index = self.ctx.queue.submit([enc.finish()]);
        let paths = w as u64 * rows as u64 * round.k as u64;
        self.in_flight.push_back(InFlight {
            index,
            features,
            paths,
            submitted: Instant::now(),
        });
        let (next_row, end) = if round.stride > 1 {
            (round.next_row + 1, round.stride.min(h))
        } else {
            (round.next_row + rows, h)
        };
        if next_row >= end {
            self.samples += round.k;
            self.round = None;
            self.fresh = false;
        } else {
            self.round = Some(Round { next_row, ..round });
        }
        Some(paths)
    }

    /// Waits until at most `keep` submissions are in flight, and learns from each finished
    /// one how long a path takes (its time on the GPU: from when it was submitted, or from
    /// when the GPU finished the one before it, whichever is later).
    pub fn wait(&mut self, keep: usize) {
        while self.in_flight.len() > keep {
            let f = self.in_flight.pop_front().expect("a submission in flight");
            self.ctx
                .device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(f.index),
                    timeout: None,
                })
                .expect("the GPU stopped answering");
            let now = Instant::now();
            let took = now - f.submitted.max(self.last_done);
            self.schedule.observe(f.paths, took);
            // Short submissions are mostly fixed cost: they would not tell the pipelines
            // apart.
            if let Some(t) = &mut self.tune
                && took >= self.schedule.target / 2
            {
                t.observe(f.features, f.paths, took.as_secs_f64());
            }
            tracing::debug!(
                "submission of {} paths took {:.2} ms ({} queued behind it)",
                f.paths,
                took.as_secs_f64() * 1e3,
                self.in_flight.len()
            );
            self.last_done = now;
        }
    }

    /// Whether work queued so far makes an image: a whole sample per pixel, or the first
    /// look's first half.
    pub fn has_image(&self) -> bool {
        self.samples > 0 || self.round.is_some_and(|r| r.stride > 1 && r.next_row > 0)
    }

    /// Traces for about `budget` (at least one submission), never past `max_samples` per
    /// pixel, keeping one submission queued behind the running one. Returns what was done;
    /// every submission has finished when it returns.
    pub fn step(&mut self, budget: Duration, max_samples: u32) -> StepStats {
        let start = Instant::now();
        let mut stats = StepStats::default();
        while let Some(paths) = self.submit(max_samples) {
            stats.paths += paths;
            stats.submissions += 1;
            if self.timer.is_some() {
                // One query set: read each submission's time before the next.
                self.wait(0);
                if let Some(t) = &self.timer {
                    stats.gpu_seconds += t.read_seconds(&self.ctx);
                }
            } else {
                self.wait(1);
            }
            if start.elapsed() >= budget {
                break;
            }
        }
        self.wait(0);
        stats.elapsed = start.elapsed();
        stats
    }

    /// Renders until every pixel has `spp` samples.
    pub fn render_spp(&mut self, spp: u32) {
        while self.samples < spp {
            self.step(Duration::from_secs(1), spp);
        }
    }

    /// The accumulation (for passes that read it, such as the preview's resolve).
    pub fn accumulation(&self) -> &Accumulation {
        &self.accum
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
