//! Helpers of the texture tests (`tests/textures.rs`, `tests/normal_maps.rs`): PNGs as data
//! URIs, a glTF file placed by a scene in front of its camera, texture coordinates scaled.

use base64::Engine;
use std::io::Write;
use termtrace::scene::{Scene, Shape};

/// A PNG of `w × h` RGBA texels, as a data URI.
pub fn png_uri(w: u32, h: u32, rgba: &[[u8; 4]]) -> String {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(rgba[(y * w + x) as usize]));
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&png)
    )
}

/// A scene placing `gltf` (written to a temporary folder) in front of a camera that sees a
/// square of side 2 at z = 0 as the middle half of the frame each way (at distance 2/tan 30°
/// the frame is 4 wide: pixels 8…24 of 32), under a uniform sky of `sky`, with `extra` TOML
/// after it.
pub fn gltf_scene(gltf: &[u8], sky: f32, extra: &str) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("square.gltf");
    std::fs::File::create(&path)
        .unwrap()
        .write_all(gltf)
        .unwrap();
    let toml = format!(
        "[camera]\nlook_from = [0, 0, 3.4641016]\nlook_at = [0, 0, 0]\nvfov = 60\n\
         [sky]\nuniform = [{sky}, {sky}, {sky}]\n[[gltf]]\nfile = \"square.gltf\"\n{extra}"
    );
    let origin = dir.path().join("scene.toml");
    let s = Scene::from_toml(&toml, &origin.display().to_string()).unwrap();
    (dir, s)
}

/// The first object's texture coordinates multiplied by `k`: its maps repeat k times.
pub fn scale_uvs(s: &mut Scene, k: f32) {
    if let Shape::Mesh { mesh, .. } = &mut s.objects[0].shape {
        let m = std::sync::Arc::get_mut(mesh).unwrap();
        for t in &mut m.uvs {
            for c in t.iter_mut() {
                c[0] *= k;
                c[1] *= k;
            }
        }
    }
}
