//! Wavefront OBJ models with their MTL materials (through `tobj`), imported as glTF files are:
//! each group and material of the file becomes a mesh object, each MTL material metallic-
//! roughness factors mapped by glTF's rules (`gltf::pbr_material`), and its `map_Kd`, `map_d`
//! and `map_Ke` images textures (docs/MODEL-NOTES.md, "OBJ materials"). The MTL format:
//! Paul Bourke's "MTL material format (Lightwave, OBJ)", paulbourke.net/dataformats/mtl/.

use super::error::Malformed;
use super::gltf::{GltfError, Imported, Pbr, pbr_material};
use super::mesh::Mesh;
use super::model::{Material, Object, Shape};
use super::texture::{AlphaMode, IDENTITY_TRANSFORM, Texture, Textured, TexturedRef, Wrap};
use glam::{DMat4, DVec3, Vec3};
use rayon::prelude::*;
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The MTL statements read; any other `map_…` (or `bump`, `norm`, `disp`, `refl`, `decal`)
/// is named once in the log and left out.
const READ_MAPS: &[&str] = &["map_Kd", "map_d", "map_Ke", "norm"];

/// The key of the material of faces that have none (no `usemtl`, or an unknown name).
pub const DEFAULT_MATERIAL: &str = "default";

/// Parses OBJ text with `tobj` (faces triangulated, one index per vertex), reading each
/// `mtllib` through `mtl`. A parse error names the first line at which the file fails.
pub(super) fn load(
    text: &str,
    mtl: impl Fn(&Path) -> tobj::MTLLoadResult,
) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>), Malformed> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let parse = |t: &str| tobj::load_obj_buf(&mut t.as_bytes(), &opts, &mtl);
    match parse(text) {
        Ok((models, materials)) => Ok((models, materials.unwrap_or_default())),
        Err(e) => {
            let (n, line) = failing_line(text, |t| parse(t).is_err());
            Err(Malformed(format!("line {n}: {e} (`{line}`)")))
        }
    }
}

/// The first line at which `fails` holds for the text up to it, with that line: tobj does not
/// say where an error is, and each line is parsed on its own, so failing is monotone in the
/// prefix and a binary search over prefixes of whole lines finds it.
fn failing_line(text: &str, fails: impl Fn(&str) -> bool) -> (usize, &str) {
    let ends: Vec<usize> = text
        .match_indices('\n')
        .map(|(i, _)| i + 1)
        .chain(std::iter::once(text.len()))
        .collect();
    let (mut lo, mut hi) = (0, ends.len() - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if fails(&text[..ends[mid]]) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    (lo + 1, text[..ends[lo]].lines().last().unwrap_or("").trim())
}

/// Reads a file's bytes (the file system's, or a fuzzer's from memory).
pub type Reader<'a> = &'a (dyn Fn(&Path) -> std::io::Result<Vec<u8>> + Sync);

/// The MTL text with every colour statement (`Ka`, `Kd`, `Ks`, `Ke`) of one number written
/// as three: the format allows `Kd r` for grey (g and b default to r), and tobj 4.0.5 panics
/// on fewer than three numbers (found by `fuzz/`). Two numbers, or none, are refused by line.
fn colours_of_three(text: &str) -> Result<String, Malformed> {
    let mut out = String::with_capacity(text.len() + 16);
    for (n, line) in text.split_inclusive('\n').enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        if matches!(key, Some("Ka" | "Kd" | "Ks" | "Ke")) {
            let key = key.unwrap_or_default();
            let rest: Vec<&str> = words.collect();
            match rest.len() {
                1 => {
                    let r = rest[0];
                    out.push_str(&format!("{key} {r} {r} {r}\n"));
                    continue;
                }
                0 | 2 => {
                    return Err(Malformed(format!(
                        "line {}: `{key}` needs one number (grey) or three (`{}`)",
                        n + 1,
                        line.trim()
                    )));
                }
                _ => {}
            }
        }
        out.push_str(line);
    }
    Ok(out)
}

