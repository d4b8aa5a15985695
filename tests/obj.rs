//! OBJ models with their MTL materials and maps, on both tracers: an OBJ square is its glTF
//! twin bit for bit, opacity (`d`, `map_d`) cuts out as glTF's BLEND does, public Kenney
//! models (CC0) open and render alike on both tracers, bad files are refused by line, and an
//! edited OBJ material is written back as an override.

mod common;
use common::textured::{png_bytes, png_uri, square_gltf, tracers_agree_on_mean};
use common::*;
use termtrace::scene::{Scene, obj};

const W: u32 = 32;

/// A 2×2 map of four colours (and full alpha).
const TEXELS: [[u8; 4]; 4] = [
    [250, 40, 30, 255],
    [20, 200, 60, 255],
    [30, 50, 220, 255],
    [240, 230, 40, 255],
];

/// Writes `files` (name, bytes) into a fresh folder and loads `scene` (TOML) from it.
fn folder(files: &[(&str, Vec<u8>)], scene: &str) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let origin = dir.path().join("scene.toml").display().to_string();
    let s = Scene::from_toml(scene, &origin).unwrap_or_else(|e| panic!("{e}"));
    (dir, s)
}

/// The camera of `common::textured::gltf_scene`: a square of side 2 at z = 0 fills the
/// middle half of a 32 × 32 frame.
fn framed(sky: f32, model: &str) -> String {
    format!(
        "[camera]\nlook_from = [0, 0, 3.4641016]\nlook_at = [0, 0, 0]\nvfov = 60\n\
         [sky]\nuniform = [{sky}, {sky}, {sky}]\n[[gltf]]\nfile = \"{model}\"\n"
    )
}

/// The square of `tests/textures.rs` as OBJ: corners (∓1, ±1, 0), facing +z, OBJ's texture
/// coordinates (v up) putting the map's first row at the top, with `mtl` as its library.
fn square_obj(material: &str) -> Vec<u8> {
    format!(
        "mtllib square.mtl\no square\nv -1 1 0\nv 1 1 0\nv -1 -1 0\nv 1 -1 0\n\
         vt 0 1\nvt 1 1\nvt 0 0\nvt 1 0\nusemtl {material}\nf 1/1 3/3 2/2\nf 2/2 3/3 4/4\n"
    )
    .into_bytes()
}

#[test]
fn an_obj_square_with_its_mtl_is_its_gltf_twin_bit_for_bit() {
    // Kd × map_Kd, Ns 250 (roughness 1 − √0.25 = 0.5), no metal: the glTF material of the
    // same factors and map, on the same square, lit by a uniform sky. Every pixel equal.
    let obj_files = [
        ("square.obj", square_obj("painted")),
        (
            "square.mtl",
            b"newmtl painted\nKd 0.9 0.8 0.7\nNs 250\nillum 2\nmap_Kd paint.png\n".to_vec(),
        ),
        ("paint.png", png_bytes(2, 2, &TEXELS)),
    ];
    let (_a, from_obj) = folder(&obj_files, &framed(0.7, "square.obj"));
    let gltf = square_gltf(
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.9,0.8,0.7,1],"metallicFactor":0,
            "roughnessFactor":0.5,"baseColorTexture":{"index":0}}}"#,
        &format!(r#"[{{"uri":"{}"}}]"#, png_uri(2, 2, &TEXELS)),
        r#"[{"source":0}]"#,
        "[]",
    );
    let (_b, from_gltf) = folder(&[("square.gltf", gltf)], &framed(0.7, "square.gltf"));
    assert_eq!(
        from_obj.objects[0]
            .material
            .textured
            .as_ref()
            .unwrap()
            .0
            .base_factor,
        [0.9, 0.8, 0.7, 1.0]
    );
    on_both(|| {
        let st = settings(W, W, 4);
        let a = snapshot(&from_obj, st, 16).image();
        let b = snapshot(&from_gltf, st, 16).image();
        assert_eq!(a.pixels, b.pixels);
        // And the map is seen: its four colours in the four quarters of the square.
        let (tl, br) = (a.get(11, 11), a.get(20, 20));
        assert!(tl[0] > tl[2] && br[1] > br[2], "{tl:?} {br:?}");
    });
}

