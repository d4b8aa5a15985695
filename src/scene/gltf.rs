//! glTF 2.0 scenes (`.gltf` with its buffers, or `.glb`) through the `gltf` crate, mapped onto
//! the render model: every triangle primitive of every node of the scene (transforms through
//! the hierarchy, baked into world space) becomes a mesh object with its material's factors
//! mapped onto MODEL.md's material (docs/MODEL-NOTES.md, "glTF materials"); the scene's
//! perspective cameras (the first by default, or one by name) become the camera, else a
//! camera that frames the scene's bounds; `KHR_lights_punctual` lights become the sun
//! (directional) or small emitting spheres of the same power (point, spot).

use super::error::Malformed;
use super::gltf_instances;
pub use super::gltf_instances::Instancing;
use super::mesh::Mesh;
use super::model::{Camera, Material, MaterialModel, Object, Shape, Sun, Volume};
use glam::{DMat4, DVec3, Vec3};
use std::path::Path;
use std::sync::Arc;

/// The reflectance of a dielectric at normal incidence that glTF's metallic-roughness model
/// assumes (glTF 2.0 specification, Appendix B: `F0 = 0.04`).
pub const DIELECTRIC_F0: f32 = 0.04;
/// glTF's index of refraction where `KHR_materials_ior` is silent.
pub const DEFAULT_IOR: f32 = 1.5;
/// The radius of the sphere a point or spot light becomes, as a fraction of the scene's
/// bounding-box diagonal: small enough to read as a point, large enough to be found by
/// paths that do not sample it.
const POINT_LIGHT_RADIUS: f64 = 0.005;
/// glTF's punctual light intensities are photometric (candela for point and spot lights, lux
/// for directional ones); the render model's radiance is relative, and one unit of either is
/// taken as one unit of the model's: a point light of intensity I becomes a sphere of
/// radiance I / (π r²) (the sphere's intensity is L·π r²), a directional light of E lux a sun
/// lobe whose irradiance at normal incidence is E (docs/MODEL-NOTES.md).
const CANDELA_PER_UNIT: f64 = std::f64::consts::PI;
/// The exponent of the sun lobe a directional light becomes: about 5° across at half
/// maximum, a sharp sun that light sampling finds.
const SUN_SIZE: f32 = 1000.0;

pub use super::gltf_textures::decode_image;
pub use super::gltf_textures::texture_transform as texture_transform_of;

/// The extensions read; a file that requires another is refused, one that only uses another
/// is opened without it, and the log names it.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "EXT_mesh_gpu_instancing",
    "EXT_texture_webp",
    "KHR_texture_basisu",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_draco_mesh_compression",
];

/// What one glTF file adds to a scene.
#[derive(Debug)]
pub struct Imported {
    pub objects: Vec<Object>,
    /// The chosen camera (`None`: the file has none; see [`framing_camera`]).
    pub camera: Option<Camera>,
    /// The first directional light, as the sun.
    pub sun: Option<Sun>,
    /// Primitives left out, with why (points, lines, no positions, degenerate triangles).
    pub skipped: Vec<String>,
    /// The bounds of every imported triangle, in world space.
    pub bounds: (DVec3, DVec3),
    /// Each glTF material the objects use, by key ([`material_key`]), as mapped.
    pub materials: Vec<(String, Material)>,
}

impl Imported {
    /// Nothing imported yet, with what was already left out; empty bounds.
    /// Logs each thing left out of `file`, once.
    pub fn log_left_out(&self, file: &str) {
        for s in &self.skipped {
            tracing::warn!("{file}: left out: {s}");
        }
    }

