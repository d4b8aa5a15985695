//! The surface both tracers' engines offer the renderer (`render::Renderer`), so that it
//! drives either through one set of calls: trace a range of samples, make the denoiser's
//! guides, give back exact sums. `gpu::GpuEngine` queues its work on the device and is waited
//! on; `cpu::CpuEngine` traces before it returns. pbrt-v4's integrators call one
//! `ParallelFor` in the same way, the backend being chosen at one seam.

use super::accum::{AccumData, Sums};
use super::layout::DispatchUniforms;
use super::{Features, FrameSettings, Resolved};
use crate::scene::Scene;
use std::ops::Range;
use std::time::Duration;

/// One tracer holding one scene's accumulation.
pub trait Engine: Send {
    /// Replaces the scene and settings (a new size starts a new accumulation); `features`
    /// is the scene's own pipeline, prepared ahead where there are pipelines.
    fn set_scene(&mut self, scene: &Scene, settings: &FrameSettings, features: Features);

    /// Zeroes the counters of invalid samples and of traversal work.
    fn reset_counters(&mut self);

    /// Whether the pipeline of `features` is compiled. Always, where there are no pipelines.
    fn ready(&self, features: Features) -> bool;

    /// Compiles the pipeline of `features` now, or (`background`) starts compiling it on
    /// another thread; nothing where it is ready or there are no pipelines.
    fn prepare(&mut self, features: Features, background: bool);

    /// Lane-pixels of scratch for parallel lanes of one pixel (0: one lane per pixel).
    fn scratch_slots(&self) -> u64;

    /// Traces the rows and samples `d` names with `features`, `width` pixels a row. Returns
    /// how long it took where it traced before returning; `None` where it was queued (then
    /// [`Engine::finish_oldest`] waits for it).
    fn dispatch(&mut self, features: Features, d: DispatchUniforms, width: u32)
    -> Option<Duration>;

    /// Waits for the oldest queued dispatch.
    fn finish_oldest(&mut self);

    /// The last dispatch's time on the device, where timed.
    fn timed_seconds(&self) -> Option<f64>;

    /// Makes the denoiser's guide sums of guide samples `samples` of every pixel; returns
    /// them where they are made on the host, `None` where they stay on the device.
    fn make_guides(
        &mut self,
        features: Features,
        size: (u32, u32),
        samples: Range<u32>,
    ) -> Option<Vec<u32>>;

    /// The guide sums made on the device, read back (empty where none were made there).
    fn read_guides(&self) -> Vec<u32>;

    /// The preview's frame made on the host; `None` where the device's resolve pass makes it.
    fn resolve_on_host(&self, factor: u32) -> Option<Resolved>;

    /// The exact sums and the invalid samples, as the tracer holds them.
    fn exact_sums(&self) -> Sums;

    /// The accumulation decoded, with the counters.
    fn read(&self) -> AccumData;

    /// Bytes the accumulation holds.
    fn bytes(&self) -> u64;

    /// Nodes of the BVH and the seconds its build took.
    fn bvh_stats(&self) -> (usize, f64);

    /// How a CPU tracer runs the paths of features `f`, and why (`bench`'s report); None for
    /// a GPU.
    fn path_loop(&self, _f: Features) -> Option<String> {
        None
    }
}
