//! The accumulation buffers (running sums of the even and odd samples of every pixel, in
//! 96-bit fixed point: see `fixed_add` in common/fixed.wgsl), the per-lane scratch sums that
//! the reduce pass adds into them, the invalid-sample and segment counters, and their
//! readback.

use super::GpuContext;
use crate::common::accum::{ACCUM_WORDS, AccumData, Sums, decode};

const PIXEL_BYTES: u64 = 4 * ACCUM_WORDS as u64;
/// One lane's sums of one pixel in `scratch`: both halves.
const SLOT_BYTES: u64 = 2 * PIXEL_BYTES;
/// Four u64 counters as (lo, hi) u32 pairs: invalid samples, path segments, BVH node visits,
/// primitive tests.
const COUNTER_BYTES: u64 = 32;

pub struct Accumulation {
    pub even: wgpu::Buffer,
    pub odd: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    /// Per-lane sums of the pixels of one submission (`scratch_slots` of them).
    pub scratch: wgpu::Buffer,
    pub scratch_slots: u64,
    staging: wgpu::Buffer,
    pixels: u64,
}

impl Accumulation {
    /// Sums for `width × height` pixels, and scratch for `scratch_slots` lane-pixels (at
    /// least one, so that the buffer can be bound).
    pub fn new(device: &wgpu::Device, width: u32, height: u32, scratch_slots: u64) -> Accumulation {
        let pixels = width as u64 * height as u64;
        let scratch_slots = scratch_slots.max(1);
        let half = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: pixels * PIXEL_BYTES,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Accumulation {
            even: half("accum.even"),
            odd: half("accum.odd"),
            counters: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("accum.counters"),
                size: COUNTER_BYTES,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            scratch: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("accum.scratch"),
                size: scratch_slots * SLOT_BYTES,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
            scratch_slots,
            staging: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("accum.staging"),
                size: 2 * pixels * PIXEL_BYTES + COUNTER_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            pixels,
        }
    }

    /// Bytes the accumulation holds on the GPU (sums, counters, the readback copy, scratch).
    pub fn gpu_bytes(&self) -> u64 {
        2 * (2 * self.pixels * PIXEL_BYTES + COUNTER_BYTES) + self.scratch_slots * SLOT_BYTES
    }

    /// Zeroes the counters (the sums are restarted by the tracer's `accumulate = 0`).
    pub fn reset_counters(&self, queue: &wgpu::Queue) {
        queue.write_buffer(&self.counters, 0, &[0u8; COUNTER_BYTES as usize]);
    }

    /// Copies the exact sums (even, odd) and the invalid count back to the host, undecoded.
    pub fn read_words(&self, ctx: &GpuContext) -> Sums {
        let n = self.pixels as usize * ACCUM_WORDS;
        self.read_with(ctx, |words, c| Sums {
            even: words[..n].to_vec(),
            odd: words[n..].to_vec(),
            invalid: c[0] as u64 | (c[1] as u64) << 32,
        })
    }

    /// Copies the sums and counters back and gives `f` the words of both halves and the
    /// counters' words, in place in the mapped readback buffer.
    fn read_with<R>(&self, ctx: &GpuContext, f: impl FnOnce(&[u32], &[u32]) -> R) -> R {
        let half = self.pixels * PIXEL_BYTES;
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("accum.readback"),
            });
        enc.copy_buffer_to_buffer(&self.even, 0, &self.staging, 0, half);
        enc.copy_buffer_to_buffer(&self.odd, 0, &self.staging, half, half);
        enc.copy_buffer_to_buffer(&self.counters, 0, &self.staging, 2 * half, COUNTER_BYTES);
        ctx.queue.submit([enc.finish()]);
        let slice = self.staging.slice(..);
        super::map_read(ctx, &slice, "reading back the image");
        let data = slice
            .get_mapped_range()
            .expect("the readback buffer is mapped");
        let out = f(
            bytemuck::cast_slice(&data[..(2 * half) as usize]),
            bytemuck::cast_slice(&data[(2 * half) as usize..]),
        );
        drop(data);
        self.staging.unmap();
        out
    }

    /// Copies everything back to the host and decodes the fixed-point sums.
    pub fn read(&self, ctx: &GpuContext) -> AccumData {
        let n = self.pixels as usize * ACCUM_WORDS;
        self.read_with(ctx, |words, c| {
            let u64_of = |lo: u32, hi: u32| lo as u64 | (hi as u64) << 32;
            AccumData {
                even: decode(&words[..n]),
                odd: decode(&words[n..]),
                invalid: u64_of(c[0], c[1]),
                segments: u64_of(c[2], c[3]),
                node_visits: u64_of(c[4], c[5]),
                primitive_tests: u64_of(c[6], c[7]),
            }
        })
    }
}