    pub fn new(skipped: Vec<String>) -> Imported {
        Imported {
            objects: Vec::new(),
            camera: None,
            sun: None,
            skipped,
            bounds: (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            materials: Vec::new(),
        }
    }
}

/// How a glTF material is named in a scene: its name, `#INDEX` when it has none, `default`
/// for glTF's default material.
pub fn material_key(m: &gltf::Material) -> String {
    match (m.name(), m.index()) {
        (Some(n), _) => n.to_string(),
        (None, Some(i)) => format!("#{i}"),
        (None, None) => "default".to_string(),
    }
}

pub use super::error::GltfError;

/// Imports the glTF file at `path` (its buffers beside it), placed by `place` (the TOML's
/// transform; identity when the file is opened directly); `camera` picks a camera by name;
/// `instancing` says how meshes drawn more than once are stored.
pub fn import(
    path: &Path,
    place: DMat4,
    camera: Option<&str>,
    instancing: Instancing,
) -> Result<Imported, GltfError> {
    let bytes = std::fs::read(path).map_err(|e| GltfError {
        path: path.display().to_string(),
        message: format!("cannot read it: {e}"),
    })?;
    import_slice(
        &bytes,
        path.parent(),
        &path.display().to_string(),
        place,
        camera,
        instancing,
    )
}

/// Imports a glTF or GLB file from memory; `base` is the folder its relative URIs are read
/// from (`None`: only embedded data), `name` names it in errors.
pub fn import_slice(
    bytes: &[u8],
    base: Option<&Path>,
    name: &str,
    place: DMat4,
    camera: Option<&str>,
    instancing: Instancing,
) -> Result<Imported, GltfError> {
    let err = |message: Malformed| GltfError {
        path: name.to_string(),
        message: message.0,
    };
    let (gltf, buffers) = parse(bytes, base).map_err(err)?;
    let doc = &gltf.document;
    let mut skipped = Vec::new();
    for ext in doc.extensions_used() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            skipped.push(format!("the extension {ext} (optional; not read)"));
        }
    }
    let textures = super::gltf_textures::decode(doc, base, &buffers).map_err(err)?;
    // Every material mapped once, so that the objects sharing one share its textures.
    let materials: Vec<Material> = doc
        .materials()
        .map(|m| Material {
            textured: super::gltf_textures::textured(&m, &textures, &mut skipped),
            ..material(&m)
        })
        .collect();
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| err("the file has no scene".into()))?;
    let mut out = Imported::new(skipped);
    let mut cameras = Vec::new();
    let mut lights = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, place)).collect();
    stack.reverse();
    // glTF's nodes form disjoint trees (specification §3.5.2): a node reached twice is a cycle
    // or a node with two parents, which would walk forever or import twice (`fuzz/` found a
    // cycle).
    let mut reached = vec![false; doc.nodes().len()];
    // The nodes that draw a mesh, in the hierarchy's order, each with its world transforms
    // (several under EXT_mesh_gpu_instancing).
    let mut drawn: Vec<(gltf::Mesh, Vec<DMat4>)> = Vec::new();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut reached[node.index()], true) {
            return Err(err(Malformed(format!(
                "nodes[{}] is reached twice in the scene's hierarchy (a cycle, or a node with \
                 two parents)",
                node.index()
            ))));
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        if !world.is_finite() {
            return Err(err(Malformed(format!(
                "node {} has a transform that is not finite",
                label(&node)
            ))));
        }
        if let Some(mesh) = node.mesh() {
            let worlds = match gltf_instances::gpu_instances(&node, doc, &buffers).map_err(err)? {
                Some(each) => each.into_iter().map(|m| world * m).collect(),
                None => vec![world],
            };
            drawn.push((mesh, worlds));
        }
        if let Some(cam) = node.camera() {
            cameras.push((cam, world));
        }
        if let Some(light) = node.light() {
            lights.push((light, world));
        }
        let children: Vec<_> = node.children().map(|c| (c, world)).collect();
        stack.extend(children.into_iter().rev());
    }
    import_drawn(&drawn, instancing, &buffers, &materials, &mut out).map_err(err)?;
    if out.objects.is_empty() {
        return Err(err(Malformed(format!(
            "the scene has no triangles{}",
            if out.skipped.is_empty() {
                String::new()
            } else {
                format!(" ({})", out.skipped.join("; "))
            }
        ))));
    }
    out.camera = pick_camera(&cameras, camera).map_err(err)?;
    let diagonal = (out.bounds.1 - out.bounds.0).length();
    for (light, world) in lights {
        add_light(&light, world, diagonal, &mut out);
    }
    Ok(out)
}

