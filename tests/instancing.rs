//! Instancing: a glTF mesh drawn by several nodes, or by `EXT_mesh_gpu_instancing`, is stored
//! once and traced through a two-level BVH on both tracers; its images are the flattened
//! twin's.

mod common;

use base64::Engine;
use common::*;
use glam::DMat4;
use termtrace::output::LinearImage;
use termtrace::render::RenderOptions;
use termtrace::scene::gltf::{Instancing, import_slice};
use termtrace::scene::{Scene, Shape};

/// BoxTextured drawn by nine nodes sharing its mesh (rotated, scaled unevenly, one mirrored),
/// and gltf-transform's EXT_mesh_gpu_instancing twin of it (scripts/instanced-gltf.py).
const NODES: &str = "tests/gltf/BoxTextured-instanced/BoxTextured-instanced.glb";
const GPU_INSTANCING: &str = "tests/gltf/BoxTextured-instanced/BoxTextured-gpu-instancing.glb";

fn placed(file: &str, instancing: &str) -> Scene {
    scene(&format!(
        r#"
        [camera]
        look_from = [4.0, 3.5, 5.0]
        look_at = [0.0, 0.2, 0.0]
        vfov = 40.0
        [sky]
        bottom = [1.0, 1.0, 1.0]
        top = [0.5, 0.7, 1.0]
        [[quad]]
        q = [-10.0, -0.6, -10.0]
        u = [20.0, 0.0, 0.0]
        v = [0.0, 0.0, 20.0]
        color = [0.5, 0.5, 0.5]
        [[gltf]]
        file = "{file}"
        instancing = "{instancing}"
        "#
    ))
}

/// (mesh objects, their instances) of a scene.
fn meshes(s: &Scene) -> Vec<usize> {
    s.objects
        .iter()
        .filter_map(|o| match &o.shape {
            Shape::Mesh { instances, .. } => Some(instances.len()),
            _ => None,
        })
        .collect()
}

#[test]
fn the_loader_instances_what_it_is_asked_to_and_flattens_small_copies_by_default() {
    for file in [NODES, GPU_INSTANCING] {
        let always = placed(file, "always");
        assert_eq!(meshes(&always), vec![9], "{file}");
        let n = always.counts();
        assert_eq!((n.triangles, n.drawn_triangles, n.instances), (12, 108, 9));
        assert!(
            always.gltf[0].left_out.is_empty(),
            "{:?}",
            always.gltf[0].left_out
        );
        // Nine copies of twelve triangles are far below what `auto` instances.
        for flat in [placed(file, "never"), placed(file, "auto")] {
            assert_eq!(meshes(&flat), vec![0; 9], "{file}");
            assert_eq!(flat.counts().triangles, 108);
        }
    }
    let e = Scene::from_toml(
        &format!("[[gltf]]\nfile = \"{NODES}\"\ninstancing = \"sometimes\"\n"),
        "test",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown instancing `sometimes`") && e.contains("auto, always, never"),
        "{e}"
    );
}

/// The share of pixels within `tol` of each other, and the relative difference of the means.
fn compare(a: &LinearImage, b: &LinearImage, tol: f32) -> (f64, f64) {
    let mean = |i: &LinearImage| {
        i.pixels.iter().flatten().map(|&c| c as f64).sum::<f64>() / (i.pixels.len() * 3) as f64
    };
    let close = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| (0..3).all(|c| (p[c] - q[c]).abs() <= tol))
        .count();
    let (ma, mb) = (mean(a), mean(b));
    (close as f64 / a.pixels.len() as f64, (ma - mb).abs() / ma)
}

#[test]
fn instanced_and_flattened_twins_render_the_same_image_on_both_tracers() {
    // The same random streams through the same geometry, found in the mesh's coordinates or
    // the world's: they differ only by rounding (measured: 99.9 % of pixels within 0.002).
    // Both instanced files, the nodes' and EXT_mesh_gpu_instancing's, against the flattened
    // nodes; and the two-level walk against the test of every primitive.
    let flat = placed(NODES, "never");
    let twins = [placed(NODES, "always"), placed(GPU_INSTANCING, "always")];
    on_both(|| {
        let s = settings(48, 40, 4);
        let want = snapshot(&flat, s, 8).image();
        for twin in &twins {
            let snap = snapshot(twin, s, 8);
            assert_eq!(snap.invalid_samples(), 0);
            let (close, means) = compare(&want, &snap.image(), 0.01);
            assert!(
                close >= 0.99 && means <= 1e-3,
                "{close} of pixels, means {means}"
            );
        }
        let brute = RenderOptions {
            no_bvh: true,
            ..Default::default()
        };
        let (close, means) = compare(&want, &snapshot_with(&twins[0], s, 8, brute).image(), 0.01);
        assert!(
            close >= 0.99 && means <= 1e-3,
            "without the BVH: {close}, {means}"
        );
    });
}