/// Imports the OBJ file at `path` with its MTL files and their images (beside it), placed by
/// `place`.
pub fn import(path: &Path, place: DMat4) -> Result<Imported, GltfError> {
    let bytes = std::fs::read(path).map_err(|e| GltfError {
        path: path.display().to_string(),
        message: format!("cannot read it: {e}"),
    })?;
    let text = String::from_utf8_lossy(&bytes);
    let base = path.parent().unwrap_or(Path::new("."));
    import_from(
        &path.display().to_string(),
        &text,
        base,
        &|p| std::fs::read(p),
        place,
    )
}

/// Imports OBJ `text` (named `name` in errors), reading its libraries and images from folder
/// `base` through `read`.
pub fn import_from(
    name: &str,
    text: &str,
    base: &Path,
    read: Reader,
    place: DMat4,
) -> Result<Imported, GltfError> {
    let err = |message: Malformed| GltfError {
        path: name.to_string(),
        message: message.0,
    };
    // Each MTL file read, with its text (to name the lines of its statements), and the first
    // that could not be read or parsed.
    let libraries: RefCell<Vec<(PathBuf, String)>> = RefCell::new(Vec::new());
    let failed: RefCell<Option<String>> = RefCell::new(None);
    let (models, mtl) = load(text, |lib: &Path| {
        let file = base.join(lib);
        let result = read(&file)
            .map_err(|e| Malformed(format!("cannot read it: {e}")))
            .and_then(|b| {
                let t = String::from_utf8_lossy(&b).into_owned();
                let parsed = colours_of_three(&t).and_then(|fixed| {
                    tobj::load_mtl_buf(&mut fixed.as_bytes()).map_err(|e| {
                        let (n, line) = failing_line(&fixed, |p| {
                            tobj::load_mtl_buf(&mut p.as_bytes()).is_err()
                        });
                        Malformed(format!("line {n}: {e} (`{line}`)"))
                    })
                });
                libraries.borrow_mut().push((file.clone(), t));
                parsed
            });
        result.map_err(|e| {
            failed
                .borrow_mut()
                .get_or_insert(format!("its material library `{}`: {e}", file.display()));
            tobj::LoadError::OpenFileFailed
        })
    })
    .map_err(err)?;
    if let Some(e) = failed.into_inner() {
        return Err(err(Malformed(e)));
    }
    let libraries = libraries.into_inner();
    let mut skipped = Vec::new();
    unknown_materials(text, &mtl, &mut skipped);
    let materials = map_materials(&mtl, &libraries, read, &mut skipped).map_err(err)?;
    let mut out = Imported::new(skipped);
    let default = || {
        pbr_material(&Pbr {
            base: super::model::DEFAULT_COLOR,
            metallic: 0.0,
            roughness: 1.0,
            emissive: Vec3::ZERO,
            transmission: 0.0,
            volume: None,
            ior: 1.5,
            clearcoat: (0.0, 0.0),
            specular: 1.0,
            specular_color: Vec3::ONE,
        })
    };
    let mirrored = place.determinant() < 0.0;
    let mut names: HashMap<String, usize> = HashMap::new();
    for model in &models {
        let m = &model.mesh;
        let (key, material) = match m.material_id.and_then(|i| Some((i, mtl.get(i)?))) {
            Some((i, mat)) => (mat.name.clone(), materials[i].clone()),
            None => (DEFAULT_MATERIAL.to_string(), default()),
        };
        let textured = material.textured.is_some();
        let normal_mapped = material
            .textured
            .as_ref()
            .is_some_and(|t| t.0.normal.is_some());
        let mut kept: Vec<[u32; 3]> = Vec::new();
        let has_uv = m.texcoords.len() >= m.positions.len() / 3 * 2;
        let mut mesh = Mesh {
            triangles: Vec::with_capacity(m.indices.len() / 3),
            skipped: 0,
            uvs: Vec::new(),
            normals: Vec::new(),
            tangents: Vec::new(),
        };
        let point = |i: u32| -> Option<DVec3> {
            let i = i as usize * 3;
            let p = m.positions.get(i..i + 3)?;
            Some(place.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
        };
        // OBJ's v runs up the image, glTF's (and the tracers') down from its top row.
        let uv = |i: u32| -> [f32; 2] {
            let i = i as usize * 2;
            match (has_uv, m.texcoords.get(i..i + 2)) {
                (true, Some(t)) => [t[0], 1.0 - t[1]],
                _ => [0.0; 2],
            }
        };
        for f in m.indices.chunks_exact(3) {
            let [Some(a), Some(b), Some(c)] = [f[0], f[1], f[2]].map(point) else {
                return Err(err(Malformed(format!(
                    "group `{}`: a face refers to vertex {} which does not exist",
                    model.name,
                    f.iter().max().unwrap_or(&0) + 1
                ))));
            };
            let area = (b - a).cross(c - a).length();
            if !(area > 0.0 && area.is_finite()) {
                mesh.skipped += 1;
                continue;
            }
            for p in [a, b, c] {
                out.bounds.0 = out.bounds.0.min(p);
                out.bounds.1 = out.bounds.1.max(p);
            }
            let [ua, ub, uc] = [f[0], f[1], f[2]].map(uv);
            kept.push([f[0], f[1], f[2]]);
            if mirrored {
                mesh.triangles.push([a, c, b]);
                if textured {
                    mesh.uvs.push([ua, uc, ub]);
                }
            } else {
                mesh.triangles.push([a, b, c]);
                if textured {
                    mesh.uvs.push([ua, ub, uc]);
                }
            }
        }
        if mesh.triangles.is_empty() {
            out.skipped
                .push(format!("group `{}`: no triangle with area", model.name));
            continue;
        }
        let chunks3 = |v: &[f32]| -> Vec<[f32; 3]> {
            v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        };
        let normals = if m.normals.len() == m.positions.len() {
            chunks3(&m.normals)
        } else {
            Vec::new()
        };
        if normal_mapped {
            // The shading frames, as glTF's: the file's normals (`vn`), MikkTSpace tangents
            // on the flipped coordinates (the tracers' v, glTF's).
            let positions = chunks3(&m.positions);
            let uvs: Vec<[f32; 2]> = (0..positions.len() as u32).map(uv).collect();
            let linear = glam::DMat3::from_mat4(place);
            for (n, t) in super::gltf_frames::frames(&kept, &positions, &normals, &[], &uvs, linear)
            {
                mesh.normals
                    .push(if mirrored { [n[0], n[2], n[1]] } else { n });
                mesh.tangents
                    .push(if mirrored { [t[0], t[2], t[1]] } else { t });
            }
        } else if !material.is_dielectric() {
            // Smooth shading from the file's normals alone.
            let linear = glam::DMat3::from_mat4(place);
            mesh.normals = super::gltf_frames::normals_only(&kept, &normals, linear, mirrored);
        }
        if !out.materials.iter().any(|(k, _)| *k == key) {
            out.materials.push((key.clone(), material.clone()));
        }
        // tobj splits a group at each `usemtl`: the parts are named `group`, `group.2`, ….
        let seen = names.entry(model.name.clone()).or_insert(0);
        *seen += 1;
        out.objects.push(Object {
            name: Some(match *seen {
                1 => model.name.clone(),
                n => format!("{}.{n}", model.name),
            }),
            shape: Shape::Mesh {
                file: String::new(),
                mesh: Arc::new(mesh),
                translate: DVec3::ZERO,
                rotation: DVec3::ZERO,
                scale: DVec3::ONE,
                instances: Default::default(),
            },
            material,
            material_name: Some(key),
            gltf: None,
        });
    }
    if out.objects.is_empty() {
        return Err(err("the file has no triangles".into()));
    }
    Ok(out)
}

/// Names each `usemtl` whose material no library defines (its faces get the default).
fn unknown_materials(text: &str, mtl: &[tobj::Material], skipped: &mut Vec<String>) {
    let mut named = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let Some(name) = line.trim().strip_prefix("usemtl ").map(str::trim) else {
            continue;
        };
        if !mtl.iter().any(|m| m.name == name) && !named.contains(&name) {
            named.push(name);
            skipped.push(format!(
                "line {}: `usemtl {name}`: no material library defines it; its faces get the \
                 default material",
                n + 1
            ));
        }
    }
}