/// Imports the meshes `drawn` in the hierarchy's order: each copy of a mesh flattened into
/// world space, or (where `instancing` chooses it) the mesh once, in its own coordinates, with
/// every copy's transform as an instance, at the place of its first copy.
fn import_drawn(
    drawn: &[(gltf::Mesh, Vec<DMat4>)],
    instancing: Instancing,
    buffers: &[gltf::buffer::Data],
    materials: &[Material],
    out: &mut Imported,
) -> Result<(), Malformed> {
    // Per mesh: its copies and triangles.
    let mut copies = std::collections::HashMap::<usize, (usize, usize)>::new();
    for (mesh, worlds) in drawn {
        copies
            .entry(mesh.index())
            .or_insert((0, gltf_instances::triangle_estimate(mesh)))
            .0 += worlds.len();
    }
    // The memory guard, before anything is read: what the chosen storage will take.
    let stored: u64 = copies
        .values()
        .map(|&(n, tris)| {
            let n = if instancing.instances(n, tris) { 1 } else { n };
            (tris as u64).saturating_mul(n as u64)
        })
        .sum();
    gltf_instances::check_memory(stored, gltf_instances::available_memory())?;
    // Per instanced mesh: its objects and every copy's transform.
    let mut instanced = std::collections::HashMap::<usize, (Vec<usize>, Vec<DMat4>)>::new();
    let mut order = Vec::new();
    for (mesh, worlds) in drawn {
        let i = mesh.index();
        let (n, tris) = copies[&i];
        if !instancing.instances(n, tris) {
            for world in worlds {
                import_mesh(mesh, *world, buffers, materials, out)?;
            }
            continue;
        }
        let entry = match instanced.entry(i) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                // In the mesh's own coordinates; its bounds count once per copy, below.
                let (first, bounds) = (out.objects.len(), out.bounds);
                import_mesh(mesh, DMat4::IDENTITY, buffers, materials, out)?;
                out.bounds = bounds;
                order.push(i);
                e.insert(((first..out.objects.len()).collect(), Vec::new()))
            }
        };
        entry.1.extend_from_slice(worlds);
    }
    for i in order {
        let (objects, worlds) = instanced.remove(&i).unwrap();
        let worlds = Arc::new(worlds);
        for k in objects {
            let Shape::Mesh {
                mesh, instances, ..
            } = &mut out.objects[k].shape
            else {
                continue;
            };
            let local = mesh
                .triangles
                .iter()
                .flatten()
                .fold(crate::bvh::Aabb::EMPTY, |b, p| b.grow(*p));
            for w in worlds.iter() {
                let b = local.transformed(w);
                out.bounds.0 = out.bounds.0.min(b.min);
                out.bounds.1 = out.bounds.1.max(b.max);
            }
            *instances = worlds.clone();
        }
    }
    Ok(())
}

/// Bytes of a GLB file's header (magic, version, length).
const GLB_HEADER: u32 = 12;

