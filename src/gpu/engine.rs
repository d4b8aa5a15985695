//! The GPU's engine: the passes and buffers of one scene on one device (the tracer and
//! reduce passes, the scene's buffers, the accumulation, the timer, the guide pass), behind
//! the renderer's seam (`common::engine::Engine`). Its dispatches are queued and waited on
//! in order, so that the device has the next one before it finishes the last.

use super::guides::GuidePass;
use super::reduce::ReducePass;
use super::timer::GpuTimer;
use super::trace::TraceDispatch;
use super::{Accumulation, GpuContext, SceneBuffers, TracePass};
use crate::common::accum::{AccumData, Sums};
use crate::common::engine::Engine;
use crate::common::layout::DispatchUniforms;
use crate::common::{Features, FrameSettings, Resolved};
use crate::scene::Scene;
use std::collections::VecDeque;
use std::ops::Range;
use std::sync::Arc;
use std::time::Duration;

/// Invocations a dispatch should have to fill a large GPU: an H100/H200 holds about 270 000
/// resident threads (132 SMs × 2048); twice that evens out the paths' unequal lengths.
/// Lanes are added until a submission has about this many.
pub const LANE_INVOCATIONS: u64 = 1 << 19;

/// How the engine compiles, times and sizes its work (from the renderer's options).
#[derive(Clone, Copy, Debug)]
pub struct GpuEngineOptions {
    /// Compile pipelines on another thread (the preview), with the generic one ahead.
    pub compile_in_background: bool,
    /// The generic pipeline, compiled ahead when compiling in the background.
    pub generic: Features,
    /// Time each dispatch on the GPU (a benchmark).
    pub gpu_timing: bool,
    /// Lanes per pixel asked for (`None`: as many as fill the GPU).
    pub lanes: Option<u32>,
}

/// The GPU's passes and buffers for one scene.
pub struct GpuEngine {
    pub ctx: Arc<GpuContext>,
    pub trace: TracePass,
    pub scene: SceneBuffers,
    pub accum: Accumulation,
    bind_group: wgpu::BindGroup,
    reduce: ReducePass,
    reduce_bind_group: wgpu::BindGroup,
    timer: Option<GpuTimer>,
    /// Made on the first denoised frame.
    pub guides: Option<GuidePass>,
    options: GpuEngineOptions,
    size: (u32, u32),
    /// Dispatches queued and not yet waited on, oldest first.
    queued: VecDeque<wgpu::SubmissionIndex>,
}

impl GpuEngine {
    pub fn new(
        ctx: Arc<GpuContext>,
        scene: &Scene,
        settings: &FrameSettings,
        options: GpuEngineOptions,
        features: Features,
    ) -> GpuEngine {
        let device = &ctx.device;
        let trace = TracePass::new(&ctx);
        if options.compile_in_background {
            // The fallback for the feature sets edits will introduce.
            trace.prepare_in_background(device, options.generic);
        }
        // The scene's pipeline compiles while its buffers (the BVH) are made: on a large mesh
        // each takes a large part of the time to the first frame.
        let buffers = std::thread::scope(|s| {
            let compiling = s.spawn(|| trace.prepare(device, features));
            let buffers = SceneBuffers::new(device, scene, settings);
            if let Err(panic) = compiling.join() {
                std::panic::resume_unwind(panic);
            }
            buffers
        });
        let accum = Accumulation::new(
            device,
            settings.width,
            settings.height,
            scratch_slots(&ctx, &options, settings),
        );
        let bind_group = trace.bind_group(device, &buffers, &accum);
        let reduce = ReducePass::new(&ctx);
        let reduce_bind_group =
            reduce.bind_group(device, &buffers, trace.dispatch_buffer(), &accum);
        accum.reset_counters(&ctx.queue);
        let timer = if options.gpu_timing {
            GpuTimer::new(&ctx)
        } else {
            None
        };
        GpuEngine {
            ctx,
            trace,
            scene: buffers,
            accum,
            bind_group,
            reduce,
            reduce_bind_group,
            timer,
            guides: None,
            options,
            size: (settings.width, settings.height),
            queued: VecDeque::new(),
        }
    }

    /// Whether its dispatches are timed on the GPU (asked for, and the device can).
    pub fn timed(&self) -> bool {
        self.timer.is_some()
    }