/// The library that defines `material`, and the line (from 1) of its statement `key`
/// (`newmtl` for the definition itself).
fn statement<'a>(
    libraries: &'a [(PathBuf, String)],
    material: &str,
    key: &str,
) -> Option<(&'a Path, usize)> {
    for (file, text) in libraries {
        let mut inside = false;
        for (n, line) in text.lines().enumerate() {
            let mut words = line.split_whitespace();
            let first = words.next();
            if first == Some("newmtl") {
                inside = line.trim()["newmtl".len()..].trim() == material;
                if inside && key == "newmtl" {
                    return Some((file, n + 1));
                }
            } else if inside && first == Some(key) {
                return Some((file, n + 1));
            }
        }
    }
    None
}

/// A statement of a material, for messages: `file:line: material `NAME`: KEY`.
fn locate(libraries: &[(PathBuf, String)], material: &str, key: &str) -> String {
    match statement(libraries, material, key) {
        Some((file, line)) => format!("{}:{line}: material `{material}`: {key}", file.display()),
        None => format!("material `{material}`: {key}"),
    }
}

/// A texture statement's options and file (`map_Kd -s 2 2 1 -clamp on wood.png`).
#[derive(Debug, PartialEq)]
pub struct TextureSpec {
    pub file: String,
    /// `-o`: added to the texture coordinates (after `-s`).
    pub offset: [f32; 2],
    /// `-s`: multiplies the texture coordinates.
    pub scale: [f32; 2],
    /// `-clamp on`: coordinates outside [0, 1] take the edge texel.
    pub clamp: bool,
    /// `-imfchan r|g|b|m|l|z`: the channel a scalar map reads.
    pub channel: Option<char>,
    /// `-bm`: a bump or normal map's multiplier.
    pub bump: Option<f32>,
}

