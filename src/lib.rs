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

/// Declares an error type whose whole content is a message for the user, naming what it is
/// about ("accessor 3 has no buffer view"): a `thiserror` struct that displays its message,
/// made from a `String` or `&str` (so `?` and `.into()` convert into it). For the errors of a
/// stage whose callers only report them; an error that callers tell apart is an enum.
macro_rules! message_error {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
        #[error("{0}")]
        pub struct $name(pub String);

        impl From<String> for $name {
            fn from(s: String) -> $name {
                $name(s)
            }
        }

        impl From<&str> for $name {
            fn from(s: &str) -> $name {
                $name(s.to_string())
            }
        }

        /// The message, to read or search.
        impl std::ops::Deref for $name {
            type Target = str;
            fn deref(&self) -> &str {
                &self.0
            }
        }
    };
}
pub(crate) use message_error;

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