    /// The guide sums on the GPU, once made (for the GPU's denoiser).
    pub fn guide_buffer(&self) -> Option<&wgpu::Buffer> {
        self.guides.as_ref().and_then(|p| p.sums())
    }
}

/// Lane-pixels of scratch: none where one lane per pixel is all a dispatch needs.
fn scratch_slots(ctx: &GpuContext, o: &GpuEngineOptions, s: &FrameSettings) -> u64 {
    let pixels = s.width as u64 * s.height as u64;
    match o.lanes {
        Some(n) if n > 1 => pixels * n as u64,
        Some(_) => 0,
        None if ctx.is_software() || 2 * pixels > LANE_INVOCATIONS => 0,
        None => LANE_INVOCATIONS,
    }
}

/// The GPU's side of the renderer's seam.
impl Engine for GpuEngine {
    fn set_scene(&mut self, scene: &Scene, settings: &FrameSettings, features: Features) {
        let device = &self.ctx.device;
        if self.options.compile_in_background {
            self.trace.prepare_in_background(device, features);
        } else {
            self.trace.prepare(device, features);
        }
        let mut rebind = self.scene.update(device, &self.ctx.queue, scene, settings);
        if (settings.width, settings.height) != self.size {
            self.accum = Accumulation::new(
                device,
                settings.width,
                settings.height,
                scratch_slots(&self.ctx, &self.options, settings),
            );
            self.size = (settings.width, settings.height);
            rebind = true;
        }
        if rebind {
            self.bind_group = self.trace.bind_group(device, &self.scene, &self.accum);
            self.reduce_bind_group = self.reduce.bind_group(
                device,
                &self.scene,
                self.trace.dispatch_buffer(),
                &self.accum,
            );
        }
    }

    fn reset_counters(&mut self) {
        self.accum.reset_counters(&self.ctx.queue);
    }

    fn ready(&self, features: Features) -> bool {
        self.trace.ready(features)
    }

    fn prepare(&mut self, features: Features, background: bool) {
        if background {
            self.trace.prepare_in_background(&self.ctx.device, features);
        } else {
            self.trace.prepare(&self.ctx.device, features);
        }
    }

    fn scratch_slots(&self) -> u64 {
        self.accum.scratch_slots
    }

    /// Encodes and submits one dispatch (and the reduce of its lanes); returns at once.
    fn dispatch(
        &mut self,
        features: Features,
        d: DispatchUniforms,
        width: u32,
    ) -> Option<Duration> {
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
                width,
                uniforms: d,
                timer: self.timer.as_ref(),
            },
        );
        if d.lanes > 1 {
            self.reduce
                .encode(&mut enc, &self.reduce_bind_group, width * d.row_count);
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        self.queued.push_back(self.ctx.queue.submit([enc.finish()]));
        None
    }

    fn finish_oldest(&mut self) {
        if let Some(index) = self.queued.pop_front() {
            self.ctx
                .device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(index),
                    timeout: None,
                })
                .expect("the GPU stopped answering");
        }
    }

    fn timed_seconds(&self) -> Option<f64> {
        self.timer.as_ref().map(|t| t.read_seconds(&self.ctx))
    }

    fn make_guides(
        &mut self,
        features: Features,
        size: (u32, u32),
        samples: Range<u32>,
    ) -> Option<Vec<u32>> {
        let pass = self
            .guides
            .get_or_insert_with(|| GuidePass::new(&self.ctx.device, self.trace.layout()));
        pass.run(
            &self.ctx,
            self.trace.module(),
            &self.bind_group,
            self.trace.dispatch_buffer(),
            features,
            size,
            samples,
        );
        None
    }

    fn read_guides(&self) -> Vec<u32> {
        self.guides
            .as_ref()
            .map_or(Vec::new(), |p| p.read(&self.ctx))
    }

    fn resolve_on_host(&self, _: u32) -> Option<Resolved> {
        None
    }

    fn exact_sums(&self) -> Sums {
        self.accum.read_words(&self.ctx)
    }

    fn read(&self) -> AccumData {
        self.accum.read(&self.ctx)
    }

    fn bytes(&self) -> u64 {
        self.accum.gpu_bytes()
    }

    fn bvh_stats(&self) -> (usize, f64) {
        (self.scene.node_count, self.scene.build_seconds)
    }
}
