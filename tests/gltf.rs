//! glTF 2.0 scenes: the import (hierarchy transforms, primitive modes, cameras, lights, the
//! material mapping of docs/MODEL-NOTES.md) checked against values worked out by hand, a real
//! public asset (Khronos's Box, `tests/gltf/Box`) rendered as a known answer on both tracers,
//! `[[gltf]]` placements with material overrides written back and read again, and malformed
//! files refused with a message (never a panic), by hand and by thousands of mutations.

mod common;
use base64::Engine;
use common::*;
use glam::{DMat4, DVec3, Vec3};
use termtrace::scene::gltf::{GltfError, import_slice};
use termtrace::scene::{Scene, Shape, Sky, to_toml};

const BOX: &str = "tests/gltf/Box/Box.gltf";

/// A glTF file of one mesh primitive: `positions`, optional u16 `indices`, primitive `mode`,
/// `nodes` JSON (the mesh is mesh 0), and extra top-level JSON members (`extra`, with a
/// leading comma) and material JSON.
fn gltf(
    positions: &[[f32; 3]],
    indices: Option<&[u16]>,
    mode: u32,
    nodes: &str,
    material: &str,
    extra: &str,
) -> Vec<u8> {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let pos_len = bin.len();
    let (mut min, mut max) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    let mut views = format!(r#"{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}}"#);
    let mut accessors = format!(
        r#"{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":{min:?},"max":{max:?}}}"#,
        positions.len()
    );
    let mut index_attr = String::new();
    if let Some(ix) = indices {
        let off = bin.len();
        bin.extend(ix.iter().flat_map(|i| i.to_le_bytes()));
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views += &format!(
            r#",{{"buffer":0,"byteOffset":{off},"byteLength":{}}}"#,
            ix.len() * 2
        );
        accessors += &format!(
            r#",{{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}"#,
            ix.len()
        );
        index_attr = r#","indices":1"#.into();
    }
    let uri = base64::engine::general_purpose::STANDARD.encode(&bin);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":{nodes},
        "meshes":[{{"name":"m","primitives":[{{"attributes":{{"POSITION":0}}{index_attr},"mode":{mode},"material":0}}]}}],
        "materials":[{material}],
        "accessors":[{accessors}],
        "bufferViews":[{views}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{uri}"}}]{extra}}}"#,
        bin.len()
    )
    .into_bytes()
}

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
const PLAIN: &str = r#"{"name":"plain"}"#;

fn import(bytes: &[u8]) -> Result<termtrace::scene::gltf::Imported, GltfError> {
    import_slice(
        bytes,
        None,
        "test.gltf",
        DMat4::IDENTITY,
        None,
        Default::default(),
    )
}

fn triangles(o: &termtrace::scene::Object) -> Vec<[DVec3; 3]> {
    match &o.shape {
        Shape::Mesh { mesh, .. } => mesh.triangles.clone(),
        other => panic!("not a mesh: {other:?}"),
    }
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-6
}

#[test]
fn node_transforms_compose_down_the_hierarchy() {
    // Parent: translation (1, 2, 3). Child: scale 2, then 90° about Z (quaternion
    // [0, 0, sin 45°, cos 45°]): (x, y) → (−y, x). So (1,0,0) → (2,0,0) → (0,2,0) → (1,4,3).
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = format!(
        r#"[{{"translation":[1,2,3],"children":[1]}},{{"mesh":0,"scale":[2,2,2],"rotation":[0,0,{h},{h}]}}]"#
    );
    let imp = import(&gltf(&TRIANGLE, None, 4, &nodes, PLAIN, "")).unwrap();
    assert_eq!(imp.objects.len(), 1);
    let t = triangles(&imp.objects[0]);
    let want = [
        DVec3::new(1.0, 2.0, 3.0),
        DVec3::new(1.0, 4.0, 3.0),
        DVec3::new(-1.0, 2.0, 3.0),
    ];
    assert_eq!(t.len(), 1);
    for k in 0..3 {
        assert!(
            close(t[0][k], want[k]),
            "corner {k}: {:?} != {:?}",
            t[0][k],
            want[k]
        );
    }
    assert!(close(imp.bounds.0, DVec3::new(-1.0, 2.0, 3.0)));
    assert!(close(imp.bounds.1, DVec3::new(1.0, 4.0, 3.0)));
}

#[test]
fn a_mirroring_transform_keeps_the_front_face() {
    // Scale −1 in x mirrors: the normal cross(b − a, c − a) of the file's winding would flip;
    // the import swaps two corners so it stays +z, as the file meant.
    let nodes = r#"[{"mesh":0,"scale":[-1,1,1]}]"#;
    let imp = import(&gltf(&TRIANGLE, None, 4, nodes, PLAIN, "")).unwrap();
    let [a, b, c] = triangles(&imp.objects[0])[0];
    assert!((b - a).cross(c - a).z > 0.0);
}

#[test]
fn indexed_strips_and_fans_become_triangles() {
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let nodes = r#"[{"mesh":0}]"#;
    // TRIANGLES with indices: two triangles of the quad.
    let imp = import(&gltf(&quad, Some(&[0, 1, 2, 2, 1, 3]), 4, nodes, PLAIN, "")).unwrap();
    assert_eq!(triangles(&imp.objects[0]).len(), 2);
    // TRIANGLE_STRIP 0 1 2 3: (0 1 2), then (2 1 3) with the winding kept.
    let imp = import(&gltf(&quad, None, 5, nodes, PLAIN, "")).unwrap();
    let t = triangles(&imp.objects[0]);
    assert_eq!(t.len(), 2);
    for [a, b, c] in &t {
        assert!((*b - *a).cross(*c - *a).z > 0.0, "a strip triangle flipped");
    }
    // TRIANGLE_FAN 0 1 3 2: (0 1 3), (0 3 2).
    let imp = import(&gltf(&quad, Some(&[0, 1, 3, 2]), 6, nodes, PLAIN, "")).unwrap();
    assert_eq!(triangles(&imp.objects[0]).len(), 2);
    // POINTS: nothing to import, and the error says why.
    let e = import(&gltf(&quad, None, 0, nodes, PLAIN, "")).unwrap_err();
    assert!(
        e.message.contains("no triangles") && e.message.contains("Points"),
        "{e}"
    );
}

#[test]
fn metallic_roughness_maps_onto_the_model() {
    use termtrace::scene::MaterialModel;
    let nodes = r#"[{"mesh":0}]"#;
    let m = |mat: &str| {
        let imp = import(&gltf(&TRIANGLE, None, 4, nodes, mat, "")).unwrap();
        imp.objects[0].material.clone()
    };
    // glTF's own BRDF (the pbr model), with glTF's defaults: base colour 1, metallic 1,
    // roughness 1, ior 1.5.
    let d = m("{}");
    assert_eq!(d.model, MaterialModel::Pbr);
    assert_eq!(
        (d.color, d.metallic, d.roughness, d.ior),
        (Vec3::ONE, 1.0, 1.0, 1.5)
    );
    // The factors as they are.
    let p = m(
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.25,1,1],"metallicFactor":0,"roughnessFactor":0.3},
        "extensions":{"KHR_materials_ior":{"ior":1.7}}}"#,
    );
    assert_eq!(p.model, MaterialModel::Pbr);
    assert_eq!(p.color, Vec3::new(0.5, 0.25, 1.0));
    assert_eq!((p.metallic, p.roughness, p.ior), (0.0, 0.3, 1.7));
    // Out-of-range factors are clamped to the specification's [0, 1].
    let h = m(r#"{"pbrMetallicRoughness":{"metallicFactor":1.5,"roughnessFactor":-1}}"#);
    assert_eq!((h.metallic, h.roughness), (1.0, 0.0));
    // Emission with KHR_materials_emissive_strength: colour normalized, strength in `light`.
    let e = m(
        r#"{"emissiveFactor":[1,0.5,0.25],"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":4}}}"#,
    );
    assert_eq!((e.color, e.light), (Vec3::new(1.0, 0.5, 0.25), 4.0));
    assert!(e.is_emitter());
    // KHR_materials_transmission with KHR_materials_ior: the pbr model's rough dielectric, a
    // thin wall without KHR_materials_volume (the specification's reading).
    let g = m(
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.9,1,0.9,1],"roughnessFactor":0},
        "extensions":{"KHR_materials_transmission":{"transmissionFactor":1},"KHR_materials_ior":{"ior":1.33}}}"#,
    );
    assert!(g.is_pbr() && !g.is_dielectric());
    assert_eq!(
        (g.ior, g.transmission, g.color, g.volume.thin_walled),
        (1.33, 1.0, Vec3::new(0.9, 1.0, 0.9), true)
    );
    // With a volume of some thickness: a solid whose medium attenuates; of thickness 0,
    // still a thin wall.
    let v = m(
        r#"{"extensions":{"KHR_materials_transmission":{"transmissionFactor":0.5},
        "KHR_materials_volume":{"thicknessFactor":0.2,"attenuationDistance":0.5,"attenuationColor":[1,0.5,0.25]}}}"#,
    );
    assert_eq!(v.transmission, 0.5);
    assert_eq!(
        v.volume,
        termtrace::scene::Volume {
            thin_walled: false,
            attenuation_color: Vec3::new(1.0, 0.5, 0.25),
            attenuation_distance: 0.5
        }
    );
    let flat = m(
        r#"{"extensions":{"KHR_materials_transmission":{"transmissionFactor":1},
        "KHR_materials_volume":{"thicknessFactor":0}}}"#,
    );
    assert!(flat.volume.thin_walled);
    // KHR_materials_clearcoat (read from its JSON): factor and roughness, clamped.
    let c = m(
        r#"{"extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":0.75,
        "clearcoatRoughnessFactor":1.5}}}"#,
    );
    assert_eq!((c.clearcoat, c.clearcoat_roughness), (0.75, 1.0));
    assert_eq!((d.clearcoat, d.clearcoat_roughness), (0.0, 0.0));
}