/// Parses a texture statement's arguments: options (the MTL format's `-blendu`, `-blendv`,
/// `-bm`, `-boost`, `-cc`, `-clamp`, `-imfchan`, `-mm`, `-o`, `-s`, `-t`, `-texres`, `-type`)
/// and then the file name, which may hold spaces.
pub fn texture_spec(args: &str) -> Result<TextureSpec, Malformed> {
    let mut spec = TextureSpec {
        file: String::new(),
        offset: [0.0; 2],
        scale: [1.0; 2],
        clamp: false,
        channel: None,
        bump: None,
    };
    let mut rest = args.trim();
    // The next word, taken off `rest`.
    fn word<'a>(rest: &mut &'a str) -> &'a str {
        let t = rest.trim_start();
        let end = t.find(char::is_whitespace).unwrap_or(t.len());
        *rest = &t[end..];
        &t[..end]
    }
    // Up to `max` numbers after a vector option (`-o u [v [w]]`): words taken while they
    // are numbers.
    fn numbers(rest: &mut &str, max: usize) -> Vec<f32> {
        let mut out = Vec::new();
        while out.len() < max {
            let mut ahead = *rest;
            let Ok(x) = word(&mut ahead).parse::<f32>() else {
                break;
            };
            out.push(x);
            *rest = ahead;
        }
        out
    }
    while rest.starts_with('-') {
        let option = word(&mut rest);
        match option {
            "-blendu" | "-blendv" | "-cc" | "-type" => {
                word(&mut rest);
            }
            "-clamp" => spec.clamp = word(&mut rest) == "on",
            "-imfchan" => spec.channel = word(&mut rest).chars().next(),
            "-bm" | "-boost" | "-texres" => {
                let v = numbers(&mut rest, 1);
                let Some(&x) = v.first() else {
                    return Err(Malformed(format!("{option} needs a number")));
                };
                if option == "-bm" {
                    spec.bump = Some(x);
                }
            }
            "-mm" => {
                numbers(&mut rest, 2);
            }
            "-o" | "-s" | "-t" => {
                let v = numbers(&mut rest, 3);
                if v.is_empty() {
                    return Err(Malformed(format!("{option} needs numbers")));
                }
                let pair = [
                    v[0],
                    *v.get(1).unwrap_or(&if option == "-s" { 1.0 } else { 0.0 }),
                ];
                match option {
                    "-o" => spec.offset = pair,
                    "-s" => spec.scale = pair,
                    _ => {}
                }
            }
            other => return Err(Malformed(format!("unknown option `{other}`"))),
        }
        rest = rest.trim_start();
    }
    spec.file = rest.trim().to_string();
    if spec.file.is_empty() {
        return Err("no file name".into());
    }
    Ok(spec)
}

