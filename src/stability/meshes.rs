//! The mesh cases of `check --stress`: meshes as people make them, built here so that they
//! need no file: degenerate and zero-area triangles, NaN and zero-length normals and
//! tangents, texture coordinates far outside [0, 1], a model of 10⁵ units with 10⁻³ detail,
//! and a thin shell seen edge-on. Each must render without an invalid sample, and each is
//! open (every path can escape), so its white furnace must be exact: a leak into a closed
//! shell or a self-intersection traps a path and darkens a pixel.

use crate::scene::mesh::{Mesh, parse_obj};
use crate::scene::{Camera, Material, Object, Scene, Shape};
use base64::Engine;
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// The cases: (name, scene).
pub fn cases() -> Vec<(String, Scene)> {
    let mut out = vec![
        (
            "mesh/degenerate and zero-area triangles".to_string(),
            with_mesh(
                degenerate_obj(),
                DVec3::ZERO,
                DVec3::new(1.2, 0.9, 1.6),
                DVec3::ZERO,
            ),
        ),
        (
            "mesh/1e5 units with 1e-3 detail, 3e4 from the origin".to_string(),
            large_and_small(),
        ),
        (
            "mesh/thin shell (1e-4 thick) seen edge-on".to_string(),
            // The camera 3° off the shell's plane: its rays meet the faces at grazing angles.
            with_mesh(
                box_obj(DVec3::new(0.5, 0.5, 5e-5)),
                DVec3::ZERO,
                DVec3::new(0.9, 0.1, 0.05),
                DVec3::ZERO,
            ),
        ),
        (
            "gltf/NaN, zero and opposed normals and tangents".to_string(),
            gltf_square(
                &[
                    [f32::NAN, 0.0, 1.0],
                    [0.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [0.0, 0.0, -1.0],
                ],
                &[
                    [f32::NAN, 0.0, 0.0, 1.0],
                    [0.0, 0.0, 0.0, 1.0],
                    [0.0, 0.0, 1.0, 1.0],
                    [1.0, 0.0, 0.0, f32::INFINITY],
                ],
                &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
                10497,
            ),
        ),
    ];
    for (wrap, name) in [
        (10497, "repeat"),
        (33648, "mirrored repeat"),
        (33071, "clamp"),
    ] {
        out.push((
            format!("gltf/texture coordinates of 1e7 to 1e30 and NaN, {name}"),
            gltf_square(
                &[[0.0, 0.0, 1.0]; 4],
                &[[1.0, 0.0, 0.0, 1.0]; 4],
                &[[1e7, -3e9], [1e30, 0.5], [f32::NAN, -1e30], [-0.5, 2e9]],
                wrap,
            ),
        ));
    }
    out
}

fn scene_looking(from: DVec3, at: DVec3) -> Scene {
    let mut s = Scene::from_toml("", "builtin:stress").expect("an empty scene");
    s.camera = Camera {
        look_from: from,
        look_at: at,
        vfov: 40.0,
        ..s.camera
    };
    s
}

fn mesh_object(mesh: Mesh, translate: DVec3) -> Object {
    Object {
        name: Some("mesh".into()),
        shape: Shape::Mesh {
            file: "(stress)".into(),
            mesh: Arc::new(mesh),
            translate,
            rotation: DVec3::ZERO,
            scale: DVec3::ONE,
            instances: Default::default(),
        },
        material: Material::default(),
        material_name: None,
        gltf: None,
    }
}

fn with_mesh(obj: String, translate: DVec3, from: DVec3, at: DVec3) -> Scene {
    let mut s = scene_looking(from, at);
    let mesh = parse_obj(&obj).expect("a mesh of the stress cases");
    s.objects.push(mesh_object(mesh, translate));
    s
}

/// A unit cube, and with it triangles without area (a repeated corner, three collinear
/// corners, a corner at infinity: dropped at load) and a needle of area 5·10⁻⁸ lying along
/// the cube's top front edge, 10⁻⁷ above it (kept).
fn degenerate_obj() -> String {
    let mut s = box_obj(DVec3::splat(0.5));
    let extra = [
        "0.5 0.5 0.5",
        "0.9 0 0",
        "1.3 0 0",
        "1.7 0 0",
        "-0.5 0.5 0.5",
        "0 0.5000001 0.5",
        "inf 0 0",
    ];
    for v in extra {
        s += &format!("v {v}\n");
    }
    // The extra vertices are 9…15.
    s += "f 9 9 13\nf 10 11 12\nf 9 13 15\nf 13 9 14\n";
    s
}

/// An axis-aligned box of half extents `h` about the origin, wound outward.
fn box_obj(h: DVec3) -> String {
    let mut s = String::new();
    for k in 0..8 {
        let c = DVec3::new(
            if k & 1 == 0 { -h.x } else { h.x },
            if k & 2 == 0 { -h.y } else { h.y },
            if k & 4 == 0 { -h.z } else { h.z },
        );
        s += &format!("v {:e} {:e} {:e}\n", c.x, c.y, c.z);
    }
    s + &box_faces(0)
}

/// The twelve outward triangles of a box whose corners are vertices `first + 1 … first + 8`
/// in the order `box_obj` writes them (bit 0: +x, bit 1: +y, bit 2: +z).
fn box_faces(first: usize) -> String {
    let mut s = String::new();
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        let f = f.map(|i| i + first);
        s += &format!(
            "f {} {} {}\nf {} {} {}\n",
            f[0], f[1], f[2], f[0], f[2], f[3]
        );
    }
    s
}