#[test]
fn instanced_scenes_converge_to_the_gpu_image_on_the_cpu() {
    // The CPU-against-GPU bias check of tests/cpu.rs (`common::cpu_converges_to_gpu`) on the
    // two-level walk: both instanced files and the mirrored, unevenly scaled, normal-mapped
    // copy, each forced to instance.
    let cases = [
        ("nodes", placed(NODES, "always")),
        ("EXT_mesh_gpu_instancing", placed(GPU_INSTANCING, "always")),
        ("mirrored copy", mirrored_twice(Instancing::Always)),
    ];
    for (name, scene) in &cases {
        assert!(
            meshes(scene).iter().any(|&n| n >= 2),
            "{name}: not instanced"
        );
    }
    let named: Vec<(&str, &Scene)> = cases.iter().map(|(n, s)| (*n, s)).collect();
    cpu_converges_to_gpu(&named);
}

/// Khronos's NormalTangentMirrorTest (normal maps, the file's tangents, mirrored UVs), drawn
/// twice: in place, and by a second node that rotates, scales unevenly and mirrors it.
fn mirrored_twice(instancing: Instancing) -> Scene {
    let out = glb_edited(
        "tests/gltf/NormalTangentMirrorTest/NormalTangentMirrorTest.glb",
        |doc| {
            let copy = serde_json::json!({
                "mesh": doc["nodes"][0]["mesh"],
                "rotation": [0.0, 0.3826834, 0.0, 0.9238795],
                "scale": [-0.7, 1.3, 0.9],
                "translation": [0.0, 0.0, -2.0]
            });
            doc["nodes"].as_array_mut().unwrap().push(copy);
            doc["scenes"][0]["nodes"] = serde_json::json!([0, 1]);
        },
    );
    let imported = import_slice(&out, None, "twice.glb", DMat4::IDENTITY, None, instancing)
        .expect("the doubled file imports");
    let mut s = scene(
        r#"
        [camera]
        look_from = [0.0, 1.0, 6.0]
        look_at = [0.0, 0.0, -1.0]
        vfov = 45.0
        [sky]
        bottom = [1.0, 1.0, 1.0]
        top = [0.5, 0.7, 1.0]
        "#,
    );
    s.objects.extend(imported.objects);
    s
}

#[test]
fn normal_maps_on_a_mirrored_unevenly_scaled_instance_match_the_flattened_mesh() {
    // An instance's frames are brought into the world before the map perturbs them, with the
    // bitangent turned over by the mirror, as the flattened mesh's are. What remains is the
    // order of interpolating and transforming the corners' frames (measured: 3.8e-4 RMSE of
    // the 8-bit image); without the frames' transform the copy's shading differed by 12x that.
    let instanced = mirrored_twice(Instancing::Always);
    assert_eq!(meshes(&instanced), vec![2]);
    let flat = mirrored_twice(Instancing::Never);
    assert_eq!(meshes(&flat), vec![0, 0]);
    on_both(|| {
        let s = settings(64, 48, 3);
        let a = snapshot(&flat, s, 8).image();
        let b = snapshot(&instanced, s, 8).image();
        let (close, means) = compare(&a, &b, 0.02);
        assert!(
            close >= 0.98 && means <= 2e-3,
            "{close} of pixels, means {means}"
        );
    });
}