/// The file parsed and validated. gltf-json 1.4.1 indexes the accessors without a check
/// while it validates a primitive's POSITION (its mesh.rs:151), so a file whose attribute
/// names an accessor it does not have would panic there (found by `fuzz/`): the references
/// are checked first, and the validation runs only on a file that passes.
fn parse(
    bytes: &[u8],
    base: Option<&Path>,
) -> Result<(gltf::Gltf, Vec<gltf::buffer::Data>), Malformed> {
    // The crate subtracts the header's size from the GLB's stated length unchecked (its
    // binary.rs:252, also found by `fuzz/`).
    if let Some(len) = bytes
        .strip_prefix(b"glTF")
        .and_then(|rest| rest.get(4..8))
        .map(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]))
        && len < GLB_HEADER
    {
        return Err(Malformed(format!(
            "not a valid GLB file: its header gives a length of {len} bytes, less than the \
             header's own {GLB_HEADER}"
        )));
    }
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| Malformed(format!("not a valid glTF file: {e}")))?;
    // Before the validation: a file in a form termtrace does not read (Draco's accessors have
    // no buffer views) is named by that form, not by what the validation trips on.
    for ext in unchecked.document.extensions_required() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            return Err(Malformed(format!(
                "it requires the extension {ext}, which termtrace does not read (it reads {})",
                SUPPORTED_EXTENSIONS.join(", ")
            )));
        }
    }
    let root = unchecked.document.as_json();
    let n = root.accessors.len();
    for (mi, m) in root.meshes.iter().enumerate() {
        for (pi, p) in m.primitives.iter().enumerate() {
            let named = p.attributes.values().chain(p.indices.as_ref());
            if let Some(bad) = named.map(|a| a.value()).find(|&a| a >= n) {
                return Err(Malformed(format!(
                    "meshes[{mi}].primitives[{pi}] names accessor {bad}, and the file has {n}"
                )));
            }
        }
    }
    // The buffers' bytes, and Draco's primitives decoded into accessors of their own, before
    // the validation (it refuses their accessors without buffer views).
    let mut buffers = read_buffers(&unchecked.document, unchecked.blob.clone(), base)?;
    let mut root = unchecked.document.into_json();
    if root
        .extensions_used
        .iter()
        .any(|e| e == super::gltf_draco::NAME)
    {
        super::gltf_draco::decode(&mut root, &mut buffers)?;
    }
    // The crate's validation, without its refusal of the required extensions it does not
    // type (KHR_mesh_quantization among them): they were checked above against what
    // termtrace reads.
    let required = std::mem::take(&mut root.extensions_required);
    let mut root = gltf::Document::from_json(root)
        .map_err(|e| Malformed(format!("not a valid glTF file: {e}")))?
        .into_json();
    root.extensions_required = required;
    let gltf = gltf::Gltf {
        document: gltf::Document::from_json_without_validation(root),
        blob: unchecked.blob,
    };
    // The crate's `Image::source` unwraps a missing `uri` and a view's missing `mimeType`
    // (its image.rs:125 and :128, found by `fuzz/`), which the validation lets through.
    for (i, image) in gltf.document.as_json().images.iter().enumerate() {
        match (&image.buffer_view, &image.uri, &image.mime_type) {
            (Some(_), _, None) => {
                return Err(Malformed(format!(
                    "images[{i}] is in a buffer view and has no mimeType (the specification \
                     requires one)"
                )));
            }
            (None, None, _) => {
                return Err(Malformed(format!(
                    "images[{i}] has neither a uri nor a bufferView"
                )));
            }
            _ => {}
        }
    }
    super::gltf_meshopt::decode(&gltf.document, &mut buffers)?;
    Ok((gltf, buffers))
}

/// The file's buffers (the GLB's binary chunk, `data:` URIs, files beside it), each checked
/// against its declared length; an error names the buffer.
fn read_buffers(
    doc: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    base: Option<&Path>,
) -> Result<Vec<gltf::buffer::Data>, Malformed> {
    let mut out = Vec::new();
    for b in doc.buffers() {
        let what = match b.source() {
            gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => {
                format!("buffers[{}] (`{u}`)", b.index())
            }
            _ => format!("buffers[{}]", b.index()),
        };
        let fallback = super::gltf_meshopt::is_fallback(&b);
        if fallback
            && b.length() as u64 > super::gltf_instances::available_memory().unwrap_or(u64::MAX) / 2
        {
            return Err(Malformed(format!(
                "{what}: a meshopt fallback of {} bytes, more than half the memory available",
                b.length()
            )));
        }
        let mut bytes = match b.source() {
            // Filled by the compressed views that decode into it.
            _ if fallback => vec![0; b.length()],
            gltf::buffer::Source::Bin => blob
                .take()
                .ok_or_else(|| Malformed(format!("{what}: the GLB file has no binary chunk")))?,
            gltf::buffer::Source::Uri(uri) => super::gltf_textures::read_uri(uri, base)
                .map_err(|e| Malformed(format!("{what}: cannot read it: {e}")))?,
        };
        // Padded to whole words, as the crate's reader pads them.
        bytes.resize(bytes.len().next_multiple_of(4), 0);
        let data = gltf::buffer::Data(bytes);
        if data.len() < b.length() {
            return Err(Malformed(format!(
                "{what}: {} bytes, but it declares {}",
                data.len(),
                b.length()
            )));
        }
        out.push(data);
    }
    Ok(out)
}

fn label(node: &gltf::Node) -> String {
    match node.name() {
        Some(n) => format!("`{n}`"),
        None => format!("#{}", node.index()),
    }
}

