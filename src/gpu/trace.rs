//! The tracer pass (`shaders/trace.wgsl`): its bind group layout, its pipelines (one per
//! feature set, compiled on first use and cached) and the encoding of one dispatch.
//!
//! A new feature set can be compiled on another thread while the generic pipeline, which
//! gives the same image bit for bit (tests/specialization.rs), keeps tracing: a key in the
//! preview that turns a sphere into glass never stalls on the compiler.
//!
//! The kernel is one "megakernel" (a path per invocation), made fast by measurement on the
//! H200 (BENCHMARKS.md, issue 12; `weekend` 1920×1080, max_bounces 50, segments/s):
//! - the BVH walk's stacks live at module scope: WGSL zeroes every variable where it is
//!   declared, and the stacks declared inside the walk (2 × 64 words) were zeroed for every
//!   ray: 3.05e9 → 3.72e9, and the loss of the specialized pipelines (issue 12) went with it;
//! - four-wide BVH nodes (`bvh::wide`, the CPU tracer's too): 4.8 node visits per segment
//!   instead of 11.7, a shorter chain of dependent loads: → 4.21e9;
//! - path regeneration: an invocation's paths are one loop over segments, a finished path
//!   replaced at once by its next sample's, so a warp no longer waits at every sample for its
//!   longest path: → 5.90e9.
//!
//! A wavefront tracer (Laine, Karras & Aila, "Megakernels Considered Harmful", HPG 2013)
//! was the other road; with these three the megakernel reached the goal (5e9) without
//! the queues' memory traffic, and specialization (the features compiled in) stays one
//! pipeline per scene.

use super::accum::Accumulation;
use super::scene_buffers::SceneBuffers;
use super::timer::GpuTimer;
use super::{GpuContext, Values, bind_buffers, layout_entry as entry, shader};
use crate::common::Features;
use crate::common::layout::DispatchUniforms;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Pipelines being compiled on background threads now, in the whole process.
static COMPILING: AtomicUsize = AtomicUsize::new(0);

/// How many pipelines are being compiled on background threads now. A driver's compiler
/// cannot be stopped, and a process that exits normally under it runs the driver's library
/// destructors while it still compiles: NVIDIA's (580) then crashes (SIGSEGV) after the
/// output has been written. `cli::leave` ends the process without them while this is not zero.
pub fn compiles_in_flight() -> usize {
    COMPILING.load(Ordering::SeqCst)
}

/// Counts one background compile from its start to its end, a panic's included.
struct InFlight;

impl InFlight {
    fn start() -> InFlight {
        COMPILING.fetch_add(1, Ordering::SeqCst);
        InFlight
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        COMPILING.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The `@workgroup_size(x, y, 1)` of the entry point `fn trace`, read from the WGSL so that
/// the shader stays the one place it is written.
fn workgroup_size(src: &str) -> (u32, u32) {
    let at = src.find("fn trace(").expect("trace.wgsl has fn trace");
    let attr = src[..at]
        .rfind("@workgroup_size(")
        .map(|i| &src[i + "@workgroup_size(".len()..at])
        .expect("fn trace has @workgroup_size");
    let mut dims = attr[..attr.find(')').expect("closed @workgroup_size")]
        .split(',')
        .map(|d| d.trim().parse::<u32>().expect("a literal workgroup size"));
    let x = dims.next().expect("a workgroup width");
    (x, dims.next().unwrap_or(1))
}

/// One dispatch of the tracer: which pipeline, over what, which rows and samples.
pub struct TraceDispatch<'a> {
    pub features: Features,
    pub bind_group: &'a wgpu::BindGroup,
    /// Image width in pixels.
    pub width: u32,
    pub uniforms: DispatchUniforms,
    pub timer: Option<&'a GpuTimer>,
}

pub struct TracePass {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    /// Invocations per workgroup in x and y.
    workgroup: (u32, u32),
    pipelines: Arc<Mutex<HashMap<Features, wgpu::ComputePipeline>>>,
    /// Feature sets being compiled on other threads.
    pending: Arc<Mutex<HashSet<Features>>>,
    dispatch: wgpu::Buffer,
}

fn compile(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    features: Features,
) -> wgpu::ComputePipeline {
    let t = std::time::Instant::now();
    let constants = features.constants();
    let p = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("trace.pipeline"),
        layout: Some(layout),
        module,
        entry_point: Some("trace"),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: &constants,
            zero_initialize_workgroup_memory: false,
        },
        cache: None,
    });
    tracing::info!(
        "compiled trace pipeline [{}] in {:.0} ms",
        features.summary(),
        t.elapsed().as_secs_f64() * 1e3
    );
    p
}