#[test]
fn an_opacity_map_cuts_out_exactly_where_it_is_zero_or_one() {
    // map_d of two texels, opaque then clear, clamped: opacity 1 for u ≤ ¼ and 0 for u ≥ ¾
    // (bilinear between). The square emits 1 (Ke): a pixel is exactly 1 where every sample
    // hits and exactly the sky where every sample passes (a stochastic cut-out at opacity 0
    // or 1 is certain); between, the share converges (a_dissolve_below_one_…).
    let files = [
        ("square.obj", square_obj("stencil")),
        (
            "square.mtl",
            b"newmtl stencil\nKd 0 0 0\nKe 1 1 1\nmap_d -clamp on stencil.png\n".to_vec(),
        ),
        (
            "stencil.png",
            png_bytes(2, 1, &[[255, 255, 255, 255], [0, 0, 0, 255]]),
        ),
    ];
    let (_d, s) = folder(&files, &framed(0.25, "square.obj"));
    on_both(|| {
        let img = snapshot(&s, settings(W, W, 4), 8).image();
        for y in 10..22 {
            // Pixel x covers u in [(x − 8)/16, (x − 7)/16].
            for x in 8..12 {
                assert_eq!(img.get(x, y), [1.0; 3], "opaque ({x},{y})");
            }
            for x in 20..24 {
                assert_eq!(img.get(x, y), [0.25; 3], "clear ({x},{y})");
            }
        }
    });
}

#[test]
fn a_dissolve_below_one_is_hit_in_its_share() {
    // d 0.25: a stochastic cut-out (glTF's BLEND), so the square's pixels converge to
    // 0.25·1 + 0.75·0. 256 samples: the mean over 144 pixels has a standard deviation of
    // sqrt(0.25·0.75/256)/12 = 0.0023; the tolerance 0.01 is 4.4 of them.
    let files = [
        ("square.obj", square_obj("veil")),
        ("square.mtl", b"newmtl veil\nKe 1 1 1\nd 0.25\n".to_vec()),
    ];
    let (_d, s) = folder(&files, &framed(0.0, "square.obj"));
    on_both(|| {
        let img = snapshot(&s, settings(W, W, 4), 256).image();
        let sum: f64 = (10..22)
            .flat_map(|y| (10..22).map(move |x| (x, y)))
            .map(|(x, y)| img.get(x, y)[0] as f64)
            .sum();
        let mean = sum / 144.0;
        assert!((mean - 0.25).abs() < 0.01, "mean {mean}");
    });
}

#[test]
fn public_kenney_models_open_with_their_materials_and_render_alike_on_both_tracers() {
    // Cube Pets' dog (CC0): five groups, one material whose map_Kd is in a subfolder.
    let dog = Scene::load("tests/assets/obj/cube-pets/animal-dog.obj").unwrap();
    assert_eq!(dog.objects.len(), 5);
    let names: Vec<&str> = dog
        .objects
        .iter()
        .map(|o| o.name.as_deref().unwrap())
        .collect();
    assert!(
        names.contains(&"body") && names.contains(&"leg-back-left"),
        "{names:?}"
    );
    let t = &dog.objects[0]
        .material
        .textured
        .as_ref()
        .expect("textured")
        .0;
    let map = t.base_color.as_ref().expect("the colour map");
    assert_eq!((map.width, map.height), (512, 512));
    assert_eq!(dog.gltf[0].materials.len(), 1);
    let termtrace::scene::Shape::Mesh { mesh, .. } = &dog.objects[0].shape else {
        panic!("not a mesh")
    };
    assert_eq!(mesh.uvs.len(), mesh.triangles.len());
    // Space Kit's racer (CC0): four materials of Kd colours alone, mapped as glTF's factors.
    let racer = Scene::load("tests/assets/obj/space-kit/craft_racer.obj").unwrap();
    let keys: Vec<&str> = racer.gltf[0]
        .materials
        .iter()
        .map(|(k, _)| k.as_str())
        .collect();
    assert_eq!(keys.len(), 4, "{keys:?}");
    let red = racer
        .objects
        .iter()
        .find(|o| o.material_name.as_deref() == Some("metalRed"))
        .unwrap();
    assert_eq!(
        red.material.color,
        glam::Vec3::new(1.0, 0.6285242, 0.2028302)
    );
    assert!(red.material.textured.is_none());
    for s in [&dog, &racer] {
        tracers_agree_on_mean(s, settings(24, 24, 4), 128);
    }
}