fn import_mesh(
    mesh: &gltf::Mesh,
    world: DMat4,
    buffers: &[gltf::buffer::Data],
    materials: &[Material],
    out: &mut Imported,
) -> Result<(), Malformed> {
    let mesh_name = mesh
        .name()
        .map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
    for prim in mesh.primitives() {
        let what = format!(
            "meshes[{}].primitives[{}] (mesh `{mesh_name}`)",
            mesh.index(),
            prim.index()
        );
        let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
            out.skipped.push(format!("{what}: no positions"));
            continue;
        };
        let gm = prim.material();
        // glTF's default material (no index) has no maps.
        let mapped = &match gm.index() {
            Some(i) => materials[i].clone(),
            None => material(&gm),
        };
        let uv_accessor = mapped
            .textured
            .as_ref()
            .and_then(|_| prim.get(&gltf::Semantic::TexCoords(0)));
        // A normal map needs the shading frames: the file's normals and tangents, if any;
        // any other surface the normals alone (smooth shading), where the file has them.
        let normal_mapped = mapped
            .textured
            .as_ref()
            .is_some_and(|t| t.0.normal.is_some());
        // (Smooth shading reads the normals of a kind glTF allows alone; other kinds are a
        // normal map's error.)
        let normal_accessor = prim.get(&gltf::Semantic::Normals).filter(|a| {
            use gltf::accessor::DataType as T;
            normal_mapped
                || (a.dimensions() == gltf::accessor::Dimensions::Vec3
                    && [T::F32, T::I8, T::I16].contains(&a.data_type()))
        });
        let tangent_accessor = normal_mapped
            .then(|| prim.get(&gltf::Semantic::Tangents))
            .flatten();
        {
            use gltf::accessor::{DataType as T, Dimensions as D};
            // Floats, and the integer kinds KHR_mesh_quantization adds.
            let checks = std::iter::once((
                pos.clone(),
                D::Vec3,
                &[T::F32, T::I8, T::U8, T::I16, T::U16][..],
            ))
            .chain(
                prim.indices()
                    .map(|a| (a, D::Scalar, &[T::U8, T::U16, T::U32][..])),
            )
            .chain(
                uv_accessor
                    .clone()
                    .map(|a| (a, D::Vec2, &[T::F32, T::U8, T::U16, T::I8, T::I16][..])),
            )
            .chain(
                normal_accessor
                    .clone()
                    .map(|a| (a, D::Vec3, &[T::F32, T::I8, T::I16][..])),
            )
            .chain(
                tangent_accessor
                    .clone()
                    .map(|a| (a, D::Vec4, &[T::F32, T::I8, T::I16][..])),
            );
            for (a, dims, types) in checks {
                // The crate's reader assumes the element type its caller asks for (a debug
                // assertion, found by `fuzz/`; garbage without it).
                if a.dimensions() != dims || !types.contains(&a.data_type()) {
                    return Err(Malformed(format!(
                        "{what}: accessor {} holds {:?} of {:?}, where {dims:?} of {types:?} belong",
                        a.index(),
                        a.dimensions(),
                        a.data_type()
                    )));
                }
                // Indices are read by the crate's reader, which does not check sparse data.
                let sparse_ok = prim.indices().is_none_or(|i| i.index() != a.index());
                super::gltf_accessors::fits(&a, buffers, sparse_ok)
                    .map_err(|e| Malformed(format!("{what}: {e}")))?;
            }
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        // Attributes dequantized (gltf_accessors), read only where checked above.
        let local: Vec<[f32; 3]> = super::gltf_accessors::read(&pos, buffers);
        // Texture coordinates, for a textured material (missing ones read as (0, 0)).
        let uvs: Vec<[f32; 2]> = uv_accessor
            .as_ref()
            .map_or_else(Vec::new, |a| super::gltf_accessors::read(a, buffers));
        let uv = |i: u32| uvs.get(i as usize).copied().unwrap_or([0.0; 2]);
        let points: Vec<DVec3> = local
            .iter()
            .map(|p| world.transform_point3(DVec3::from(p.map(f64::from))))
            .collect();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..points.len() as u32).collect(),
        };
        let triangles = match prim.mode() {
            gltf::mesh::Mode::Triangles => indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect::<Vec<_>>(),
            gltf::mesh::Mode::TriangleStrip => (2..indices.len())
                .map(|i| {
                    // Every second triangle of a strip is flipped to keep the winding.
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            gltf::mesh::Mode::TriangleFan => (2..indices.len())
                .map(|i| [indices[0], indices[i - 1], indices[i]])
                .collect(),
            other => {
                out.skipped
                    .push(format!("{what}: {other:?} (not triangles)"));
                continue;
            }
        };
        // A transform that mirrors (negative determinant) turns the winding over; swap two
        // corners so that the front stays where the file's winding puts it.
        let mirrored = world.determinant() < 0.0;
        let mut m = Mesh {
            triangles: Vec::with_capacity(triangles.len()),
            skipped: 0,
            uvs: Vec::new(),
            normals: Vec::new(),
            tangents: Vec::new(),
        };
        let mut kept: Vec<[u32; 3]> = Vec::new();
        for t in triangles {
            let v = t.map(|i| points.get(i as usize).copied());
            let [Some(a), Some(b), Some(c)] = v else {
                return Err(Malformed(format!(
                    "{what}: an index refers to vertex {} of {}",
                    t.iter().max().unwrap_or(&0),
                    points.len()
                )));
            };
            let area = (b - a).cross(c - a).length();
            if area > 0.0 && area.is_finite() {
                for p in [a, b, c] {
                    out.bounds.0 = out.bounds.0.min(p);
                    out.bounds.1 = out.bounds.1.max(p);
                }
                m.triangles
                    .push(if mirrored { [a, c, b] } else { [a, b, c] });
                kept.push(t);
                if mapped.textured.is_some() {
                    let [ua, ub, uc] = t.map(uv);
                    m.uvs
                        .push(if mirrored { [ua, uc, ub] } else { [ua, ub, uc] });
                }
            } else {
                m.skipped += 1;
            }
        }
        if m.triangles.is_empty() {
            out.skipped.push(format!("{what}: no triangle with area"));
            continue;
        }
        // Likewise read only where checked.
        let normals: Vec<[f32; 3]> = normal_accessor
            .as_ref()
            .map_or_else(Vec::new, |a| super::gltf_accessors::read(a, buffers));
        if normal_mapped {
            let tangents: Vec<[f32; 4]> = tangent_accessor
                .as_ref()
                .map_or_else(Vec::new, |a| super::gltf_accessors::read(a, buffers));
            let linear = glam::DMat3::from_mat4(world);
            for (n, t) in
                super::gltf_frames::frames(&kept, &local, &normals, &tangents, &uvs, linear)
            {
                m.normals
                    .push(if mirrored { [n[0], n[2], n[1]] } else { n });
                m.tangents
                    .push(if mirrored { [t[0], t[2], t[1]] } else { t });
            }
        } else if !mapped.is_dielectric() {
            let linear = glam::DMat3::from_mat4(world);
            m.normals = super::gltf_frames::normals_only(&kept, &normals, linear, mirrored);
        }
        let key = material_key(&gm);
        let mapped = mapped.clone();
        if !out.materials.iter().any(|(k, _)| *k == key) {
            out.materials.push((key.clone(), mapped.clone()));
        }
        out.objects.push(Object {
            name: Some(match prim.index() {
                0 => mesh_name.clone(),
                i => format!("{mesh_name}.{i}"),
            }),
            shape: Shape::Mesh {
                file: String::new(),
                mesh: Arc::new(m),
                translate: DVec3::ZERO,
                rotation: DVec3::ZERO,
                scale: DVec3::ONE,
                instances: Default::default(),
            },
            material: mapped,
            material_name: Some(key),
            gltf: None,
        });
    }
    Ok(())
}

