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

/// How the passes bind their small per-scene and per-dispatch values, which the WGSL declares
/// `var<uniform>` (`SceneUniforms`, `DispatchUniforms`, `ResolveUniforms`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Values {
    /// Uniform buffers, on every adapter but lavapipe: a GPU reads them through its constant
    /// cache. Read-only storage buffers cost an H100 3–6 % of its samples/s (BENCHMARKS.md,
    /// "Shaders compiled once on lavapipe").
    Uniform,
    /// Read-only storage buffers, on lavapipe. Its Mesa (22.3 in Debian 12) inlines the
    /// uniform-buffer values that branches and loop bounds read and compiles the whole shader
    /// again with LLVM at every dispatch that binds it (Mesa,
    /// src/gallium/frontends/lavapipe/lvp_inline_uniforms.c, and `update_inline_shader_state`
    /// in lvp_execute.c); storage buffers are never inlined, so a pipeline compiles once and
    /// Mesa's shader cache keeps it for the next process.
    Storage,
}

impl Values {
    /// The binding for `ctx`'s adapter.
    pub fn of(ctx: &context::GpuContext) -> Values {
        if context::is_lavapipe(&ctx.info) {
            Values::Storage
        } else {
            Values::Uniform
        }
    }

    /// A layout's binding type `ty` as bound here: a uniform buffer becomes a read-only
    /// storage buffer where `self` is `Storage`, as [`Values::wgsl`] rewrites its declaration.
    pub fn binding(self, ty: wgpu::BufferBindingType) -> wgpu::BufferBindingType {
        match (self, ty) {
            (Values::Storage, wgpu::BufferBindingType::Uniform) => {
                wgpu::BufferBindingType::Storage { read_only: true }
            }
            _ => ty,
        }
    }

    /// The WGSL with its `var<uniform>` declarations bound as `self` says.
    pub fn wgsl(self, src: String) -> String {
        match self {
            Values::Uniform => src,
            Values::Storage => src.replace("var<uniform>", "var<storage, read>"),
        }
    }

    /// The usages of a values buffer: both, so that one buffer serves either binding.
    pub const USAGE: wgpu::BufferUsages = wgpu::BufferUsages::UNIFORM
        .union(wgpu::BufferUsages::STORAGE)
        .union(wgpu::BufferUsages::COPY_DST);
}

/// The bind group layout (buffers of these types, bound in order from 0) and the pipeline
/// of a small compute pass whose WGSL file and entry point are both named `name`
/// (`reduce.wgsl`, `fn reduce`).
pub(crate) fn simple_pass(
    ctx: &GpuContext,
    name: &str,
    buffers: &[wgpu::BufferBindingType],
) -> (wgpu::BindGroupLayout, wgpu::ComputePipeline) {
    let (layout, mut pipelines) = passes(ctx, name, buffers, &[name]);
    (layout, pipelines.remove(0))
}

/// The bind group layout (buffers of these types, bound in order from 0) shared by the
/// pipelines of `entry_points` of the WGSL file `name.wgsl`, one pipeline each. Its uniform
/// buffers are bound as [`Values::of`] the context says.
pub(crate) fn passes(
    ctx: &GpuContext,
    name: &str,
    buffers: &[wgpu::BufferBindingType],
    entry_points: &[&str],
) -> (wgpu::BindGroupLayout, Vec<wgpu::ComputePipeline>) {
    let (device, values) = (&ctx.device, Values::of(ctx));
    let entries: Vec<_> = buffers
        .iter()
        .enumerate()
        .map(|(i, &ty)| layout_entry(i as u32, values.binding(ty)))
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
    let src = values.wgsl(shader::assemble(&file).unwrap_or_else(|e| panic!("{file}: {e}")));
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

#[cfg(test)]
mod tests {
    use super::Values;
    use wgpu::BufferBindingType::{Storage, Uniform};

    #[test]
    fn storage_values_rebind_every_uniform_and_nothing_else() {
        for file in ["trace.wgsl", "reduce.wgsl", "resolve.wgsl", "denoise.wgsl"] {
            let src = super::shader::assemble(file).unwrap();
            let uniforms = src.matches("var<uniform>").count();
            assert!(uniforms > 0, "{file} declares its values var<uniform>");
            let storage = Values::Storage.wgsl(src.clone());
            assert!(!storage.contains("var<uniform>"), "{file}");
            assert_eq!(
                storage.matches("var<storage, read>").count(),
                src.matches("var<storage, read>").count() + uniforms,
                "{file}"
            );
            assert_eq!(Values::Uniform.wgsl(src.clone()), src);
            naga::front::wgsl::parse_str(&storage).unwrap_or_else(|e| panic!("{file}: {e}"));
        }
        let rw = Storage { read_only: false };
        assert_eq!(
            Values::Storage.binding(Uniform),
            Storage { read_only: true }
        );
        assert_eq!(Values::Storage.binding(rw), rw);
        assert_eq!(Values::Uniform.binding(Uniform), Uniform);
    }
}