#[test]
fn cameras_are_found_by_name_and_look_down_minus_z() {
    let nodes = r#"[{"mesh":0,"children":[1,2]},{"camera":0,"translation":[0,0,5]},{"camera":1,"translation":[3,0,0],"rotation":[0,0.7071068,0,0.7071068]}]"#;
    let extra = r#","cameras":[{"name":"front","type":"perspective","perspective":{"yfov":0.5,"znear":0.1}},
        {"name":"side","type":"perspective","perspective":{"yfov":1.0,"znear":0.1}}]"#;
    let bytes = gltf(&TRIANGLE, None, 4, nodes, PLAIN, extra);
    let first = import(&bytes).unwrap().camera.unwrap();
    assert!(close(first.look_from, DVec3::new(0.0, 0.0, 5.0)));
    assert!(close(first.look_at, DVec3::new(0.0, 0.0, 4.0)));
    assert!((first.vfov - 0.5f64.to_degrees()).abs() < 1e-5);
    // 90° about +Y turns −Z into −X: the side camera at x = 3 looks back toward the origin.
    let side = import_slice(
        &bytes,
        None,
        "t.gltf",
        DMat4::IDENTITY,
        Some("side"),
        Default::default(),
    )
    .unwrap()
    .camera
    .unwrap();
    assert!(close(
        side.look_at - side.look_from,
        DVec3::new(-1.0, 0.0, 0.0)
    ));
    let e = import_slice(
        &bytes,
        None,
        "t.gltf",
        DMat4::IDENTITY,
        Some("top"),
        Default::default(),
    )
    .unwrap_err();
    assert!(
        e.message.contains("no camera `top`") && e.message.contains("front, side"),
        "{e}"
    );
}