/// A ground of 10⁵ units (two triangles) and, 3·10⁴ units from the origin (where an f32
/// step is 0.002), a cube of side 10⁻³ resting on it, in one mesh; the camera 5·10⁻³ away.
fn large_and_small() -> Scene {
    let c = DVec3::new(3e4, 0.0, -2e4);
    let h = 0.5e-3;
    let mut obj = String::new();
    for v in [
        [-5e4, 0.0, -5e4],
        [5e4, 0.0, -5e4],
        [-5e4, 0.0, 5e4],
        [5e4, 0.0, 5e4],
    ] {
        obj += &format!("v {:e} {:e} {:e}\n", v[0], v[1], v[2]);
    }
    obj += "f 1 3 2\nf 2 3 4\n";
    for k in 0..8 {
        let p = c + DVec3::new(
            if k & 1 == 0 { -h } else { h },
            if k & 2 == 0 { 0.0 } else { 2.0 * h },
            if k & 4 == 0 { -h } else { h },
        );
        obj += &format!("v {:.9e} {:.9e} {:.9e}\n", p.x, p.y, p.z);
    }
    obj += &box_faces(4);
    with_mesh(
        obj,
        DVec3::ZERO,
        c + DVec3::new(3e-3, 2.5e-3, 4e-3),
        c + DVec3::new(0.0, h, 0.0),
    )
}

/// A normal-mapped, base-colour-mapped square (side 2, at z = 0, facing +z) with the given
/// vertex normals, tangents and texture coordinates, its maps flat and white (so that its
/// furnace is exact whatever they read) under the sampler wrap mode `wrap` (GL enum).
fn gltf_square(
    normals: &[[f32; 3]; 4],
    tangents: &[[f32; 4]; 4],
    uvs: &[[f32; 2]; 4],
    wrap: u32,
) -> Scene {
    let pos: [[f32; 3]; 4] = [[-1., 1., 0.], [1., 1., 0.], [-1., -1., 0.], [1., -1., 0.]];
    let idx: [u16; 6] = [0, 2, 1, 1, 2, 3];
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: Vec<u8>, bin: &mut Vec<u8>| {
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}"#,
            bin.len(),
            bytes.len()
        ));
        bin.extend(bytes);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    push(f32s(pos.as_flattened()), &mut bin);
    push(f32s(normals.as_flattened()), &mut bin);
    push(f32s(tangents.as_flattened()), &mut bin);
    push(f32s(uvs.as_flattened()), &mut bin);
    push(idx.iter().flat_map(|x| x.to_le_bytes()).collect(), &mut bin);
    let png = |rgba: [u8; 4]| {
        let img = image::RgbaImage::from_pixel(2, 2, image::Rgba(rgba));
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .expect("a PNG in memory");
        base64::engine::general_purpose::STANDARD.encode(out)
    };
    let b64 = base64::engine::general_purpose::STANDARD.encode(&bin);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TANGENT":2,"TEXCOORD_0":3}},"indices":4,"material":0}}]}}],
        "materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}},"metallicFactor":0,"roughnessFactor":0}},"normalTexture":{{"index":1}}}}],
        "samplers":[{{"wrapS":{wrap},"wrapT":{wrap}}}],
        "textures":[{{"source":0,"sampler":0}},{{"source":1,"sampler":0}}],
        "images":[{{"uri":"data:image/png;base64,{}"}},{{"uri":"data:image/png;base64,{}"}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},
          {{"bufferView":2,"componentType":5126,"count":4,"type":"VEC4"}},
          {{"bufferView":3,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":4,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{b64}"}}]}}"#,
        png([255, 255, 255, 255]),
        png([128, 128, 255, 255]),
        views.join(","),
        bin.len(),
    );
    let imported = crate::scene::gltf::import_slice(
        json.as_bytes(),
        None,
        "stress.gltf",
        DMat4::IDENTITY,
        None,
        Default::default(),
    )
    .expect("the stress square imports");
    let mut s = scene_looking(DVec3::new(0.4, 0.3, 3.0), DVec3::ZERO);
    s.objects.extend(imported.objects);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_degenerate_triangles_are_dropped_and_the_needle_kept() {
        let m = parse_obj(&degenerate_obj()).unwrap();
        assert_eq!((m.triangles.len(), m.skipped), (13, 3));
    }
}
