//! The texture words both tracers read (`shaders/common/texture.wgsl`, `cpu::texture`): one
//! array of u32 holding the sRGB decoding table, each triangle's texture coordinates, a
//! record per textured material (its maps and glTF factors) and the texels, RGBA8. One
//! storage buffer, so that every adapter binds it (lavapipe and llvmpipe included); a scene
//! without textures uploads one word and compiles none of the code that reads them.

use crate::scene::texture::{AlphaMode, Texture, Textured};
use crate::scene::{Scene, Shape};
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
/// roughness, emissive factor (3), alpha cutoff, and two words of padding.
pub const RECORD_WORDS: usize = 16;
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

/// The scene's texture words, or `None` when no material has maps or a cut-out. Layout:
/// the sRGB table, `UV_BASE`, the material count and record offsets, the texture headers,
/// the records, the texels, and the triangles' texture coordinates.
pub fn words(scene: &Scene) -> Option<Vec<u32>> {
    fn textured(m: &crate::scene::Material) -> Option<&Arc<Textured>> {
        m.textured
            .as_ref()
            .filter(|_| !m.is_dielectric())
            .map(|t| &t.0)
    }
    // The distinct textured materials and textures, in order of first use.
    let mut records: Vec<&Arc<Textured>> = Vec::new();
    let mut textures: Vec<&Arc<Texture>> = Vec::new();
    for o in &scene.objects {
        let Some(t) = textured(&o.material) else {
            continue;
        };
        if records.iter().any(|r| Arc::ptr_eq(r, t)) {
            continue;
        }
        records.push(t);
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
    let texels_at = records_at + RECORD_WORDS * records.len();
    let mut w: Vec<u32> = (0..=255u8).map(|v| srgb_decode(v).to_bits()).collect();
    w.push(0); // UV_BASE, set below
    w.push(scene.objects.len() as u32);
    for o in &scene.objects {
        w.push(match textured(&o.material) {
            Some(t) => {
                let k = records.iter().position(|r| Arc::ptr_eq(r, t)).unwrap();
                (records_at + RECORD_WORDS * k) as u32
            }
            None => NONE,
        });
    }
    let mut next_texel = texels_at;
    for tex in &textures {
        w.extend([
            tex.width,
            tex.height,
            tex.wrap[0] as u32,
            tex.wrap[1] as u32,
            next_texel as u32,
        ]);
        next_texel += tex.texels.len();
    }
    let header = |tex: &Arc<Texture>| {
        let k = textures.iter().position(|x| Arc::ptr_eq(x, tex)).unwrap();
        (headers_at + TEXTURE_WORDS * k) as u32
    };
    for t in &records {
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
                maps[k] = header(tex);
            }
        }
        w.push(flags);
        w.extend(maps);
        w.extend(t.base_factor.map(f32::to_bits));
        w.push(t.metallic.to_bits());
        w.push(t.roughness.to_bits());
        w.extend(t.emissive_factor.map(f32::to_bits));
        let cutoff = match t.alpha {
            AlphaMode::Mask(c) => c,
            _ => 0.0,
        };
        w.extend([cutoff.to_bits(), 0, 0]);
    }
    debug_assert_eq!(w.len(), texels_at);
    for tex in &textures {
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
