//! termtrace: a wgpu path tracer with a live terminal preview.
//!
//! Data flows scene file → [`scene`] → [`common`] (the scene's arrays, the exact-sum
//! format, the frame settings and features: what both tracers read) → the two tracers,
//! [`gpu`] (adapter, tracer pass, accumulation) and [`cpu`] (the native tracer), side by side
//! → [`render`] (progressive driver over either) → [`denoise`] (the guided filter and its
//! estimated error) → [`output`] (transfer, PNG/EXR, cells) →
//! the [`ui`] and the [`cli`]; [`converge`], [`stability`] and [`measure`] are the measuring
//! tools. `tests/architecture.rs` keeps the modules free of import circles and the two
//! tracers from importing each other.

pub mod bvh;
pub mod cli;
pub mod common;
pub mod converge;
pub mod cpu;
pub mod denoise;
pub mod gpu;
pub mod measure;
pub mod output;
pub mod render;
pub mod scene;
pub mod stability;
pub mod ui;
