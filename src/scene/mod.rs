//! The render model of `MODEL.md` on the host: scene types and their defaults (`model`),
//! and loading them from TOML (`parse`, `reader`) or the built-in scenes.
//!
//! A [`Scene`] is what a scene file says after validation: every default filled in, every
//! named material merged into the objects that use it, colours already linear.

mod builtin;
pub mod color;
mod error;
pub mod generate;
pub mod mesh;
mod model;
mod parse;
mod reader;
mod write;

pub use builtin::{BUILTIN_FILES, BUILTIN_SCENES, DEFAULT_SCENE, EXTREME_SCENES, builtin_source};
pub use error::{Diagnostic, SceneError};
pub use mesh::Mesh;
pub use model::*;
pub use write::to_toml;

use std::path::{Path, PathBuf};

impl Scene {
    /// Parses a scene from TOML text; `origin` names the source in error messages.
    pub fn from_toml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        parse::parse(text, origin)
    }

    /// Loads a scene from a path, or from the built-in scenes when `name` is no file but is
    /// the name of one (`weekend`, `cornell`, …).
    pub fn load(name: &str) -> Result<Scene, SceneError> {
        let path = Path::new(name);
        if path.exists() {
            return Self::load_file(path);
        }
        if let Some(text) = builtin_source(name) {
            return Self::from_toml(text, &format!("builtin:{name}"));
        }
        Err(SceneError::NotFound {
            name: name.to_string(),
            builtins: BUILTIN_SCENES.iter().map(|(n, _)| n.to_string()).collect(),
        })
    }

    /// Loads a scene file.
    pub fn load_file(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: PathBuf::from(path),
            source,
        })?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// The built-in scene the preview opens when none is given.
    pub fn default_scene() -> Scene {
        Self::load(DEFAULT_SCENE).expect("the built-in default scene is valid")
    }
}

/// A scene by built-in name or file path, with an error message for the command line (an
/// invalid scene lists every problem, each with its file, line and key). Below both the
/// commands and the preview, which load scenes the same way.
pub fn load_scene(name: &str) -> anyhow::Result<Scene> {
    Scene::load(name).map_err(|e| match e {
        SceneError::Invalid(_) => anyhow::anyhow!("invalid scene\n{e}"),
        other => other.into(),
    })
}
