//! Tangent-space normal maps on both tracers: a flat map is no map, bit for bit (with the
//! file's tangents, with MikkTSpace's, without normals); a map that tilts every normal by 45°
//! in a white furnace loses exactly the share of its lobes that falls below the surface;
//! the map's x and y turn the normal toward the texture's +u and up the image, whether the
//! tangents come from the file or from MikkTSpace; the CPU and GPU tracers agree on a lit,
//! normal-mapped scene. Smooth shading from the file's normals alone, likewise: normals equal
//! to the face's change no bit, normals tilted 45° lose the same share of the lobe as the
//! tilting normal map, and both tracers agree on a square whose normals spread like a dome.

mod common;
use base64::Engine;
use common::textured::*;
use common::*;

/// A square of side 2 at z = 0 facing +z, UV (0, 0) at its upper-left corner (u along +x, v
/// along −y), with the vertex `normal` and `tangent` given (or not), and a material whose
/// `pbrMetallicRoughness` and extra members are `material`, using `images`.
fn square(
    material: &str,
    images: &[String],
    normal: Option<[f32; 3]>,
    tangent: Option<[f32; 4]>,
) -> Vec<u8> {
    square_with(material, images, normal.map(|n| [n; 4]), tangent)
}

/// [`square`] with a normal at each corner (upper-left, upper-right, lower-left, lower-right).
fn square_with(
    material: &str,
    images: &[String],
    normals: Option<[[f32; 3]; 4]>,
    tangent: Option<[f32; 4]>,
) -> Vec<u8> {
    let mut bin = square_bin();
    bin.extend([0, 0]); // align to 4
    let mut attributes = r#""POSITION":0,"TEXCOORD_0":1"#.to_string();
    let mut accessors = vec![
        r#"{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}"#.to_string(),
        r#"{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}"#.to_string(),
        r#"{"bufferView":2,"componentType":5123,"count":6,"type":"SCALAR"}"#.to_string(),
    ];
    let mut views = vec![
        r#"{"buffer":0,"byteOffset":0,"byteLength":48}"#.to_string(),
        r#"{"buffer":0,"byteOffset":48,"byteLength":32}"#.to_string(),
        r#"{"buffer":0,"byteOffset":80,"byteLength":12}"#.to_string(),
    ];
    let mut add = |name: &str, kind: &str, values: Vec<f32>, bin: &mut Vec<u8>| {
        let k = accessors.len();
        attributes += &format!(r#","{name}":{k}"#);
        accessors.push(format!(
            r#"{{"bufferView":{k},"componentType":5126,"count":4,"type":"{kind}"}}"#
        ));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}"#,
            bin.len(),
            4 * values.len()
        ));
        bin.extend(values.iter().flat_map(|x| x.to_le_bytes()));
    };
    if let Some(n) = normals {
        add("NORMAL", "VEC3", n.concat(), &mut bin);
    }
    if let Some(t) = tangent {
        add("TANGENT", "VEC4", t.repeat(4), &mut bin);
    }
    let images: Vec<String> = images
        .iter()
        .map(|u| format!(r#"{{"uri":"{u}"}}"#))
        .collect();
    let textures: Vec<String> = (0..images.len())
        .map(|i| format!(r#"{{"source":{i}}}"#))
        .collect();
    let uri = base64::engine::general_purpose::STANDARD.encode(&bin);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{{attributes}}},"indices":2,"material":0}}]}}],
        "materials":[{{{material}}}],"images":[{}],"textures":[{}],
        "accessors":[{}],"bufferViews":[{}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{uri}"}}]}}"#,
        images.join(","),
        textures.join(","),
        accessors.join(","),
        views.join(","),
        bin.len()
    )
    .into_bytes()
}

const W: u32 = 32;

/// A 2×2 normal map of one texel value.
fn normal_map(texel: [u8; 3]) -> String {
    png_uri(2, 2, &[[texel[0], texel[1], texel[2], 255]; 4])
}

