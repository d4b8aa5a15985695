//! Which importer reads a model file (glTF, GLB or OBJ), by its extension: below both the
//! scene loader and the TOML's `[[gltf]]` tables.

use super::{gltf, obj};
use std::path::Path;

/// Whether `path` names a glTF file (`.gltf` or `.glb`, any case).
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// Whether `path` names an OBJ file (`.obj`, any case).
pub fn is_obj(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
}

/// Whether `path` names a model file that opens as a scene and that `[[gltf]]` places: glTF,
/// GLB or OBJ.
pub fn is_model(path: &Path) -> bool {
    is_gltf(path) || is_obj(path)
}

/// Imports a model file, glTF or OBJ by its extension, placed by `place`; `camera` picks a
/// glTF camera by name (an OBJ file has none); `instancing` chooses how a glTF file's
/// repeated meshes are stored.
pub fn import_model(
    path: &Path,
    place: glam::DMat4,
    camera: Option<&str>,
    instancing: gltf::Instancing,
) -> Result<gltf::Imported, gltf::GltfError> {
    if !is_obj(path) {
        return gltf::import(path, place, camera, instancing);
    }
    if let Some(c) = camera {
        return Err(gltf::GltfError {
            path: path.display().to_string(),
            message: format!("camera `{c}`: an OBJ file has no cameras"),
        });
    }
    obj::import(path, place)
}
