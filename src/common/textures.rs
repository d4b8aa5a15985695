//! The texture words both tracers read (`shaders/common/texture.wgsl`, `cpu::texture`): one
//! array of u32 holding the sRGB decoding table, each triangle's texture coordinates, a
//! record per textured material (its maps and glTF factors) and the texels, RGBA8. One
//! storage buffer, so that every adapter binds it (lavapipe and llvmpipe included); a scene
//! without textures uploads one word and compiles none of the code that reads them.

use crate::scene::gltf::DIELECTRIC_F0;
use crate::scene::texture::{AlphaMode, Texture, Textured};
use crate::scene::{Material, Scene, Shape};
use std::sync::Arc;

/// Word 0…255: an 8-bit sRGB value's linear value, as f32 bits (IEC 61966-2-1).
pub const SRGB_LUT: usize = 0;
/// The word holding where the triangles' texture coordinates start: six f32 per triangle
/// (u, v at each corner), in `Primitives::triangles` order.
pub const UV_BASE: usize = 256;
/// The word holding the number of materials; the next words hold each material's record
/// offset, or [`NONE`].
pub const MATERIALS: usize = 257;
pub const NONE: u32 = u32::MAX;

/// Record words: flags, the three maps' texture headers, base factor (4), metallic,
/// roughness, emissive factor (3), alpha cutoff, two words of padding, then each map's
/// texture transform (six words from [`TRANSFORMS`]).
pub const RECORD_WORDS: usize = 34;
/// The record word where the maps' texture transforms start.
pub const TRANSFORMS: usize = 16;
pub const FLAG_BASE: u32 = 1;
pub const FLAG_MR: u32 = 2;
pub const FLAG_EMISSIVE: u32 = 4;
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

/// Where things go in the words of a scene with textures.
struct Layout<'a> {
    /// Each distinct textured material, with the first object's material that uses it (the
    /// preview edits a glTF material as one, so every object using it has the same).
    records: Vec<(&'a Arc<Textured>, &'a Material)>,
    textures: Vec<&'a Arc<Texture>>,
    headers_at: usize,
    records_at: usize,
    texels_at: usize,
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
            for tex in [&t.base_color, &t.metallic_roughness, &t.emissive]
                .into_iter()
                .flatten()
            {
                if !textures.iter().any(|x| Arc::ptr_eq(x, tex)) {
                    textures.push(tex);
                }
            }
        }
        if records.is_empty() {
            return None;
        }
        let headers_at = MATERIALS + 1 + scene.objects.len();
        let records_at = headers_at + TEXTURE_WORDS * textures.len();
        Some(Layout {
            texels_at: records_at + RECORD_WORDS * records.len(),
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
    /// too: colour keys tint its base colour map, `specular` is the metallic share, fuzz the
    /// roughness, light the emission), the inverse of `scene::gltf::material`.
    fn records(&self) -> Vec<u32> {
        let mut w = Vec::with_capacity(RECORD_WORDS * self.records.len());
        for (t, m) in &self.records {
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
            } else {
                let c = m.color;
                let metallic =
                    ((m.specular - DIELECTRIC_F0) / (1.0 - DIELECTRIC_F0)).clamp(0.0, 1.0);
                (
                    [c.x, c.y, c.z, t.base_factor[3]],
                    metallic,
                    m.absorption,
                    t.emissive_factor,
                )
            };
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
            w.extend([cutoff.to_bits(), 0, 0]);
            for t in &t.transforms {
                w.extend(t.map(f32::to_bits));
            }
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

/// The scene's texture words, or `None` when no material has maps or a cut-out. Layout:
/// the sRGB table, `UV_BASE`, the material count and record offsets, the texture headers,
/// the records, the texels, and the triangles' texture coordinates.
pub fn words(scene: &Scene) -> Option<Vec<u32>> {
    let l = Layout::of(scene)?;
    let mut w: Vec<u32> = (0..=255u8).map(|v| srgb_decode(v).to_bits()).collect();
    w.push(0); // UV_BASE, set below
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
    for o in &scene.objects {
        if let Shape::Mesh { mesh, .. } = &o.shape {
            for k in 0..mesh.triangles.len() {
                let uv = mesh.uvs.get(k).copied().unwrap_or([[0.0; 2]; 3]);
                w.extend(uv.iter().flatten().map(|x| x.to_bits()));
            }
        }
    }
    Some(w)
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
