//! The progressive renderer: owns the GPU passes and buffers of one scene, advances the
//! accumulation in watchdog-safe submissions, and resets it on any change (the lecture's
//! `should_accumulate`).
//!
//! Submissions are pipelined: [`Renderer::submit`] queues one and returns at once, and
//! [`Renderer::wait`] lets at most a given number stay in flight, so the GPU has the next
//! one before it finishes the last. A small image fills the GPU by tracing several samples
//! of each pixel in parallel ("lanes", see `fn trace` in trace.wgsl), whose exact
//! fixed-point sums the reduce pass adds up: the image is the same bit for bit.
//!
//! The same rounds run on the native CPU tracer (`crate::cpu`) where there is no GPU: a
//! submission there is traced on every core before `submit` returns.

pub mod claims;
pub mod failure;
pub mod frames;
mod schedule;
pub mod shard;
mod snapshot;
pub mod stages;
pub mod team;
pub mod tune;

pub use schedule::Schedule;
pub use snapshot::{ErrorEstimate, Snapshot};

use crate::common::Resolved;
use crate::common::accum::Sums;
use crate::common::engine::Engine as TracerEngine;
use crate::common::guides::{GUIDE_SAMPLES, Guides};
use crate::common::layout::DispatchUniforms;
use crate::common::{Features, FrameSettings};
use crate::cpu::CpuEngine;
use crate::gpu::{Accumulation, GpuContext, GpuEngine, GpuEngineOptions, GpuError};
use crate::scene::Scene;
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

pub use crate::gpu::engine::LANE_INVOCATIONS;

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
    /// Measure the two pipelines on a software adapter too (tests of the tuner). Off by
    /// default: on lavapipe the generic pipeline's first dispatch compiles for about 100 s
    /// (BENCHMARKS.md, "Shaders compiled once on lavapipe"), and a CPU's few cores favour the
    /// specialized one anyway.
    pub tune_on_software: bool,
    /// The index of the first sample of every pixel (0: a whole render): a shard of a render
    /// traces samples `first_sample..` with their own random streams, as the whole render
    /// would (`render --shard`).
    pub first_sample: u32,
}

impl RenderOptions {
    /// Whether the tuner times the pipeline of `features` against the generic one, on a GPU
    /// adapter that is `software` or not (`Renderer::retune` says why not on the others).
    fn tunes(&self, features: Features, software: bool) -> bool {
        !self.generic
            && !self.no_tune
            && self.extra.is_none()
            && (self.tune_on_software || !software)
            && features != self.generic_features()
    }

    /// The generic pipeline with these options' own switches (segment counting, BVH).
    fn generic_features(&self) -> Features {
        Features {
            count_segments: self.count_segments,
            bvh: !self.no_bvh,
            ..Features::generic()
        }
    }
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
            tune_on_software: false,
            first_sample: 0,
        }
    }
}

/// Where paths are traced: a wgpu adapter, or the native CPU tracer.
#[derive(Clone)]
pub enum Backend {
    Gpu(Arc<GpuContext>),
    Cpu,
}

impl From<Arc<GpuContext>> for Backend {
    fn from(ctx: Arc<GpuContext>) -> Backend {
        Backend::Gpu(ctx)
    }
}

/// A scene that a GPU cannot bind: what overruns which limit ([`Backend::check_fits`]).
#[derive(Debug, thiserror::Error)]
#[error("{scene}: {why} ({adapter})")]
pub struct TooLarge {
    pub scene: String,
    pub why: String,
    pub adapter: String,
}

/// Why the devices a selector names could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(
        "adapter `{selector}` names several devices where one is needed: name one adapter \
         (`termtrace adapters` lists them); `view`, `render`, `bench` and `converge` take several"
    )]
    Several { selector: String },
}