#[test]
fn punctual_lights_become_the_sun_and_small_emitters() {
    let nodes = r#"[{"mesh":0,"children":[1,2]},{"extensions":{"KHR_lights_punctual":{"light":0}},"translation":[0,2,0]},
        {"extensions":{"KHR_lights_punctual":{"light":1}},"rotation":[-0.7071068,0,0,0.7071068]}]"#;
    let extra = r#","extensionsUsed":["KHR_lights_punctual"],"extensions":{"KHR_lights_punctual":{"lights":[
        {"type":"point","intensity":10,"color":[1,0.5,0.5]},{"type":"directional","intensity":3}]}}"#;
    let imp = import(&gltf(&TRIANGLE, None, 4, nodes, PLAIN, extra)).unwrap();
    let bulb = imp
        .objects
        .iter()
        .find(|o| matches!(o.shape, Shape::Sphere { .. }))
        .expect("the point light's sphere");
    let Shape::Sphere { center, radius } = bulb.shape else {
        unreachable!()
    };
    assert!(close(center, DVec3::new(0.0, 2.0, 0.0)));
    // Its intensity L·π r² is the light's 10 candela.
    let intensity = bulb.material.light as f64 * std::f64::consts::PI * radius * radius;
    assert!((intensity - 10.0).abs() < 1e-4, "{intensity}");
    assert_eq!(bulb.material.color, Vec3::new(1.0, 0.5, 0.5));
    // −90° about X turns −Z into −Y: the light shines down, so the sun is up (+Y).
    let sun = imp.sun.expect("the directional light");
    assert!(
        close(sun.direction.normalize(), DVec3::Y),
        "{:?}",
        sun.direction
    );
    // Its lobe's irradiance at normal incidence, intensity·2π/(size + 2), is the 3 lux.
    let e = sun.intensity as f64 * std::f64::consts::TAU / (sun.size as f64 + 2.0);
    assert!((e - 3.0).abs() < 1e-4, "{e}");
}

#[test]
fn malformed_files_are_refused_with_a_message() {
    let nodes = r#"[{"mesh":0}]"#;
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"not json".to_vec(), "not a valid glTF"),
        (
            gltf(&TRIANGLE, Some(&[0, 1, 7]), 4, nodes, PLAIN, ""),
            "refers to vertex 7 of 3",
        ),
        (
            String::from_utf8(gltf(&TRIANGLE, None, 4, nodes, PLAIN, ""))
                .unwrap()
                .replace(r#""count":3"#, r#""count":300"#)
                .into_bytes(),
            "reaches past",
        ),
        (
            String::from_utf8(gltf(&TRIANGLE, None, 4, nodes, PLAIN, ""))
                .unwrap()
                .replace(r#""byteLength":36,"uri""#, r#""byteLength":3600,"uri""#)
                .into_bytes(),
            "buffer",
        ),
        (
            gltf(&[[0.0; 3]; 3], None, 4, nodes, PLAIN, ""),
            "no triangle with area",
        ),
    ];
    for (bytes, want) in cases {
        let e = import(&bytes).expect_err(want);
        assert!(e.to_string().contains(want), "{e} (wanted `{want}`)");
        assert!(e.to_string().starts_with("test.gltf: "), "{e}");
    }
}

/// Deterministic mutations of real files (the Box, as JSON and as GLB): every one is imported
/// or refused, none panics. `fuzz/` runs the same entry point under cargo-fuzz.
#[test]
fn thousands_of_mutated_files_never_panic() {
    let json = std::fs::read(BOX).unwrap();
    let glb = to_glb(&json);
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let (mut ok, mut refused) = (0, 0);
    for round in 0..3000 {
        let mut b = if round % 2 == 0 {
            json.clone()
        } else {
            glb.clone()
        };
        for _ in 0..1 + next() % 4 {
            let at = (next() % b.len() as u64) as usize;
            match next() % 3 {
                0 => b[at] = next() as u8,
                1 => b[at] = b"0123456789-.e,[]{}\""[(next() % 19) as usize],
                _ => {
                    b.truncate(at.max(1));
                }
            }
        }
        match std::panic::catch_unwind(|| import(&b)) {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                assert!(!e.message.is_empty());
                refused += 1
            }
            Err(_) => panic!(
                "round {round}: the import panicked on {}",
                String::from_utf8_lossy(&b[..b.len().min(400)])
            ),
        }
    }
    assert!(ok > 0 && refused > 0, "{ok} imported, {refused} refused");
}

/// Deterministic mutations of the compressed streams (the BIN chunks of the Draco and meshopt
/// twins of BoxTextured, where their decoders read): every one is imported or refused.
#[test]
fn mutated_compressed_streams_never_panic() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for file in [
        "tests/gltf/BoxTextured-draco/BoxTextured-draco.glb",
        "tests/gltf/BoxTextured-meshopt/BoxTextured-meshopt.glb",
        "tests/gltf/BoxTextured-meshopt/BoxTextured-meshopt-instancing.glb",
    ] {
        let glb = std::fs::read(file).unwrap();
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        let bin = 20 + json_len + 8;
        let (mut ok, mut refused) = (0, 0);
        for round in 0..1000 {
            let mut b = glb.clone();
            for _ in 0..1 + next() % 4 {
                // Mostly the geometry's streams, which come first in the chunk.
                let span = (b.len() - bin).min(if round % 2 == 0 { 2000 } else { usize::MAX });
                let at = bin + (next() % span as u64) as usize;
                b[at] = next() as u8;
            }
            match std::panic::catch_unwind(|| import(&b)) {
                Ok(Ok(_)) => ok += 1,
                Ok(Err(e)) => {
                    assert!(!e.message.is_empty());
                    refused += 1
                }
                Err(_) => panic!("{file}, round {round}: the import panicked"),
            }
        }
        eprintln!("{file}: {ok} imported, {refused} refused");
        assert!(ok > 0, "{file}: {ok} imported, {refused} refused");
    }
}