#[test]
fn bad_obj_and_mtl_files_are_refused_by_file_line_and_key() {
    let message = |files: &[(&str, Vec<u8>)]| -> String {
        let dir = tempfile::tempdir().unwrap();
        for (name, bytes) in files {
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let path = dir.path().join("square.obj");
        match Scene::load(&path.display().to_string()) {
            Ok(_) => panic!("{files:?} opened"),
            Err(e) => e.to_string(),
        }
    };
    // A library that is not there.
    let e = message(&[("square.obj", square_obj("m"))]);
    assert!(
        e.contains("square.obj") && e.contains("square.mtl") && e.contains("cannot read it"),
        "{e}"
    );
    // A map that is not there: the library's line, the material and the statement.
    let e = message(&[
        ("square.obj", square_obj("m")),
        (
            "square.mtl",
            b"newmtl m\nKd 1 1 1\n\nmap_Kd gone.png\n".to_vec(),
        ),
    ]);
    assert!(
        e.contains("square.mtl:4: material `m`: map_Kd") && e.contains("`gone.png` is not there"),
        "{e}"
    );
    // A malformed statement in the library, by line.
    let e = message(&[
        ("square.obj", square_obj("m")),
        ("square.mtl", b"newmtl m\nKd 1 x 1\n".to_vec()),
    ]);
    assert!(e.contains("square.mtl") && e.contains("line 2"), "{e}");
    // A malformed line in the OBJ file.
    let mut bad = square_obj("m");
    bad.extend(b"v 1 nope 0\n");
    let e = message(&[("square.obj", bad), ("square.mtl", b"newmtl m\n".to_vec())]);
    assert!(e.contains("line 14") && e.contains("`v 1 nope 0`"), "{e}");
    // An OBJ file has no cameras.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("square.obj"), square_obj("m")).unwrap();
    std::fs::write(dir.path().join("square.mtl"), "newmtl m\n").unwrap();
    let path = dir.path().join("square.obj").display().to_string();
    let e = Scene::load_with_camera(&path, Some("main"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("an OBJ file has no cameras"), "{e}");
}

#[test]
fn an_unknown_material_and_unread_maps_are_named_and_left_out() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("square.obj"), square_obj("nowhere")).unwrap();
    std::fs::write(
        dir.path().join("square.mtl"),
        "newmtl m\nKd 1 1 1\nmap_Ks shine.png\nmap_Bump bumps.png\n",
    )
    .unwrap();
    let i = obj::import(&dir.path().join("square.obj"), glam::DMat4::IDENTITY).unwrap();
    assert_eq!(
        i.objects[0].material_name.as_deref(),
        Some(obj::DEFAULT_MATERIAL)
    );
    let said = i.skipped.join("\n");
    assert!(said.contains("line 11: `usemtl nowhere`"), "{said}");
    assert!(
        said.contains("material `m`: map_Ks, bump (not read)"),
        "{said}"
    );
}

