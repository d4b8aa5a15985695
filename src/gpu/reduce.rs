//! The reduce pass (`shaders/reduce.wgsl`): adds the per-lane sums that the tracer left in the
//! accumulation's scratch into the pixels' sums, after a dispatch that traced a pixel's
//! samples on several lanes.

use super::accum::Accumulation;
use super::scene_buffers::SceneBuffers;
use super::{GpuContext, bind_buffers, simple_pass};

/// Invocations per workgroup (`@workgroup_size` of `fn reduce`).
const WORKGROUP: u32 = 64;

pub struct ReducePass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl ReducePass {
    pub fn new(ctx: &GpuContext) -> ReducePass {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let (layout, pipeline) = simple_pass(
            ctx,
            "reduce",
            &[
                Uniform,
                Uniform,
                Storage { read_only: false },
                Storage { read_only: false },
                Storage { read_only: true },
            ],
        );
        ReducePass { layout, pipeline }
    }

    /// The bindings of one scene and accumulation; `dispatch` holds the tracer's
    /// per-submission uniforms (the rows and lanes to add up).
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        scene: &SceneBuffers,
        dispatch: &wgpu::Buffer,
        accum: &Accumulation,
    ) -> wgpu::BindGroup {
        bind_buffers(
            device,
            "reduce.bind_group",
            &self.layout,
            &[
                &scene.uniforms,
                dispatch,
                &accum.even,
                &accum.odd,
                &accum.scratch,
            ],
        )
    }

    /// Records the reduction of `pixels` pixels (the submission's rows × the image width).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
        pixels: u32,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("reduce"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(pixels.div_ceil(WORKGROUP), 1, 1);
    }
}