impl TextureSpec {
    /// `-s` and `-o` as the model's texture transform. They act on OBJ's coordinates (v up);
    /// the tracers' v runs down (v' = 1 − v), so v' ↦ s·v' + (1 − s − o).
    pub fn transform(&self) -> [f32; 6] {
        let ([su, sv], [ou, ov]) = (self.scale, self.offset);
        [su, 0.0, ou, 0.0, sv, 1.0 - sv - ov]
    }
}

/// One image decoded, for a material's statement.
struct Loaded {
    image: Arc<image::RgbaImage>,
    /// Which distinct image file it is (statements naming one file share its decoding and,
    /// with the same wrap mode, its texture).
    source: usize,
    spec: TextureSpec,
    name: String,
}

/// The textures made so far, by (image file, clamped): one allocation per image and wrap
/// mode, which the texture words then hold once.
type TextureCache = HashMap<(usize, bool), Arc<Texture>>;

/// Each MTL material mapped: factors by [`mtl_pbr`], maps decoded in parallel.
fn map_materials(
    mtl: &[tobj::Material],
    libraries: &[(PathBuf, String)],
    read: Reader,
    skipped: &mut Vec<String>,
) -> Result<Vec<Material>, Malformed> {
    // Every (material, statement, arguments) whose image is read.
    let mut wanted: Vec<(usize, &str, &str)> = Vec::new();
    for (i, m) in mtl.iter().enumerate() {
        for (key, value) in [
            ("map_Kd", m.diffuse_texture.as_deref()),
            ("map_d", m.dissolve_texture.as_deref()),
            ("map_Ke", m.unknown_param.get("map_Ke").map(String::as_str)),
            ("norm", m.unknown_param.get("norm").map(String::as_str)),
        ] {
            if let Some(v) = value {
                wanted.push((i, key, v));
            }
        }
        let mut unread: Vec<&str> = [
            ("map_Ka", m.ambient_texture.is_some()),
            ("map_Ks", m.specular_texture.is_some()),
            ("map_Ns", m.shininess_texture.is_some()),
            ("bump", m.normal_texture.is_some()),
        ]
        .into_iter()
        .filter_map(|(k, present)| present.then_some(k))
        .collect();
        let mut others: Vec<&str> = m
            .unknown_param
            .keys()
            .map(String::as_str)
            .filter(|k| {
                (k.starts_with("map_") || ["norm", "disp", "decal", "refl"].contains(k))
                    && !READ_MAPS.contains(k)
            })
            .collect();
        others.sort_unstable();
        unread.extend(others);
        if !unread.is_empty() {
            skipped.push(format!(
                "material `{}`: {} (not read)",
                m.name,
                unread.join(", ")
            ));
        }
    }
    // A map's file is found beside the library that defines its material.
    let base = |i: usize| -> PathBuf {
        statement(libraries, &mtl[i].name, "newmtl")
            .and_then(|(f, _)| f.parent())
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    };
    // Each statement's options, and the distinct files they name (by folder and name as
    // written), each with the first statement naming it, for messages.
    let mut specs = Vec::with_capacity(wanted.len());
    let mut files: Vec<(PathBuf, String, String)> = Vec::new();
    for &(i, key, args) in &wanted {
        let what = locate(libraries, &mtl[i].name, key);
        let spec = texture_spec(args).map_err(|e| Malformed(format!("{what}: {e}")))?;
        let folder = base(i);
        let source = match files
            .iter()
            .position(|(f, n, _)| *f == folder && *n == spec.file)
        {
            Some(k) => k,
            None => {
                files.push((folder, spec.file.clone(), what));
                files.len() - 1
            }
        };
        specs.push((source, spec));
    }
    // Each file read and decoded once, in parallel.
    let decoded: Vec<Result<Arc<image::RgbaImage>, Malformed>> = files
        .par_iter()
        .map(|(folder, file, what)| {
            let bytes =
                find_image(folder, file, read).map_err(|e| Malformed(format!("{what}: {e}")))?;
            let image = image::load_from_memory(&bytes)
                .map_err(|e| Malformed(format!("{what}: `{file}`: {e}")))?;
            Ok(Arc::new(image.to_rgba8()))
        })
        .collect();
    let images = decoded.into_iter().collect::<Result<Vec<_>, _>>()?;
    let mut maps: HashMap<(usize, &str), Loaded> = HashMap::new();
    for (&(i, key, _), (source, spec)) in wanted.iter().zip(specs) {
        let loaded = Loaded {
            image: images[source].clone(),
            source,
            name: format!("`{}` ({key} of `{}`)", spec.file, mtl[i].name),
            spec,
        };
        maps.insert((i, key), loaded);
    }
    let mut cache = TextureCache::new();
    Ok(mtl
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let pbr = mtl_pbr(m);
            let mut material = pbr_material(&pbr);
            material.textured = textured(
                m,
                &pbr,
                maps.remove(&(i, "map_Kd")),
                maps.remove(&(i, "map_d")),
                maps.remove(&(i, "map_Ke")),
                maps.remove(&(i, "norm")),
                &mut cache,
            );
            material
        })
        .collect())
}

