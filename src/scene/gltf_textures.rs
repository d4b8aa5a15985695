//! The textures of a glTF file: the images its materials use, decoded in parallel (PNG, JPEG
//! and WebP through `image`, KTX2 / Basis Universal through `basisu`) into the model's RGBA8
//! textures with their samplers' wrap modes, and each textured material as the model's
//! [`Textured`].

use super::error::Malformed;
use super::texture::{
    AlphaMode, ExtensionMaps, IDENTITY_TRANSFORM, Texture, Textured, TexturedRef, Wrap,
};
use base64::Engine;
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Each glTF texture a material uses, decoded (`None`: unused).
pub type Textures = Vec<Option<Arc<Texture>>>;

/// Decodes every image that a material's base colour, metallic-roughness, emissive or normal
/// map, or a map of the material extensions read ([`extension_textures`]), uses, each once, in
/// parallel.
pub fn decode(
    doc: &gltf::Document,
    base: Option<&Path>,
    buffers: &[gltf::buffer::Data],
) -> Result<Textures, Malformed> {
    let mut used = vec![false; doc.textures().len()];
    for m in doc.materials() {
        let pbr = m.pbr_metallic_roughness();
        for info in [
            pbr.base_color_texture(),
            pbr.metallic_roughness_texture(),
            m.emissive_texture(),
        ]
        .into_iter()
        .flatten()
        {
            used[info.texture().index()] = true;
        }
        if let Some(n) = m.normal_texture() {
            used[n.texture().index()] = true;
        }
        for i in extension_textures(&m) {
            if let Some(u) = used.get_mut(i) {
                *u = true;
            }
        }
    }
    let mut images: Vec<usize> = doc
        .textures()
        .filter(|t| used[t.index()])
        .map(|t| image_of(&t, doc))
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .flatten()
        .collect();
    images.sort_unstable();
    images.dedup();
    // Each image: its pixels and how messages name it.
    type Decoded = Result<(Arc<image::RgbaImage>, String), Malformed>;
    let decoded: Vec<(usize, Decoded)> = images
        .par_iter()
        .map(|&i| {
            let image = doc.images().nth(i).expect("an image index of the document");
            let what = match (image.name(), image.source()) {
                (Some(n), _) => format!("images[{i}] (`{n}`)"),
                (None, gltf::image::Source::Uri { uri, .. }) if !uri.starts_with("data:") => {
                    format!("images[{i}] (`{uri}`)")
                }
                _ => format!("images[{i}]"),
            };
            let pixels = encoded(&image, base, buffers)
                .and_then(|bytes| decode_image(&bytes))
                .map(Arc::new)
                .map_err(|e| Malformed(format!("{what}: {e}")));
            (i, pixels.map(|p| (p, what)))
        })
        .collect();
    let mut by_image = std::collections::HashMap::new();
    for (i, d) in decoded {
        by_image.insert(i, d?);
    }
    Ok(doc
        .textures()
        .map(|t| {
            let (img, what) = by_image.get(&image_of(&t, doc).ok()??)?;
            let wrap = |w: gltf::texture::WrappingMode| match w {
                gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
                gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
                gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            };
            let s = t.sampler();
            Some(Arc::new(Texture {
                width: img.width(),
                height: img.height(),
                texels: img.pixels().map(|p| u32::from_le_bytes(p.0)).collect(),
                wrap: [wrap(s.wrap_s()), wrap(s.wrap_t())],
                name: what.clone(),
            }))
        })
        .collect())
}

