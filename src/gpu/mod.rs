//! The GPU stage: adapter and device, the scene's buffers, the tracer pass, the accumulation
//! it writes, the reduce pass that merges lanes and the preview's resolve pass.

pub mod accum;
pub mod context;
pub mod features;
pub mod layout;
pub mod reduce;
pub mod resolve;
pub mod scene_buffers;
pub mod shader;
pub mod timer;
pub mod trace;

pub use accum::{AccumData, Accumulation};
pub use context::{GpuContext, GpuError, describe, list_adapters, select_adapter};
pub use features::Features;
pub use scene_buffers::{FrameSettings, SceneBuffers};
pub use trace::TracePass;

/// A compute-stage buffer binding of the given type.
pub(crate) fn layout_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
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

/// A bind group of whole buffers, bound in order from binding 0.
pub(crate) fn bind_buffers(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}
