//! The denoiser's pass on the GPU (`shaders/denoise.wgsl`): the filter of `src/denoise` run
//! where the accumulation and the guides already are, so that a denoised preview frame reads
//! back only the small image and the tiles' estimate sums. Six entry points of one module
//! over one bind group layout; the two filter layers swap between iterations, and the
//! regression writes the one the last iteration did not.

use super::accum::Accumulation;
use super::{GpuContext, Values, bind_buffers};
use crate::common::layout::ResolveUniforms;
use crate::denoise::{DenoisedTiles, TILE_FLOATS};

/// À-trous iterations (src/denoise/atrous.rs: ITERATIONS), taps 1 to 16 pixels apart.
const ITERATIONS: u32 = 5;
/// Traced pixels per tile side (src/denoise: TILE).
pub const TILE: u32 = 16;
/// Floats per pixel of the filter's layers, of the demodulated halves, of the images.
const LAYER: u64 = 10;
const DEMOD: u64 = 12;
const IMAGES: u64 = 9;
/// Bytes per tile of the estimate's sums (eight floats), and per output pixel (r, g, b).
const TILE_BYTES: u64 = 4 * TILE_FLOATS as u64;
const OUT_BYTES: u64 = 12;

/// Bytes of the accumulation's invalid-sample counter, read back behind the tiles.
const COUNTER_BYTES: u64 = 8;

struct Buffers {
    size: (u32, u32, u32),
    texels: wgpu::Buffer,
    demod: wgpu::Buffer,
    layer_a: wgpu::Buffer,
    layer_b: wgpu::Buffer,
    images: wgpu::Buffer,
    tiles: wgpu::Buffer,
    out: wgpu::Buffer,
    staging: wgpu::Buffer,
    out_bytes: u64,
    tile_bytes: u64,
}

pub struct DenoisePass {
    layout: wgpu::BindGroupLayout,
    /// prepare, settle, atrous, regress, finish, compose.
    pipelines: Vec<wgpu::ComputePipeline>,
    /// Uniforms of the passes without a step (0) and of each iteration (1..).
    uniforms: Vec<wgpu::Buffer>,
    buffers: Option<Buffers>,
    /// Timestamps around every dispatch, where asked for (`profile`).
    profile: Option<Profile>,
    /// The bind groups of the last run (the passes without a step, then each iteration's)
    /// and what they bind: made again only when the accumulation, the guides or the size
    /// change.
    bound: Option<(Bound, Vec<wgpu::BindGroup>)>,
}

/// What a run's bind groups and uniforms depend on: the accumulation's halves, the guides'
/// sums, and the size and factor.
#[derive(PartialEq)]
struct Bound {
    even: wgpu::Buffer,
    odd: wgpu::Buffer,
    guides: wgpu::Buffer,
    size: (u32, u32, u32),
}

/// Two timestamps around each of the `DISPATCHES` dispatches of a run (benchmarks).
struct Profile {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
}

/// prepare, settle, the iterations, regress, finish, compose.
const DISPATCHES: u32 = 5 + ITERATIONS;

const ENTRY_POINTS: [&str; 6] = [
    "prepare", "settle", "atrous", "regress", "finish", "compose",
];

