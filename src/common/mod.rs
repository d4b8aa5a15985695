//! What both tracers stand on, backend-neutral: the scene's arrays and the Pod mirrors of
//! the WGSL structs they are made of, the exact-sum accumulation format and its decoding, the
//! resolved preview frame, the denoiser's guides, the frame settings, the feature set that drives specialization,
//! an environment map's directions and sampling distribution, and the WGSL text the shared
//! constants are read from. `gpu` uploads these arrays and
//! `cpu` reads them as they are; neither imports the other.

pub mod accum;
pub mod arrays;
pub mod engine;
pub mod envmap;
pub mod estimate;
pub mod features;
pub mod guides;
pub mod image;
pub mod layout;
pub mod resolved;
pub mod textures;
pub mod wgsl;

pub use accum::AccumData;
pub use arrays::FrameSettings;
pub use features::Features;
pub use guides::Guides;
pub use image::LinearImage;
pub use resolved::Resolved;
