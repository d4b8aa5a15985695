//! termtrace: a wgpu path tracer with a live terminal preview.
//!
//! Data flows scene file → [`scene`] → [`gpu`] (adapter, tracer pass, accumulation) →
//! [`render`] (progressive driver) → [`output`] (transfer, PNG/EXR) and the [`cli`].

pub mod bvh;
pub mod cli;
pub mod converge;
pub mod cpu;
pub mod gpu;
pub mod output;
pub mod render;
pub mod scene;
pub mod stability;
pub mod ui;
