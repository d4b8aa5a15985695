//! Textures on the CPU: shaders/common/texture.wgsl in Rust, term for term, reading the same
//! words (`common::textures`): bilinear sampling with wrap modes, the glTF material mapped
//! onto the model's at a hit, tangent-space normal maps, and alpha cut-outs.

use super::intersect::{Ray, Triangle, triangle_barycentrics};
use super::sampling::normalize_or;
use super::scene::Material;
use crate::common::textures::{
    ALPHA_SHIFT, EXTENSION_MAPS, EXTENSION_TRANSFORMS, FLAG_BASE, FLAG_CLEARCOAT,
    FLAG_CLEARCOAT_ROUGHNESS, FLAG_EMISSIVE, FLAG_MR, FLAG_NORMAL, FLAG_SPECULAR,
    FLAG_SPECULAR_COLOR, FLAG_TRANSMISSION, FRAME_WORDS, FRAMES, MATERIALS, NONE, NORMAL_MAP,
    SRGB_LUT, TRANSFORMS, UV_BASE,
};
use glam::{Vec2, Vec3A, Vec4};

/// Coordinates are clamped to this before texel arithmetic (texture.wgsl: TEX_UV_LIMIT).
pub(super) const UV_LIMIT: f32 = 1048576.0;
/// The least tangent-space z a normal map's normal keeps (texture.wgsl: TEX_NORMAL_MIN_Z).
const NORMAL_MIN_Z: f32 = 0.01;

/// How a texel's bytes are read (texture.wgsl: TEX_UNORM, TEX_SRGB, TEX_SNORM).
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Decode {
    /// b / 255.
    Unorm,
    /// The colour sRGB-decoded, alpha b / 255.
    Srgb,
    /// max((b − 128) / 127, −1): 128 is exactly zero (normal maps).
    Snorm,
}

#[inline(always)]
fn f(tex: &[u32], i: u32) -> f32 {
    f32::from_bits(tex[i as usize])
}

fn wrap(i: i32, n: i32, mode: u32) -> i32 {
    match mode {
        1 => i.clamp(0, n - 1),
        2 => {
            let p = 2 * n;
            let k = i.rem_euclid(p);
            if k >= n { p - 1 - k } else { k }
        }
        _ => i.rem_euclid(n),
    }
}

/// Index `i` brought into [0, n): itself when it is already there (most lookups), else by
/// the wrap mode.
#[inline(always)]
fn wrapped(i: i32, n: i32, mode: u32) -> i32 {
    if (0..n).contains(&i) {
        i
    } else {
        wrap(i, n, mode)
    }
}

/// One texel's value (texture.wgsl: tex_texel), by its word.
#[inline(always)]
fn decode(tex: &[u32], word: u32, mode: Decode) -> Vec4 {
    let b = [
        word & 0xff,
        (word >> 8) & 0xff,
        (word >> 16) & 0xff,
        word >> 24,
    ];
    match mode {
        Decode::Srgb => {
            let d = |c: u32| f(tex, SRGB_LUT as u32 + c);
            Vec4::new(d(b[0]), d(b[1]), d(b[2]), b[3] as f32 / 255.0)
        }
        Decode::Snorm => {
            let s = b.map(|c| c as i32 - 128);
            (Vec4::new(s[0] as f32, s[1] as f32, s[2] as f32, s[3] as f32) / 127.0)
                .max(Vec4::splat(-1.0))
        }
        Decode::Unorm => Vec4::new(b[0] as f32, b[1] as f32, b[2] as f32, b[3] as f32) / 255.0,
    }
}

/// Bilinear filtering, texel centres at half-integers (texture.wgsl: tex_sample); the four
/// texels' indices are wrapped once per axis (the same indices texture.wgsl computes per
/// texel).
pub fn sample(tex: &[u32], h: u32, uv: Vec2, mode: Decode) -> Vec4 {
    let h = h as usize;
    let (w, ht) = (tex[h] as i32, tex[h + 1] as i32);
    let uv = uv.clamp(Vec2::splat(-UV_LIMIT), Vec2::splat(UV_LIMIT));
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * ht as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i32, y0 as i32);
    let (mu, mv) = (tex[h + 2], tex[h + 3]);
    let (xa, xb) = (wrapped(ix, w, mu), wrapped(ix + 1, w, mu));
    let (ya, yb) = (wrapped(iy, ht, mv), wrapped(iy + 1, ht, mv));
    let base = tex[h + 4] as usize;
    let at = |x: i32, y: i32| decode(tex, tex[base + (y * w + x) as usize], mode);
    let (t00, t10, t01, t11) = (at(xa, ya), at(xb, ya), at(xa, yb), at(xb, yb));
    let top = t00 + (t10 - t00) * fx;
    let bottom = t01 + (t11 - t01) * fx;
    top + (bottom - top) * fy
}

/// The record of material `material`, or `None`.
#[inline(always)]
pub fn record(tex: &[u32], material: u32) -> Option<u32> {
    let r = tex[MATERIALS + 1 + material as usize];
    (r != NONE).then_some(r)
}