#[test]
fn an_edited_obj_material_is_written_back_as_an_override_of_the_file() {
    let files = [
        ("square.obj", square_obj("painted")),
        ("square.mtl", b"newmtl painted\nKd 0.5 0.5 0.5\n".to_vec()),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in &files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let mut s = Scene::load(&dir.path().join("square.obj").display().to_string()).unwrap();
    s.objects[0].material.color = glam::Vec3::new(0.25, 0.5, 0.75);
    let toml = termtrace::scene::to_toml(&s);
    assert!(toml.contains("file = \"square.obj\""), "{toml}");
    let saved = dir.path().join("saved.toml");
    std::fs::write(&saved, &toml).unwrap();
    let back = Scene::load(&saved.display().to_string()).unwrap();
    assert_eq!(back.objects[0].material, s.objects[0].material);
    // The OBJ and its library are untouched.
    assert_eq!(
        std::fs::read(dir.path().join("square.mtl")).unwrap(),
        files[1].1
    );
}

#[test]
fn fuzzer_finds_are_refused_or_imported_without_a_panic() {
    // Each file under tests/assets/obj/fuzz/ is an input of `fuzz/fuzz_targets/obj.rs` that
    // once panicked: the OBJ text, the MTL library and an image, split by the byte 0x1e.
    let mut cases = 0;
    for entry in std::fs::read_dir("tests/assets/obj/fuzz").unwrap() {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        let mut parts = data.split(|&b| b == 0x1e);
        let text = String::from_utf8_lossy(parts.next().unwrap_or_default()).into_owned();
        let mtl = parts.next().unwrap_or_default().to_vec();
        let image = parts.next().unwrap_or_default().to_vec();
        let read = |p: &std::path::Path| -> std::io::Result<Vec<u8>> {
            match p.extension().and_then(|e| e.to_str()) {
                Some("mtl") => Ok(mtl.clone()),
                Some(_) => Ok(image.clone()),
                None => Err(std::io::ErrorKind::NotFound.into()),
            }
        };
        let result = std::panic::catch_unwind(|| {
            obj::import_from(
                "fuzz.obj",
                &text,
                std::path::Path::new("."),
                &read,
                glam::DMat4::IDENTITY,
            )
            .map(|_| ())
        });
        match result {
            Ok(Err(e)) => assert!(!e.message.is_empty(), "{}", path.display()),
            Ok(Ok(())) => {}
            Err(_) => panic!("{} panicked", path.display()),
        }
        cases += 1;
    }
    assert!(cases >= 1);
}

#[test]
fn every_committed_asset_converges_to_one_image_on_both_tracers() {
    // The bias check of `converge` (a Welch t-test per 8×8 tile of the two tracers' images,
    // independent seeds, Bonferroni-corrected over every tile of every asset at α = 0.01) on
    // each public asset in the repository: glTF's Box, BoxTextured, NormalTangentMirrorTest
    // and MultiUVTest, and the two OBJ models.
    let assets = [
        "tests/gltf/Box/Box.gltf",
        "tests/gltf/BoxTextured/BoxTextured.gltf",
        "tests/gltf/NormalTangentMirrorTest/NormalTangentMirrorTest.glb",
        "tests/gltf/MultiUVTest/MultiUVTest.glb",
        "tests/assets/obj/cube-pets/animal-dog.obj",
        "tests/assets/obj/space-kit/craft_racer.obj",
    ];
    let mut tally = BiasTally::default();
    for a in assets {
        let s = Scene::load(a).unwrap();
        let at = |seed| termtrace::common::FrameSettings {
            seed,
            ..settings(32, 24, 6)
        };
        let gpu = snapshot_on(
            termtrace::render::Backend::Gpu(ctx()),
            &s,
            at(1),
            48,
            Default::default(),
        );
        let cpu = cpu_snapshot(&s, at(2), 48);
        assert_eq!(
            (gpu.invalid_samples(), cpu.invalid_samples()),
            (0, 0),
            "{a}"
        );
        tally.check(a, &cpu, &gpu, 0.01 / assets.len() as f64);
    }
    tally.assert_none_differ(12 * assets.len());
}

#[test]
fn a_flat_norm_map_is_no_map_bit_for_bit_and_a_tilted_one_turns_the_light() {
    // The PBR extension's `norm`: a tangent-space normal map, read as glTF's (MikkTSpace
    // tangents on the file's `vn` normals). A flat map (128, 128, 255) leaves every normal as
    // it is: the image equals the map's absence bit for bit. A map tilting the normals 45°
    // towards +u (+x on the screen), under a broad sun lobe from +x+z (exponent 1), brightens
    // the square: 64 pixels × 64 samples, a margin of 5 %.
    let obj = |with_vn: bool| {
        let mut s = String::from_utf8(square_obj("m")).unwrap();
        if with_vn {
            s = s.replace("vt 0 1", "vn 0 0 1\nvt 0 1").replace(
                "f 1/1 3/3 2/2\nf 2/2 3/3 4/4",
                "f 1/1/1 3/3/1 2/2/1\nf 2/2/1 3/3/1 4/4/1",
            );
        }
        s.into_bytes()
    };
    let sky = "[camera]\nlook_from = [0, 0, 3.4641016]\nlook_at = [0, 0, 0]\nvfov = 60\n\
               [sky]\nbottom = [0.1, 0.1, 0.1]\ntop = [0.1, 0.1, 0.1]\n\
               sun = { direction = [1, 0, 1], color = [1, 1, 1], intensity = 2, size = 1 }\n\
               [[gltf]]\nfile = \"square.obj\"\n";
    for with_vn in [true, false] {
        let scene = |norm: &str, texel: [u8; 4]| {
            folder(
                &[
                    ("square.obj", obj(with_vn)),
                    (
                        "square.mtl",
                        format!("newmtl m\nKd 0.8 0.8 0.8\nNs 10\n{norm}").into_bytes(),
                    ),
                    ("n.png", png_bytes(1, 1, &[texel])),
                ],
                sky,
            )
        };
        let (_a, plain) = scene("", [0; 4]);
        let (_b, flat) = scene("norm n.png\n", [128, 128, 255, 255]);
        let (_c, tilted) = scene("norm -bm 1 n.png\n", [218, 128, 218, 255]);
        assert!(
            flat.objects[0]
                .material
                .textured
                .as_ref()
                .unwrap()
                .0
                .normal
                .is_some()
        );
        on_both(|| {
            let st = settings(W, W, 3);
            let a = snapshot(&plain, st, 16).image();
            let b = snapshot(&flat, st, 16).image();
            assert_eq!(a.pixels, b.pixels, "flat map, vn {with_vn}");
            let c = snapshot(&tilted, st, 64).image();
            let a = snapshot(&plain, st, 64).image();
            let centre = |i: &termtrace::output::LinearImage| -> f32 {
                (12..20)
                    .flat_map(|y| (12..20).map(move |x| (x, y)))
                    .map(|(x, y)| i.get(x, y)[0])
                    .sum()
            };
            assert!(
                centre(&c) > 1.05 * centre(&a),
                "{} against {}",
                centre(&c),
                centre(&a)
            );
        });
    }
}

#[test]
fn materials_naming_one_image_share_its_texture() {
    // Two materials with the same map and wrap mode hold one texture allocation (so the
    // texture words hold its texels once); a clamped use of the same file is another.
    let obj = b"mtllib square.mtl\nv -1 1 0\nv 1 1 0\nv -1 -1 0\nv 1 -1 0\nvt 0 1\nvt 1 1\n\
                vt 0 0\nvt 1 0\ng a\nusemtl a\nf 1/1 3/3 2/2\ng b\nusemtl b\nf 2/2 3/3 4/4\n\
                g c\nusemtl c\nf 1/1 3/3 4/4\n";
    let mtl = b"newmtl a\nmap_Kd paint.png\nnewmtl b\nKd 0.5 0.5 0.5\nmap_Kd paint.png\n\
                newmtl c\nmap_Kd -clamp on paint.png\n";
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("square.obj"), obj).unwrap();
    std::fs::write(dir.path().join("square.mtl"), mtl).unwrap();
    std::fs::write(dir.path().join("paint.png"), png_bytes(2, 2, &TEXELS)).unwrap();
    let i = obj::import(&dir.path().join("square.obj"), glam::DMat4::IDENTITY).unwrap();
    let map = |k: usize| {
        i.objects[k]
            .material
            .textured
            .as_ref()
            .unwrap()
            .0
            .base_color
            .clone()
            .unwrap()
    };
    assert!(std::sync::Arc::ptr_eq(&map(0), &map(1)));
    assert!(!std::sync::Arc::ptr_eq(&map(0), &map(2)));
    assert_eq!(map(0).texels, map(2).texels);
}
