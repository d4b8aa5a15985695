//! Where the preview writes: the edited scene (`w`, with a `.bak` of the one it replaces)
//! and the next free PNG name (`p`).

use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// `dir/NAME.edited.toml` beside a scene file, `./NAME.edited.toml` for a built-in scene.
pub fn edited_scene_path(scene: &Scene) -> PathBuf {
    let name = format!("{}.edited.toml", scene.short_name());
    match Path::new(&scene.origin).parent() {
        Some(dir) if !scene.origin.starts_with("builtin:") => dir.join(name),
        _ => PathBuf::from(name),
    }
}

/// The first of `NAME.png`, `NAME-1.png`, … that does not exist yet.
pub fn free_png_path(scene: &Scene) -> PathBuf {
    let stem = scene.short_name();
    (0..)
        .map(|i| match i {
            0 => PathBuf::from(format!("{stem}.png")),
            i => PathBuf::from(format!("{stem}-{i}.png")),
        })
        .find(|p| !p.exists())
        .expect("some name is free")
}

crate::message_error!(
    /// Why the preview could not save (a scene or an image), naming the file.
    SaveError
);

/// Writes the edited scene; an existing file of that name is kept as `….bak` first.
pub fn write_scene(scene: &Scene) -> Result<String, SaveError> {
    let path = edited_scene_path(scene);
    let mut note = String::new();
    if path.exists() {
        let backup = PathBuf::from(format!("{}.bak", path.display()));
        std::fs::rename(&path, &backup)
            .map_err(|e| format!("cannot back up {}: {e}", path.display()))?;
        note = format!(" (the previous one is now {})", backup.display());
    }
    crate::output::write::write_text(&path, &crate::scene::to_toml(scene))
        .map_err(|e| SaveError(e.to_string()))?;
    // A built-in scene's meshes live in the binary: write them beside the scene, so that the
    // file loads on its own.
    if scene.origin.starts_with("builtin:") {
        let dir = path.parent().unwrap_or(Path::new("."));
        for o in &scene.objects {
            if let crate::scene::Shape::Mesh { file, .. } = &o.shape
                && let Some((_, text)) = crate::scene::BUILTIN_FILES.iter().find(|(n, _)| n == file)
            {
                let target = dir.join(file);
                if !target.exists() {
                    if let Some(d) = target.parent() {
                        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
                    }
                    crate::output::write::write_text(&target, text)
                        .map_err(|e| SaveError(e.to_string()))?;
                    note.push_str(&format!(" and {}", target.display()));
                }
            }
        }
        if let Some(e) = &scene.environment
            && let Some((_, bytes)) = crate::scene::BUILTIN_MAPS
                .iter()
                .find(|(n, _)| *n == e.file)
        {
            let target = dir.join(&e.file);
            if !target.exists() {
                if let Some(d) = target.parent() {
                    std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
                }
                crate::output::write::write_bytes(&target, bytes)
                    .map_err(|e| SaveError(e.to_string()))?;
                note.push_str(&format!(" and {}", target.display()));
            }
        }
    }
    Ok(format!("wrote {}{note}", path.display()))
}
