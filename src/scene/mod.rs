//! The render model of `MODEL.md` on the host: scene types and their defaults (`model`),
//! and loading them from TOML (`parse`, `reader`) or the built-in scenes.
//!
//! A [`Scene`] is what a scene file says after validation: every default filled in, every
//! named material merged into the objects that use it, colours already linear.

mod builtin;
pub mod color;
pub mod envmap;
pub mod envmap_sampling;
mod error;
mod files;
pub mod generate;
pub mod gltf;
mod gltf_accessors;
mod gltf_draco;
mod gltf_frames;
mod gltf_instances;
mod gltf_meshopt;
mod gltf_textures;
pub mod mesh;
mod model;
pub mod obj;
pub mod params;
mod parse;
mod reader;
pub mod texture;
pub mod trig;
mod write;

pub use builtin::{
    BUILTIN_FILES, BUILTIN_MAPS, BUILTIN_SCENES, DEFAULT_SCENE, EXTREME_SCENES, builtin_source,
};
pub use error::{Diagnostic, SceneError};
pub use files::{import_model, is_gltf, is_model, is_obj};
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
        Self::load_with_camera(name, None)
    }

    /// [`Scene::load`], with a glTF file's camera chosen by name (`--camera`); a TOML scene
    /// chooses its glTF cameras itself (`[[gltf]] camera = "…"`), and `camera` must be `None`
    /// for one.
    pub fn load_with_camera(name: &str, camera: Option<&str>) -> Result<Scene, SceneError> {
        let path = Path::new(name);
        if is_model(path) {
            return Self::from_model(path, camera);
        }
        if let Some(c) = camera {
            return Err(SceneError::Gltf(gltf::GltfError {
                path: name.to_string(),
                message: format!(
                    "camera `{c}`: only a glTF file is opened with a camera chosen; in a TOML \
                     scene write `camera = \"{c}\"` in its [[gltf]] table"
                ),
            }));
        }
        // A file of that name, not a folder: `fuzz/` in the current folder does not hide the
        // built-in `fuzz` scene.
        if path.is_file() {
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

    /// A glTF 2.0 file (`.gltf` or `.glb`) or an OBJ file with its MTL materials as a scene:
    /// its objects, its camera (the first, or `camera` by name; without one, a camera that
    /// frames it), its directional light as the sun over the default sky, and the default
    /// render settings.
    pub fn from_model(path: &Path, camera: Option<&str>) -> Result<Scene, SceneError> {
        let imported = import_model(path, glam::DMat4::IDENTITY, camera, Default::default())?;
        imported.log_left_out(&path.display().to_string());
        let file = path.file_name().map_or_else(
            || path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        let mut sky = Sky::default();
        if let (Sky::Gradient { sun, .. }, Some(s)) = (&mut sky, imported.sun.clone()) {
            *sun = Some(s);
        }
        Ok(Scene {
            origin: path.display().to_string(),
            camera: imported
                .camera
                .unwrap_or_else(|| gltf::framing_camera(imported.bounds)),
            render: RenderSettings::default(),
            sky,
            environment: None,
            materials: Vec::new(),
            objects: imported
                .objects
                .into_iter()
                .map(|o| Object { gltf: Some(0), ..o })
                .collect(),
            gltf: vec![GltfPlacement {
                file,
                translate: glam::DVec3::ZERO,
                rotation: glam::DVec3::ZERO,
                scale: glam::DVec3::ONE,
                instancing: Default::default(),
                materials: imported.materials,
                left_out: imported.skipped,
            }],
        })
    }

    /// The built-in scene the preview opens when none is given.
    pub fn default_scene() -> Scene {
        Self::load(DEFAULT_SCENE).expect("the built-in default scene is valid")
    }
}

/// A scene by built-in name or file path, lit by the map at `sky` when one is given (an
/// invalid scene lists every problem, each with its file, line and key). Below both the
/// commands and the preview, which load scenes the same way.
pub fn load_scene(
    name: &str,
    camera: Option<&str>,
    sky: Option<&Path>,
) -> Result<Scene, SceneError> {
    let mut scene = Scene::load_with_camera(name, camera)?;
    if let Some(path) = sky {
        scene.set_sky_map(path)?;
    }
    Ok(scene)
}

impl Scene {
    /// Lights the scene with the map at `path` (the command line's sky): it replaces the scene's map,
    /// keeping its intensity, rotation and visibility, or adds one with the defaults. The
    /// file is kept by its absolute path, so that a scene written back anywhere finds it.
    pub fn set_sky_map(&mut self, path: &Path) -> Result<(), SceneError> {
        let file = std::path::absolute(path)
            .unwrap_or_else(|_| path.to_path_buf())
            .display()
            .to_string();
        let mut env = Environment::load(&file, path)?;
        if let Some(old) = &self.environment {
            env.intensity = old.intensity;
            env.rotation = old.rotation;
            env.visible = old.visible;
        }
        self.environment = Some(env);
        Ok(())
    }
}