fn mapped(base: &str) -> String {
    format!(r#""pbrMetallicRoughness":{{{base}}},"normalTexture":{{"index":0}}"#)
}

/// A sphere light above and in front of the square, so that light sampling runs too.
const LAMP: &str =
    "[[sphere]]\ncenter = [0.5, 1.5, 1.5]\nradius = 0.3\ncolor = [1, 1, 1]\nlight = 8\n";

#[test]
fn a_flat_normal_map_is_no_normal_map_bit_for_bit() {
    let base = r#""baseColorFactor":[0.6,0.5,0.4,1],"metallicFactor":0.3,"roughnessFactor":0.4"#;
    let flat = [normal_map([128, 128, 255])];
    let plain = square(
        &format!(r#""pbrMetallicRoughness":{{{base}}}"#),
        &[],
        None,
        None,
    );
    let variants = [
        (
            "file normals and tangents",
            Some([0., 0., 1.]),
            Some([1., 0., 0., 1.]),
        ),
        (
            "file normals, MikkTSpace tangents",
            Some([0., 0., 1.]),
            None,
        ),
        ("no normals", None, None),
    ];
    let (_d0, want) = gltf_scene(&plain, 0.5, LAMP);
    let scenes: Vec<_> = variants
        .iter()
        .map(|(what, n, t)| {
            (
                what,
                gltf_scene(&square(&mapped(base), &flat, *n, *t), 0.5, LAMP),
            )
        })
        .collect();
    on_both(|| {
        let st = settings(W, W, 4);
        let a = snapshot(&want, st, 8).image();
        assert!(a.get(16, 16)[0] > 0.05, "the square is dark");
        for (what, (_d, s)) in &scenes {
            assert!(termtrace::common::Features::of(s).normal_maps);
            let b = snapshot(s, st, 8).image();
            assert_eq!(
                a.pixels, b.pixels,
                "{what}: a flat normal map changed the image"
            );
        }
    });
}

#[test]
fn a_map_tilting_every_normal_45_degrees_loses_the_lobe_below_the_surface() {
    // A white square under a uniform sky of 1, its every shading normal turned 45° (texel
    // x = 1, z = 1): a path bounces once and meets the sky unless its direction enters the
    // surface, which ends it. The material is put into the lecture's model by an override,
    // as the glTF mapping of earlier rounds made it (metallic 0: a specular share of 0.04):
    // - the diffuse lobe (0.96): a cosine lobe about the tilted normal, of which the share
    //   (1 − cos 45°) / 2 enters the surface (the lune below the surface projects onto the
    //   lobe's disk as half the disk less half an ellipse of axes 1 and cos 45°);
    // - the specular lobe (0.04, white, roughness 1 = fuzz 1): the mirror direction about the
    //   tilted normal, (1, 0, 0), plus a uniform unit vector u, which enters the surface
    //   exactly when u_z ≤ 0: a share of 1/2.
    // So the square's expected value is 0.96 (1 + cos 45°) / 2 + 0.04 / 2 = 0.83941. 196
    // pixels × 256 samples: the standard error of the mean is √(p(1 − p) / 50176) = 0.0016;
    // the tolerance, 0.0066, is four of it.
    let c = std::f64::consts::FRAC_1_SQRT_2;
    let want = 0.96 * (1.0 + c) / 2.0 + 0.04 * 0.5;
    let tilt = [normal_map([255, 128, 255])];
    let white = r#""baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":1"#;
    let lecture = "[gltf.materials.\"#0\"]\nmodel = \"lecture\"\nsmoothness = 1\nabsorption = 1\n\
                   specular = 0.04\nspecular_color = [1, 1, 1]\n";
    let (_d, s) = gltf_scene(
        &square(&mapped(white), &tilt, Some([0., 0., 1.]), None),
        1.0,
        lecture,
    );
    on_both(|| {
        let img = snapshot(&s, settings(W, W, 4), 256).image();
        let (mut sum, mut n) = (0.0f64, 0);
        for y in 9..23 {
            for x in 9..23 {
                let p = img.get(x, y);
                assert!(p[0] == p[1] && p[1] == p[2], "({x},{y}) {p:?}");
                sum += p[0] as f64;
                n += 1;
            }
        }
        let mean = sum / n as f64;
        assert!(
            (mean - want).abs() <= 0.0066,
            "the tilted square's mean is {mean}, not {want}"
        );
        // Outside, the sky exactly.
        assert_eq!(img.get(2, 2), [1.0; 3]);
    });
}

/// The CPU tracer's shading normal at the square's centre, with the map's single `texel`.
fn centre_normal(texel: [u8; 3], tangent: Option<[f32; 4]>) -> glam::Vec3A {
    use termtrace::common::textures;
    let gltf = square(
        &mapped(r#""baseColorFactor":[1,1,1,1]"#),
        &[normal_map(texel)],
        Some([0., 0., 1.]),
        tangent,
    );
    let (_d, s) = gltf_scene(&gltf, 1.0, "");
    let words = textures::words(&s).unwrap();
    assert_eq!(
        textures::word_count(&s),
        words.len(),
        "the frames are counted"
    );
    let rec = termtrace::cpu::texture::record(&words, 0).expect("a record");
    // Triangle 0 (corners (−1, 1), (−1, −1), (1, 1)): its point (−0.5, 0.5, 0) has UV
    // (0.25, 0.25); the triangle as the tracers store it.
    let tri = termtrace::cpu::intersect::Triangle {
        v0: glam::Vec3A::new(-1.0, 1.0, 0.0),
        e1: glam::Vec3A::new(0.0, -2.0, 0.0),
        e2: glam::Vec3A::new(2.0, 0.0, 0.0),
        material: 0,
    };
    let p = glam::Vec3A::new(-0.5, 0.5, 0.0);
    let bary = termtrace::cpu::intersect::triangle_barycentrics(&tri, p - tri.v0);
    let uv = termtrace::cpu::texture::uv_at(&words, 0, bary);
    assert_eq!(uv, glam::Vec2::new(0.25, 0.25));
    termtrace::cpu::texture::shading_normal(&words, rec, 0, bary, uv, glam::Vec3A::Z)
}

#[test]
fn a_maps_x_turns_toward_u_and_its_y_up_the_image_with_either_tangents() {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let cases = [
        ([255, 128, 255], [s, 0.0, s]), // +x: toward +u (+x in the world)
        ([0, 128, 255], [-s, 0.0, s]),  // −x
        ([128, 255, 255], [0.0, s, s]), // +y: up the image, where v falls (+y here)
        ([128, 0, 255], [0.0, -s, s]),  // −y
        ([128, 128, 255], [0.0, 0.0, 1.0]),
    ];
    for (texel, want) in cases {
        for tangent in [Some([1.0, 0.0, 0.0, 1.0]), None] {
            let n = centre_normal(texel, tangent);
            let err = (n - glam::Vec3A::from(want)).length();
            assert!(
                err < 1e-5,
                "texel {texel:?}, tangents {tangent:?}: {n:?}, not {want:?}"
            );
        }
    }
}

#[test]
fn both_tracers_agree_on_a_lit_normal_mapped_scene() {
    // A 4×4 map of varied normals (repeated twice across the square), a glossy base, a
    // sphere light (light sampling and MIS) and a sky: the tracers' images of 256 samples
    // must agree to their noise: the means within 1 %, each 4×4 block's within 6 %.
    let texels: Vec<[u8; 4]> = (0..16u32)
        .map(|i| [40 + i * 11, 220 - i * 9, 200 + (i * 7) % 55, 255].map(|c| c as u8))
        .collect();
    let gltf = square(
        &mapped(r#""baseColorFactor":[0.8,0.7,0.6,1],"metallicFactor":0.5,"roughnessFactor":0.3"#),
        &[png_uri(4, 4, &texels)],
        Some([0.0, 0.0, 1.0]),
        None,
    );
    let (_d, mut s) = gltf_scene(&gltf, 0.4, LAMP);
    scale_uvs(&mut s, 2.0);
    let st = settings(24, 24, 6);
    let gpu = snapshot_on(
        termtrace::render::Backend::Gpu(ctx()),
        &s,
        st,
        256,
        Default::default(),
    );
    let cpu = cpu_snapshot(&s, st, 256);
    assert_eq!(gpu.invalid_samples() + cpu.invalid_samples(), 0);
    let (a, b) = (gpu.image(), cpu.image());
    let sum =
        |i: &termtrace::output::LinearImage, xs: std::ops::Range<u32>, ys: std::ops::Range<u32>| {
            let mut t = 0.0f64;
            for y in ys.clone() {
                for x in xs.clone() {
                    let p = i.get(x, y);
                    t += (p[0] + p[1] + p[2]) as f64;
                }
            }
            t
        };
    let (ma, mb) = (sum(&a, 0..24, 0..24), sum(&b, 0..24, 0..24));
    assert!(
        (ma - mb).abs() <= 0.01 * ma.max(mb),
        "sums {ma} (GPU), {mb} (CPU)"
    );
    for by in 0..6 {
        for bx in 0..6 {
            let r = |i| sum(i, bx * 4..bx * 4 + 4, by * 4..by * 4 + 4);
            let (x, y) = (r(&a), r(&b));
            assert!(
                (x - y).abs() <= 0.06 * x.max(y),
                "block ({bx},{by}): {x}, {y}"
            );
        }
    }
}

#[test]
fn the_public_mirror_test_keeps_its_tangents_and_renders_alike_on_both_tracers() {
    // Khronos's NormalTangentMirrorTest (Analytical Graphics, CC BY 4.0): a plate of
    // normal-mapped bumps whose texture coordinates are mirrored in u and in v, with the
    // file's TANGENTs of both handedness signs.
    let s = termtrace::scene::Scene::load(
        "tests/gltf/NormalTangentMirrorTest/NormalTangentMirrorTest.glb",
    )
    .unwrap();
    let termtrace::scene::Shape::Mesh { mesh, .. } = &s.objects[0].shape else {
        panic!("not a mesh")
    };
    assert_eq!(mesh.tangents.len(), mesh.triangles.len());
    let signs: Vec<f32> = mesh.tangents.iter().flatten().map(|t| t[3]).collect();
    assert!(
        signs.contains(&1.0) && signs.contains(&-1.0),
        "both handednesses"
    );
    tracers_agree_on_mean(&s, settings(24, 24, 4), 96);
}

#[test]
fn file_normals_equal_to_the_faces_change_nothing_bit_for_bit() {
    // Smooth shading interpolates the file's normals: where they are the face's own, the
    // image is the flat one, bit for bit, on both tracers (lit by the lamp: light sampling
    // and MIS weigh the shading normal too).
    let m = r#""pbrMetallicRoughness":{"baseColorFactor":[0.6,0.5,0.4,1],"metallicFactor":0.3,"roughnessFactor":0.4}"#;
    let (_d0, flat) = gltf_scene(&square(m, &[], None, None), 0.5, LAMP);
    let (_d1, smooth) = gltf_scene(&square(m, &[], Some([0., 0., 1.]), None), 0.5, LAMP);
    assert!(!termtrace::common::Features::of(&flat).smooth_normals);
    assert!(termtrace::common::Features::of(&smooth).smooth_normals);
    on_both(|| {
        let st = settings(W, W, 4);
        let a = snapshot(&flat, st, 8).image();
        assert!(a.get(16, 16)[0] > 0.05, "the square is dark");
        assert_eq!(a.pixels, snapshot(&smooth, st, 8).image().pixels);
    });
}

#[test]
fn file_normals_tilted_45_degrees_lose_the_lobe_below_the_surface() {
    // The normal map test above with the tilt in the file's normals instead of a map (no
    // texture at all): every corner's normal is (sin 45°, 0, cos 45°), so every interpolated
    // normal is; the expected value and its tolerance are the same, 0.96 (1 + cos 45°) / 2 +
    // 0.04 / 2 = 0.83941 ± 0.0066 (four standard errors).
    let c = std::f64::consts::FRAC_1_SQRT_2;
    let want = 0.96 * (1.0 + c) / 2.0 + 0.04 * 0.5;
    let white = r#""pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":1}"#;
    let lecture = "[gltf.materials.\"#0\"]\nmodel = \"lecture\"\nsmoothness = 1\nabsorption = 1\n\
                   specular = 0.04\nspecular_color = [1, 1, 1]\n";
    let tilted = [c as f32, 0.0, c as f32];
    let (_d, s) = gltf_scene(&square(white, &[], Some(tilted), None), 1.0, lecture);
    let f = termtrace::common::Features::of(&s);
    assert!(
        f.smooth_normals && !f.textures && !f.normal_maps,
        "{}",
        f.summary()
    );
    on_both(|| {
        let img = snapshot(&s, settings(W, W, 4), 256).image();
        let (mut sum, mut n) = (0.0f64, 0);
        for y in 9..23 {
            for x in 9..23 {
                sum += img.get(x, y)[0] as f64;
                n += 1;
            }
        }
        let mean = sum / n as f64;
        assert!(
            (mean - want).abs() <= 0.0066,
            "the square of tilted normals has mean {mean}, not {want}"
        );
        assert_eq!(img.get(2, 2), [1.0; 3]);
    });
}

#[test]
fn both_tracers_agree_on_a_square_of_dome_normals() {
    // The corners' normals lean outward (a dome's, (x/2, y/2, 1) normalised), so the shading
    // normal turns across the square: a glossy base under the lamp and the sky. The tracers'
    // means agree within 1 % (`tracers_agree_on_mean`), neither with an invalid sample; and
    // the dome is not the flat square (its halves turn toward and away from the lamp).
    let dome = [[-1.0f32, 1.0], [1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]].map(|[x, y]| {
        glam::Vec3::new(x / 2.0, y / 2.0, 1.0)
            .normalize()
            .to_array()
    });
    let m = r#""pbrMetallicRoughness":{"baseColorFactor":[0.8,0.7,0.6,1],"metallicFactor":0.5,"roughnessFactor":0.3}"#;
    let (_d, s) = gltf_scene(&square_with(m, &[], Some(dome), None), 0.4, LAMP);
    let st = settings(24, 24, 6);
    tracers_agree_on_mean(&s, st, 256);
    let (_d0, flat) = gltf_scene(&square(m, &[], None, None), 0.4, LAMP);
    let a = cpu_snapshot(&s, st, 64).image();
    let b = cpu_snapshot(&flat, st, 64).image();
    let half = |img: &termtrace::output::LinearImage, xs: std::ops::Range<u32>| {
        let mut sum = 0.0f64;
        for y in 8..16 {
            for x in xs.clone() {
                sum += img.get(x, y).iter().map(|&c| c as f64).sum::<f64>();
            }
        }
        sum
    };
    let (dl, dr) = (half(&a, 6..12), half(&a, 12..18));
    let (fl, fr) = (half(&b, 6..12), half(&b, 12..18));
    // The lamp is to the right (x = 0.5): the dome's right half leans toward it and its
    // left half away, so its right-left contrast is well above the flat square's (measured
    // 8.5 against 3.3; each half's sum has a standard error of about 0.3).
    assert!(
        fr - fl > 0.0 && dr - dl > 2.0 * (fr - fl),
        "the dome's halves {dl:.3} {dr:.3} against the flat square's {fl:.3} {fr:.3}"
    );
}

#[test]
fn the_lectures_meshes_stay_flat() {
    // A TOML [[mesh]] (the lecture's scenes) reads no normals: nothing of smooth shading is
    // compiled for it, and its images stay what they were.
    for name in termtrace::scene::BUILTIN_SCENES.iter().map(|(n, _)| *n) {
        let s = termtrace::scene::Scene::load(name).unwrap();
        assert!(
            !termtrace::common::Features::of(&s).smooth_normals,
            "{name}"
        );
    }
}