/// glTF's metallic-roughness material as the `pbr` model renders it (docs/MODEL-NOTES.md,
/// "pbr"): base colour (linear already), metallic, roughness and `KHR_materials_ior` (default
/// 1.5) as they are; and where the model has no lobe for it yet:
/// - emission → an emitter: `light` (strength × the brightest channel of `emissiveFactor`)
///   with the emissive colour as `color`, since an emitter's radiance is `color × light`;
/// - `KHR_materials_transmission` and `KHR_materials_volume` → the model's rough dielectric:
///   a thin wall without a volume (or of thickness 0), else a refracting boundary whose
///   medium attenuates by `attenuationColor` over `attenuationDistance`.
pub fn material(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    pbr_material(&Pbr {
        base: Vec3::new(r, g, b),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        emissive: Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0).max(0.0),
        transmission: m.transmission().map_or(0.0, |t| t.transmission_factor()),
        volume: m
            .volume()
            .filter(|v| v.thickness_factor() > 0.0)
            .map(|v| Volume {
                thin_walled: false,
                attenuation_color: Vec3::from(v.attenuation_color()),
                attenuation_distance: v.attenuation_distance(),
            }),
        ior: m.ior().unwrap_or(1.5),
        clearcoat: clearcoat(m),
        specular: m.specular().map_or(1.0, |s| s.specular_factor()),
        specular_color: Vec3::from(m.specular().map_or([1.0; 3], |s| s.specular_color_factor())),
    })
}

