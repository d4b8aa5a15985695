//! The tracer pass (`shaders/trace.wgsl`): its bind group layout, its pipelines (one per
//! feature set, compiled on first use and cached) and the encoding of one dispatch.

use super::accum::Accumulation;
use super::features::Features;
use super::layout::DispatchUniforms;
use super::scene_buffers::SceneBuffers;
use super::shader;
use super::timer::GpuTimer;
use std::collections::HashMap;

/// Invocations per workgroup side (`@workgroup_size(8, 8, 1)` in trace.wgsl).
pub const WORKGROUP: u32 = 8;

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
    pipelines: HashMap<Features, wgpu::ComputePipeline>,
    dispatch: wgpu::Buffer,
}

fn entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl TracePass {
    pub fn new(device: &wgpu::Device) -> TracePass {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let ro = Storage { read_only: true };
        let rw = Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("trace.layout"),
            entries: &[
                entry(0, Uniform),
                entry(1, Uniform),
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
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("trace.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let src = shader::assemble("trace.wgsl").expect("trace.wgsl assembles");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("trace.wgsl"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let dispatch = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace.dispatch"),
            size: std::mem::size_of::<DispatchUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        TracePass {
            layout,
            pipeline_layout,
            module,
            pipelines: HashMap::new(),
            dispatch,
        }
    }

    /// The pipeline specialized for `features`, compiled now if it is new.
    pub fn prepare(&mut self, device: &wgpu::Device, features: Features) {
        if self.pipelines.contains_key(&features) {
            return;
        }
        let t = std::time::Instant::now();
        let constants = features.constants();
        let p = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("trace.pipeline"),
            layout: Some(&self.pipeline_layout),
            module: &self.module,
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
        self.pipelines.insert(features, p);
    }

    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        scene: &SceneBuffers,
        accum: &Accumulation,
    ) -> wgpu::BindGroup {
        let buffers = [
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
        ];
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace.bind_group"),
            layout: &self.layout,
            entries: &entries,
        })
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
        let pipeline = &self.pipelines[&d.features];
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("trace"),
            timestamp_writes: d.timer.map(GpuTimer::writes),
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, d.bind_group, &[]);
        pass.dispatch_workgroups(
            d.width.div_ceil(WORKGROUP),
            d.uniforms.row_count.div_ceil(WORKGROUP),
            1,
        );
    }
}
