//! The GPU stage: adapter and device, the scene's buffers, the tracer pass and the
//! accumulation it writes.

pub mod accum;
pub mod context;
pub mod features;
pub mod layout;
pub mod scene_buffers;
pub mod shader;
pub mod timer;
pub mod trace;

pub use accum::{AccumData, Accumulation};
pub use context::{GpuContext, GpuError, describe, list_adapters, select_adapter};
pub use features::Features;
pub use scene_buffers::{FrameSettings, SceneBuffers};
pub use trace::TracePass;
