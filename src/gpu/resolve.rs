//! The preview's resolve pass (`shaders/resolve.wgsl`): makes the small image that the
//! terminal shows, and the terms of its noise estimate, on the GPU from the accumulation, and
//! reads it back asynchronously through two staging buffers: the render thread requests a
//! frame, goes on tracing, and takes the frame once its copy has landed. On several devices
//! the others' sums, uploaded once per frame (`set_extra`), are added to each pixel's on the
//! GPU, so that the frame is still made there and only the small image read back.

use super::accum::Accumulation;
use super::{GpuContext, Values, bind_buffers, simple_pass};
use crate::common::layout::ResolveUniforms;
use crate::common::resolved::Resolved;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

/// Staging buffers: one frame can land while the next is in flight.
pub const SLOTS: usize = 2;
/// Bytes per output pixel: two vec4f (see resolve.wgsl; the denoiser's output too).
pub(super) const OUT_BYTES: u64 = 32;
/// Bytes of the invalid-sample counter copied behind the image.
const COUNTER_BYTES: u64 = 8;

const FREE: u8 = 0;
const PENDING: u8 = 1;
const MAPPED: u8 = 2;
const FAILED: u8 = 3;

struct Slot {
    buffer: Option<wgpu::Buffer>,
    state: Arc<AtomicU8>,
    out: (u32, u32),
    /// Traced pixels per output pixel, each way.
    factor: u32,
}

pub struct ResolvePass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    uniforms: wgpu::Buffer,
    output: Option<wgpu::Buffer>,
    slots: Vec<Slot>,
    /// The other devices' even and odd sums (`set_extra`), while they are added.
    extra: Option<(wgpu::Buffer, wgpu::Buffer)>,
    extra_on: bool,
}