impl DenoisePass {
    pub fn new(ctx: &GpuContext) -> DenoisePass {
        use wgpu::BufferBindingType::{Storage, Uniform};
        let device = &ctx.device;
        let (ro, rw) = (Storage { read_only: true }, Storage { read_only: false });
        let kinds = [Uniform, ro, ro, ro, rw, rw, ro, rw, rw, rw, rw];
        let (layout, pipelines) = super::passes(ctx, "denoise", &kinds, &ENTRY_POINTS);
        let uniforms = (0..=ITERATIONS)
            .map(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("denoise.uniforms"),
                    size: std::mem::size_of::<ResolveUniforms>() as u64,
                    usage: Values::USAGE,
                    mapped_at_creation: false,
                })
            })
            .collect();
        DenoisePass {
            layout,
            pipelines,
            uniforms,
            buffers: None,
            profile: None,
            bound: None,
        }
    }

    /// Times every dispatch of the following runs on the GPU, where the device has timestamp
    /// queries (`bench`); [`DenoisePass::profile`] reads the last run's times.
    pub fn enable_profile(&mut self, ctx: &GpuContext) {
        if !ctx.timestamps || self.profile.is_some() {
            return;
        }
        let d = &ctx.device;
        let bytes = 16 * DISPATCHES as u64;
        let buffer = |label, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        self.profile = Some(Profile {
            set: d.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("denoise.queries"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * DISPATCHES,
            }),
            resolve: buffer("denoise.queries.resolve", U::QUERY_RESOLVE | U::COPY_SRC),
            readback: buffer("denoise.queries.readback", U::MAP_READ | U::COPY_DST),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        });
    }

    /// Milliseconds each dispatch of the last run took on the GPU (prepare, settle, the
    /// iterations, regress, finish, compose), where profiling.
    pub fn profile(&self, ctx: &GpuContext) -> Option<Vec<f64>> {
        let p = self.profile.as_ref()?;
        let slice = p.readback.slice(..);
        super::map_read(ctx, &slice, "the denoiser's timestamps");
        let ms = {
            let data = slice.get_mapped_range().expect("mapped");
            let t: &[u64] = bytemuck::cast_slice(&data);
            t.chunks_exact(2)
                .map(|c| c[1].saturating_sub(c[0]) as f64 * p.period_ns * 1e-6)
                .collect()
        };
        p.readback.unmap();
        Some(ms)
    }

    fn buffers(&mut self, device: &wgpu::Device, w: u32, h: u32, factor: u32) -> &Buffers {
        if self
            .buffers
            .as_ref()
            .is_none_or(|b| b.size != (w, h, factor))
        {
            let pixels = w as u64 * h as u64;
            let storage = |label, bytes: u64, extra| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes.max(4),
                    usage: wgpu::BufferUsages::STORAGE | extra,
                    mapped_at_creation: false,
                })
            };
            let none = wgpu::BufferUsages::empty();
            let out = ((w / factor).max(1) as u64, (h / factor).max(1) as u64);
            let tiles = w.div_ceil(TILE) as u64 * h.div_ceil(TILE) as u64;
            let (out_bytes, tile_bytes) = (out.0 * out.1 * OUT_BYTES, tiles * TILE_BYTES);
            self.buffers = Some(Buffers {
                size: (w, h, factor),
                texels: storage("denoise.texels", pixels * 32, none),
                demod: storage("denoise.demod", pixels * DEMOD * 4, none),
                layer_a: storage("denoise.layer_a", pixels * LAYER * 4, none),
                layer_b: storage("denoise.layer_b", pixels * LAYER * 4, none),
                images: storage("denoise.images", pixels * IMAGES * 4, none),
                tiles: storage("denoise.tiles", tile_bytes, wgpu::BufferUsages::COPY_SRC),
                out: storage("denoise.out", out_bytes, wgpu::BufferUsages::COPY_SRC),
                staging: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("denoise.staging"),
                    size: out_bytes + tile_bytes + COUNTER_BYTES,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                out_bytes,
                tile_bytes,
            });
        }
        self.buffers.as_ref().expect("denoise buffers")
    }

    /// Denoises the `width × height` accumulation with the guides' sums (`GUIDE_WORDS` words
    /// a pixel) and reads back the image averaged by `factor` and the tiles' sums; waits
    /// for the GPU.
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        accum: &Accumulation,
        guides: &wgpu::Buffer,
        (width, height): (u32, u32),
        factor: u32,
    ) -> DenoisedTiles {
        let factor = factor.max(1);
        let device = &ctx.device;
        let out = ((width / factor).max(1), (height / factor).max(1));
        let tiles_x = width.div_ceil(TILE);
        let key = Bound {
            even: accum.even.clone(),
            odd: accum.odd.clone(),
            guides: guides.clone(),
            size: (width, height, factor),
        };
        if self.bound.as_ref().is_none_or(|(k, _)| *k != key) {
            self.bound = None;
            for (i, u) in self.uniforms.iter().enumerate() {
                let step = if i == 0 { 0 } else { 1 << (i - 1) };
                let params = ResolveUniforms {
                    width,
                    height,
                    factor,
                    out_width: out.0,
                    out_height: out.1,
                    mode: step,
                    _pad: [0, 0],
                };
                ctx.queue.write_buffer(u, 0, bytemuck::bytes_of(&params));
            }
            self.buffers(device, width, height, factor);
            let b = self.buffers.as_ref().expect("denoise buffers");
            let group = |uniform: usize, a_to_b: bool| {
                let (src, dst) = if a_to_b {
                    (&b.layer_a, &b.layer_b)
                } else {
                    (&b.layer_b, &b.layer_a)
                };
                bind_buffers(
                    device,
                    "denoise.bind_group",
                    &self.layout,
                    &[
                        &self.uniforms[uniform],
                        &accum.even,
                        &accum.odd,
                        guides,
                        &b.texels,
                        &b.demod,
                        src,
                        dst,
                        &b.images,
                        &b.tiles,
                        &b.out,
                    ],
                )
            };
            // settle writes layer a; iteration i reads a and writes b when i is even; the
            // result (after an odd number of iterations) is in b, which regress reads,
            // writing a, and finish reads both.
            let mut groups = vec![group(0, false)];
            groups.extend((0..ITERATIONS).map(|i| group(i as usize + 1, i % 2 == 0)));
            self.bound = Some((key, groups));
        }
        let b = self.buffers.as_ref().expect("denoise buffers");
        let groups = &self.bound.as_ref().expect("bind groups made").1;
        let (plain, iterations) = (&groups[0], &groups[1..]);
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("denoise.submission"),
        });
        let (gx, gy) = (width.div_ceil(8), height.div_ceil(8));
        // Workgroups (x, y, z); the regression's z is the half.
        let mut dispatches: Vec<(&wgpu::BindGroup, usize, (u32, u32, u32))> =
            vec![(plain, 0, (gx, gy, 1)), (plain, 1, (gx, gy, 1))];
        dispatches.extend(iterations.iter().map(|g| (g, 2, (gx, gy, 1))));
        dispatches.push((plain, 3, (gx, gy, 2)));
        dispatches.push((plain, 4, (tiles_x, height.div_ceil(TILE), 1)));
        dispatches.push((plain, 5, (out.0.div_ceil(8), out.1.div_ceil(8), 1)));
        for (i, (group, pipeline, (x, y, z))) in dispatches.into_iter().enumerate() {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(ENTRY_POINTS[pipeline]),
                timestamp_writes: self
                    .profile
                    .as_ref()
                    .map(|p| wgpu::ComputePassTimestampWrites {
                        query_set: &p.set,
                        beginning_of_pass_write_index: Some(2 * i as u32),
                        end_of_pass_write_index: Some(2 * i as u32 + 1),
                    }),
            });
            pass.set_bind_group(0, group, &[]);
            pass.set_pipeline(&self.pipelines[pipeline]);
            pass.dispatch_workgroups(x, y, z);
        }
        if let Some(p) = &self.profile {
            enc.resolve_query_set(&p.set, 0..2 * DISPATCHES, &p.resolve, 0);
            enc.copy_buffer_to_buffer(&p.resolve, 0, &p.readback, 0, 16 * DISPATCHES as u64);
        }
        enc.copy_buffer_to_buffer(&b.out, 0, &b.staging, 0, b.out_bytes);
        enc.copy_buffer_to_buffer(&b.tiles, 0, &b.staging, b.out_bytes, b.tile_bytes);
        let counter_at = b.out_bytes + b.tile_bytes;
        enc.copy_buffer_to_buffer(&accum.counters, 0, &b.staging, counter_at, COUNTER_BYTES);
        ctx.queue.submit([enc.finish()]);
        let slice = b.staging.slice(..);
        super::map_read(ctx, &slice, "denoising");
        let data = slice.get_mapped_range().expect("mapped");
        let blocks: Vec<[f32; 3]> = bytemuck::cast_slice(&data[..b.out_bytes as usize]).to_vec();
        let tiles: Vec<[f32; TILE_FLOATS]> =
            bytemuck::cast_slice(&data[b.out_bytes as usize..counter_at as usize]).to_vec();
        let c: &[u32] = bytemuck::cast_slice(&data[counter_at as usize..]);
        let invalid = c[0] as u64 | (c[1] as u64) << 32;
        drop(data);
        b.staging.unmap();
        DenoisedTiles {
            out,
            blocks,
            tiles_x,
            tiles,
            invalid,
        }
    }
}
