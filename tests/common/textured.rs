//! Helpers of the texture tests (`tests/textures.rs`, `tests/normal_maps.rs`): PNGs as data
//! URIs, a glTF file placed by a scene in front of its camera, texture coordinates scaled.

use base64::Engine;
use std::io::Write;
use termtrace::scene::{Scene, Shape};

/// A PNG of `w × h` RGBA texels.
pub fn png_bytes(w: u32, h: u32, rgba: &[[u8; 4]]) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(rgba[(y * w + x) as usize]));
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// A PNG of `w × h` RGBA texels, as a data URI.
pub fn png_uri(w: u32, h: u32, rgba: &[[u8; 4]]) -> String {
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(png_bytes(w, h, rgba))
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

/// The square's buffer: four positions (f32 × 3), their UVs (f32 × 2), six u16 indices
/// (92 bytes; bufferViews at 0, 48 and 80).
pub fn square_bin() -> Vec<u8> {
    let pos: [[f32; 3]; 4] = [[-1., 1., 0.], [1., 1., 0.], [-1., -1., 0.], [1., -1., 0.]];
    let uv: [[f32; 2]; 4] = [[0., 0.], [1., 0.], [0., 1.], [1., 1.]];
    let idx: [u16; 6] = [0, 2, 1, 1, 2, 3];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    bin.extend(uv.iter().flatten().flat_map(|x| x.to_le_bytes()));
    bin.extend(idx.iter().flat_map(|x| x.to_le_bytes()));
    bin
}

/// A square of side 2 at z = 0 facing +z, with UVs (0,0) at its upper-left corner, one
/// material (`material` JSON), `images`, `textures` and `samplers` JSON arrays.
pub fn square_gltf(material: &str, images: &str, textures: &str, samplers: &str) -> Vec<u8> {
    let bin = square_bin();
    let uri = base64::engine::general_purpose::STANDARD.encode(&bin);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
        "materials":[{material}],"images":{images},"textures":{textures},"samplers":{samplers},
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},
          {{"buffer":0,"byteOffset":80,"byteLength":12}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{uri}"}}]}}"#,
        bin.len()
    )
    .into_bytes()
}

/// The mean over an image's pixels of r + g + b.
pub fn mean(i: &termtrace::output::LinearImage) -> f64 {
    i.pixels
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) as f64)
        .sum::<f64>()
        / i.pixels.len() as f64
}

/// Renders `scene` on the GPU and on the CPU tracer (`spp` each, the same seed) and checks
/// that their mean values agree within 1 % and that neither has an invalid sample.
pub fn tracers_agree_on_mean(scene: &Scene, settings: termtrace::common::FrameSettings, spp: u32) {
    let gpu = super::snapshot_on(
        termtrace::render::Backend::Gpu(super::ctx()),
        scene,
        settings,
        spp,
        Default::default(),
    );
    let cpu = super::cpu_snapshot(scene, settings, spp);
    assert_eq!(
        (gpu.invalid_samples(), cpu.invalid_samples()),
        (0, 0),
        "{}",
        scene.origin
    );
    let (a, b) = (mean(&gpu.image()), mean(&cpu.image()));
    assert!(
        (a - b).abs() <= 0.01 * a.max(b),
        "{}: means {a} (GPU) and {b} (CPU)",
        scene.origin
    );
}
