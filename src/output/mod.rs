//! The output stage: linear images, transfer functions, and files written atomically.

pub mod cells;
pub mod image;
pub mod write;

pub use image::{LinearImage, Transfer, srgb8};
pub use write::{ImageFile, OutputError, check_writable, write_exr, write_png};