/// Whether record `rec`'s material may emit: its emissive factor is not black (the lanes,
/// which trace no emitter of a texture, ask).
pub fn may_emit(tex: &[u32], rec: u32) -> bool {
    (10..13).any(|k| f(tex, rec + k) != 0.0)
}

/// The texture coordinates at `p` on triangle `index` (texture.wgsl: tex_uv).
pub fn uv(tex: &[u32], tri: &Triangle, index: u32, p_world: Vec3A) -> Vec2 {
    uv_at(tex, index, triangle_barycentrics(tri, p_world - tri.v0))
}

/// The texture coordinates on triangle `index` at barycentrics `(b1, b2)` (texture.wgsl:
/// tex_uv_at).
pub fn uv_at(tex: &[u32], index: u32, (b1, b2): (f32, f32)) -> Vec2 {
    let at = tex[UV_BASE] + 6 * index;
    let c = |k: u32| Vec2::new(f(tex, at + k), f(tex, at + k + 1));
    let (uv0, uv1, uv2) = (c(0), c(2), c(4));
    let uv = uv0 + b1 * (uv1 - uv0) + b2 * (uv2 - uv0);
    Vec2::new(
        if uv.x.is_finite() { uv.x } else { 0.0 },
        if uv.y.is_finite() { uv.y } else { 0.0 },
    )
}

/// Map k's coordinates through its texture transform (texture.wgsl: tex_xform).
fn xform(tex: &[u32], rec: u32, k: u32, uv: Vec2) -> Vec2 {
    let m = rec + TRANSFORMS as u32 + 6 * k;
    Vec2::new(
        f(tex, m) * uv.x + f(tex, m + 1) * uv.y + f(tex, m + 2),
        f(tex, m + 3) * uv.x + f(tex, m + 4) * uv.y + f(tex, m + 5),
    )
}

/// The material at a hit (texture.wgsl: tex_material).
pub fn material(tex: &[u32], m: &Material, rec: u32, uv: Vec2) -> Material {
    let flags = tex[rec as usize];
    let mut base = Vec4::new(
        f(tex, rec + 4),
        f(tex, rec + 5),
        f(tex, rec + 6),
        f(tex, rec + 7),
    );
    if flags & FLAG_BASE != 0 {
        base *= sample(
            tex,
            tex[rec as usize + 1],
            xform(tex, rec, 0, uv),
            Decode::Srgb,
        );
    }
    let mut e = Vec3A::new(f(tex, rec + 10), f(tex, rec + 11), f(tex, rec + 12));
    if flags & FLAG_EMISSIVE != 0 {
        e *= Vec3A::from(
            sample(
                tex,
                tex[rec as usize + 3],
                xform(tex, rec, 2, uv),
                Decode::Srgb,
            )
            .truncate(),
        );
    }
    let mut out = *m;
    let light = e.x.max(e.y).max(e.z);
    if light > 0.0 {
        out.color = e / light;
        out.light = light;
        return out;
    }
    out.light = 0.0;
    let base = Vec3A::from(base.truncate());
    if m.pbr {
        // The metallic-roughness map: a pbr material's alone (an emitter's or a lecture
        // material's is not read).
        let mut metallic = f(tex, rec + 8);
        let mut roughness = f(tex, rec + 9);
        if flags & FLAG_MR != 0 {
            let mr = sample(
                tex,
                tex[rec as usize + 2],
                xform(tex, rec, 1, uv),
                Decode::Unorm,
            );
            roughness *= mr.y;
            metallic *= mr.z;
        }
        out.color = base;
        out.metallic = metallic;
        out.roughness = roughness;
        // The material extensions' maps, each times the material's factor.
        if flags & FLAG_TRANSMISSION != 0 {
            out.transmission *= extension_map(tex, rec, 0, uv, Decode::Unorm).x;
        }
        if flags & FLAG_CLEARCOAT != 0 {
            out.clearcoat *= extension_map(tex, rec, 1, uv, Decode::Unorm).x;
        }
        if flags & FLAG_CLEARCOAT_ROUGHNESS != 0 {
            out.clearcoat_roughness *= extension_map(tex, rec, 2, uv, Decode::Unorm).y;
        }
        if flags & FLAG_SPECULAR != 0 {
            out.specular *= extension_map(tex, rec, 3, uv, Decode::Unorm).w;
        }
        if flags & FLAG_SPECULAR_COLOR != 0 {
            out.specular_color *=
                Vec3A::from(extension_map(tex, rec, 4, uv, Decode::Srgb).truncate());
        }
        return out;
    }
    // A lecture material keeps its own lobes (`specular`, `smoothness`, …, as the user set
    // them); its maps give the colour alone.
    out.color = base;
    out
}