/// The image a texture shows: its `EXT_texture_webp` source where it has one (WebP, which
/// termtrace decodes, in preference to a fallback), else its own source, else its
/// `KHR_texture_basisu` source (KTX2 is a lossy re-encoding: a fallback, usually the original
/// PNG or JPEG, is preferred where there is one); `None`: none of them.
fn image_of(t: &gltf::Texture, doc: &gltf::Document) -> Result<Option<usize>, Malformed> {
    let extension_source = |name: &str| -> Result<Option<usize>, Malformed> {
        let Some(ext) = t.extension_value(name) else {
            return Ok(None);
        };
        match ext.get("source").and_then(|v| v.as_u64()) {
            Some(i) if (i as usize) < doc.images().len() => Ok(Some(i as usize)),
            _ => Err(Malformed(format!(
                "textures[{}].extensions.{name}.source is not an image",
                t.index()
            ))),
        }
    };
    if let Some(i) = extension_source("EXT_texture_webp")? {
        return Ok(Some(i));
    }
    let basisu = extension_source("KHR_texture_basisu")?;
    Ok(t.source().map(|i| i.index()).or(basisu))
}

/// KTX 2.0's identifier, the file's first 12 bytes (KTX 2.0 specification §3.1).
const KTX2_IDENTIFIER: [u8; 12] = [
    0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
];

/// The largest image decoded, in texels (16384², 1 GiB as RGBA8): a KTX2 header can claim any
/// size, and the transcoder allocates what it claims.
const MAX_TEXELS: u64 = 1 << 28;

/// An encoded image's texels: KTX2 (by its identifier) transcoded from Basis Universal, any
/// other format decoded by `image` (PNG, JPEG, WebP).
pub fn decode_image(bytes: &[u8]) -> Result<image::RgbaImage, Malformed> {
    if bytes.starts_with(&KTX2_IDENTIFIER) {
        return decode_ktx2(bytes);
    }
    image::load_from_memory(bytes)
        .map(|img| img.to_rgba8())
        .map_err(|e| Malformed(format!("cannot decode it: {e}")))
}

/// A KTX2 image (`KHR_texture_basisu`: ETC1S in BasisLZ, or UASTC, possibly in Zstandard)
/// transcoded to RGBA8: its first level, first layer and face. The texels are the encoded
/// values, sRGB or linear as the material slot says (glTF §3.9.2), like a PNG's.
fn decode_ktx2(bytes: &[u8]) -> Result<image::RgbaImage, Malformed> {
    // The transcoder is a port of C++ that trusts the file's offsets and counts: `fuzz/` found
    // a key/value length that indexes past the end (a panic in its header parse) and an
    // overflow in its ETC1S run lengths (a panic where overflow checks are on). A panic in it
    // is this file's error, not the program's end.
    std::panic::catch_unwind(|| transcode_ktx2(bytes)).unwrap_or_else(|_| {
        Err(Malformed(
            "its KTX2 data is corrupt (the transcoder failed on it)".into(),
        ))
    })
}

