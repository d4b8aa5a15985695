//! The texture words both tracers read (`shaders/common/texture.wgsl`, `cpu::texture`): one
//! array of u32 holding the sRGB decoding table, each triangle's texture coordinates (where a
//! material has maps) and shading frames (where a normal map or smooth shading needs them), a
//! record per textured material (its maps and glTF factors) and the texels, RGBA8. One
//! storage buffer, so that every adapter binds it (lavapipe and llvmpipe included); a scene
//! with neither textures nor the files' normals uploads one word and compiles none of the
//! code that reads them.

use super::Features;
use crate::scene::texture::{AlphaMode, IDENTITY_TRANSFORM, Texture, Textured};
use crate::scene::{Material, Scene, Shape, euler_xyz};
use glam::DVec3;
use std::sync::Arc;

/// Word 0…255: an 8-bit sRGB value's linear value, as f32 bits (IEC 61966-2-1).
pub const SRGB_LUT: usize = 0;
/// The word holding where the triangles' texture coordinates start: six f32 per triangle
/// (u, v at each corner), in `Primitives::triangles` order.
pub const UV_BASE: usize = 256;
/// The word holding where the triangles' shading frames start (0: the scene has no normal
/// map and no mesh with normals): [`FRAME_WORDS`] f32 per triangle, the corners' normals
/// (3 × 3) then tangents (3 × 4, `w` the bitangent's sign), zero where unknown.
pub const FRAMES: usize = 257;
pub const FRAME_WORDS: usize = 21;
/// The word holding the number of materials; the next words hold each material's record
/// offset, or [`NONE`].
pub const MATERIALS: usize = 258;
pub const NONE: u32 = u32::MAX;

/// Record words: flags, the base colour, metallic-roughness and emissive maps' texture
/// headers, base factor (4), metallic, roughness, emissive factor (3), alpha cutoff, the
/// normal map's header ([`NORMAL_MAP`]) and scale, then each of the nine maps' texture
/// transform (six words from [`TRANSFORMS`]: the four above, then the extensions' five), then
/// the extensions' maps' headers ([`EXTENSION_MAPS`]: transmission, clearcoat, clearcoat
/// roughness, specular, specular colour).
pub const RECORD_WORDS: usize = 75;
/// The record word holding the first extension map's texture header.
pub const EXTENSION_MAPS: usize = 70;
/// The transform index of the first extension map.
pub const EXTENSION_TRANSFORMS: u32 = 4;
/// The record word holding the normal map's texture header (its scale follows).
pub const NORMAL_MAP: usize = 14;
/// The record word where the maps' texture transforms start.
pub const TRANSFORMS: usize = 16;
pub const FLAG_BASE: u32 = 1;
pub const FLAG_MR: u32 = 2;
pub const FLAG_EMISSIVE: u32 = 4;
pub const FLAG_NORMAL: u32 = 8;
/// The extensions' maps (bits 4–7 and 10; bits 8–9 are the alpha mode).
pub const FLAG_TRANSMISSION: u32 = 16;
pub const FLAG_CLEARCOAT: u32 = 32;
pub const FLAG_CLEARCOAT_ROUGHNESS: u32 = 64;
pub const FLAG_SPECULAR: u32 = 128;
pub const FLAG_SPECULAR_COLOR: u32 = 1024;
/// Bits 8–9 of the flags: 0 opaque, 1 mask (cut-out at the cutoff), 2 blend (a stochastic
/// cut-out).
pub const ALPHA_SHIFT: u32 = 8;
pub const ALPHA_MASK: u32 = 1;
pub const ALPHA_BLEND: u32 = 2;
/// Texture header words: width, height, wrap along u, wrap along v, first texel's word.
pub const TEXTURE_WORDS: usize = 5;

/// The sRGB transfer's inverse (IEC 61966-2-1), for the 256 8-bit values.
pub fn srgb_decode(v: u8) -> f32 {
    let c = v as f64 / 255.0;
    (if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }) as f32
}