/// Extension map `k` of record `rec` (transmission, clearcoat, clearcoat roughness, specular,
/// specular colour) at `uv`, through its transform (texture.wgsl: tex_extension_map).
fn extension_map(tex: &[u32], rec: u32, k: u32, uv: Vec2, decode: Decode) -> Vec4 {
    let h = tex[rec as usize + EXTENSION_MAPS + k as usize];
    sample(
        tex,
        h,
        xform(tex, rec, EXTENSION_TRANSFORMS + k, uv),
        decode,
    )
}

/// Whether a hit at `t` on triangle `index` falls through a cut-out (texture.wgsl:
/// tex_cut_out).
pub fn cut_out(tex: &[u32], tri: &Triangle, index: u32, ray: &Ray, t: f32) -> bool {
    let Some(rec) = record(tex, tri.material) else {
        return false;
    };
    let flags = tex[rec as usize];
    let mode = (flags >> ALPHA_SHIFT) & 3;
    if mode == 0 {
        return false;
    }
    let mut alpha = f(tex, rec + 7);
    if flags & FLAG_BASE != 0 {
        let uv = xform(tex, rec, 0, uv(tex, tri, index, ray.origin + t * ray.dir));
        alpha *= sample(tex, tex[rec as usize + 1], uv, Decode::Unorm).w;
    }
    if mode == 1 {
        return alpha < f(tex, rec + 13);
    }
    let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
    let bits = |a: f32, b: f32| a.to_bits() ^ b.to_bits();
    let h = super::rng::hash3([
        bits(o[0], d[0]),
        bits(o[1], d[1]),
        bits(o[2], d[2]).wrapping_add(index),
    ]);
    super::rng::unit(h) >= alpha
}

/// Whether the words hold the triangles' shading frames (texture.wgsl: tex_has_frames).
#[inline(always)]
pub fn has_frames(tex: &[u32]) -> bool {
    tex.len() > MATERIALS && tex[FRAMES] != 0
}

/// The file's normals of triangle `index` interpolated at barycentrics `(b1, b2)`, or `n_geo`
/// where there are none (texture.wgsl: tex_smooth_normal, term for term).
pub fn smooth_normal(tex: &[u32], index: u32, (b1, b2): (f32, f32), n_geo: Vec3A) -> Vec3A {
    let at = tex[FRAMES] + FRAME_WORDS as u32 * index;
    let v3 = |k: u32| Vec3A::new(f(tex, at + k), f(tex, at + k + 1), f(tex, at + k + 2));
    let n0 = v3(0);
    normalize_or(n0 + b1 * (v3(3) - n0) + b2 * (v3(6) - n0), n_geo)
}

/// Whether the material of record `rec` has a normal map.
#[inline(always)]
pub fn has_normal_map(tex: &[u32], rec: u32) -> bool {
    tex[rec as usize] & FLAG_NORMAL != 0
}

/// The shading normal at barycentrics `(b1, b2)` of triangle `index` (texture.wgsl:
/// tex_shading_normal, term for term): the interpolated frame, made orthonormal, and the map's
/// normal taken into it.
pub fn shading_normal(
    tex: &[u32],
    rec: u32,
    index: u32,
    (b1, b2): (f32, f32),
    uv: Vec2,
    n_geo: Vec3A,
) -> Vec3A {
    let n = smooth_normal(tex, index, (b1, b2), n_geo);
    perturbed(tex, rec, uv, n, tangent(tex, index, (b1, b2)))
}

/// The corners' tangents of triangle `index` interpolated at `(b1, b2)`, and the bitangent's
/// sign (texture.wgsl's `tex_tangent`).
#[inline(always)]
pub fn tangent(tex: &[u32], index: u32, (b1, b2): (f32, f32)) -> (Vec3A, f32) {
    let at = tex[FRAMES] + FRAME_WORDS as u32 * index;
    let v3 = |k: u32| Vec3A::new(f(tex, at + k), f(tex, at + k + 1), f(tex, at + k + 2));
    let t0 = v3(9);
    let t = t0 + b1 * (v3(13) - t0) + b2 * (v3(17) - t0);
    (t, if f(tex, at + 12) < 0.0 { -1.0 } else { 1.0 })
}

/// The normal map of record `rec` read at `uv`, taken into the frame of `n` and the tangent
/// `(t, w)` (texture.wgsl's `tex_perturbed`).
#[inline(always)]
pub fn perturbed(tex: &[u32], rec: u32, uv: Vec2, n: Vec3A, (t, w): (Vec3A, f32)) -> Vec3A {
    let mut t = t;
    t -= n * n.dot(t);
    let other = if n.x.abs() > 0.9 { Vec3A::Y } else { Vec3A::X };
    t = normalize_or(t, other.cross(n).normalize());
    let bt = n.cross(t) * w;
    let r = rec + NORMAL_MAP as u32;
    let s = sample(tex, tex[r as usize], xform(tex, rec, 3, uv), Decode::Snorm);
    let scale = f(tex, r + 1);
    let d = (s.x * scale * t + s.y * scale * bt) / s.z.max(NORMAL_MIN_Z);
    if d == Vec3A::ZERO {
        return n;
    }
    normalize_or(n + d, n)
}