/// The bytes of the image a map names: its path beside the library, else (a path written
/// on another machine, `C:\\textures\\wood.png`) its file name there.
fn find_image(base: &Path, file: &str, read: Reader) -> Result<Vec<u8>, Malformed> {
    let as_written = base.join(file.replace('\\', "/"));
    let first = match read(&as_written) {
        Ok(b) => return Ok(b),
        Err(e) => e,
    };
    let name = file.rsplit(['/', '\\']).next().unwrap_or(file);
    let beside = base.join(name);
    if beside != as_written
        && let Ok(b) = read(&beside)
    {
        return Ok(b);
    }
    Err(Malformed(format!(
        "`{file}` is not there (looked for {} and {}: {first})",
        as_written.display(),
        beside.display()
    )))
}

/// An MTL material's factors in glTF's terms (docs/MODEL-NOTES.md, "OBJ materials"):
/// - `Kd` → base colour (0.8 grey when absent);
/// - `Pr` → roughness, else `Ns` by Blender's rule, roughness = 1 − √(Ns / 1000) (its exporter
///   writes Ns = 1000 · (1 − roughness)²); no `Ns`: roughness 1;
/// - `Pm` → metallic, else 1 for the reflecting illumination models 3, 5 and 8, else 0;
/// - the transparent illumination models 4, 6, 7 and 9 → glass (transmission 1) of ior `Ni`;
/// - `Ke` → emission;
/// - `Pc` and `Pcr` (the clear coat's thickness and roughness) → KHR_materials_clearcoat's
///   factor and roughness.
pub fn mtl_pbr(m: &tobj::Material) -> Pbr {
    let param = |k: &str| -> Option<f32> {
        m.unknown_param
            .get(k)?
            .split_whitespace()
            .next()?
            .parse()
            .ok()
    };
    let illum = m.illumination_model.unwrap_or(2);
    let roughness = param("Pr").unwrap_or_else(|| match m.shininess {
        Some(ns) => 1.0 - (ns.clamp(0.0, 1000.0) / 1000.0).sqrt(),
        None => 1.0,
    });
    let metallic = param("Pm").unwrap_or(if [3, 5, 8].contains(&illum) { 1.0 } else { 0.0 });
    let glass = [4, 6, 7, 9].contains(&illum);
    Pbr {
        base: Vec3::from(m.diffuse.unwrap_or(super::model::DEFAULT_COLOR.to_array())),
        metallic,
        roughness,
        emissive: m.emissive.map_or(Vec3::ZERO, Vec3::from),
        transmission: if glass { 1.0 } else { 0.0 },
        // An OBJ mesh is a solid: its glass refracts.
        volume: glass.then(super::model::Volume::default),
        ior: m.optical_density.unwrap_or(1.5),
        clearcoat: (param("Pc").unwrap_or(0.0), param("Pcr").unwrap_or(0.0)),
        specular: 1.0,
        specular_color: Vec3::ONE,
    }
}

/// The material's opacity: `d`, else 1 − `Tr`.
fn dissolve(m: &tobj::Material) -> f32 {
    let tr = m
        .unknown_param
        .get("Tr")
        .and_then(|t| t.split_whitespace().next()?.parse::<f32>().ok());
    m.dissolve
        .or(tr.map(|t| 1.0 - t))
        .unwrap_or(1.0)
        .clamp(0.0, 1.0)
}