impl Backend {
    /// The backend `selector` names (`cpu-native`, or any adapter `termtrace adapters`
    /// lists), or the best one: a GPU where there is one, else the native CPU tracer (which
    /// replaces Mesa's software adapters, being many times faster than they are).
    pub fn open(selector: Option<&str>) -> Result<Backend, OpenError> {
        let selector = selector.map(str::trim).filter(|s| !s.is_empty());
        if let Some(s) = selector.filter(|s| s.eq_ignore_ascii_case("all") || s.contains(',')) {
            return Err(OpenError::Several {
                selector: s.to_string(),
            });
        }
        if selector.is_some_and(|s| s.eq_ignore_ascii_case(crate::cpu::ADAPTER_NAME)) {
            return Ok(Backend::Cpu);
        }
        match crate::gpu::select_adapter(selector) {
            Ok(a) if selector.is_none() && a.get_info().device_type == wgpu::DeviceType::Cpu => {
                tracing::info!(
                    "the best adapter is a software one ({}): tracing on the CPU natively",
                    crate::gpu::describe(&a.get_info())
                );
                Ok(Backend::Cpu)
            }
            Ok(a) => Ok(Backend::Gpu(Arc::new(GpuContext::on(a)?))),
            Err(GpuError::NoAdapter { tried }) if selector.is_none() => {
                tracing::info!("no GPU adapter ({tried}): tracing on the CPU natively");
                Ok(Backend::Cpu)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// The devices `selector` names: `all` (every hardware GPU of the host, on the best one's
    /// backend; the default backend where there is none), a comma-separated list of what
    /// [`Backend::open`] takes (`0,1`, `vulkan,cpu-native`; an adapter named twice is opened
    /// twice), or one of them.
    pub fn open_all(selector: Option<&str>) -> Result<Vec<Backend>, OpenError> {
        let selector = selector.map(str::trim).filter(|s| !s.is_empty());
        match selector {
            Some(s) if s.eq_ignore_ascii_case("all") => {
                let gpus = crate::gpu::hardware_adapters();
                if gpus.is_empty() {
                    tracing::info!(
                        "adapter `all`: no hardware GPU, tracing on the default backend"
                    );
                    return Ok(vec![Backend::open(None)?]);
                }
                gpus.into_iter()
                    .map(|a| Ok(Backend::Gpu(Arc::new(GpuContext::on(a)?))))
                    .collect()
            }
            Some(s) if s.contains(',') => s
                .split(',')
                .map(|one| match one.trim() {
                    "" => Err(GpuError::NoMatch {
                        selector: s.to_string(),
                        tried: "an empty name in the list".into(),
                    }
                    .into()),
                    one => Backend::open(Some(one)),
                })
                .collect(),
            _ => Ok(vec![Backend::open(selector)?]),
        }
    }

    /// Whether `scene` fits this backend: a GPU binds each storage buffer up to a size
    /// (`max_storage_buffer_binding_size`, `max_buffer_size`); the triangles, the texture words
    /// and an environment map, one buffer each, are what a real scene can overrun. The CPU tracer has no such limit.
    pub fn check_fits(&self, scene: &Scene) -> Result<(), TooLarge> {
        let Backend::Gpu(ctx) = self else {
            return Ok(());
        };
        let l = ctx.device.limits();
        let limit = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
        let why = crate::common::arrays::too_large(scene, limit)
            .or_else(|| crate::common::textures::too_large(scene, limit))
            .or_else(|| {
                scene.environment.as_ref().and_then(|e| {
                    crate::common::envmap::too_large(&e.map.distribution, &e.map.name, limit)
                })
            });
        match why {
            Some(why) => Err(TooLarge {
                scene: scene.origin.clone(),
                why,
                adapter: ctx.adapter_name(),
            }),
            None => Ok(()),
        }
    }

    /// One line naming the adapter or the CPU tracer.
    pub fn describe(&self) -> String {
        match self {
            Backend::Gpu(ctx) => ctx.adapter_name(),
            Backend::Cpu => crate::cpu::describe(),
        }
    }

    /// The device as the preview's status line names it, short:
    /// `llvmpipe (LLVM 15.0.6, 256 bits)` → `llvmpipe (Vulkan)`, `CPU (2 threads, x86_64)`.
    pub fn short_name(&self) -> String {
        match self {
            Backend::Gpu(ctx) => {
                let short = ctx.info.name.split(" (").next().unwrap_or(&ctx.info.name);
                format!("{short} ({:?})", ctx.info.backend)
            }
            Backend::Cpu => format!("CPU ({})", crate::cpu::threads()),
        }
    }

    /// The GPU, where there is one.
    pub fn gpu(&self) -> Option<&Arc<GpuContext>> {
        match self {
            Backend::Gpu(ctx) => Some(ctx),
            Backend::Cpu => None,
        }
    }

    /// A CPU does the tracing (a software adapter or the native tracer): few cores, which
    /// a small image already fills.
    pub fn is_cpu(&self) -> bool {
        match self {
            Backend::Gpu(ctx) => ctx.is_software(),
            Backend::Cpu => true,
        }
    }
}

/// The renderer's engine: either backend's, driven through the one surface
/// ([`common::engine::Engine`](crate::common::engine::Engine)); the GPU's also hands its
/// buffers to the passes that read them on the device (the preview's resolve, the denoiser).
enum Engine {
    Gpu(Box<GpuEngine>),
    Cpu(Box<CpuEngine>),
}

impl Engine {
    fn get(&self) -> &dyn TracerEngine {
        match self {
            Engine::Gpu(g) => g.as_ref(),
            Engine::Cpu(c) => c.as_ref(),
        }
    }

    fn get_mut(&mut self) -> &mut dyn TracerEngine {
        match self {
            Engine::Gpu(g) => g.as_mut(),
            Engine::Cpu(c) => c.as_mut(),
        }
    }

    fn gpu(&self) -> Option<&GpuEngine> {
        match self {
            Engine::Gpu(g) => Some(g),
            Engine::Cpu(_) => None,
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
    base: u32,
    k: u32,
    next_row: u32,
    /// 1: submissions take contiguous rows from `next_row` on; n > 1: each takes every n-th
    /// row from `next_row` (the first look), and the round ends when `next_row` reaches n.
    stride: u32,
    /// The tuner's candidate this round is timing, and the round's number.
    trial: Option<(usize, u64)>,
}

/// A round being timed for the tuner: its candidate and number, the paths and GPU seconds of
/// its submissions so far, and whether all of them used the candidate's pipeline.
#[derive(Clone, Copy)]
struct Trial {
    candidate: usize,
    round: u64,
    paths: u64,
    seconds: f64,
    uniform: bool,
}

/// A submission the GPU has not finished (the CPU's finish before `submit` returns).
struct InFlight {
    /// Known at once where the engine traced before returning (the CPU); else measured
    /// when it is waited on.
    took: Option<Duration>,
    features: Features,
    paths: u64,
    submitted: Instant,
    /// The tuner's (candidate, round number) where the round is timed, and whether this is
    /// the round's last submission.
    trial: Option<(usize, u64)>,
    ends_round: bool,
}

pub struct Renderer {
    engine: Engine,
    settings: FrameSettings,
    options: RenderOptions,
    features: Features,
    schedule: Schedule,
    /// Samples per pixel of every completed round since the last reset.
    samples: u32,
    round: Option<Round>,
    /// The next round restarts the sums (`should_accumulate = 0`).
    fresh: bool,
    in_flight: VecDeque<InFlight>,
    /// Timing the specialized pipeline against the generic one, until one is chosen.
    tune: Option<tune::Tune>,
    /// The round being timed, as its submissions finish; rounds are numbered by `rounds`.
    trial: Option<Trial>,
    rounds: u64,
    /// The first round the current tuner gave out (rounds before it timed an older one).
    tune_from: u64,
    /// The pipeline of the latest submission.
    last_pipeline: Option<Features>,
    /// When the GPU last finished a submission (as seen by `wait`).
    last_done: Instant,
    /// Whether the denoiser's guides of the current scene and settings are made (on the
    /// tracer's side), and their host copy once asked for.
    guides_made: bool,
    guides: Option<Guides>,
    /// Where the samples of each round come from when several devices share a render
    /// (`claims::Claims`); `None`: `first_sample + samples()` on.
    /// With this renderer's device number there.
    claims: Option<(Arc<claims::Claims>, usize)>,
}

impl Renderer {
    pub fn new(
        backend: impl Into<Backend>,
        scene: &Scene,
        settings: FrameSettings,
        mut options: RenderOptions,
    ) -> Renderer {
        let features = Self::features_for(scene, &options, &settings);
        let backend = backend.into();
        // Where the tuner will time the generic pipeline against the scene's own (a hardware
        // GPU), the generic one compiles on another thread while the scene's own traces: a
        // driver can take a minute over the generic kernel (NVIDIA's, `glass`: BENCHMARKS.md),
        // which a headless render used to wait for before its second round.
        if let Backend::Gpu(ctx) = &backend {
            options.compile_in_background |= !ctx.is_software() && options.tunes(features, false);
        }
        let schedule = match &backend {
            Backend::Gpu(ctx) if ctx.is_software() => Schedule::software(options.submission),
            _ => Schedule::new(options.submission),
        };
        let engine = match backend {
            Backend::Gpu(ctx) => Engine::Gpu(Box::new(GpuEngine::new(
                ctx,
                scene,
                &settings,
                GpuEngineOptions {
                    compile_in_background: options.compile_in_background,
                    generic: options.generic_features(),
                    gpu_timing: options.gpu_timing,
                    lanes: options.lanes,
                },
                features,
            ))),
            Backend::Cpu => Engine::Cpu(Box::new(CpuEngine::new(scene, &settings))),
        };
        let mut r = Renderer {
            engine,
            settings,
            options,
            features,
            schedule,
            samples: 0,
            round: None,
            fresh: true,
            in_flight: VecDeque::new(),
            tune: None,
            trial: None,
            rounds: 0,
            tune_from: 0,
            last_pipeline: None,
            last_done: Instant::now(),
            guides_made: false,
            guides: None,
            claims: None,
        };
        r.retune();
        r
    }

    /// Starts timing the specialized pipeline against the generic one, where they differ.
    /// Not on the CPU tracer: there both are monomorphizations of one Rust function, with no
    /// driver between the code and the machine to surprise, and the specialized CPU tracer is
    /// measured at least as fast as the generic one on every shipped scene instead
    /// (BENCHMARKS.md). Nor on a software adapter unless asked (`tune_on_software`).
    fn retune(&mut self) {
        let timed = match &self.engine {
            Engine::Gpu(g) => self.options.tunes(self.features, g.ctx.is_software()),
            Engine::Cpu(_) => false,
        };
        self.tune = timed.then(|| tune::Tune::new(self.features, self.generic_features()));
        self.trial = None;
        self.tune_from = self.rounds + 1;
    }

    /// The pipeline the latest submission used (the scene's own, the generic one, or the
    /// candidate a round times).
    pub fn last_pipeline(&self) -> Option<Features> {
        self.last_pipeline
    }

    /// Whether the tuner's choice is still to come (`Tune::pending`).
    pub fn tuning(&self) -> bool {
        self.tune.as_ref().is_some_and(tune::Tune::pending)
    }

    /// The tuner's outcome: the pipeline chosen and the seconds per path measured of the
    /// (specialized, generic) ones; `None` while measuring or when there was no choice.
    pub fn tuned(&self) -> Option<(Features, (f64, f64))> {
        let t = self.tune.as_ref()?;
        Some((t.chosen()?, t.measured()))
    }

    /// Lanes per pixel of a submission of `rows` rows at `k` samples per pixel.
    fn lanes(&self, rows: u32, k: u32) -> u32 {
        let slots = self.engine.get().scratch_slots();
        if slots == 0 {
            return 1;
        }
        let pixels = self.settings.width as u64 * rows as u64;
        let fit = slots / pixels.max(1);
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

    /// The backend this renderer traces on.
    pub fn backend(&self) -> Backend {
        match &self.engine {
            Engine::Gpu(g) => Backend::Gpu(g.ctx.clone()),
            Engine::Cpu(_) => Backend::Cpu,
        }
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
        self.engine.gpu().is_some_and(GpuEngine::timed)
    }

    /// Nodes in the BVH and the seconds its last build took.
    pub fn bvh_stats(&self) -> (usize, f64) {
        self.engine.get().bvh_stats()
    }

    /// How the CPU tracer runs the paths, and why (None on a GPU).
    pub fn path_loop(&self) -> Option<String> {
        self.engine.get().path_loop(self.features())
    }

    /// Memory held by the accumulation (on the GPU, or the host's).
    pub fn accumulation_bytes(&self) -> u64 {
        self.engine.get().bytes()
    }

    /// Takes each round's samples from `claims` from now on (and restarts the accumulation):
    /// several devices share one render, each claiming the next samples when it is ready
    /// (`multi`); `samples()` then counts this renderer's share.
    pub fn share(&mut self, claims: Arc<claims::Claims>, device: usize) {
        self.claims = Some((claims, device));
        self.reset();
    }

    /// A new round of up to `k` samples per pixel (`stride` as in `Round`), timing the
    /// tuner's next candidate while it has not chosen; `None` when the shared claims are
    /// used up.
    fn start_round(&mut self, k: u32, stride: u32) -> Option<Round> {
        #[cfg(test)]
        if let Some((c, device)) = &self.claims
            && c.failing(*device)
        {
            panic!("device {device} failed (a test's injected failure)");
        }
        let (base, k) = match &self.claims {
            Some((c, device)) => c.claim(*device, k, self.schedule.rate())?,
            None => (self.options.first_sample + self.samples, k),
        };
        self.rounds += 1;
        let trial = self
            .tune
            .as_mut()
            .and_then(tune::Tune::start_round)
            .map(|i| (i, self.rounds));
        Some(Round {
            base,
            k,
            next_row: 0,
            stride,
            trial,
        })
    }

    /// Adds finished submission `f` to the round it times; a whole round is the tuner's
    /// trial. Rounds shorter than half a submission's target are mostly fixed cost and would
    /// not tell the pipelines apart; a round cut short by a reset, or traced partly by the
    /// other pipeline while its own compiled, does not count either.
    fn time_trial(&mut self, f: &InFlight, took: Duration) {
        let (Some(t), Some((candidate, round))) = (&mut self.tune, f.trial) else {
            return;
        };
        if round < self.tune_from {
            return;
        }
        if let Some(old) = self.trial.filter(|o| o.round != round) {
            t.refund(old.candidate);
            self.trial = None;
        }
        let trial = self.trial.get_or_insert(Trial {
            candidate,
            round,
            paths: 0,
            seconds: 0.0,
            uniform: true,
        });
        trial.paths += f.paths;
        trial.seconds += took.as_secs_f64();
        trial.uniform &= f.features == t.candidate(candidate);
        if f.ends_round {
            let done = self.trial.take().expect("the trial just added to");
            if done.uniform && done.seconds >= self.schedule.target.as_secs_f64() / 2.0 {
                t.record(done.candidate, done.paths, done.seconds);
            } else {
                t.refund(done.candidate);
            }
        }
    }

    /// Starts the accumulation afresh on the next submission.
    pub fn reset(&mut self) {
        self.samples = 0;
        self.round = None;
        self.fresh = true;
        self.engine.get_mut().reset_counters();
    }

    /// The generic pipeline with this renderer's own switches (segment counting, BVH).
    fn generic_features(&self) -> Features {
        self.options.generic_features()
    }

    /// The pipeline the next submission uses: `want` (the round's candidate, the tuner's
    /// choice or the scene's own) when compiled; else, when compiling in the background,
    /// whichever of the scene's own and the generic one is ready (they render the same
    /// image); else compiled now.
    fn pipeline_features(&mut self, want: Features) -> Features {
        let generic = self.generic_features();
        let e = self.engine.get_mut();
        if e.ready(want) {
            return want;
        }
        if self.options.compile_in_background {
            e.prepare(want, true);
            for f in [self.features, generic] {
                if e.ready(f) {
                    return f;
                }
            }
        }
        e.prepare(want, false);
        want
    }

    /// Replaces the scene (and settings); resizes the accumulation if needed; resets.
    pub fn set_scene(&mut self, scene: &Scene, settings: FrameSettings) {
        let features = Self::features_for(scene, &self.options, &settings);
        if features != self.features {
            self.features = features;
            self.retune();
        }
        self.engine
            .get_mut()
            .set_scene(scene, &settings, self.features);
        self.settings = settings;
        self.guides_made = false;
        self.guides = None;
        self.reset();
    }

    /// Makes the denoiser's guides (albedo and normal of every pixel, `GUIDE_SAMPLES`
    /// samples each) on the first call after the scene or settings change: on a GPU they
    /// stay there (for its denoiser, [`Renderer::guide_buffer`]) until the host asks for
    /// them ([`Renderer::guides`]).
    pub fn make_guides(&mut self) {
        if self.guides_made {
            return;
        }
        let (w, h) = (self.settings.width, self.settings.height);
        let samples = 0..GUIDE_SAMPLES;
        let features = self.features;
        if let Some(words) = self.engine.get_mut().make_guides(features, (w, h), samples) {
            self.guides = Some(Guides::decode(w, h, &words));
        }
        self.guides_made = true;
    }

    /// The guides' sums on the GPU once [`Renderer::make_guides`] has made them, for the
    /// GPU's denoiser; `None` on the CPU.
    pub fn guide_buffer(&self) -> Option<&wgpu::Buffer> {
        if !self.guides_made {
            return None;
        }
        self.engine.gpu()?.guide_buffer()
    }

    /// The denoiser's guides on the host (made if needed; read back from a GPU once).
    pub fn guides(&mut self) -> &Guides {
        self.make_guides();
        if self.guides.is_none() {
            let words = self.engine.get().read_guides();
            let (w, h) = (self.settings.width, self.settings.height);
            self.guides = Some(Guides::decode(w, h, &words));
        }
        self.guides.as_ref().expect("guides made")
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
        let round = match self.round {
            Some(r) => r,
            // The first round after a reset takes one sample, so that a first image exists
            // as soon as possible.
            None if self.fresh => {
                self.start_round(1, if self.options.first_look { 2 } else { 1 })?
            }
            None => {
                let k = self
                    .schedule
                    .samples_per_round(w, h, max_samples - self.samples);
                self.start_round(k, 1)?
            }
        };
        let want = match (round.trial, &self.tune) {
            (Some((i, _)), Some(t)) => t.candidate(i),
            (None, Some(t)) => t.chosen().unwrap_or(self.features),
            _ => self.features,
        };
        let features = self.pipeline_features(want);
        self.last_pipeline = Some(features);
        let rows = if round.stride > 1 {
            (h - round.next_row).div_ceil(round.stride)
        } else {
            self.schedule.rows(w, round.k, h - round.next_row)
        };
        let lanes = self.lanes(rows, round.k);
        let d = DispatchUniforms {
            sample_base: round.base,
            sample_count: round.k,
            row_offset: round.next_row,
            row_count: rows,
            accumulate: u32::from(!self.fresh),
            lanes,
            row_stride: round.stride,
            _pad: 0,
        };
        let paths = w as u64 * rows as u64 * round.k as u64;
        let took = self.engine.get_mut().dispatch(features, d, w);
        let (next_row, end) = if round.stride > 1 {
            (round.next_row + 1, round.stride.min(h))
        } else {
            (round.next_row + rows, h)
        };
        self.in_flight.push_back(InFlight {
            took,
            features,
            paths,
            submitted: Instant::now(),
            trial: round.trial,
            ends_round: next_row >= end,
        });
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
            if f.took.is_none() {
                self.engine.get_mut().finish_oldest();
            }
            let now = Instant::now();
            let took = f
                .took
                .unwrap_or_else(|| now - f.submitted.max(self.last_done));
            self.schedule.observe(f.paths, took);
            self.time_trial(&f, took);
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
            if self.gpu_timed() {
                // One query set: read each submission's time before the next.
                self.wait(0);
                stats.gpu_seconds += self.engine.get().timed_seconds().unwrap_or(0.0);
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

    /// The accumulation on the GPU (for passes that read it, such as the preview's
    /// resolve); `None` on the CPU.
    pub fn accumulation(&self) -> Option<&Accumulation> {
        Some(&self.engine.gpu()?.accum)
    }

    /// The preview's frame made on the host (the CPU tracer's counterpart of the resolve
    /// pass); `None` on a GPU, whose frames the resolve pass makes.
    pub fn resolve_on_host(&self, factor: u32) -> Option<Resolved> {
        self.engine.get().resolve_on_host(factor)
    }

    /// The exact sums (`ACCUM_WORDS` words per pixel, even then odd half) and the samples
    /// discarded as invalid, as the tracer holds them: what a shard writes (`render::shard`).
    pub fn exact_sums(&self) -> Sums {
        self.engine.get().exact_sums()
    }

    /// Reads the accumulation back.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            width: self.settings.width,
            height: self.settings.height,
            data: self.engine.get().read(),
            samples: self.samples,
        }
    }
}