/// Where things go in the words of a scene with textures or shading frames.
struct Layout<'a> {
    /// Each distinct textured material, with the first object's material that uses it (the
    /// preview edits a glTF material as one, so every object using it has the same).
    records: Vec<(&'a Arc<Textured>, &'a Material)>,
    textures: Vec<&'a Arc<Texture>>,
    headers_at: usize,
    records_at: usize,
    texels_at: usize,
    /// The triangles' shading frames are written: a normal map or a mesh with normals.
    frames: bool,
}

fn textured(m: &Material) -> Option<&Arc<Textured>> {
    m.textured
        .as_ref()
        .filter(|_| !m.is_dielectric())
        .map(|t| &t.0)
}

impl<'a> Layout<'a> {
    fn of(scene: &'a Scene) -> Option<Layout<'a>> {
        let mut records: Vec<(&Arc<Textured>, &Material)> = Vec::new();
        let mut textures: Vec<&Arc<Texture>> = Vec::new();
        for o in &scene.objects {
            let Some(t) = textured(&o.material) else {
                continue;
            };
            if records.iter().any(|(r, _)| Arc::ptr_eq(r, t)) {
                continue;
            }
            records.push((t, &o.material));
            let extensions = t.extensions.all().map(|m| m.as_ref().map(|(t, _)| t));
            for tex in [&t.base_color, &t.metallic_roughness, &t.emissive, &t.normal]
                .into_iter()
                .flatten()
                .chain(extensions.into_iter().flatten())
            {
                if !textures.iter().any(|x| Arc::ptr_eq(x, tex)) {
                    textures.push(tex);
                }
            }
        }
        let smooth = Features::of(scene).smooth_normals;
        if records.is_empty() && !smooth {
            return None;
        }
        let frames = smooth || records.iter().any(|(t, _)| t.normal.is_some());
        let headers_at = MATERIALS + 1 + scene.objects.len();
        let records_at = headers_at + TEXTURE_WORDS * textures.len();
        Some(Layout {
            texels_at: records_at + RECORD_WORDS * records.len(),
            frames,
            records,
            textures,
            headers_at,
            records_at,
        })
    }

    fn header(&self, tex: &Arc<Texture>) -> u32 {
        let k = self
            .textures
            .iter()
            .position(|x| Arc::ptr_eq(x, tex))
            .unwrap();
        (self.headers_at + TEXTURE_WORDS * k) as u32
    }

    /// The records: each glTF material's maps and factors, the factors taken from the
    /// model's material as it is now (so that the preview's keys edit a textured material
    /// too: colour keys tint its base colour map, light the emission; a pbr material's
    /// metallic and roughness are its own; a lecture material's lobes are its own, and its
    /// maps give it the colour alone).
    fn records(&self) -> Vec<u32> {
        let mut w = Vec::with_capacity(RECORD_WORDS * self.records.len());
        for (t, m) in &self.records {
            debug_assert_eq!(w.len() % RECORD_WORDS, 0);
            let mut flags = match t.alpha {
                AlphaMode::Opaque => 0,
                AlphaMode::Mask(_) => ALPHA_MASK << ALPHA_SHIFT,
                AlphaMode::Blend => ALPHA_BLEND << ALPHA_SHIFT,
            };
            let mut maps = [NONE; 3];
            for (k, (map, flag)) in [
                (&t.base_color, FLAG_BASE),
                (&t.metallic_roughness, FLAG_MR),
                (&t.emissive, FLAG_EMISSIVE),
            ]
            .into_iter()
            .enumerate()
            {
                if let Some(tex) = map {
                    flags |= flag;
                    maps[k] = self.header(tex);
                }
            }
            let (base, metallic, roughness, emissive) = if m.light > 0.0 {
                let e = m.color * m.light;
                (t.base_factor, t.metallic, t.roughness, e.to_array())
            } else if m.is_pbr() {
                let c = m.color;
                (
                    [c.x, c.y, c.z, t.base_factor[3]],
                    m.metallic,
                    m.roughness,
                    t.emissive_factor,
                )
            } else {
                // A lecture material keeps its own lobes: its maps give the colour alone, and
                // the metallic and roughness words are not read.
                let c = m.color;
                (
                    [c.x, c.y, c.z, t.base_factor[3]],
                    0.0,
                    0.0,
                    t.emissive_factor,
                )
            };
            let start = w.len();
            w.push(flags);
            w.extend(maps);
            w.extend(base.map(f32::to_bits));
            w.push(metallic.to_bits());
            w.push(roughness.to_bits());
            w.extend(emissive.map(f32::to_bits));
            let cutoff = match t.alpha {
                AlphaMode::Mask(c) => c,
                _ => 0.0,
            };
            let normal_map = match &t.normal {
                Some(tex) => {
                    flags |= FLAG_NORMAL;
                    self.header(tex)
                }
                None => NONE,
            };
            w[start] = flags;
            w.extend([cutoff.to_bits(), normal_map, t.normal_scale.to_bits()]);
            for t in &t.transforms {
                w.extend(t.map(f32::to_bits));
            }
            let maps = t.extensions.all();
            for m in maps {
                let xf = m.as_ref().map_or(IDENTITY_TRANSFORM, |(_, xf)| *xf);
                w.extend(xf.map(f32::to_bits));
            }
            let flags_of = [
                FLAG_TRANSMISSION,
                FLAG_CLEARCOAT,
                FLAG_CLEARCOAT_ROUGHNESS,
                FLAG_SPECULAR,
                FLAG_SPECULAR_COLOR,
            ];
            for (m, flag) in maps.into_iter().zip(flags_of) {
                match m {
                    Some((tex, _)) => {
                        w[start] |= flag;
                        w.push(self.header(tex));
                    }
                    None => w.push(NONE),
                }
            }
            debug_assert_eq!(w.len() - start, RECORD_WORDS);
        }
        w
    }
}

/// The record words alone and the word they start at: what an edit of a material changes
/// (the rest stays while the textured materials and the geometry do).
pub fn record_words(scene: &Scene) -> Option<(usize, Vec<u32>)> {
    let l = Layout::of(scene)?;
    Some((l.records_at, l.records()))
}

/// The scene's texture words, or `None` when no material has maps or a cut-out and no mesh
/// has normals. Layout: the sRGB table, `UV_BASE`, `FRAMES`, the material count and record
/// offsets, the texture headers, the records, the texels, the triangles' texture coordinates
/// (where there are records) and their shading frames (where needed).
pub fn words(scene: &Scene) -> Option<Vec<u32>> {
    let l = Layout::of(scene)?;
    let mut w: Vec<u32> = (0..=255u8).map(|v| srgb_decode(v).to_bits()).collect();
    w.push(0); // UV_BASE, set below
    w.push(0); // FRAMES, set below where needed
    w.push(scene.objects.len() as u32);
    for o in &scene.objects {
        w.push(match textured(&o.material) {
            Some(t) => {
                let k = l
                    .records
                    .iter()
                    .position(|(r, _)| Arc::ptr_eq(r, t))
                    .unwrap();
                (l.records_at + RECORD_WORDS * k) as u32
            }
            None => NONE,
        });
    }
    let mut next_texel = l.texels_at;
    for tex in &l.textures {
        w.extend([
            tex.width,
            tex.height,
            tex.wrap[0] as u32,
            tex.wrap[1] as u32,
            next_texel as u32,
        ]);
        next_texel += tex.texels.len();
    }
    w.extend(l.records());
    debug_assert_eq!(w.len(), l.texels_at);
    for tex in &l.textures {
        w.extend_from_slice(&tex.texels);
    }
    w[UV_BASE] = w.len() as u32;
    // Read only at a textured material's hits.
    if !l.records.is_empty() {
        for o in scene.triangle_order() {
            if let Shape::Mesh { mesh, .. } = &o.shape {
                for k in 0..mesh.triangles.len() {
                    let uv = mesh.uvs.get(k).copied().unwrap_or([[0.0; 2]; 3]);
                    w.extend(uv.iter().flatten().map(|x| x.to_bits()));
                }
            }
        }
    }
    if l.frames {
        w[FRAMES] = w.len() as u32;
        for o in scene.triangle_order() {
            frames(&o.shape, &mut w);
        }
    }
    Some(w)
}

/// A mesh's shading frames, its own transform applied (not an instanced one's) (normals by the inverse transpose,
/// tangents by the matrix, the bitangent's sign turned over by a mirroring scale), appended
/// to `w`: [`FRAME_WORDS`] per triangle, zero where the mesh has none.
fn frames(shape: &Shape, w: &mut Vec<u32>) {
    let Shape::Mesh {
        mesh,
        rotation,
        scale,
        instances,
        ..
    } = shape
    else {
        return;
    };
    // An instanced mesh's frames stay in its coordinates (the tracers transform them).
    let (rotation, scale) = if instances.is_empty() {
        (rotation, scale)
    } else {
        (&DVec3::ZERO, &DVec3::ONE)
    };
    let r = euler_xyz(*rotation);
    let flip = if scale.x * scale.y * scale.z < 0.0 {
        -1.0
    } else {
        1.0
    };
    let unit = |v: DVec3| v.normalize_or_zero().as_vec3().to_array();
    let identity = *rotation == DVec3::ZERO && *scale == DVec3::ONE;
    for k in 0..mesh.triangles.len() {
        // A smooth-shaded mesh has normals without tangents (no normal map needs them).
        let n = mesh.normals.get(k).copied().unwrap_or([[0.0; 3]; 3]);
        let t = mesh.tangents.get(k).copied().unwrap_or([[0.0; 4]; 3]);
        for c in n {
            let c = if identity {
                c
            } else {
                unit(r * (DVec3::from(c.map(f64::from)) / *scale))
            };
            w.extend(c.map(f32::to_bits));
        }
        for c in t {
            let c = if identity || c == [0.0; 4] {
                c
            } else {
                let [x, y, z] =
                    unit(r * (DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * *scale));
                [x, y, z, c[3] * flip]
            };
            w.extend(c.map(f32::to_bits));
        }
    }
}

/// Per object, the address of its textured material as the words use it (0: none): while
/// it is the same (and the geometry), only the records can have changed.
pub fn material_key(scene: &Scene) -> Vec<usize> {
    scene
        .objects
        .iter()
        .map(|o| textured(&o.material).map_or(0, |t| Arc::as_ptr(t) as usize))
        .collect()
}

/// How many words [`words`] makes for `scene` (0: none), without making them.
pub fn word_count(scene: &Scene) -> usize {
    let Some(l) = Layout::of(scene) else {
        return 0;
    };
    let triangles: usize = scene
        .objects
        .iter()
        .map(|o| match &o.shape {
            Shape::Mesh { mesh, .. } => mesh.triangles.len(),
            _ => 0,
        })
        .sum();
    let uvs = if l.records.is_empty() { 0 } else { 6 };
    l.texels_at
        + l.textures.iter().map(|t| t.texels.len()).sum::<usize>()
        + triangles * (uvs + if l.frames { FRAME_WORDS } else { 0 })
}

/// Why `scene`'s texture words cannot be bound where one storage buffer holds at most
/// `limit` bytes: their size, and the largest images, by name. `None` when they fit.
pub fn too_large(scene: &Scene, limit: u64) -> Option<String> {
    let bytes = 4 * word_count(scene) as u64;
    if bytes <= limit {
        return None;
    }
    let l = Layout::of(scene)?;
    let mut textures = l.textures.clone();
    textures.sort_by_key(|t| std::cmp::Reverse(t.texels.len()));
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    let largest: Vec<String> = textures
        .iter()
        .take(3)
        .map(|t| {
            format!(
                "{} ({}×{}, {:.1} MiB)",
                t.name,
                t.width,
                t.height,
                mib(t.bytes() as u64)
            )
        })
        .collect();
    Some(format!(
        "the scene's textures take {:.1} MiB in one storage buffer, more than the {:.1} MiB \
         this adapter binds; the largest: {}. Use smaller images, or trace on the CPU \
         (the adapter `cpu-native`), which has no such limit",
        mib(bytes),
        mib(limit),
        largest.join(", ")
    ))
}