/// The same glTF as a binary GLB: its embedded buffer moved into the BIN chunk.
fn to_glb(json: &[u8]) -> Vec<u8> {
    let text = String::from_utf8(json.to_vec()).unwrap();
    let start = text.find("base64,").unwrap() + 7;
    let end = start + text[start..].find('"').unwrap();
    let mut bin = base64::engine::general_purpose::STANDARD
        .decode(&text[start..end])
        .unwrap();
    let uri_start = text[..start].rfind(",\n").unwrap_or(0);
    let mut j = format!("{}{}", &text[..uri_start], &text[end + 1..]).into_bytes();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&j);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

#[test]
fn the_public_box_opens_as_json_and_as_glb() {
    let s = Scene::load(BOX).unwrap();
    assert_eq!(s.objects.len(), 1);
    let t = triangles(&s.objects[0]);
    assert_eq!(t.len(), 12);
    for p in t.iter().flatten() {
        assert!((p.abs().max_element() - 0.5).abs() < 1e-9, "{p}");
    }
    // The file's only material: red, glTF's default metallic 1 and roughness 1.
    let m = &s.objects[0].material;
    assert_eq!(m.color, Vec3::new(0.8, 0.0, 0.0));
    assert_eq!(s.objects[0].material_name.as_deref(), Some("#0"));
    // No camera in the file: one that frames the box, looking at its centre.
    assert!(close(s.camera.look_at, DVec3::ZERO));
    let glb = to_glb(&std::fs::read(BOX).unwrap());
    let imp = import(&glb).unwrap();
    assert_eq!(triangles(&imp.objects[0]), t);
}

/// A scene that places the Box and overrides its material: diffuse, coloured.
fn placed_box(extra: &str) -> String {
    format!(
        "[camera]\nlook_from = [1.5, 1.2, 2.0]\nlook_at = [0, 0, 0]\nvfov = 40\n\
         [sky]\nuniform = [0.5, 0.5, 0.5]\n\
         [[gltf]]\nfile = \"{BOX}\"\ntranslate = [0, 0.1, 0]\n{extra}"
    )
}

#[test]
fn a_placed_box_is_a_furnace_on_both_tracers() {
    // A convex object: every bounce off it escapes to the uniform sky, so a pixel that sees
    // only the box is exactly albedo × sky and one that misses it exactly the sky; pixels on
    // the edge mix the two, with one share for all channels.
    // The override puts the glTF material into the lecture's model, as a Lambertian one.
    let toml = placed_box(
        "[gltf.materials.\"#0\"]\nmodel = \"lecture\"\ncolor = [0.5, 0.25, 0.75]\nspecular = 0\n\
         absorption = 0\n",
    );
    on_both(|| {
        let img = render(&toml, 40, 40, 8, 10);
        let (inside, outside) = ([0.25f32, 0.125, 0.375], [0.5f32; 3]);
        let (mut n_in, mut n_out) = (0, 0);
        for (i, p) in img.pixels.iter().enumerate() {
            if rel_err(*p, inside) <= 4.0 * f32::EPSILON as f64 {
                n_in += 1;
            } else if rel_err(*p, outside) <= 4.0 * f32::EPSILON as f64 {
                n_out += 1;
            } else {
                // p = a·inside + (1 − a)·outside, the same a in every channel.
                let a: Vec<f32> = (0..3)
                    .map(|k| (outside[k] - p[k]) / (outside[k] - inside[k]))
                    .collect();
                assert!(
                    a.iter()
                        .all(|x| (x - a[0]).abs() < 1e-5 && (0.0..=1.0).contains(x)),
                    "pixel {i}: {p:?} is no mix of the box and the sky"
                );
            }
        }
        assert!(
            n_in > 200 && n_out > 600,
            "{n_in} box pixels, {n_out} sky pixels"
        );
    });
}

#[test]
fn overrides_and_edits_are_written_back_and_read_again() {
    let toml = placed_box("[gltf.materials.\"#0\"]\nroughness = 0.25\n");
    let mut s = Scene::from_toml(&toml, "test").unwrap();
    assert_eq!(s.objects[0].material.roughness, 0.25);
    // An override speaks the glTF material's model: the lecture's keys are refused by name.
    let lecture = placed_box("[gltf.materials.\"#0\"]\nabsorption = 0.25\n");
    let e = Scene::from_toml(&lecture, "test").unwrap_err().to_string();
    assert!(
        e.contains("`absorption` belongs to another material model than `pbr`"),
        "{e}"
    );
    // `specular` is both models' (the pbr model's KHR_materials_specular factor).
    let both = placed_box("[gltf.materials.\"#0\"]\nspecular = 0.25\n");
    assert_eq!(
        Scene::from_toml(&both, "test").unwrap().objects[0]
            .material
            .specular,
        0.25
    );
    // A bad value in an override is reported once.
    let bad = placed_box("[gltf.materials.\"#0\"]\nroughness = 5\n");
    let e = Scene::from_toml(&bad, "test").unwrap_err().to_string();
    assert_eq!(e.matches("is out of range").count(), 1, "{e}");
    assert_eq!(s.objects[0].gltf, Some(0));
    // The object is placed: translated by 0.1 in y.
    let ys: Vec<f64> = triangles(&s.objects[0])
        .iter()
        .flatten()
        .map(|p| p.y)
        .collect();
    assert!(
        ys.iter()
            .all(|y| (y - 0.6).abs() < 1e-9 || (y + 0.4).abs() < 1e-9)
    );
    // An edit, as the preview makes one.
    s.objects[0].material.color = Vec3::new(0.1, 0.2, 0.3);
    let written = to_toml(&s);
    assert!(
        written.contains("[[gltf]]") && !written.contains("[[mesh]]"),
        "{written}"
    );
    let back = Scene::from_toml(&written, "test").unwrap();
    assert_eq!(back.objects.len(), 1);
    assert_eq!(back.objects[0].material, s.objects[0].material);
    assert_eq!(triangles(&back.objects[0]), triangles(&s.objects[0]));
    assert!(matches!(back.sky, Sky::Uniform(_)));
}