/// A glTF file (a data URI inside) in which `copies` nodes share one rippled grid of 2·n²
/// triangles, 1.2 apart.
fn forest(copies: usize, n: usize) -> String {
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            pos.extend([x - 0.5, 0.05 * (6.0 * x).sin() * (5.0 * z).cos(), z - 0.5]);
        }
    }
    let mut idx = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * (n as u32 + 1) + i;
            let b = a + n as u32 + 1;
            idx.extend([a, b, a + 1, a + 1, b, b + 1]);
        }
    }
    let mut bin: Vec<u8> = bytemuck::cast_slice(&pos).to_vec();
    let pos_len = bin.len();
    bin.extend_from_slice(bytemuck::cast_slice(&idx));
    let nodes: Vec<String> = (0..copies)
        .map(|k| {
            let (x, z) = ((k % 100) as f32 * 1.2, (k / 100) as f32 * 1.2);
            format!(r#"{{"mesh":0,"translation":[{x},0,{z}]}}"#)
        })
        .collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],
        "nodes":[{}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3",
        "min":[-0.5,-0.05,-0.5],"max":[0.5,0.05,0.5]}},
        {{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteLength":{pos_len}}},
        {{"buffer":0,"byteOffset":{pos_len},"byteLength":{}}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        (0..copies)
            .map(|k| k.to_string())
            .collect::<Vec<_>>()
            .join(","),
        nodes.join(","),
        pos.len() / 3,
        idx.len(),
        idx.len() * 4,
        bin.len(),
        base64::engine::general_purpose::STANDARD.encode(&bin),
    )
}

/// A `forest` file imported with `instancing`.
fn import_forest(
    json: &str,
    instancing: Instancing,
) -> Result<termtrace::scene::gltf::Imported, termtrace::scene::gltf::GltfError> {
    import_slice(
        json.as_bytes(),
        None,
        "forest.gltf",
        DMat4::IDENTITY,
        None,
        instancing,
    )
}

#[test]
fn ten_thousand_copies_are_stored_once() {
    // A grid of 2 048 triangles drawn by 10 000 nodes: `auto` instances it (flattened it would
    // be 2·10⁷ triangles), so the scene holds the mesh once and the top level 10 000 copies.
    let imported = import_forest(&forest(10_000, 32), Instancing::Auto).unwrap();
    let mut s = scene(
        r#"
        [camera]
        look_from = [60.0, 30.0, -20.0]
        look_at = [60.0, 0.0, 60.0]
        [sky]
        bottom = [1.0, 1.0, 1.0]
        top = [0.5, 0.7, 1.0]
        "#,
    );
    s.objects.extend(imported.objects);
    assert_eq!(meshes(&s), vec![10_000]);
    let c = s.counts();
    assert_eq!((c.triangles, c.drawn_triangles), (2048, 2048 * 10_000));
    // Every pixel sees the forest or the sky, on both tracers alike.
    on_both(|| {
        let snap = snapshot(&s, settings(24, 16, 2), 2);
        assert_eq!(snap.invalid_samples(), 0);
        let img = snap.image();
        let ground = img.pixels.iter().filter(|p| p[0] < 0.9).count();
        assert!(
            ground > img.pixels.len() / 4,
            "{ground} pixels see the forest"
        );
    });
}

#[test]
fn a_file_too_large_to_flatten_is_refused_with_its_figure() {
    // 40 000 copies of 20 000 triangles, flattened: 8·10⁸ triangles, some 313 GiB. The memory
    // guard refuses before reading a vertex, naming the figure, the limit and the way out;
    // instanced, the same file opens.
    let json = forest(40_000, 100);
    let e = import_forest(&json, Instancing::Never)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("forest.gltf")
            && e.contains("800000000 triangles")
            && e.contains("GiB this machine has available")
            && e.contains("instancing"),
        "{e}"
    );
    let i = import_forest(&json, Instancing::Auto).unwrap();
    assert_eq!(i.objects.len(), 1);
    // An adapter whose buffers hold less than the triangles refuses the scene by its figure.
    let mut s = scene("");
    s.objects.extend(i.objects);
    let why = termtrace::common::arrays::too_large(&s, 100 << 10).expect("over 100 KiB");
    assert!(why.contains("20000 triangles take 0.9 MiB"), "{why}");
    assert!(termtrace::common::arrays::too_large(&s, 1 << 20).is_none());
}

#[test]
fn the_geometry_hashes_see_the_copies() {
    // The shards' scene hash and the BVH's cache key both change when one copy moves (and
    // the content hash is the same for the same file loaded twice).
    use termtrace::common::arrays::{geometry_content_hash, geometry_hash};
    let a = placed(NODES, "always");
    let b = placed(NODES, "always");
    assert_eq!(geometry_content_hash(&a), geometry_content_hash(&b));
    let mut moved = a.clone();
    if let Shape::Mesh { instances, .. } = &mut moved.objects[1].shape {
        let mut m = instances.as_ref().clone();
        m[3] = DMat4::from_translation(glam::DVec3::X) * m[3];
        *instances = std::sync::Arc::new(m);
    } else {
        panic!("the second object is the instanced mesh");
    }
    assert_ne!(geometry_content_hash(&a), geometry_content_hash(&moved));
    assert_ne!(geometry_hash(&a), geometry_hash(&moved));
}