/// The material's maps as the model's [`Textured`]: `map_Kd` × `Kd` the base colour, `map_d` ×
/// `d` its alpha (a stochastic cut-out, glTF's BLEND, when below 1; read through `map_Kd`'s
/// coordinates), `map_Ke` × `Ke` the emission, `norm` a tangent-space normal map (its `-bm`
/// the scale). `None` when it has no map and is opaque.
fn textured(
    m: &tobj::Material,
    pbr: &Pbr,
    kd: Option<Loaded>,
    d: Option<Loaded>,
    ke: Option<Loaded>,
    norm: Option<Loaded>,
    cache: &mut TextureCache,
) -> Option<TexturedRef> {
    let opacity = dissolve(m);
    let glass = pbr.transmission > 0.5;
    let cut = !glass && (opacity < 1.0 || d.is_some());
    if kd.is_none() && ke.is_none() && norm.is_none() && !cut {
        return None;
    }
    let wrap = |s: &TextureSpec| [if s.clamp { Wrap::Clamp } else { Wrap::Repeat }; 2];
    let texture = |l: &Loaded| Texture {
        width: l.image.width(),
        height: l.image.height(),
        texels: l.image.pixels().map(|p| u32::from_le_bytes(p.0)).collect(),
        wrap: wrap(&l.spec),
        name: l.name.clone(),
    };
    // A map as it is, shared by every statement naming its file with its wrap mode.
    let mut shared = |l: &Loaded| -> Arc<Texture> {
        cache
            .entry((l.source, l.spec.clamp))
            .or_insert_with(|| Arc::new(texture(l)))
            .clone()
    };
    let base_xf = kd
        .as_ref()
        .map_or(IDENTITY_TRANSFORM, |l| l.spec.transform());
    // With an opacity map the base map is this material's own (its alpha replaced).
    let base_color = match (&kd, d.as_ref().filter(|_| cut)) {
        (Some(kd), None) => Some(shared(kd)),
        (kd, Some(d)) => Some(Arc::new(with_alpha(kd.as_ref().map(texture), d, wrap))),
        (None, None) => None,
    };
    Some(TexturedRef(Arc::new(Textured {
        base_color,
        metallic_roughness: None,
        emissive: ke.as_ref().map(&mut shared),
        normal: norm.as_ref().map(&mut shared),
        normal_scale: norm.as_ref().and_then(|l| l.spec.bump).unwrap_or(1.0),
        base_factor: [pbr.base.x, pbr.base.y, pbr.base.z, opacity].map(|x| x.max(0.0)),
        metallic: pbr.metallic.clamp(0.0, 1.0),
        roughness: pbr.roughness.clamp(0.0, 1.0),
        // A map_Ke without Ke emits the map itself (the spec's factor would be black).
        emissive_factor: if ke.is_some() && pbr.emissive == Vec3::ZERO {
            [1.0; 3]
        } else {
            pbr.emissive.max(Vec3::ZERO).to_array()
        },
        alpha: if cut {
            AlphaMode::Blend
        } else {
            AlphaMode::Opaque
        },
        transforms: [
            base_xf,
            IDENTITY_TRANSFORM,
            ke.as_ref()
                .map_or(IDENTITY_TRANSFORM, |l| l.spec.transform()),
            norm.as_ref()
                .map_or(IDENTITY_TRANSFORM, |l| l.spec.transform()),
        ],
        extensions: Default::default(),
    })))
}