impl TracePass {
    pub fn new(ctx: &GpuContext) -> TracePass {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let device = &ctx.device;
        let values = Values::of(ctx);
        let ro = Storage { read_only: true };
        let rw = Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("trace.layout"),
            entries: &[
                entry(0, values.binding(Uniform)),
                entry(1, values.binding(Uniform)),
                entry(2, ro),
                entry(3, ro),
                entry(4, ro),
                entry(5, ro),
                entry(6, rw),
                entry(7, rw),
                entry(8, rw),
                entry(9, ro),
                entry(10, ro),
                entry(11, ro),
                entry(12, ro),
                entry(13, rw),
                entry(14, ro),
                entry(15, ro),
                entry(16, ro),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("trace.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let src = values.wgsl(shader::assemble("trace.wgsl").expect("trace.wgsl assembles"));
        let workgroup = workgroup_size(&src);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("trace.wgsl"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let dispatch = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace.dispatch"),
            size: std::mem::size_of::<DispatchUniforms>() as u64,
            usage: Values::USAGE,
            mapped_at_creation: false,
        });
        TracePass {
            layout,
            pipeline_layout,
            module,
            workgroup,
            pipelines: Arc::default(),
            pending: Arc::default(),
            dispatch,
        }
    }

    /// The pipeline specialized for `features`, compiled now if it is new.
    pub fn prepare(&self, device: &wgpu::Device, features: Features) {
        if self.ready(features) {
            return;
        }
        let p = compile(device, &self.pipeline_layout, &self.module, features);
        self.pipelines
            .lock()
            .expect("pipeline cache")
            .insert(features, p);
    }

    /// Whether the pipeline for `features` is compiled.
    pub fn ready(&self, features: Features) -> bool {
        self.pipelines
            .lock()
            .expect("pipeline cache")
            .contains_key(&features)
    }

    /// Starts compiling the pipeline for `features` on another thread, unless it is ready or
    /// already being compiled.
    pub fn prepare_in_background(&self, device: &wgpu::Device, features: Features) {
        if self.ready(features) || !self.pending.lock().expect("pending set").insert(features) {
            return;
        }
        let (device, layout, module) = (
            device.clone(),
            self.pipeline_layout.clone(),
            self.module.clone(),
        );
        let (pipelines, pending) = (self.pipelines.clone(), self.pending.clone());
        let in_flight = InFlight::start();
        std::thread::spawn(move || {
            let _in_flight = in_flight;
            let p = compile(&device, &layout, &module, features);
            pipelines
                .lock()
                .expect("pipeline cache")
                .insert(features, p);
            pending.lock().expect("pending set").remove(&features);
        });
    }

    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        scene: &SceneBuffers,
        accum: &Accumulation,
    ) -> wgpu::BindGroup {
        bind_buffers(
            device,
            "trace.bind_group",
            &self.layout,
            &[
                &scene.uniforms,
                &self.dispatch,
                &scene.materials,
                &scene.spheres,
                &scene.quads,
                &scene.boxes,
                &accum.even,
                &accum.odd,
                &accum.counters,
                &scene.nodes,
                &scene.refs,
                &scene.triangles,
                &scene.lights,
                &accum.scratch,
                &scene.tex,
                &scene.env,
                &scene.instances,
            ],
        )
    }

    /// The shader module (the guide pass compiles its entry point `guides` from it).
    pub fn module(&self) -> &wgpu::ShaderModule {
        &self.module
    }

    /// The layout of group 0, the scene's and accumulation's buffers.
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// The per-submission uniforms buffer (the reduce pass reads it too).
    pub fn dispatch_buffer(&self) -> &wgpu::Buffer {
        &self.dispatch
    }

    /// Writes the dispatch's uniforms and records it. The uniforms are per submission:
    /// submit before encoding the next dispatch.
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        d: &TraceDispatch<'_>,
    ) {
        queue.write_buffer(&self.dispatch, 0, bytemuck::bytes_of(&d.uniforms));
        let pipelines = self.pipelines.lock().expect("pipeline cache");
        let pipeline = &pipelines[&d.features];
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("trace"),
            timestamp_writes: d.timer.map(GpuTimer::writes),
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, d.bind_group, &[]);
        pass.dispatch_workgroups(
            d.width.div_ceil(self.workgroup.0),
            d.uniforms.row_count.div_ceil(self.workgroup.1),
            d.uniforms.lanes.max(1),
        );
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_workgroup_size_is_read_from_the_shader() {
        let src = super::shader::assemble("trace.wgsl").unwrap();
        assert_eq!(super::workgroup_size(&src), (8, 8));
        let other = "@compute @workgroup_size(16, 4)\nfn trace(a: u32) {}";
        assert_eq!(super::workgroup_size(other), (16, 4));
    }
}
