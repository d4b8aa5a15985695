//! What a walk's rays met on triangles, in lanes: `Tracer::met` for a triangle hit (the
//! point, the face's normal, the material, a base-colour texture's bilinear lookup, the
//! file's normals interpolated), gathered from the scalar tracer's own tables and computed
//! operation for operation as `intersect` and `texture` compute it, so that each lane's
//! values are the scalar ones bit for bit (tested with the paths,
//! `lanes_trace_the_scalar_paths_bit_for_bit`). A hit these lanes do not cover (a normal
//! map, a texel past the texture's edge, coordinates that are not finite) is left to
//! `Tracer::met`.

use super::map::floor;
use crate::common::textures::{
    FLAG_BASE, FLAG_NORMAL, FRAME_WORDS, FRAMES, MATERIALS, NONE, SRGB_LUT, TRANSFORMS, UV_BASE,
};
use crate::cpu::intersect::Triangle;
use crate::cpu::scene::CpuScene;
use crate::cpu::simd::{F, I, Isa, M, MAX_LANES, Make, V3, cross, dot, normalize, normalize_or};
use crate::cpu::texture::UV_LIMIT;
use std::arch::x86_64::_CMP_UNORD_Q;

/// What a walk's rays met, in lanes (`Tracer::met`'s): the material, the point, the
/// geometric normal (outward), the colour there and the shading normal on the rays' side.
pub(super) struct Met<S: Isa> {
    pub(super) material: I<S>,
    pub(super) position: V3<S>,
    pub(super) normal: V3<S>,
    pub(super) color: V3<S>,
    pub(super) shading: V3<S>,
}

/// Words of a `Triangle` (repr(C)): v0, e1 and e2 at words 0, 4 and 8, the material at 12.
const TRIANGLE_WORDS: i32 = (size_of::<Triangle>() / 4) as i32;

/// The scalar tracer's tables a triangle's surface reads.
pub(super) struct Triangles<'a> {
    triangles: &'a [Triangle],
    tex: &'a [u32],
    /// Per material of the scene, its colour's components (as bits), where no texture
    /// gives it.
    color: [Vec<u32>; 3],
    /// Per material, its row of the lanes' tables (`Walk::rows`).
    rows: Vec<u32>,
    /// The file's normals are interpolated (`Tracer::shading_normal_at`).
    smooth: bool,
    normal_maps: bool,
}