/// [`decode_ktx2`]'s work, which may panic on a corrupt file.
fn transcode_ktx2(bytes: &[u8]) -> Result<image::RgbaImage, Malformed> {
    use basisu::{DecodeFlags, Error, TargetFormat, Transcoder};
    // A transcoder error as this image's.
    let fail = |e: Error| {
        let why = match e {
            Error::InvalidData => "it is not Basis Universal data, or it is corrupt \
                                   (KHR_texture_basisu images are KTX2 in ETC1S or UASTC)"
                .to_string(),
            Error::Truncated => "it is cut short (an offset or length reaches past its end)".into(),
            Error::Unsupported { source, .. } => {
                format!("its format ({source:?}) has no 8-bit RGBA decoding (an HDR image?)")
            }
            Error::UnsupportedFeature(what) => {
                format!("the transcoder does not read what it holds ({what}), or it is corrupt")
            }
            other => format!("{other:?}"),
        };
        Malformed(format!("cannot transcode its KTX2: {why}"))
    };
    let ktx = Transcoder::new(bytes).map_err(fail)?;
    let (width, height) = ktx.base_dimensions();
    if width == 0 || height == 0 || width as u64 * height as u64 > MAX_TEXELS {
        return Err(Malformed(format!(
            "its KTX2 header says {width}×{height} texels (at most {MAX_TEXELS} are read)"
        )));
    }
    // The first level's inflated size, which the transcoder allocates as the file states it,
    // must fit the level: at most 16 bytes per 4×4 block of each layer, face and slice.
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let (depth, layers, faces) = (u32_at(28), u32_at(32), u32_at(36));
    let level_bytes = [depth, layers, faces].into_iter().fold(
        16 * width.div_ceil(4) as u64 * height.div_ceil(4) as u64,
        |n, k| n.saturating_mul(k.max(1) as u64),
    );
    let inflated = bytes
        .get(96..104)
        .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
        .ok_or_else(|| Malformed("its KTX2 level index is cut short".into()))?;
    if inflated > level_bytes {
        return Err(Malformed(format!(
            "its KTX2 level 0 claims {inflated} bytes inflated, more than its {width}×{height} \
             texels ({depth} slices, {layers} layers, {faces} faces) can hold ({level_bytes})"
        )));
    }
    if !ktx.supports(TargetFormat::Rgba32) {
        return Err(Malformed(format!(
            "its KTX2 format ({:?}) has no 8-bit RGBA decoding (an HDR image?)",
            ktx.source_format()
        )));
    }
    let info = ktx.image_level_info(0).map_err(fail)?;
    let texels = ktx
        .transcode(0, TargetFormat::Rgba32, DecodeFlags::NONE)
        .map_err(fail)?;
    image::RgbaImage::from_raw(info.width, info.height, texels).ok_or_else(|| {
        Malformed(format!(
            "its KTX2 level 0 transcoded to a buffer that is not {}×{} RGBA",
            info.width, info.height
        ))
    })
}

/// The textures the maps of KHR_materials_transmission, _specular and _clearcoat name (the
/// last from its JSON, which the crate does not type).
fn extension_textures(m: &gltf::Material) -> Vec<usize> {
    let mut out = Vec::new();
    if let Some(i) = m.transmission().and_then(|t| t.transmission_texture()) {
        out.push(i.texture().index());
    }
    if let Some(s) = m.specular() {
        out.extend(s.specular_texture().map(|i| i.texture().index()));
        out.extend(s.specular_color_texture().map(|i| i.texture().index()));
    }
    if let Some(c) = m.extension_value("KHR_materials_clearcoat") {
        for key in ["clearcoatTexture", "clearcoatRoughnessTexture"] {
            let index = c.get(key).and_then(|v| v.get("index")?.as_u64());
            out.extend(index.map(|i| i as usize));
        }
    }
    out
}

/// The encoded bytes of an image: from a buffer view, a `data:` URI, or a file beside the
/// glTF file.
fn encoded(
    image: &gltf::Image,
    base: Option<&Path>,
    buffers: &[gltf::buffer::Data],
) -> Result<Vec<u8>, Malformed> {
    match image.source() {
        gltf::image::Source::View { view, .. } => {
            let data = buffers
                .get(view.buffer().index())
                .ok_or("its buffer is missing")?;
            let end = view.offset().checked_add(view.length());
            match end {
                Some(end) if end <= data.len() => Ok(data[view.offset()..end].to_vec()),
                _ => Err("its buffer view reaches past the end of its buffer".into()),
            }
        }
        gltf::image::Source::Uri { uri, .. } => read_uri(uri, base),
    }
}

/// The bytes a URI names: a `data:` URI's (base64), or a file's beside the glTF file (its
/// `%XX` escapes decoded; not the crate's reader, which panics on an escape that is not
/// UTF-8, as `fuzz/` found).
pub(super) fn read_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>, Malformed> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, b64) = rest
            .split_once(";base64,")
            .ok_or("a data URI that is not base64")?;
        return base64::engine::general_purpose::STANDARD
            .decode(b64)
            .map_err(|e| Malformed(format!("its data URI is not valid base64: {e}")));
    }
    let base = base.ok_or("data in another file, and no folder to read it from")?;
    let path = base.join(percent_decode(uri.strip_prefix("file://").unwrap_or(uri)));
    std::fs::read(&path).map_err(|e| Malformed(format!("cannot read {}: {e}", path.display())))
}

