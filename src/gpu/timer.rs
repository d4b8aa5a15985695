//! GPU time of the tracer's passes, from timestamp queries where the adapter has them.

use super::GpuContext;

/// Two timestamps around one pass, resolved and read back after each submission.
pub struct GpuTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
}

const BYTES: u64 = 16;

impl GpuTimer {
    /// A timer, if the device was opened with timestamp queries.
    pub fn new(ctx: &GpuContext) -> Option<GpuTimer> {
        if !ctx.timestamps {
            return None;
        }
        let d = &ctx.device;
        Some(GpuTimer {
            set: d.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timer.queries"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timer.resolve"),
                size: BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            readback: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timer.readback"),
                size: BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        })
    }

    /// The pass's timestamp writes.
    pub fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// Records the copy of the timestamps; call after the pass, in the same encoder.
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, BYTES);
    }

    /// Seconds between the two timestamps; call once the submission has completed.
    pub fn read_seconds(&self, ctx: &GpuContext) -> f64 {
        let slice = self.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        let _ = ctx.device.poll(wgpu::PollType::wait_indefinitely());
        let seconds = match slice.get_mapped_range() {
            Ok(data) => {
                let t: &[u64] = bytemuck::cast_slice(&data);
                t[1].saturating_sub(t[0]) as f64 * self.period_ns * 1e-9
            }
            Err(_) => 0.0,
        };
        self.readback.unmap();
        seconds
    }
}