/// `KHR_materials_clearcoat`'s factor and roughness factor (0 and 0 without it; the crate
/// has no type for the extension, so its JSON is read).
fn clearcoat(m: &gltf::Material) -> (f32, f32) {
    let Some(ext) = m.extension_value("KHR_materials_clearcoat") else {
        return (0.0, 0.0);
    };
    let factor = |key: &str| ext.get(key).and_then(|v| v.as_f64()).unwrap_or(0.0) as f32;
    (
        factor("clearcoatFactor"),
        factor("clearcoatRoughnessFactor"),
    )
}

/// A metallic-roughness material's factors, as glTF gives them or as an MTL material maps
/// onto them (`scene::obj`), before [`pbr_material`] maps them onto the model.
#[derive(Clone, Debug, PartialEq)]
pub struct Pbr {
    /// Linear base colour.
    pub base: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    /// Emitted radiance (factor × strength).
    pub emissive: Vec3,
    pub transmission: f32,
    /// `KHR_materials_volume` of a thickness above 0 (`None`: a thin wall).
    pub volume: Option<Volume>,
    pub ior: f32,
    /// `KHR_materials_clearcoat`: the coat's factor and roughness (0, 0 without it).
    pub clearcoat: (f32, f32),
    /// `KHR_materials_specular`: the dielectric layer's strength and its f0's colour (1 and
    /// white without the extension).
    pub specular: f32,
    pub specular_color: Vec3,
}

/// [`Pbr`] factors as a material, by the rules of [`material`].
pub fn pbr_material(p: &Pbr) -> Material {
    let base = p.base.max(Vec3::ZERO);
    let metallic = p.metallic.clamp(0.0, 1.0);
    let roughness = p.roughness.clamp(0.0, 1.0);
    let emissive = p.emissive.max(Vec3::ZERO);
    let ior = if p.ior > 0.0 && p.ior.is_finite() {
        p.ior
    } else {
        DEFAULT_IOR
    };
    let finite = |v: f32, or: f32| if v.is_finite() { v.max(0.0) } else { or };
    let specular = finite(p.specular, 1.0).min(1.0);
    let specular_color =
        (p.specular_color != Vec3::ONE).then(|| p.specular_color.map(|c| finite(c, 1.0)));
    let transmission = finite(p.transmission, 0.0).min(1.0);
    let clearcoat = finite(p.clearcoat.0, 0.0).min(1.0);
    let clearcoat_roughness = finite(p.clearcoat.1, 0.0).min(1.0);
    let volume = match p.volume {
        Some(v) => Volume {
            thin_walled: false,
            attenuation_color: v.attenuation_color.map(|c| finite(c, 1.0).min(1.0)),
            attenuation_distance: if v.attenuation_distance > 0.0 {
                v.attenuation_distance
            } else {
                f32::INFINITY
            },
        },
        None => Volume {
            thin_walled: true,
            ..Volume::default()
        },
    };
    if emissive.max_element() > 0.0 {
        let light = emissive.max_element();
        // Still a pbr material: where its emissive map is dark, a texel is glTF's BRDF.
        return Material {
            color: emissive / light,
            light,
            model: MaterialModel::Pbr,
            metallic,
            roughness,
            ior,
            specular,
            specular_color,
            transmission,
            volume,
            clearcoat,
            clearcoat_roughness,
            ..Material::default()
        };
    }
    Material {
        color: base,
        model: MaterialModel::Pbr,
        metallic,
        roughness,
        ior,
        specular,
        specular_color,
        transmission,
        volume,
        clearcoat,
        clearcoat_roughness,
        ..Material::default()
    }
}

