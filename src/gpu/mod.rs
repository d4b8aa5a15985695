//! The GPU stage: adapter and device, the scene's buffers (the arrays of [`crate::common`]
//! uploaded), the tracer pass, the accumulation it writes, the reduce pass that merges lanes,
//! the preview's resolve pass and the denoiser's guide and filter passes.

pub mod accum;
pub mod context;
pub mod denoise;
pub mod engine;
pub mod guides;
pub mod reduce;
pub mod resolve;
pub mod scene_buffers;
pub mod shader;
pub mod timer;
pub mod trace;

pub use accum::Accumulation;
pub use context::{
    GpuContext, GpuError, describe, hardware_adapters, list_adapters, select_adapter,
};
pub use engine::{GpuEngine, GpuEngineOptions};
pub use scene_buffers::SceneBuffers;
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

/// The bind group layout (buffers of these types, bound in order from 0) and the pipeline
/// of a small compute pass whose WGSL file and entry point are both named `name`
/// (`reduce.wgsl`, `fn reduce`).
pub(crate) fn simple_pass(
    device: &wgpu::Device,
    name: &str,
    buffers: &[wgpu::BufferBindingType],
) -> (wgpu::BindGroupLayout, wgpu::ComputePipeline) {
    let (layout, mut pipelines) = passes(device, name, buffers, &[name]);
    (layout, pipelines.remove(0))
}

/// The bind group layout (buffers of these types, bound in order from 0) shared by the
/// pipelines of `entry_points` of the WGSL file `name.wgsl`, one pipeline each.
pub(crate) fn passes(
    device: &wgpu::Device,
    name: &str,
    buffers: &[wgpu::BufferBindingType],
    entry_points: &[&str],
) -> (wgpu::BindGroupLayout, Vec<wgpu::ComputePipeline>) {
    let entries: Vec<_> = buffers
        .iter()
        .enumerate()
        .map(|(i, &ty)| layout_entry(i as u32, ty))
        .collect();
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(&format!("{name}.layout")),
        entries: &entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(&format!("{name}.pipeline_layout")),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let file = format!("{name}.wgsl");
    let src = shader::assemble(&file).unwrap_or_else(|e| panic!("{file}: {e}"));
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&file),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    let pipelines = entry_points
        .iter()
        .map(|e| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&format!("{name}.{e}")),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(e),
                compilation_options: Default::default(),
                cache: None,
            })
        })
        .collect();
    (layout, pipelines)
}

/// Maps `slice` of a readback buffer for reading and waits until it is mapped (every
/// submission before it done); `what` names the work in the panic message if the GPU stops
/// answering.
pub(crate) fn map_read(ctx: &GpuContext, slice: &wgpu::BufferSlice<'_>, what: &str) {
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .unwrap_or_else(|e| panic!("the GPU stopped answering while {what}: {e}"));
    rx.recv()
        .expect("map callback")
        .unwrap_or_else(|e| panic!("mapping the readback of {what} failed: {e}"));
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