/// The base-colour texture with `map_d`'s opacity as its alpha (nearest texel where the
/// sizes differ); without `map_Kd`, a white texture of `map_d`'s size. The opacity is the
/// channel `-imfchan` names, else the image's alpha where it has some, else its luminance.
fn with_alpha(
    kd: Option<Texture>,
    d: &Loaded,
    wrap: impl Fn(&TextureSpec) -> [Wrap; 2],
) -> Texture {
    let img = &d.image;
    let translucent = img.pixels().any(|p| p.0[3] < 255);
    let channel = d
        .spec
        .channel
        .unwrap_or(if translucent { 'm' } else { 'l' });
    let opacity = |p: &image::Rgba<u8>| -> u32 {
        let [r, g, b, a] = p.0.map(u32::from);
        match channel {
            'r' => r,
            'g' => g,
            'b' => b,
            'm' => a,
            _ => (r * 2126 + g * 7152 + b * 722 + 5000) / 10000,
        }
    };
    let mut t = kd.unwrap_or_else(|| Texture {
        width: img.width(),
        height: img.height(),
        texels: vec![0x00ff_ffff; (img.width() * img.height()) as usize],
        wrap: wrap(&d.spec),
        name: d.name.clone(),
    });
    let (w, h) = (t.width, t.height);
    for y in 0..h {
        let sy = (y as u64 * img.height() as u64 / h as u64) as u32;
        for x in 0..w {
            let sx = (x as u64 * img.width() as u64 / w as u64) as u32;
            let texel = &mut t.texels[(y * w + x) as usize];
            *texel = (*texel & 0x00ff_ffff) | opacity(img.get_pixel(sx, sy)) << 24;
        }
    }
    t.name = format!("{} with the opacity of {}", t.name, d.name);
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_options_are_read_and_the_file_may_hold_spaces() {
        let s = texture_spec("-s 2 3 1 -o 0.5 0.25 -clamp on -bm 0.3 my wood.png").unwrap();
        assert_eq!(s.file, "my wood.png");
        assert_eq!(
            (s.scale, s.offset, s.clamp),
            ([2.0, 3.0], [0.5, 0.25], true)
        );
        // OBJ's v' = 3v + 0.25 seen with v flipped: 1 − (3(1 − v) + 0.25) = 3v − 2.25.
        assert_eq!(s.transform(), [2.0, 0.0, 0.5, 0.0, 3.0, -2.25]);
        assert_eq!(
            texture_spec("a.png").unwrap().transform(),
            IDENTITY_TRANSFORM
        );
        assert!(texture_spec("-s").unwrap_err().contains("-s needs numbers"));
        assert!(
            texture_spec("-wobble 1 a.png")
                .unwrap_err()
                .contains("`-wobble`")
        );
        assert!(
            texture_spec("-clamp on")
                .unwrap_err()
                .contains("no file name")
        );
    }

    #[test]
    fn a_parse_error_names_its_line() {
        let e = load(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 1 x 2\nf 1 2 3\n",
            |_| Err(tobj::LoadError::OpenFileFailed),
        )
        .unwrap_err();
        assert!(e.starts_with("line 5:") && e.contains("`v 1 x 2`"), "{e}");
    }

    #[test]
    fn a_colour_of_one_number_is_grey_and_of_two_is_refused() {
        assert_eq!(
            colours_of_three("Kd 0.5\nKs 1 2 3\n").unwrap(),
            "Kd 0.5 0.5 0.5\nKs 1 2 3\n"
        );
        let e = colours_of_three("newmtl m\nKa 1 1\n").unwrap_err();
        assert!(e.starts_with("line 2: `Ka` needs one number"), "{e}");
        assert!(colours_of_three("Kd\n").is_err());
    }

    #[test]
    fn mtl_factors_map_by_the_documented_rules() {
        let (_, mats) = load("mtllib a.mtl\n", |_| {
            tobj::load_mtl_buf(
                &mut "newmtl plain\nKd 0.5 0.25 1\nNs 250\n\
                      newmtl mirror\nillum 3\nKd 0.9 0.9 0.9\nNs 1000\n\
                      newmtl glass\nillum 7\nNi 1.33\n\
                      newmtl lamp\nKe 4 2 0\n\
                      newmtl pbr\nPr 0.3\nPm 0.5\nillum 3\n"
                    .as_bytes(),
            )
        })
        .unwrap();
        let p: Vec<Pbr> = mats.iter().map(mtl_pbr).collect();
        assert_eq!(p[0].base, Vec3::new(0.5, 0.25, 1.0));
        assert_eq!((p[0].metallic, p[0].roughness), (0.0, 0.5));
        assert_eq!((p[1].metallic, p[1].roughness), (1.0, 0.0));
        assert_eq!((p[2].transmission, p[2].ior), (1.0, 1.33));
        let glass = pbr_material(&p[2]);
        assert!(glass.is_pbr() && glass.transmission == 1.0 && !glass.volume.thin_walled);
        let lamp = pbr_material(&p[3]);
        assert_eq!((lamp.light, lamp.color), (4.0, Vec3::new(1.0, 0.5, 0.0)));
        assert_eq!((p[4].metallic, p[4].roughness), (0.5, 0.3));
    }
}