/// The camera named `name` (or the first perspective camera) as the model's camera: the
/// node looks down its −Z with +Y up (glTF 2.0 §3.10.3).
fn pick_camera(
    cameras: &[(gltf::Camera, DMat4)],
    name: Option<&str>,
) -> Result<Option<Camera>, Malformed> {
    let found = match name {
        Some(n) => Some(
            cameras
                .iter()
                .find(|(c, _)| c.name() == Some(n))
                .ok_or_else(|| {
                    let names: Vec<String> = cameras
                        .iter()
                        .map(|(c, _)| c.name().unwrap_or("(unnamed)").to_string())
                        .collect();
                    if names.is_empty() {
                        format!("no camera `{n}`: the file has no cameras")
                    } else {
                        format!("no camera `{n}`; its cameras: {}", names.join(", "))
                    }
                })?,
        ),
        None => cameras
            .iter()
            .find(|(c, _)| matches!(c.projection(), gltf::camera::Projection::Perspective(_))),
    };
    let Some((cam, world)) = found else {
        return Ok(None);
    };
    let gltf::camera::Projection::Perspective(p) = cam.projection() else {
        return Err(Malformed(format!(
            "camera `{}` is orthographic; the model's camera is a perspective one",
            cam.name().unwrap_or("(unnamed)")
        )));
    };
    let from = world.transform_point3(DVec3::ZERO);
    let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
    if forward == DVec3::ZERO || up == DVec3::ZERO || up.cross(forward).length() < 1e-9 {
        return Err("a camera's node transform is degenerate".into());
    }
    Ok(Some(Camera {
        look_from: from,
        look_at: from + forward,
        up,
        vfov: (p.yfov() as f64).to_degrees().clamp(1e-3, 179.0),
        aperture: 0.0,
        focus_distance: None,
    }))
}

/// A camera that frames `bounds`: from the front-right and a little above, at the distance
/// at which the bounding sphere fills the vertical field of view.
pub fn framing_camera(bounds: (DVec3, DVec3)) -> Camera {
    let d = Camera::default();
    let center = (bounds.0 + bounds.1) / 2.0;
    let radius = ((bounds.1 - bounds.0).length() / 2.0).max(1e-6);
    let dir = DVec3::new(0.35, 0.3, 1.0).normalize();
    let distance = radius / (d.vfov.to_radians() / 2.0).sin();
    Camera {
        look_from: center + dir * distance * 1.1,
        look_at: center,
        up: DVec3::Y,
        ..d
    }
}

/// A punctual light (KHR_lights_punctual) as the model has lights: a directional light is
/// the sun (the first one; MODEL.md has one), a point or spot light a small emitting sphere
/// of the same intensity (a spot's cone is not modelled: it shines every way).
fn add_light(
    light: &gltf::khr_lights_punctual::Light,
    world: DMat4,
    diagonal: f64,
    out: &mut Imported,
) {
    use gltf::khr_lights_punctual::Kind;
    let color = Vec3::from(light.color()).max(Vec3::ZERO);
    let intensity = light.intensity().max(0.0) as f64;
    match light.kind() {
        Kind::Directional => {
            if out.sun.is_some() {
                out.skipped
                    .push("a second directional light (the model has one sun)".into());
                return;
            }
            // The light shines down the node's −Z; the sun's direction points toward it.
            let toward = -world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
            if toward != DVec3::ZERO {
                out.sun = Some(Sun {
                    direction: toward,
                    color,
                    intensity: (intensity * (SUN_SIZE as f64 + 2.0) / std::f64::consts::TAU) as f32,
                    size: SUN_SIZE,
                });
            }
        }
        Kind::Point | Kind::Spot { .. } => {
            let radius = (POINT_LIGHT_RADIUS * diagonal).max(1e-4);
            let center = world.transform_point3(DVec3::ZERO);
            // Intensity I (candela) from a sphere of radiance L: I = L·π r².
            let strength = (intensity / CANDELA_PER_UNIT / (radius * radius)) as f32;
            if strength > 0.0 && strength.is_finite() {
                out.objects.push(Object {
                    name: Some(
                        light
                            .name()
                            .map_or_else(|| format!("light{}", light.index()), str::to_string),
                    ),
                    shape: Shape::Sphere { center, radius },
                    material: Material {
                        color,
                        light: strength,
                        ..Material::default()
                    },
                    material_name: None,
                    gltf: None,
                });
            }
        }
    }
}
