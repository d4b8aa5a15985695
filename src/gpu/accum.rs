//! The accumulation buffers (running sums of the even and odd samples of every pixel, in
//! 96-bit fixed point: see `fixed_add` in common/fixed.wgsl), the per-lane scratch sums that
//! the reduce pass adds into them, the invalid-sample and segment counters, and their
//! readback.

use super::GpuContext;

/// Words of one pixel in one half: three per channel (fraction, low and high 32 bits of
/// the integer part) and the sample count (ACCUM_WORDS in trace.wgsl).
pub const ACCUM_WORDS: usize = 10;
const PIXEL_BYTES: u64 = 4 * ACCUM_WORDS as u64;
/// One lane's sums of one pixel in `scratch`: both halves.
const SLOT_BYTES: u64 = 2 * PIXEL_BYTES;
/// Four u64 counters as (lo, hi) u32 pairs: invalid samples, path segments, BVH node visits,
/// primitive tests.
const COUNTER_BYTES: u64 = 32;

/// The per-pixel sums read back from the GPU, each `[r, g, b, samples]` (the exact sums,
/// rounded to f32 only here).
#[derive(Clone, Debug)]
pub struct AccumData {
    pub even: Vec<[f32; 4]>,
    pub odd: Vec<[f32; 4]>,
    /// Samples discarded because they were NaN or infinite, since the last reset.
    pub invalid: u64,
    /// Path segments traced since the last reset (counted only when asked for).
    pub segments: u64,
    /// BVH nodes visited and primitives tested since the last reset (likewise).
    pub node_visits: u64,
    pub primitive_tests: u64,
}

impl AccumData {
    /// Sums from elsewhere (a cache, a test), with every counter at zero.
    pub fn from_halves(even: Vec<[f32; 4]>, odd: Vec<[f32; 4]>) -> AccumData {
        AccumData {
            even,
            odd,
            invalid: 0,
            segments: 0,
            node_visits: 0,
            primitive_tests: 0,
        }
    }
}

/// One pixel's fixed-point sums (its `ACCUM_WORDS` words) as `[r, g, b, samples]`, exact
/// until this rounding to f32.
pub fn decode_pixel(p: &[u32]) -> [f32; 4] {
    let channel = |c: usize| {
        let (frac, low, high) = (p[3 * c], p[3 * c + 1], p[3 * c + 2]);
        (high as f64 * 4294967296.0 + low as f64 + frac as f64 / 4294967296.0) as f32
    };
    [channel(0), channel(1), channel(2), p[9] as f32]
}

/// Decodes fixed-point sums (`ACCUM_WORDS` words per pixel) to `[r, g, b, samples]`.
pub fn decode(words: &[u32]) -> Vec<[f32; 4]> {
    words.chunks_exact(ACCUM_WORDS).map(decode_pixel).collect()
}

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

    /// Copies everything back to the host and decodes the fixed-point sums.
    pub fn read(&self, ctx: &GpuContext) -> AccumData {
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
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("the GPU stopped answering while reading back the image");
        rx.recv()
            .expect("map callback")
            .expect("mapping the readback buffer failed");
        let data = slice
            .get_mapped_range()
            .expect("the readback buffer is mapped");
        let words: &[u32] = bytemuck::cast_slice(&data[..(2 * half) as usize]);
        let n = self.pixels as usize;
        let even = decode(&words[..n * ACCUM_WORDS]);
        let odd = decode(&words[n * ACCUM_WORDS..]);
        let c: &[u32] = bytemuck::cast_slice(&data[(2 * half) as usize..]);
        let u64_of = |lo: u32, hi: u32| lo as u64 | (hi as u64) << 32;
        let out = AccumData {
            even,
            odd,
            invalid: u64_of(c[0], c[1]),
            segments: u64_of(c[2], c[3]),
            node_visits: u64_of(c[4], c[5]),
            primitive_tests: u64_of(c[6], c[7]),
        };
        drop(data);
        self.staging.unmap();
        out
    }
}