/// A relative URI's `%XX` escapes decoded (glTF URIs are percent-encoded: `my%20file.png`).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// `m` as the model's textured material, when it has a map the tracers read or is not
/// opaque; `None` otherwise (its factors alone are the whole material). Maps on a texture
/// coordinate set other than 0 are left out and named in `skipped`.
pub fn textured(
    m: &gltf::Material,
    textures: &Textures,
    skipped: &mut Vec<String>,
) -> Option<TexturedRef> {
    let pbr = m.pbr_metallic_roughness();
    // The map on texture `index`, read through coordinate set `set` with the transform `xf`;
    // `None` where the texture is missing, or (named in `skipped`) on a set other than 0.
    let mut pick = |(index, set, xf): (usize, u32, [f32; 6]), what: &str| {
        if set != 0 {
            skipped.push(format!(
                "the {what} map of materials[{}]: TEXCOORD_{set} (only TEXCOORD_0 is read)",
                m.index().map_or("default".into(), |i| i.to_string()),
            ));
            return None;
        }
        Some((textures.get(index).cloned().flatten()?, xf))
    };
    let info = |info: gltf::texture::Info| {
        let t = info.texture_transform();
        let set = t
            .as_ref()
            .and_then(|t| t.tex_coord())
            .unwrap_or(info.tex_coord());
        let xf = t.map_or(IDENTITY_TRANSFORM, |t| {
            texture_transform(t.offset(), t.rotation(), t.scale())
        });
        (info.texture().index(), set, xf)
    };
    let base_color = pbr
        .base_color_texture()
        .and_then(|i| pick(info(i), "base colour"));
    let metallic_roughness = pbr
        .metallic_roughness_texture()
        .and_then(|i| pick(info(i), "metallic-roughness"));
    let emissive = m.emissive_texture().and_then(|i| pick(info(i), "emissive"));
    let normal_info = m.normal_texture();
    let normal = normal_info.as_ref().and_then(|n| {
        // The crate reads KHR_texture_transform on `Info` only; a normal map's is in its JSON.
        let xf = n
            .extension_value("KHR_texture_transform")
            .map(NormalTransform::from_json)
            .unwrap_or_default();
        let set = xf.tex_coord.unwrap_or(n.tex_coord());
        let matrix = texture_transform(xf.offset, xf.rotation, xf.scale);
        pick((n.texture().index(), set, matrix), "normal")
    });
    // The material extensions' maps: the crate's types where it has them, the JSON's
    // textureInfo for KHR_materials_clearcoat (as a normal map's transform is read).
    let coat = m.extension_value("KHR_materials_clearcoat");
    let json_info = |key: &str| -> Option<(usize, u32, [f32; 6])> {
        let v = coat?.get(key)?;
        let index = v.get("index")?.as_u64()? as usize;
        let xf = v
            .get("extensions")
            .and_then(|e| e.get("KHR_texture_transform"))
            .map(NormalTransform::from_json)
            .unwrap_or_default();
        let set = xf.tex_coord.unwrap_or_else(|| {
            v.get("texCoord")
                .and_then(|t| t.as_u64())
                .map_or(0, |t| t.min(u32::MAX as u64) as u32)
        });
        Some((
            index,
            set,
            texture_transform(xf.offset, xf.rotation, xf.scale),
        ))
    };
    let extensions = ExtensionMaps {
        transmission: m
            .transmission()
            .and_then(|t| t.transmission_texture())
            .and_then(|i| pick(info(i), "transmission")),
        clearcoat: json_info("clearcoatTexture").and_then(|i| pick(i, "clearcoat")),
        clearcoat_roughness: json_info("clearcoatRoughnessTexture")
            .and_then(|i| pick(i, "clearcoat roughness")),
        specular: m
            .specular()
            .and_then(|s| s.specular_texture())
            .and_then(|i| pick(info(i), "specular")),
        specular_color: m
            .specular()
            .and_then(|s| s.specular_color_texture())
            .and_then(|i| pick(info(i), "specular colour")),
    };
    // Maps that are not read: named, once each. The coat follows the material's shading
    // normal; a path tracer takes a volume's thickness from its geometry.
    let which = m.index().map_or("default".into(), |i| i.to_string());
    for (map, what, ext) in [
        (
            coat.is_some_and(|c| c.get("clearcoatNormalTexture").is_some()),
            "clearcoatNormalTexture",
            "KHR_materials_clearcoat",
        ),
        (
            m.volume().is_some_and(|v| v.thickness_texture().is_some()),
            "thicknessTexture",
            "KHR_materials_volume",
        ),
    ] {
        if map {
            skipped.push(format!(
                "the {what} of materials[{which}] ({ext}'s other maps and its factors are read)"
            ));
        }
    }
    let transforms = [&base_color, &metallic_roughness, &emissive, &normal]
        .map(|x| x.as_ref().map_or(IDENTITY_TRANSFORM, |(_, t)| *t));
    let (base_color, metallic_roughness, emissive, normal) = (
        base_color.map(|(t, _)| t),
        metallic_roughness.map(|(t, _)| t),
        emissive.map(|(t, _)| t),
        normal.map(|(t, _)| t),
    );
    let alpha = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
    };
    if base_color.is_none()
        && metallic_roughness.is_none()
        && emissive.is_none()
        && normal.is_none()
        && extensions.all().iter().all(|m| m.is_none())
        && alpha == AlphaMode::Opaque
    {
        return None;
    }
    let strength = m.emissive_strength().unwrap_or(1.0).max(0.0);
    Some(TexturedRef(Arc::new(Textured {
        base_color,
        metallic_roughness,
        emissive,
        normal,
        normal_scale: normal_info.map_or(1.0, |n| n.scale()),
        base_factor: pbr.base_color_factor().map(|x| x.max(0.0)),
        metallic: pbr.metallic_factor().clamp(0.0, 1.0),
        roughness: pbr.roughness_factor().clamp(0.0, 1.0),
        emissive_factor: m.emissive_factor().map(|x| x.max(0.0) * strength),
        alpha,
        transforms,
        extensions,
    })))
}

