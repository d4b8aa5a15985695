//! The probe passes: the tracer's own intersection and scattering functions
//! (`shaders/probe.wgsl`) and the pbr model's sampler (`shaders/pbr_probe.wgsl`), run on the
//! GPU on inputs from the host.

use crate::common::layout::{GpuMaterial, GpuQuad, GpuSphere};
use crate::gpu::GpuContext;
use crate::gpu::shader;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

pub const PROBE_SPHERE: u32 = 0;
pub const PROBE_QUAD: u32 = 1;
pub const PROBE_SCATTER: u32 = 2;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuProbeInput {
    pub origin: [f32; 3],
    pub kind: u32,
    pub dir: [f32; 3],
    pub ratio: f32,
    pub normal: [f32; 3],
    pub _pad0: f32,
    pub sphere: GpuSphere,
    pub quad: GpuQuad,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuProbeOutput {
    pub t: f32,
    pub schlick: f32,
    pub _pad0: [f32; 2],
    pub point: [f32; 3],
    pub _pad2: f32,
    pub normal: [f32; 3],
    pub _pad3: f32,
    pub reflected: [f32; 3],
    pub _pad4: f32,
    pub refracted: [f32; 3],
    pub _pad5: f32,
}

/// A lobe of the pbr model to draw from (`PbrProbeInput` in pbr_probe.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuPbrProbeInput {
    pub material: GpuMaterial,
    pub wo: [f32; 3],
    pub seed: u32,
    pub n: [f32; 3],
    /// 1: `wo` is on the outer side of the surface (a volume's boundary is entered).
    pub front: u32,
}

/// One draw of the pbr sampler (`PbrProbeOutput` in pbr_probe.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuPbrProbeOutput {
    pub dir: [f32; 3],
    pub pdf: f32,
    pub weight: [f32; 3],
    pub ok: u32,
}

const _: () = {
    assert!(std::mem::size_of::<GpuProbeInput>() == 160);
    assert!(std::mem::size_of::<GpuProbeOutput>() == 80);
    assert!(std::mem::size_of::<GpuPbrProbeInput>() == 128);
    assert!(std::mem::size_of::<GpuPbrProbeOutput>() == 32);
};

/// The compute pipeline of a probe shader's entry point (named as its file).
fn pipeline(device: &wgpu::Device, file: &str, entry: &str) -> wgpu::ComputePipeline {
    let src = shader::assemble(file).unwrap_or_else(|e| panic!("{file}: {e}"));
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(file),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

pub struct ProbePass {
    pipeline: wgpu::ComputePipeline,
}

impl ProbePass {
    pub fn new(device: &wgpu::Device) -> ProbePass {
        ProbePass {
            pipeline: pipeline(device, "probe.wgsl", "probe"),
        }
    }

    /// Runs every input and returns the outputs in order.
    pub fn run(&self, ctx: &GpuContext, inputs: &[GpuProbeInput]) -> Vec<GpuProbeOutput> {
        dispatch(ctx, &self.pipeline, inputs, inputs.len())
    }
}

/// The pbr model's sampler on the GPU (`shaders/pbr_probe.wgsl`).
pub struct PbrProbePass {
    pipeline: wgpu::ComputePipeline,
}

impl PbrProbePass {
    pub fn new(device: &wgpu::Device) -> PbrProbePass {
        PbrProbePass {
            pipeline: pipeline(device, "pbr_probe.wgsl", "pbr_probe"),
        }
    }

    /// Draws `n` directions from the lobe of `input`, draw i from sample i's random stream.
    pub fn run(
        &self,
        ctx: &GpuContext,
        input: GpuPbrProbeInput,
        n: usize,
    ) -> Vec<GpuPbrProbeOutput> {
        dispatch(ctx, &self.pipeline, &[input], n)
    }
}

/// Runs `pipeline` (bindings 0: the inputs, 1: the outputs) over `n` outputs, one invocation
/// each, and returns them in order.
fn dispatch<I: Pod, O: Pod>(
    ctx: &GpuContext,
    pipeline: &wgpu::ComputePipeline,
    inputs: &[I],
    n: usize,
) -> Vec<O> {
    if inputs.is_empty() || n == 0 {
        return Vec::new();
    }
    let d = &ctx.device;
    let input = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("probe.inputs"),
        contents: bytemuck::cast_slice(inputs),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let size = (n * std::mem::size_of::<O>()) as u64;
    let output = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some("probe.outputs"),
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some("probe.readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("probe.bind_group"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("probe"),
    });
    {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("probe"),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
    }
    enc.copy_buffer_to_buffer(&output, 0, &readback, 0, size);
    ctx.queue.submit([enc.finish()]);
    let slice = readback.slice(..);
    slice.map_async(wgpu::MapMode::Read, |_| {});
    d.poll(wgpu::PollType::wait_indefinitely())
        .expect("the GPU stopped answering");
    let out = bytemuck::cast_slice(&slice.get_mapped_range().expect("mapped")).to_vec();
    readback.unmap();
    out
}