impl<'a> Triangles<'a> {
    pub(super) fn of(s: &'a CpuScene, rows: &[i32]) -> Option<Triangles<'a>> {
        if s.triangles.is_empty() {
            return None;
        }
        let has_frames = crate::cpu::texture::has_frames(&s.tex);
        Some(Triangles {
            triangles: &s.triangles,
            tex: &s.tex,
            color: std::array::from_fn(|c| {
                s.materials.iter().map(|m| m.color[c].to_bits()).collect()
            }),
            rows: rows.iter().map(|&r| r as u32).collect(),
            smooth: s.smooth_normals && has_frames,
            normal_maps: s.normal_maps,
        })
    }

    /// Word `w` (0 to 15) of the triangles `i`.
    #[inline(always)]
    fn word<S: Isa>(&self, s: S, i: I<S>, w: i32) -> I<S> {
        // SAFETY: `i` are the lanes' triangle indices, all within `triangles`, and words 0
        // to 2, 4 to 6, 8 to 10 and 12 of a `Triangle` are its fields' (repr(C)).
        unsafe {
            I::gather_from(
                self.triangles.as_ptr().cast(),
                i * s.int(TRIANGLE_WORDS) + s.int(w),
            )
        }
    }

    #[inline(always)]
    fn vector<S: Isa>(&self, s: S, i: I<S>, w: i32) -> V3<S> {
        each!(|c| self.word(s, i, w + c as i32).float_of_bits())
    }

    /// Texture word `w` of the lanes, as a float.
    #[inline(always)]
    fn f<S: Isa>(&self, w: I<S>) -> F<S> {
        I::gather(self.tex, w).float_of_bits()
    }

    /// The surfaces of the rays (o, d) at distances `t` on triangles `i` (reference indices,
    /// the kind bits cleared), in the lanes of `lanes`: what `Tracer::met` gives there, and
    /// the lanes it could not be computed in (left to it).
    #[inline(always)]
    pub(super) fn met<S: Isa>(
        &self,
        s: S,
        (o, d): (V3<S>, V3<S>),
        t: F<S>,
        i: I<S>,
        lanes: M<S>,
    ) -> (Met<S>, M<S>) {
        let zero = s.zero();
        let i = i.blend(s.int(0), !lanes);
        let (v0, e1, e2) = (
            self.vector(s, i, 0),
            self.vector(s, i, 4),
            self.vector(s, i, 8),
        );
        let material = self.word(s, i, 12);
        // `triangle_surface`: the point in the triangle's plane (a sliver's: the ray's own).
        let p: V3<S> = each!(|c| o[c] + t * d[c]);
        let q: V3<S> = each!(|c| p[c] - v0[c]);
        let (v, w, on) = plane_barycentrics(s, (e1, e2), q);
        let position: V3<S> = each!(|c| ((v0[c] + v * e1[c]) + w * e2[c]).blend(p[c], !on));
        let normal = normalize(cross(e1, e2));
        // `triangle_barycentrics` of that point: where the corners' attributes are read.
        let q: V3<S> = each!(|c| position[c] - v0[c]);
        let (b1, b2, on) = plane_barycentrics(s, (e1, e2), q);
        let third = s.splat(1.0 / 3.0);
        let (b1, b2) = (b1.blend(third, !on), b2.blend(third, !on));
        let mut slow = s.mask(0);
        // A material the same in every lane (a model of one material, most often): its
        // words read once, not gathered.
        let mut mats = [0; MAX_LANES];
        material.store(&mut mats);
        let first = mats[lanes.bits().trailing_zeros() as usize];
        let one = (!lanes.without(material.eq(s.int(first))).any()).then_some(first as u32);
        let mut color: V3<S> = match one {
            Some(m) => each!(|c| s.splat(f32::from_bits(self.color[c][m as usize]))),
            None => each!(|c| I::gather(&self.color[c], material).float_of_bits()),
        };
        if !self.tex.is_empty() {
            let at = (
                one.map(|m| MATERIALS as u32 + 1 + m),
                material + s.int(MATERIALS as i32 + 1),
            );
            let rec = self.base(s, at, 0);
            let textured = lanes.without(rec.1.eq(s.int(NONE as i32)));
            if textured.any() {
                let rec = (rec.0, rec.1.blend(s.int(0), !textured));
                let flags = self.words(s, rec, 0);
                let uv = self.uv(s, i, (b1, b2));
                let factor: V3<S> = each!(|c| self.words(s, rec, 4 + c as i32).float_of_bits());
                let mut base = factor;
                let sampled = textured
                    & flags
                        .and(s.int(FLAG_BASE as i32))
                        .eq(s.int(FLAG_BASE as i32));
                if sampled.any() {
                    let (texel, off) = self.base_colour(s, rec, uv, sampled);
                    slow = slow | off;
                    base = each!(|c| (factor[c] * texel[c]).blend(factor[c], !sampled));
                }
                if self.normal_maps {
                    let mapped = flags
                        .and(s.int(FLAG_NORMAL as i32))
                        .eq(s.int(FLAG_NORMAL as i32));
                    slow = slow | (textured & mapped);
                }
                color = each!(|c| color[c].blend(base[c], textured));
            }
        }
        let facing = dot(d, normal).lt(zero);
        let n: V3<S> = each!(|c| normal[c].blend(-normal[c], !facing));
        let shading = if self.smooth {
            let at = self.tex_word(s, FRAMES) + i * s.int(FRAME_WORDS as i32);
            let (n0, n1, n2) = (
                self.tex_vector(s, at),
                self.tex_vector(s, at + s.int(3)),
                self.tex_vector(s, at + s.int(6)),
            );
            let v: V3<S> = each!(|c| (n0[c] + b1 * (n1[c] - n0[c])) + b2 * (n2[c] - n0[c]));
            let ns = normalize_or(s, v, normal);
            let away = dot(ns, n).lt(zero);
            each!(|c| ns[c].blend(-ns[c], away))
        } else {
            n
        };
        let met = Met {
            material: match one {
                Some(m) => s.int(self.rows[m as usize] as i32),
                None => I::gather(&self.rows, material),
            },
            position,
            normal,
            color,
            shading,
        };
        (met, slow & lanes)
    }

    /// Texture words `at` + k of the lanes: read once where `at` is the same in every lane
    /// (`one`, its value), else gathered.
    #[inline(always)]
    fn words<S: Isa>(&self, s: S, (one, at): (Option<u32>, I<S>), k: i32) -> I<S> {
        match one {
            Some(w) => s.int(self.tex[(w as i32 + k) as usize] as i32),
            None => I::gather(self.tex, at + s.int(k)),
        }
    }

    /// Texture words `at` + k as the start of further reads (`words`): the word where `at` is
    /// the same in every lane, and the lanes' words.
    #[inline(always)]
    fn base<S: Isa>(&self, s: S, at: (Option<u32>, I<S>), k: i32) -> (Option<u32>, I<S>) {
        match at.0 {
            Some(w) => {
                let word = self.tex[(w as i32 + k) as usize];
                (Some(word), s.int(word as i32))
            }
            None => (None, I::gather(self.tex, at.1 + s.int(k))),
        }
    }

    /// Texture words `at` to `at` + 2, as floats.
    #[inline(always)]
    fn tex_vector<S: Isa>(&self, s: S, at: I<S>) -> V3<S> {
        each!(|c| self.f(at + s.int(c as i32)))
    }

    /// Texture word `w`, in every lane.
    #[inline(always)]
    fn tex_word<S: Isa>(&self, s: S, w: usize) -> I<S> {
        s.int(self.tex[w] as i32)
    }

    /// `texture::uv_at` of triangles `i` at barycentrics (b1, b2).
    #[inline(always)]
    fn uv<S: Isa>(&self, s: S, i: I<S>, (b1, b2): (F<S>, F<S>)) -> (F<S>, F<S>) {
        let at = self.tex_word(s, UV_BASE) + s.int(6) * i;
        let (u0, v0) = (self.f(at), self.f(at + s.int(1)));
        let (u1, v1) = (self.f(at + s.int(2)), self.f(at + s.int(3)));
        let (u2, v2) = (self.f(at + s.int(4)), self.f(at + s.int(5)));
        let u = (u0 + b1 * (u1 - u0)) + b2 * (u2 - u0);
        let v = (v0 + b1 * (v1 - v0)) + b2 * (v2 - v0);
        (finite_or_zero(s, u), finite_or_zero(s, v))
    }

    /// `texture::material`'s base-colour lookup of records `rec` at `uv`, through the map's
    /// transform (`texture::xform`, `texture::sample` with `Decode::Srgb`), in the lanes of
    /// `lanes`; and the lanes where it is not computed here: coordinates that are not
    /// finite, or a texel past the texture's edge (which its wrap mode brings back).
    #[inline(always)]
    fn base_colour<S: Isa>(
        &self,
        s: S,
        rec: (Option<u32>, I<S>),
        (u, v): (F<S>, F<S>),
        lanes: M<S>,
    ) -> (V3<S>, M<S>) {
        let m = TRANSFORMS as i32;
        let [a, b, c] = each!(|j| self.words(s, rec, m + j as i32).float_of_bits());
        let [d, e, f] = each!(|j| self.words(s, rec, m + 3 + j as i32).float_of_bits());
        let (u, v) = ((a * u + b * v) + c, (d * u + e * v) + f);
        let nan = u.cmp::<_CMP_UNORD_Q>(v);
        let limit = s.splat(UV_LIMIT);
        let (u, v) = (u.max(-limit).min(limit), v.max(-limit).min(limit));
        let h = self.base(s, rec, 1);
        let (w, ht) = (self.words(s, h, 0), self.words(s, h, 1));
        let x = u * w.to_float() - s.splat(0.5);
        let y = v * ht.to_float() - s.splat(0.5);
        let (x0, y0) = (floor(s, x), floor(s, y));
        let (fx, fy) = (x - x0, y - y0);
        // Both texels of each axis inside the texture: no wrap.
        let two = s.splat(2.0);
        let inside_x = x0.ge(s.zero()) & x0.le(w.to_float() - two);
        let inside_y = y0.ge(s.zero()) & y0.le(ht.to_float() - two);
        let off = lanes & (nan | !(inside_x & inside_y));
        let ok = lanes.without(off);
        let (x0, y0) = (x0.keep(ok), y0.keep(ok));
        let (ix, iy) = (x0.truncate(), y0.truncate());
        let base = self.words(s, h, 4) + iy * w + ix;
        let (t00, t10) = (self.texel(s, base), self.texel(s, base + s.int(1)));
        let (t01, t11) = (self.texel(s, base + w), self.texel(s, base + w + s.int(1)));
        let out = each!(|c| {
            let top = t00[c] + (t10[c] - t00[c]) * fx;
            let bottom = t01[c] + (t11[c] - t01[c]) * fx;
            top + (bottom - top) * fy
        });
        (out, off)
    }
}

impl Triangles<'_> {
    /// `texture::decode` of the texels at words `at`, sRGB (the colour alone).
    #[inline(always)]
    fn texel<S: Isa>(&self, s: S, at: I<S>) -> V3<S> {
        let word = I::gather(self.tex, at);
        let lut = s.int(SRGB_LUT as i32);
        each!(|c| self.f(lut + word.shr(8 * c as i32).and(s.int(0xff))))
    }
}

/// `intersect::plane_barycentrics` of points `q` (relative to v0) on triangles of edges
/// (e1, e2): (v, w), and the lanes where they are the triangle's.
#[inline(always)]
fn plane_barycentrics<S: Isa>(s: S, (e1, e2): (V3<S>, V3<S>), q: V3<S>) -> (F<S>, F<S>, M<S>) {
    let d00 = dot(e1, e1);
    let d01 = dot(e1, e2);
    let d11 = dot(e2, e2);
    let d20 = dot(q, e1);
    let d21 = dot(q, e2);
    let denom = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    let half = s.splat(-0.5);
    (v, w, (v.ge(half) & w.ge(half)) & (v + w).le(s.splat(1.5)))
}

/// x, or 0 where it is not finite (`texture::uv_at`).
#[inline(always)]
fn finite_or_zero<S: Isa>(s: S, x: F<S>) -> F<S> {
    x.keep(x.abs().lt(s.splat(f32::INFINITY)))
}
