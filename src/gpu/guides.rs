//! The denoiser's guide pass (`fn guides` in shaders/trace.wgsl): the albedo and normal sums
//! of every pixel, made by an entry point of the tracer's module over the tracer's own bind
//! group (group 0) and its output (group 1), compiled per feature set on first use, so that a
//! render that does not denoise compiles none of it.

use super::{GpuContext, layout_entry};
use crate::common::Features;
use crate::common::guides::GUIDE_WORDS;
use crate::common::layout::DispatchUniforms;
use std::collections::HashMap;

pub struct GuidePass {
    out_layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: HashMap<Features, wgpu::ComputePipeline>,
    /// The sums and their bind group, for the image size they were made for.
    sums: Option<(wgpu::Buffer, wgpu::BindGroup, u64)>,
}

impl GuidePass {
    pub fn new(device: &wgpu::Device, trace_layout: &wgpu::BindGroupLayout) -> GuidePass {
        let out_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("guides.layout"),
            entries: &[layout_entry(
                0,
                wgpu::BufferBindingType::Storage { read_only: false },
            )],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("guides.pipeline_layout"),
            bind_group_layouts: &[Some(trace_layout), Some(&out_layout)],
            immediate_size: 0,
        });
        GuidePass {
            out_layout,
            pipeline_layout,
            pipelines: HashMap::new(),
            sums: None,
        }
    }

    /// The sums of the last run (`GUIDE_WORDS` words a pixel), where the GPU's denoiser reads
    /// them.
    pub fn sums(&self) -> Option<&wgpu::Buffer> {
        self.sums.as_ref().map(|s| &s.0)
    }

    /// Traces guide samples `samples` of every pixel of the `width × height` image into fresh
    /// sums (`GUIDE_WORDS` words per pixel), left on the GPU ([`GuidePass::read`] brings
    /// them back). `dispatch` is the tracer's uniforms buffer, which group 0 binds; nothing
    /// else may be encoded meanwhile.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        module: &wgpu::ShaderModule,
        trace_group: &wgpu::BindGroup,
        dispatch: &wgpu::Buffer,
        features: Features,
        (width, height): (u32, u32),
        samples: std::ops::Range<u32>,
    ) {
        let device = &ctx.device;
        let pipeline = self.pipelines.entry(features).or_insert_with(|| {
            let constants = features.constants();
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("guides.pipeline"),
                layout: Some(&self.pipeline_layout),
                module,
                entry_point: Some("guides"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    zero_initialize_workgroup_memory: false,
                },
                cache: None,
            })
        });
        let bytes = (width as u64 * height as u64 * GUIDE_WORDS as u64 * 4).max(4);
        if self.sums.as_ref().is_none_or(|s| s.2 != bytes) {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("guides.sums"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("guides.bind_group"),
                layout: &self.out_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: buffer.as_entire_binding(),
                }],
            });
            self.sums = Some((buffer, group, bytes));
        }
        let (_, group, _) = self.sums.as_ref().expect("guide sums");
        let u = DispatchUniforms {
            sample_base: samples.start,
            sample_count: samples.len() as u32,
            row_offset: 0,
            row_count: height,
            accumulate: 0,
            lanes: 1,
            row_stride: 1,
            _pad: 0,
        };
        ctx.queue.write_buffer(dispatch, 0, bytemuck::bytes_of(&u));
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("guides.submission"),
        });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("guides"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, trace_group, &[]);
            pass.set_bind_group(1, group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        ctx.queue.submit([enc.finish()]);
    }

    /// The sums of the last run, read back to the host (empty before any run).
    pub fn read(&self, ctx: &GpuContext) -> Vec<u32> {
        let Some((buffer, _, bytes)) = &self.sums else {
            return Vec::new();
        };
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("guides.staging"),
            size: *bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("guides.readback"),
            });
        enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, *bytes);
        ctx.queue.submit([enc.finish()]);
        let slice = staging.slice(..);
        super::map_read(ctx, &slice, "reading back the guides");
        let data = slice.get_mapped_range().expect("mapped");
        let words: Vec<u32> = bytemuck::cast_slice(&data[..]).to_vec();
        drop(data);
        staging.unmap();
        words
    }
}