/// `KHR_texture_transform`'s matrix, translation × rotation × scale (the extension's
/// specification), as the rows [a, b, c, d, e, f] of u' = a·u + b·v + c, v' = d·u + e·v + f.
pub fn texture_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> [f32; 6] {
    let (s, c) = rotation.sin_cos();
    [
        c * scale[0],
        s * scale[1],
        offset[0],
        -s * scale[0],
        c * scale[1],
        offset[1],
    ]
}

/// A normal map's `KHR_texture_transform`, read from its JSON (absent fields at their
/// defaults; malformed ones too).
struct NormalTransform {
    offset: [f32; 2],
    rotation: f32,
    scale: [f32; 2],
    tex_coord: Option<u32>,
}

impl Default for NormalTransform {
    fn default() -> Self {
        NormalTransform {
            offset: [0.0; 2],
            rotation: 0.0,
            scale: [1.0; 2],
            tex_coord: None,
        }
    }
}

impl NormalTransform {
    fn from_json(v: &gltf::json::Value) -> NormalTransform {
        let d = NormalTransform::default();
        let pair = |key: &str, or: [f32; 2]| {
            v.get(key)
                .and_then(|a| Some([a.get(0)?.as_f64()? as f32, a.get(1)?.as_f64()? as f32]))
                .filter(|p| p.iter().all(|x| x.is_finite()))
                .unwrap_or(or)
        };
        NormalTransform {
            offset: pair("offset", d.offset),
            rotation: v
                .get("rotation")
                .and_then(|r| r.as_f64())
                .map(|r| r as f32)
                .filter(|r| r.is_finite())
                .unwrap_or(0.0),
            scale: pair("scale", d.scale),
            tex_coord: v
                .get("texCoord")
                .and_then(|t| t.as_u64())
                .map(|t| t.min(u32::MAX as u64) as u32),
        }
    }
}