#[test]
fn toml_mistakes_in_a_placement_are_located() {
    let e = Scene::from_toml(
        &placed_box("[gltf.materials.\"#9\"]\ncolor = [1, 0, 0]\n"),
        "test",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("has no material `#9`") && e.contains("#0"),
        "{e}"
    );
    let e = Scene::from_toml("[[gltf]]\nfile = \"tests/gltf/none.glb\"\n", "test")
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.glb") && e.contains("cannot read"), "{e}");
    let e = Scene::from_toml(&placed_box("camera = \"main\"\n"), "test")
        .unwrap_err()
        .to_string();
    assert!(e.contains("no camera `main`"), "{e}");
}

#[test]
fn missing_files_and_required_extensions_are_named() {
    let dir = tempfile::tempdir().unwrap();
    // The Box with its buffer moved out to a file that is not there.
    let text = std::fs::read_to_string(BOX).unwrap();
    let start = text.find("data:application").unwrap();
    let end = start + text[start..].find('"').unwrap();
    let missing_bin = format!("{}box.bin{}", &text[..start], &text[end..]);
    let path = dir.path().join("nobin.gltf");
    std::fs::write(&path, &missing_bin).unwrap();
    let e = Scene::load(path.to_str().unwrap()).unwrap_err().to_string();
    assert!(
        e.contains("nobin.gltf") && e.contains("buffers[0] (`box.bin`)"),
        "{e}"
    );
    // A missing image.
    let with_image = text.replacen(
        "\"materials\": [",
        "\"images\": [{\"uri\": \"gone.png\"}], \"textures\": [{\"source\": 0}], \"materials\": [",
        1,
    )
    .replacen(
        "\"baseColorFactor\"",
        "\"baseColorTexture\": {\"index\": 0}, \"baseColorFactor\"",
        1,
    );
    let path = dir.path().join("noimage.gltf");
    std::fs::write(&path, &with_image).unwrap();
    let e = Scene::load(path.to_str().unwrap()).unwrap_err().to_string();
    assert!(
        e.contains("images[0] (`gone.png`)") && e.contains("cannot read"),
        "{e}"
    );
    // A required extension termtrace does not read; an optional one is only logged.
    let required = text.replacen(
        "\"asset\"",
        "\"extensionsUsed\": [\"KHR_materials_anisotropy\"], \"extensionsRequired\": [\"KHR_materials_anisotropy\"], \"asset\"",
        1,
    );
    // (Said once, by termtrace rather than the glTF crate's validation.)
    let e = import(required.as_bytes()).unwrap_err().to_string();
    assert!(
        e.contains(
            "requires the extension KHR_materials_anisotropy, which termtrace does not read"
        ) && e.matches("KHR_materials_anisotropy").count() == 1,
        "{e}"
    );
    let optional = text.replacen(
        "\"asset\"",
        "\"extensionsUsed\": [\"EXT_example\"], \"asset\"",
        1,
    );
    let imp = import(optional.as_bytes()).unwrap();
    assert!(
        imp.skipped.iter().any(|s| s.contains("EXT_example")),
        "{:?}",
        imp.skipped
    );
    // … named once by the scene (for `check`) whether opened alone or placed by a TOML scene,
    // and `check` lists it.
    let path = dir.path().join("optional.gltf");
    std::fs::write(&path, &optional).unwrap();
    let toml = dir.path().join("placed.toml");
    std::fs::write(&toml, "[[gltf]]\nfile = \"optional.gltf\"\n").unwrap();
    for opened in [&path, &toml] {
        let s = Scene::load(opened.to_str().unwrap()).unwrap();
        let named: Vec<_> = s.gltf[0]
            .left_out
            .iter()
            .filter(|l| l.contains("EXT_example"))
            .collect();
        assert_eq!(named.len(), 1, "{:?}", s.gltf[0].left_out);
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_termtrace"))
        .args(["check", path.to_str().unwrap()])
        .output()
        .unwrap();
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{shown}");
    assert!(
        shown.contains("left out   optional.gltf: the extension EXT_example"),
        "{shown}"
    );
    // The element of a broken accessor is named by its JSON path.
    let nodes = r#"[{"mesh":0}]"#;
    let e = import(&gltf(&TRIANGLE, Some(&[0, 1, 9]), 4, nodes, PLAIN, "")).unwrap_err();
    assert!(e.message.contains("meshes[0].primitives[0]"), "{e}");
}

/// Files `fuzz/` found crashing the import, each with what its refusal must say.
const FUZZ_CRASHES: &[(&str, &str)] = &[
    (
        "tests/gltf/fuzz/position-accessor-out-of-range.gltf",
        "names accessor",
    ),
    (
        "tests/gltf/fuzz/glb-length-below-header.glb",
        "less than the header",
    ),
    (
        "tests/gltf/fuzz/accessor-element-type.gltf",
        "accessor 2 holds Vec4 of F32, where Vec3 of [F32, I8, U8, I16, U16] belong",
    ),
    (
        "tests/gltf/fuzz/buffer-uri-escape-not-utf8.gltf",
        "buffers[0]",
    ),
    (
        "tests/gltf/fuzz/node-cycle.gltf",
        "nodes[0] is reached twice",
    ),
    (
        "tests/gltf/fuzz/image-without-uri.gltf",
        "images[1] has neither a uri nor a bufferView",
    ),
    (
        "tests/gltf/fuzz/accessor-count-zero.gltf",
        "accessor 2 has a count of 0",
    ),
];

/// The fuzzer's crashes, kept as cases: each is refused with a message.
#[test]
fn fuzzer_crashes_are_refused() {
    for (file, want) in FUZZ_CRASHES {
        let bytes = std::fs::read(file).unwrap();
        let e = import(&bytes).expect_err(file);
        assert!(e.message.contains(want), "{file}: {e}");
    }
}

/// KTX2 images `fuzz/` (its `ktx2` target) found crashing the transcode, each with what its
/// refusal must say: a level claiming 10¹² bytes inflated (the transcoder allocated them), an
/// ETC1S stream whose run length overflows, and a key/value entry whose length reaches past
/// the file's end (both panics inside the transcoder).
#[test]
fn ktx2_fuzzer_crashes_are_refused() {
    for (file, want) in [
        (
            "ktx2-inflated-length-huge.ktx2",
            "claims 1099461361664 bytes inflated",
        ),
        ("ktx2-etc1s-repeat-count-overflow.ktx2", "KTX2"),
        (
            "ktx2-key-value-length-past-end.ktx2",
            "KTX2 data is corrupt",
        ),
    ] {
        let bytes = std::fs::read(format!("tests/gltf/fuzz/{file}")).unwrap();
        let e = termtrace::scene::gltf::decode_image(&bytes).expect_err(file);
        assert!(e.0.contains(want), "{file}: {}", e.0);
    }
}

/// A file `fuzz/` found crashing the import that is valid enough to open: a primitive whose
/// material has no maps, with a TEXCOORD_0 of an element type texture coordinates cannot have
/// (the crate's reader panicked on it); the coordinates are not read, and it opens.
#[test]
fn a_fuzzer_crash_that_is_a_valid_file_imports() {
    let bytes = std::fs::read("tests/gltf/fuzz/texcoord-type-untextured.gltf").unwrap();
    let imported = import(&bytes).expect("its TEXCOORD_0 is not read");
    assert_eq!(imported.objects.len(), 1);
    assert!(imported.objects[0].material.textured.is_none());
}

#[test]
fn a_map_on_a_second_texture_coordinate_set_is_left_out_and_named() {
    // Khronos's MultiUVTest (Analytical Graphics, CC BY 4.0): its base colour map reads
    // TEXCOORD_0 and its emissive map TEXCOORD_1, which termtrace does not read.
    let i = termtrace::scene::gltf::import(
        std::path::Path::new("tests/gltf/MultiUVTest/MultiUVTest.glb"),
        glam::DMat4::IDENTITY,
        None,
        Default::default(),
    )
    .unwrap();
    let said = i.skipped.join("\n");
    assert!(
        said.contains("the emissive map of materials[0]: TEXCOORD_1 (only TEXCOORD_0 is read)"),
        "{said}"
    );
    let t = &i.objects[0].material.textured.as_ref().expect("textured").0;
    assert!(t.base_color.is_some() && t.emissive.is_none());
}

#[test]
fn a_quantized_file_renders_like_its_original() {
    // gltfpack's KHR_mesh_quantization twin of BoxTextured (u16 positions scaled by its node,
    // i8 normals, u16 texture coordinates with a texture transform; the extension required)
    // opens and renders like the original on both tracers: with the same random streams,
    // the images' means agree within 0.5 % and 95 % of their pixels within 0.02.
    let original = Scene::load("tests/gltf/BoxTextured/BoxTextured.gltf").unwrap();
    let quantized =
        Scene::load("tests/gltf/BoxTextured-quantized/BoxTextured-quantized.glb").unwrap();
    assert!(
        quantized.gltf[0].left_out.is_empty(),
        "{:?}",
        quantized.gltf[0].left_out
    );
    renders_alike(&original, &quantized);
}

/// Both tracers render `a` and `b` alike, with the same random streams: the images' means
/// within 0.5 %, and 95 % of their pixels within 0.02 (quantized geometry moves edges).
fn renders_alike(a: &Scene, b: &Scene) {
    on_both(|| {
        let a = snapshot(a, settings(48, 48, 4), 16).image();
        let b = snapshot(b, settings(48, 48, 4), 16).image();
        let mean = |i: &termtrace::output::LinearImage| {
            i.pixels.iter().flatten().map(|&c| c as f64).sum::<f64>() / (i.pixels.len() * 3) as f64
        };
        let (ma, mb) = (mean(&a), mean(&b));
        assert!((ma - mb).abs() <= 0.005 * ma, "means {ma} and {mb}");
        let close = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .filter(|(p, q)| (0..3).all(|c| (p[c] - q[c]).abs() <= 0.02))
            .count();
        assert!(
            close * 100 >= 95 * a.pixels.len(),
            "{close} of {}",
            a.pixels.len()
        );
    });
}

#[test]
fn meshopt_compressed_files_render_like_their_originals() {
    // gltfpack's EXT_meshopt_compression twins (tests/gltf/BoxTextured-meshopt/LICENSE.md):
    // every mode and filter the extension has but INDICES (TRIANGLES, and the OCTAHEDRAL,
    // EXPONENTIAL and QUATERNION filters), the last through EXT_mesh_gpu_instancing.
    let original = Scene::load("tests/gltf/BoxTextured/BoxTextured.gltf").unwrap();
    let packed = Scene::load("tests/gltf/BoxTextured-meshopt/BoxTextured-meshopt.glb").unwrap();
    assert!(
        packed.gltf[0].left_out.is_empty(),
        "{:?}",
        packed.gltf[0].left_out
    );
    renders_alike(&original, &packed);
    let nodes = Scene::load("tests/gltf/BoxTextured-instanced/BoxTextured-instanced.glb").unwrap();
    let packed =
        Scene::load("tests/gltf/BoxTextured-meshopt/BoxTextured-meshopt-instancing.glb").unwrap();
    assert_eq!(packed.objects.len(), 9, "nine copies, flattened");
    renders_alike(&nodes, &packed);
}

#[test]
fn a_draco_compressed_file_renders_like_its_original() {
    // glTF-Transform's KHR_draco_mesh_compression twin of BoxTextured (positions, normals and
    // texture coordinates quantized by Draco's defaults), decoded by draco-core.
    let original = Scene::load("tests/gltf/BoxTextured/BoxTextured.gltf").unwrap();
    let draco = Scene::load("tests/gltf/BoxTextured-draco/BoxTextured-draco.glb").unwrap();
    assert!(
        draco.gltf[0].left_out.is_empty(),
        "{:?}",
        draco.gltf[0].left_out
    );
    assert_eq!(draco.counts().triangles, original.counts().triangles);
    renders_alike(&original, &draco);
}

#[test]
fn khronos_draco_sample_renders_like_its_plain_twin() {
    // Khronos's own BoomBox and its glTF-Draco twin (Google's encoder, edgebreaker
    // connectivity; tests/gltf/BoomBox/SOURCE.md): the same 6 036 triangles, rendered alike.
    let plain = Scene::load("tests/gltf/BoomBox/BoomBox.gltf").unwrap();
    let draco = Scene::load("tests/gltf/BoomBox/BoomBox-draco.gltf").unwrap();
    assert_eq!(draco.counts().triangles, 6036);
    assert_eq!(plain.counts().triangles, 6036);
    renders_alike(&plain, &draco);
}

#[test]
fn a_corrupt_draco_stream_is_refused_naming_its_primitive() {
    // The Draco stream's view cut to 20 bytes, then its accessor's count made wrong: each is
    // refused by name, never a panic.
    let cut = glb_edited(
        "tests/gltf/BoxTextured-draco/BoxTextured-draco.glb",
        |doc| {
            let v = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
            ["bufferView"]
            .as_u64()
            .unwrap() as usize;
            doc["bufferViews"][v]["byteLength"] = 20.into();
        },
    );
    let e = import(&cut).unwrap_err().message;
    assert!(
        e.starts_with(
            "meshes[0].primitives[0] (KHR_draco_mesh_compression): the Draco stream does not decode"
        ),
        "{e}"
    );
    let miscounted = glb_edited(
        "tests/gltf/BoxTextured-draco/BoxTextured-draco.glb",
        |doc| {
            let a = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            doc["accessors"][a]["count"] = 5.into();
        },
    );
    let e = import(&miscounted).unwrap_err().message;
    assert!(
        e.contains("declares 5 of") && e.contains("Draco decodes"),
        "{e}"
    );
}

#[test]
fn a_corrupt_meshopt_stream_is_refused_naming_its_view() {
    let mut k = 0;
    // The first compressed view's stream cut to 8 bytes.
    let out = glb_edited(
        "tests/gltf/BoxTextured-meshopt/BoxTextured-meshopt.glb",
        |doc| {
            let views = doc["bufferViews"].as_array_mut().unwrap();
            let (i, view) = views
                .iter_mut()
                .enumerate()
                .find(|(_, v)| v.pointer("/extensions/EXT_meshopt_compression").is_some())
                .unwrap();
            view["extensions"]["EXT_meshopt_compression"]["byteLength"] = 8.into();
            k = i;
        },
    );
    let e = import(&out).unwrap_err().message;
    assert!(
        e.starts_with(&format!("bufferViews[{k}] (meshopt): its "))
            && e.contains("does not decode"),
        "{e}"
    );
}

#[test]
fn sparse_positions_are_substituted() {
    // A triangle (0,0,0), (1,0,0), (0,1,0) whose positions accessor has one sparse
    // substitution: vertex 2 moves to (0,2,0). Sparse indices are still refused, by name.
    let mut bin = Vec::new();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 2., 0.]] {
        bin.extend(p.iter().flat_map(|x| x.to_le_bytes()));
    }
    bin.extend(2u16.to_le_bytes());
    bin.extend([0u8; 2]);
    let data = base64::engine::general_purpose::STANDARD.encode(&bin);
    let file = |indices: &str| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}{indices}}}]}}],
            "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{data}"}}],
            "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":12}},
              {{"buffer":0,"byteOffset":48,"byteLength":2}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,2,0],
              "sparse":{{"count":1,"indices":{{"bufferView":2,"componentType":5123}},"values":{{"bufferView":1}}}}}},
              {{"componentType":5123,"count":3,"type":"SCALAR",
              "sparse":{{"count":1,"indices":{{"bufferView":2,"componentType":5123}},"values":{{"bufferView":2}}}}}}]}}"#,
            bin.len()
        )
    };
    let imp = import(file("").as_bytes()).unwrap();
    let Shape::Mesh { mesh, .. } = &imp.objects[0].shape else {
        panic!("not a mesh")
    };
    let t = mesh.triangles[0];
    assert_eq!(
        [t[0], t[1], t[2]],
        [DVec3::ZERO, DVec3::X, DVec3::new(0.0, 2.0, 0.0)]
    );
    let e = import(file(r#","indices":1"#).as_bytes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("accessor 1 is sparse"), "{e}");
}

/// The base colour map of `s`'s first object, which must have one; nothing of the file left
/// out.
fn base_color_map(s: &Scene) -> std::sync::Arc<termtrace::scene::texture::Texture> {
    assert!(s.gltf[0].left_out.is_empty(), "{:?}", s.gltf[0].left_out);
    s.objects[0]
        .material
        .textured
        .as_ref()
        .and_then(|t| t.0.base_color.clone())
        .expect("a base colour map")
}

/// `map`'s texels equal, every one, those of the PNG at `path` (an independent decoder's).
fn assert_texels_are(map: &termtrace::scene::texture::Texture, path: &str, what: &str) {
    let png = image::open(path).unwrap().to_rgba8();
    assert_eq!((map.width, map.height), png.dimensions(), "{what}");
    let same = map
        .texels
        .iter()
        .zip(png.pixels())
        .filter(|(t, p)| t.to_le_bytes() == p.0)
        .count();
    assert_eq!(same, map.texels.len(), "{what}: texels equal to {path}'s");
}

/// `twin` renders like BoxTextured with its PNG, on both tracers: image means within 3 %.
fn renders_like_the_png_original(twin: &Scene, what: &str) {
    let original = Scene::load("tests/gltf/BoxTextured/BoxTextured.gltf").unwrap();
    on_both(|| {
        let a = snapshot(&original, settings(32, 32, 3), 4).image();
        let b = snapshot(twin, settings(32, 32, 3), 4).image();
        let mean = |i: &termtrace::output::LinearImage| {
            i.pixels.iter().flatten().map(|&c| c as f64).sum::<f64>() / (i.pixels.len() * 3) as f64
        };
        let (ma, mb) = (mean(&a), mean(&b));
        assert!((ma - mb).abs() <= 0.03 * ma, "{what}: means {ma} and {mb}");
    });
}

#[test]
fn a_ktx2_basis_texture_renders_like_its_png_original() {
    // BoxTextured with its PNG re-encoded by Basis Universal's encoder as KTX2, ETC1S in
    // BasisLZ and UASTC in Zstandard (KHR_texture_basisu required, no PNG fallback; see the
    // folder's LICENSE.md). The transcoded texels must equal Basis Universal's own C++
    // transcoder's, exactly; the render must match the PNG original's within what the lossy
    // codec moved (3 % of the mean).
    let png_texels = image::open("tests/gltf/BoxTextured/CesiumLogoFlat.png")
        .unwrap()
        .to_rgba8();
    for codec in ["etc1s", "uastc"] {
        let dir = "tests/gltf/BoxTextured-basisu";
        let ktx = Scene::load(&format!("{dir}/BoxTextured-{codec}.glb")).unwrap();
        let map = base_color_map(&ktx);
        assert_texels_are(
            &map,
            &format!("{dir}/{codec}-decoded-by-basis-universal.png"),
            codec,
        );
        // The codec is lossy, but not that lossy: the texels stay near the PNG's.
        let off = map
            .texels
            .iter()
            .zip(png_texels.pixels())
            .flat_map(|(t, p)| {
                (0..3).map(move |c| (t.to_le_bytes()[c] as f64 - p.0[c] as f64).abs())
            })
            .sum::<f64>()
            / (map.texels.len() * 3) as f64;
        assert!(
            off < 4.0,
            "{codec}: mean texel difference from the PNG {off} levels"
        );
        renders_like_the_png_original(&ktx, codec);
    }
}

#[test]
fn a_corrupt_ktx2_texture_is_refused_by_name() {
    // The ETC1S file with its KTX2 image cut to half, and with its header's width made huge:
    // each is refused naming the image and what is wrong, without a panic.
    let glb = std::fs::read("tests/gltf/BoxTextured-basisu/BoxTextured-etc1s.glb").unwrap();
    let start = glb
        .windows(12)
        .position(|w| w == b"\xABKTX 20\xBB\r\n\x1A\n")
        .expect("the KTX2 image in the GLB");
    let dir = tempfile::tempdir().unwrap();
    let mut cut = glb.clone();
    let len = cut.len();
    // Zero the image's second half: its BasisLZ stream no longer decodes.
    for b in &mut cut[start + (len - start) / 2..] {
        *b = 0;
    }
    let mut huge = glb.clone();
    huge[start + 20..start + 24].copy_from_slice(&1_000_000u32.to_le_bytes());
    huge[start + 24..start + 28].copy_from_slice(&1_000_000u32.to_le_bytes());
    for (name, bytes, why) in [
        ("cut.glb", cut, "cannot transcode its KTX2"),
        ("huge.glb", huge, "1000000×1000000"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = format!("{:#}", Scene::load(path.to_str().unwrap()).unwrap_err());
        assert!(e.contains("images[0]") && e.contains(why), "{name}: {e}");
    }
}

#[test]
fn a_webp_texture_renders_like_its_png_original() {
    // glTF-Transform's lossless WebP twin of BoxTextured (EXT_texture_webp required, no PNG
    // fallback). Its encoder (sharp) applied the PNG's ICC profile (Apple's Generic RGB), so
    // the texels moved by up to 19 levels of 255 (mean 8): the image is compared with its
    // own independent decode, and the render with the original's within 3 %.
    let webp = Scene::load("tests/gltf/BoxTextured-webp/BoxTextured-webp.glb").unwrap();
    // The texels are the WebP's as an independent decoder reads it (ImageMagick's decode,
    // committed beside the file), exactly.
    let map = base_color_map(&webp);
    assert_texels_are(
        &map,
        "tests/gltf/BoxTextured-webp/decoded-by-imagemagick.png",
        "WebP",
    );
    renders_like_the_png_original(&webp, "WebP");
}