impl ResolvePass {
    pub fn new(ctx: &GpuContext) -> ResolvePass {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let (layout, pipeline) = simple_pass(
            ctx,
            "resolve",
            &[
                Uniform,
                Storage { read_only: true },
                Storage { read_only: true },
                Storage { read_only: false },
                Storage { read_only: true },
                Storage { read_only: true },
            ],
        );
        let uniforms = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resolve.uniforms"),
            size: std::mem::size_of::<ResolveUniforms>() as u64,
            usage: Values::USAGE,
            mapped_at_creation: false,
        });
        let slots = (0..SLOTS)
            .map(|_| Slot {
                buffer: None,
                state: Arc::new(AtomicU8::new(FREE)),
                out: (0, 0),
                factor: 1,
            })
            .collect();
        ResolvePass {
            layout,
            pipeline,
            uniforms,
            output: None,
            slots,
            extra: None,
            extra_on: false,
        }
    }

    /// Adds `even` and `odd` (exact sums, `ACCUM_WORDS` words a pixel: the other devices'
    /// of the same image) to the accumulation in the frames requested from now on; they are
    /// uploaded now, in the queue's order, so a frame in flight is not changed.
    pub fn set_extra(&mut self, ctx: &GpuContext, even: &[u32], odd: &[u32]) {
        let bytes = std::mem::size_of_val(even) as u64;
        if self
            .extra
            .as_ref()
            .is_none_or(|(e, _)| e.size() < bytes.max(4))
        {
            let make = |label| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes.max(4),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            self.extra = Some((make("resolve.extra_even"), make("resolve.extra_odd")));
        }
        let (e, o) = self.extra.as_ref().expect("extra buffers");
        ctx.queue.write_buffer(e, 0, bytemuck::cast_slice(even));
        ctx.queue.write_buffer(o, 0, bytemuck::cast_slice(odd));
        self.extra_on = true;
    }

    /// Frames requested from now on show the accumulation alone.
    pub fn clear_extra(&mut self) {
        self.extra_on = false;
    }

    /// Whether some slot can take a request.
    pub fn has_free_slot(&self) -> bool {
        self.slots
            .iter()
            .any(|s| s.state.load(Ordering::Acquire) == FREE)
    }

    /// Resolves the `width × height` accumulation to `width / factor × height / factor` in its
    /// own submission (after all work submitted before) and starts its readback. Returns the
    /// slot to [`ResolvePass::take`] it from, or `None` when both slots are busy.
    pub fn request(
        &mut self,
        ctx: &GpuContext,
        accum: &Accumulation,
        (width, height): (u32, u32),
        factor: u32,
    ) -> Option<usize> {
        let slot = self
            .slots
            .iter()
            .position(|s| s.state.load(Ordering::Acquire) == FREE)?;
        let factor = factor.max(1);
        let out = ((width / factor).max(1), (height / factor).max(1));
        let bytes = out.0 as u64 * out.1 as u64 * OUT_BYTES;
        let device = &ctx.device;
        if self.output.as_ref().is_none_or(|b| b.size() < bytes) {
            self.output = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("resolve.output"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }));
        }
        let s = &mut self.slots[slot];
        if s.buffer
            .as_ref()
            .is_none_or(|b| b.size() < bytes + COUNTER_BYTES)
        {
            s.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("resolve.staging"),
                size: bytes + COUNTER_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let output = self.output.as_ref().expect("output buffer");
        let staging = s.buffer.as_ref().expect("staging buffer");
        let u = ResolveUniforms {
            width,
            height,
            factor,
            out_width: out.0,
            out_height: out.1,
            mode: u32::from(self.extra_on),
            _pad: [0; 2],
        };
        ctx.queue
            .write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&u));
        // Unread unless `mode` says so: the accumulation stands in for no extra sums.
        let (extra_even, extra_odd) = match (&self.extra, self.extra_on) {
            (Some((e, o)), true) => (e, o),
            _ => (&accum.even, &accum.odd),
        };
        let bind_group = bind_buffers(
            device,
            "resolve.bind_group",
            &self.layout,
            &[
                &self.uniforms,
                &accum.even,
                &accum.odd,
                output,
                extra_even,
                extra_odd,
            ],
        );
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("resolve.submission"),
        });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("resolve"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(out.0.div_ceil(8), out.1.div_ceil(8), 1);
        }
        enc.copy_buffer_to_buffer(output, 0, staging, 0, bytes);
        enc.copy_buffer_to_buffer(&accum.counters, 0, staging, bytes, COUNTER_BYTES);
        ctx.queue.submit([enc.finish()]);
        s.state.store(PENDING, Ordering::Release);
        s.out = out;
        s.factor = factor;
        let state = s.state.clone();
        staging
            .slice(..bytes + COUNTER_BYTES)
            .map_async(wgpu::MapMode::Read, move |r| {
                state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
        Some(slot)
    }

    /// Whether `slot`'s readback has landed (poll the device to make progress).
    pub fn ready(&self, slot: usize) -> bool {
        matches!(
            self.slots[slot].state.load(Ordering::Acquire),
            MAPPED | FAILED
        )
    }

    /// The frame of `slot` once it has landed (`None` before, or if mapping failed); frees
    /// the slot.
    pub fn take(&mut self, slot: usize) -> Option<Resolved> {
        let s = &mut self.slots[slot];
        match s.state.load(Ordering::Acquire) {
            MAPPED => {}
            FAILED => {
                s.state.store(FREE, Ordering::Release);
                return None;
            }
            _ => return None,
        }
        let staging = s.buffer.as_ref().expect("a mapped slot has a buffer");
        let n = s.out.0 as usize * s.out.1 as usize;
        let bytes = n as u64 * OUT_BYTES;
        let resolved = {
            let data = staging
                .slice(..bytes + COUNTER_BYTES)
                .get_mapped_range()
                .expect("the staging buffer is mapped");
            let words: &[[f32; 8]] = bytemuck::cast_slice(&data[..bytes as usize]);
            let c: &[u32] = bytemuck::cast_slice(&data[bytes as usize..]);
            Resolved::from_blocks(words, s.out, s.factor, c[0] as u64 | (c[1] as u64) << 32)
        };
        staging.unmap();
        s.state.store(FREE, Ordering::Release);
        Some(resolved)
    }
}
