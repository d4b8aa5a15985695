//! The path loop in eight AVX lanes, one path a lane, for scenes of a few Lambertian spheres
//! under the sky (no lights, no map, no lens): `Tracer::trace_path`'s arithmetic for those
//! scenes, operation for operation in the same order (glam's dot is (x·x′ + y·y′) + z·z′, its
//! normalize a division by the square root, nothing fused), so that each lane's path is the
//! scalar one bit for bit; tested against it on every lane. The scalar loop runs one path's
//! dependent chain of divisions and square roots at a time; here eight run side by side,
//! every sphere tested against eight rays at once (the wavefront of Laine, Karras and Aila,
//! "Megakernels Considered Harmful", HPG 2013, kept in one kernel as in Mitsuba 3's LLVM
//! backend, which traces sixteen lanes wide). A lane whose path has ended idles until the
//! group's last path ends. The draws stay each lane's own sampler's, taken in the order the
//! scalar path takes them.
//!
//! The one difference a path can show: where two spheres are hit at the same distance, the
//! scalar walk keeps the one its BVH order tests first, and this the one of the lower index.

use super::intersect::{LANES, NO_HIT, Ray};
use super::rng::Rng;
use super::scene::CpuScene;
use super::trace::T_FAR;
use crate::common::Features;
use glam::Vec3A;
use std::arch::x86_64::*;

/// The most spheres a scene may have here: their parameters are permuted into the lanes
/// from one register of eight.
pub const MAX_SPHERES: usize = 8;

/// A scene's spheres and sky as the lanes read them. Built per row from the scene (a few
/// spheres: nothing to keep in step with material edits).
pub struct Lanes {
    count: usize,
    /// Per sphere, by component: the anchor, the anchor normal, |radius| times the anchor
    /// normal (`hit_sphere`'s r·n, a product of the same two floats), |radius|, 2·|radius|,
    /// whether the radius is positive (the sphere's outside is where its normal points) and
    /// whether it is negative (its normal is turned inward), as 1.0 or 0.0, and the
    /// material's lobe: whether it is the specular one (1.0 or 0.0), its smoothness s and
    /// 1 − s, and its tint (the specular colour or the colour).
    anchor: [[f32; 8]; 3],
    normal: [[f32; 8]; 3],
    r_normal: [[f32; 8]; 3],
    r: [f32; 8],
    two_r: [f32; 8],
    outward: [f32; 8],
    inward: [f32; 8],
    spec: [f32; 8],
    smooth: [f32; 8],
    rough: [f32; 8],
    tint: [[f32; 8]; 3],
    sky_uniform: bool,
    sky_bottom: [f32; 3],
    sky_top: [f32; 3],
    max_bounces: u32,
}

/// One lane's path: its radiance, its segments, and its sphere tests.
pub type Traced = (Vec3A, u32);

impl Lanes {
    /// The lanes for `s` traced with features `f`, where they apply: a CPU with AVX2, one to
    /// `MAX_SPHERES` spheres and nothing else, every sphere's material the lecture's
    /// Lambertian one (no specular lobe, no light, not a dielectric), no lights and no map
    /// (so no light sampling and no Russian roulette: `trace_path` runs neither without a
    /// light), and the sky without its sun. The camera rays, a lens's included, are the
    /// caller's.
    pub fn of(s: &CpuScene, f: Features) -> Option<Lanes> {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return None;
        }
        let only_spheres = f.spheres
            && !(f.quads || f.boxes || f.triangles || f.instances)
            && s.quads.is_empty()
            && s.boxes.is_empty()
            && s.triangles.is_empty()
            && s.instances.is_empty();
        let plain = !(f.dielectrics
            || f.emitters
            || f.sun
            || f.textures
            || f.env_map
            || f.pbr
            || f.mirror_nee
            || f.lens_nee);
        if !only_spheres
            || !plain
            || s.spheres.is_empty()
            || s.spheres.len() > MAX_SPHERES
            || s.u.n_lights != 0
            || s.env.is_some()
            || s.shading_normals()
        {
            return None;
        }
        let mut l = Lanes {
            count: s.spheres.len(),
            anchor: [[0.0; 8]; 3],
            normal: [[0.0; 8]; 3],
            r_normal: [[0.0; 8]; 3],
            r: [0.0; 8],
            two_r: [0.0; 8],
            outward: [0.0; 8],
            inward: [0.0; 8],
            spec: [0.0; 8],
            smooth: [0.0; 8],
            rough: [0.0; 8],
            tint: [[0.0; 8]; 3],
            sky_uniform: s.u.sky_uniform,
            sky_bottom: s.u.sky_bottom.to_array(),
            sky_top: s.u.sky_top.to_array(),
            max_bounces: s.u.max_bounces,
        };
        for (k, sp) in s.spheres.iter().enumerate() {
            let m = s.materials.get(sp.material as usize)?;
            // The lobe is certain (no draw picks it), and the specular one takes no fuzz.
            let spec = m.specular >= 1.0;
            let lobe = !m.pbr
                && m.light == 0.0
                && m.smoothness >= 0.0
                && (spec || m.specular == 0.0)
                && !(spec && m.absorption > 0.0);
            if !lobe {
                return None;
            }
            let r = sp.radius.abs();
            for c in 0..3 {
                l.anchor[c][k] = sp.anchor[c];
                l.normal[c][k] = sp.anchor_normal[c];
                l.r_normal[c][k] = (r * sp.anchor_normal)[c];
                l.tint[c][k] = if spec {
                    m.specular_color[c]
                } else {
                    m.color[c]
                };
            }
            l.r[k] = r;
            l.two_r[k] = 2.0 * r;
            l.outward[k] = if sp.radius > 0.0 { 1.0 } else { 0.0 };
            l.inward[k] = if sp.radius < 0.0 { 1.0 } else { 0.0 };
            l.spec[k] = if spec { 1.0 } else { 0.0 };
            l.smooth[k] = m.smoothness;
            l.rough[k] = 1.0 - m.smoothness;
        }
        Some(l)
    }

    /// The paths of up to eight camera rays (`None`: no pixel in that lane), each drawing
    /// from its own sampler, as `Tracer::trace_path` traces them; and the sphere tests made.
    ///
    /// # Safety
    /// The CPU must have AVX2 (`of` checks it).
    #[target_feature(enable = "avx,avx2")]
    pub unsafe fn trace(
        &self,
        rays: &[Option<Ray>; LANES],
        rngs: &mut [Rng; LANES],
    ) -> ([Traced; LANES], u64) {
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let sign = _mm256_set1_ps(-0.0);
        let mut o = [[0.0f32; 8]; 3];
        let mut d = [[0.0f32; 8]; 3];
        let mut active = 0u32;
        for (k, r) in rays.iter().enumerate() {
            if let Some(r) = r {
                for c in 0..3 {
                    o[c][k] = r.origin[c];
                    d[c][k] = r.dir[c];
                }
                active |= 1 << k;
            } else {
                // A unit direction, so that an empty lane computes nothing odd.
                d[2][k] = 1.0;
            }
        }
        // SAFETY: unaligned loads of eight floats from arrays of eight.
        let load = |a: &[f32; 8]| unsafe { _mm256_loadu_ps(a.as_ptr()) };
        let mut o = o.map(|a| load(&a));
        let mut d = d.map(|a| load(&a));
        let mut throughput = [one; 3];
        let mut radiance = [zero; 3];
        let mut segments = _mm256_setzero_si256();
        let mut skip = _mm256_set1_epi32(-1);
        let mut tests = 0u64;
        let tables = |a: &[[f32; 8]; 3]| a.map(|t| load(&t));
        let (anchor_t, normal_t, tint_t) = (
            tables(&self.anchor),
            tables(&self.normal),
            tables(&self.tint),
        );
        let (spec_t, smooth_t, rough_t) = (load(&self.spec), load(&self.smooth), load(&self.rough));
        let (r_t, two_r_t) = (load(&self.r), load(&self.two_r));
        let (outward_t, inward_t) = (load(&self.outward), load(&self.inward));
        let mut bounce = 0;
        while bounce <= self.max_bounces && active != 0 {
            let live = lane_mask(active);
            segments = _mm256_sub_epi32(segments, _mm256_castps_si256(live));
            tests += (active.count_ones() as u64) * self.count as u64;
            // The nearest sphere, the one the ray leaves left out (`hit_except`).
            let mut best = _mm256_set1_ps(T_FAR);
            let mut index = _mm256_set1_epi32(-1);
            for k in 0..self.count {
                let t = self.hit_sphere(k, o, d);
                let kk = _mm256_set1_epi32(k as i32);
                let not_skipped = _mm256_castsi256_ps(_mm256_xor_si256(
                    _mm256_cmpeq_epi32(skip, kk),
                    _mm256_set1_epi32(-1),
                ));
                let nearer = _mm256_and_ps(
                    _mm256_and_ps(
                        _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
                        _mm256_cmp_ps::<_CMP_LT_OQ>(t, best),
                    ),
                    not_skipped,
                );
                best = _mm256_blendv_ps(best, t, nearer);
                index = _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(index),
                    _mm256_castsi256_ps(kk),
                    nearer,
                ));
            }
            let found = _mm256_castsi256_ps(_mm256_cmpgt_epi32(index, _mm256_set1_epi32(-1)));
            let missed = _mm256_andnot_ps(found, live);
            if _mm256_movemask_ps(missed) != 0 {
                let sky = self.sky(d[1]);
                for c in 0..3 {
                    let add = _mm256_add_ps(radiance[c], _mm256_mul_ps(throughput[c], sky[c]));
                    radiance[c] = _mm256_blendv_ps(radiance[c], add, missed);
                }
            }
            let hit = _mm256_and_ps(found, live);
            active = _mm256_movemask_ps(hit) as u32;
            if active == 0 || bounce == self.max_bounces {
                break;
            }
            // `sphere_surface`, the sphere's parameters permuted into the lanes.
            let idx = _mm256_max_epi32(index, _mm256_setzero_si256());
            let pick = |t: __m256| _mm256_permutevar8x32_ps(t, idx);
            let r = pick(r_t);
            let an = normal_t.map(pick);
            let anc = anchor_t.map(pick);
            let q: [__m256; 3] = std::array::from_fn(|c| {
                _mm256_add_ps(_mm256_sub_ps(o[c], anc[c]), _mm256_mul_ps(best, d[c]))
            });
            let m: [__m256; 3] =
                std::array::from_fn(|c| _mm256_add_ps(_mm256_div_ps(q[c], r), an[c]));
            let len = _mm256_sqrt_ps(dot(m, m));
            let n = m.map(|x| _mm256_div_ps(x, len));
            let h = _mm256_div_ps(
                _mm256_add_ps(dot(q, q), _mm256_mul_ps(pick(two_r_t), dot(q, an))),
                _mm256_add_ps(_mm256_mul_ps(r, len), r),
            );
            let position: [__m256; 3] = std::array::from_fn(|c| {
                _mm256_add_ps(anc[c], _mm256_sub_ps(q[c], _mm256_mul_ps(h, n[c])))
            });
            let inward = _mm256_cmp_ps::<_CMP_GT_OQ>(pick(inward_t), zero);
            let n_out = n.map(|x| _mm256_blendv_ps(x, _mm256_xor_ps(x, sign), inward));
            // The facing normal, and the Lambertian lobe's direction (`scatter_surface`).
            let front = _mm256_cmp_ps::<_CMP_LT_OQ>(dot(d, n_out), zero);
            let nf = n_out.map(|x| _mm256_blendv_ps(_mm256_xor_ps(x, sign), x, front));
            let (mut uu, mut vv) = ([0.0f32; 8], [0.0f32; 8]);
            for k in 0..LANES {
                if active >> k & 1 != 0 {
                    (uu[k], vv[k]) = rngs[k].rand2();
                }
            }
            let unit = random_unit_vector(load(&uu), load(&vv));
            let v: [__m256; 3] = std::array::from_fn(|c| _mm256_add_ps(nf[c], unit[c]));
            let diffuse = normalize_or(v, nf);
            // The specular lobe: the diffuse direction blended toward the mirror one by the
            // smoothness (`Vec3A::lerp`), normalized again.
            let spec = _mm256_cmp_ps::<_CMP_GT_OQ>(pick(spec_t), zero);
            let dir = if _mm256_movemask_ps(_mm256_and_ps(spec, hit)) != 0 {
                let dn = _mm256_mul_ps(_mm256_set1_ps(2.0), dot(d, nf));
                let (s, rough) = (pick(smooth_t), pick(rough_t));
                let blend: [__m256; 3] = std::array::from_fn(|c| {
                    let mirror = _mm256_sub_ps(d[c], _mm256_mul_ps(dn, nf[c]));
                    _mm256_add_ps(_mm256_mul_ps(diffuse[c], rough), _mm256_mul_ps(mirror, s))
                });
                let specular = normalize_or(blend, nf);
                std::array::from_fn(|c| _mm256_blendv_ps(diffuse[c], specular[c], spec))
            } else {
                diffuse
            };
            // Absorbed where dir·n <= 0 (a NaN goes on, as in `scatter_surface`).
            let kept = _mm256_and_ps(_mm256_cmp_ps::<_CMP_NLE_UQ>(dot(dir, nf), zero), hit);
            active = _mm256_movemask_ps(kept) as u32;
            let tint = tint_t.map(pick);
            for c in 0..3 {
                throughput[c] =
                    _mm256_blendv_ps(throughput[c], _mm256_mul_ps(throughput[c], tint[c]), kept);
            }
            // The side the ray leaves by, the sphere it cannot meet next (`leaving`), and its
            // origin moved off the surface (`offset_ray`).
            let out = _mm256_cmp_ps::<_CMP_GT_OQ>(dot(dir, n_out), zero);
            let side = n_out.map(|x| _mm256_blendv_ps(_mm256_xor_ps(x, sign), x, out));
            let outward = _mm256_cmp_ps::<_CMP_GT_OQ>(pick(outward_t), zero);
            let same = _mm256_xor_ps(
                _mm256_xor_ps(out, outward),
                _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
            );
            skip = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
                _mm256_castsi256_ps(idx),
                same,
            ));
            let moved = offset_ray(position, side);
            for c in 0..3 {
                o[c] = _mm256_blendv_ps(o[c], moved[c], kept);
                d[c] = _mm256_blendv_ps(d[c], dir[c], kept);
            }
            bounce += 1;
        }
        let mut out = [[0.0f32; 8]; 3];
        let mut segs = [0u32; 8];
        // SAFETY: unaligned stores of eight lanes into arrays of eight.
        unsafe {
            for c in 0..3 {
                _mm256_storeu_ps(out[c].as_mut_ptr(), radiance[c]);
            }
            _mm256_storeu_si256(segs.as_mut_ptr() as *mut __m256i, segments);
        }
        let traced =
            std::array::from_fn(|k| (Vec3A::new(out[0][k], out[1][k], out[2][k]), segs[k]));
        (traced, tests)
    }

    /// `hit_sphere` of sphere `k` for the eight rays (t_max `T_FAR`): the nearest t in (0,
    /// T_FAR), or NO_HIT.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn hit_sphere(&self, k: usize, o: [__m256; 3], d: [__m256; 3]) -> __m256 {
        let zero = _mm256_setzero_ps();
        let r = _mm256_set1_ps(self.r[k]);
        let g: [__m256; 3] =
            std::array::from_fn(|c| _mm256_sub_ps(o[c], _mm256_set1_ps(self.anchor[c][k])));
        let f: [__m256; 3] =
            std::array::from_fn(|c| _mm256_add_ps(g[c], _mm256_set1_ps(self.r_normal[c][k])));
        let b = dot(f, d);
        let l: [__m256; 3] = std::array::from_fn(|c| _mm256_sub_ps(f[c], _mm256_mul_ps(b, d[c])));
        let ll = _mm256_sqrt_ps(dot(l, l));
        let disc = _mm256_mul_ps(_mm256_sub_ps(r, ll), _mm256_add_ps(r, ll));
        let an = [0, 1, 2].map(|c| _mm256_set1_ps(self.normal[c][k]));
        let c = _mm256_add_ps(
            dot(g, g),
            _mm256_mul_ps(_mm256_set1_ps(self.two_r[k]), dot(g, an)),
        );
        let sq = _mm256_sqrt_ps(disc);
        let neg_b = _mm256_xor_ps(b, _mm256_set1_ps(-0.0));
        let below = _mm256_cmp_ps::<_CMP_LT_OQ>(b, zero);
        let signed = _mm256_blendv_ps(sq, _mm256_xor_ps(sq, _mm256_set1_ps(-0.0)), below);
        let q = _mm256_sub_ps(neg_b, signed);
        let t0 = _mm256_div_ps(c, q);
        // f32::min and max: where t0 is NaN, q.
        let near = _mm256_min_ps(t0, q);
        let far = _mm256_max_ps(t0, q);
        let t_max = _mm256_set1_ps(T_FAR);
        let within = |t: __m256| {
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(t, t_max),
            )
        };
        let no_hit = _mm256_set1_ps(NO_HIT);
        let t = _mm256_blendv_ps(
            _mm256_blendv_ps(no_hit, far, within(far)),
            near,
            within(near),
        );
        // Neither a ray that passes the sphere (disc < 0) nor one with q = 0 hits it.
        let fails = _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(disc, zero),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(q, zero),
        );
        _mm256_blendv_ps(t, no_hit, fails)
    }

    /// The sky in direction d (its y component): uniform, or the gradient (`Tracer::sky`).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    fn sky(&self, dy: __m256) -> [__m256; 3] {
        if self.sky_uniform {
            return self.sky_bottom.map(|b| _mm256_set1_ps(b));
        }
        let one = _mm256_set1_ps(1.0);
        let t = _mm256_mul_ps(_mm256_set1_ps(0.5), _mm256_add_ps(dy, one));
        let s = _mm256_sub_ps(one, t);
        std::array::from_fn(|c| {
            _mm256_add_ps(
                _mm256_mul_ps(s, _mm256_set1_ps(self.sky_bottom[c])),
                _mm256_mul_ps(t, _mm256_set1_ps(self.sky_top[c])),
            )
        })
    }
}

/// All bits of lane k set where bit k of `mask` is.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn lane_mask(mask: u32) -> __m256 {
    let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let m = _mm256_and_si256(_mm256_set1_epi32(mask as i32), bits);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(m, bits))
}

/// glam's Vec3A dot: (x·x′ + y·y′) + z·z′.
#[inline]
#[target_feature(enable = "avx")]
fn dot(a: [__m256; 3], b: [__m256; 3]) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
        _mm256_mul_ps(a[2], b[2]),
    )
}

/// `sampling::normalize_or`: v / |v|, or `fallback` where |v|² < 10⁻¹².
#[inline]
#[target_feature(enable = "avx")]
fn normalize_or(v: [__m256; 3], fallback: [__m256; 3]) -> [__m256; 3] {
    let l2 = dot(v, v);
    let short = _mm256_cmp_ps::<_CMP_LT_OQ>(l2, _mm256_set1_ps(1e-12));
    let root = _mm256_sqrt_ps(l2);
    std::array::from_fn(|c| _mm256_blendv_ps(_mm256_div_ps(v[c], root), fallback[c], short))
}

/// `sampling::random_unit_vector` from its draws u and v.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn random_unit_vector(u: __m256, v: __m256) -> [__m256; 3] {
    let one = _mm256_set1_ps(1.0);
    let z = _mm256_sub_ps(one, _mm256_mul_ps(_mm256_set1_ps(2.0), u));
    let r = _mm256_sqrt_ps(_mm256_max_ps(
        _mm256_sub_ps(one, _mm256_mul_ps(z, z)),
        _mm256_setzero_ps(),
    ));
    let (s, c) = sin_cos_turns(v);
    [_mm256_mul_ps(r, c), _mm256_mul_ps(r, s), z]
}

/// `sampling::sin_cos_turns` in lanes: the same polynomials, the same quadrant turns.
#[inline]
#[target_feature(enable = "avx,avx2")]
fn sin_cos_turns(t: __m256) -> (__m256, __m256) {
    use std::f32::consts::PI;
    let set = _mm256_set1_ps;
    let qi = _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(set(4.0), t), set(0.5)));
    let q = _mm256_cvtepi32_ps(qi);
    let x = _mm256_mul_ps(set(2.0 * PI), _mm256_sub_ps(t, _mm256_mul_ps(set(0.25), q)));
    let x2 = _mm256_mul_ps(x, x);
    let (add, mul, div) = (_mm256_add_ps, _mm256_mul_ps, _mm256_div_ps);
    // x * (1 + x2 * (-1/6 + x2 * (1/120 + x2 * (-1/5040 + x2 / 362880))))
    let s = mul(
        x,
        add(
            set(1.0),
            mul(
                x2,
                add(
                    set(-1.0 / 6.0),
                    mul(
                        x2,
                        add(
                            set(1.0 / 120.0),
                            mul(x2, add(set(-1.0 / 5040.0), div(x2, set(362880.0)))),
                        ),
                    ),
                ),
            ),
        ),
    );
    // 1 + x2 * (-1/2 + x2 * (1/24 + x2 * (-1/720 + x2 * (1/40320))))
    let c = add(
        set(1.0),
        mul(
            x2,
            add(
                set(-0.5),
                mul(
                    x2,
                    add(
                        set(1.0 / 24.0),
                        mul(x2, add(set(-1.0 / 720.0), mul(x2, set(1.0 / 40320.0)))),
                    ),
                ),
            ),
        ),
    );
    let one = _mm256_set1_epi32(1);
    let two = _mm256_set1_epi32(2);
    let odd = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(qi, one), one));
    let a = _mm256_blendv_ps(s, c, odd);
    let b = _mm256_blendv_ps(c, s, odd);
    let flip_a = _mm256_slli_epi32::<30>(_mm256_and_si256(qi, two));
    let flip_b = _mm256_slli_epi32::<30>(_mm256_and_si256(_mm256_add_epi32(qi, one), two));
    (
        _mm256_xor_ps(a, _mm256_castsi256_ps(flip_a)),
        _mm256_xor_ps(b, _mm256_castsi256_ps(flip_b)),
    )
}

/// `intersect::offset_ray` in lanes (Wächter and Binder, Ray Tracing Gems ch. 6).
#[inline]
#[target_feature(enable = "avx,avx2")]
fn offset_ray(p: [__m256; 3], n: [__m256; 3]) -> [__m256; 3] {
    use super::intersect::{OFFSET_FLOAT_SCALE, OFFSET_INT_SCALE, OFFSET_ORIGIN};
    let abs = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    std::array::from_fn(|c| {
        let of_i = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_set1_ps(OFFSET_INT_SCALE), n[c]));
        let near = _mm256_add_ps(
            p[c],
            _mm256_mul_ps(_mm256_set1_ps(OFFSET_FLOAT_SCALE), n[c]),
        );
        let negative = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(p[c], _mm256_setzero_ps()));
        let step = _mm256_sub_epi32(_mm256_xor_si256(of_i, negative), negative);
        let far = _mm256_castsi256_ps(_mm256_add_epi32(_mm256_castps_si256(p[c]), step));
        let small =
            _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(p[c], abs), _mm256_set1_ps(OFFSET_ORIGIN));
        _mm256_blendv_ps(far, near, small)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::common::FrameSettings;
    use crate::cpu::rng::GROUP;
    use crate::cpu::trace::{SPHERES, Tracer};
    use crate::scene::Scene;

    /// Eight spheres: a hollow one (negative radius) behind the others, Lambertian and
    /// specular lobes at smoothness 0, 0.3 and 1, a lens, a uniform sky, and few bounces, so
    /// that paths end at the bounce limit, by a miss and by absorption.
    const SHELL: &str = r##"
[camera]
look_from = [0, 0.4, 2.5]
look_at = [0, 0, -1]
vfov = 70
aperture = 0.1
focus_distance = 3.0
[render]
max_bounces = 3
[sky]
uniform = [0.6, 0.7, 0.9]
[[sphere]]
center = [0, 0, -12]
radius = -8
color = "#c0c0c0"
[[sphere]]
center = [0, -100.5, -1]
radius = 100
color = "#80a060"
[[sphere]]
center = [-1.1, 0, -1]
radius = 0.5
color = "#d04040"
[[sphere]]
center = [0, 0, -1]
radius = 0.5
color = "#e0e0e0"
specular = 1
smoothness = 1
[[sphere]]
center = [1.1, 0, -1]
radius = 0.5
color = "#4060d0"
specular = 1
smoothness = 0.3
[[sphere]]
center = [0.5, 0.8, -1.8]
radius = 0.3
color = "#a0a0a0"
specular = 1
[[sphere]]
center = [-0.5, 0.9, -2.2]
radius = 0.35
color = "#f0d080"
[[sphere]]
center = [0, -0.3, 0.2]
radius = 0.2
color = "#606060"
"##;

    /// Every lane's path against `Tracer::trace_path`'s, bit for bit: radiance, segments,
    /// and where each sampler's stream stands after it.
    fn same_paths(scene: &Scene, w: u32, h: u32, spp: u32) -> u64 {
        let settings = FrameSettings::new(w, h, scene.render.max_bounces.min(8), 5);
        let s = CpuScene::new(scene, &settings);
        let f = Features::of(scene);
        let Some(lanes) = Lanes::of(&s, f) else {
            assert!(
                !std::arch::is_x86_feature_detected!("avx2"),
                "no lanes for the scene"
            );
            return 0;
        };
        let mut t = Tracer::new(&s, f);
        let mut paths = 0;
        for y in 0..h {
            for x0 in (0..w).step_by(LANES) {
                for sample in 0..spp {
                    let pixels: [u32; GROUP] = std::array::from_fn(|x| y * w + x0 + x as u32);
                    let mut rngs = Rng::group(&pixels, sample, s.u.seed, 3);
                    let mut scalar = rngs;
                    let n = (w - x0).min(LANES as u32) as usize;
                    let rays: [Option<Ray>; LANES] = std::array::from_fn(|x| {
                        (x < n).then(|| t.camera_ray(x0 + x as u32, y, &mut rngs[x]))
                    });
                    for (x, rng) in scalar.iter_mut().enumerate().take(n) {
                        t.camera_ray(x0 + x as u32, y, rng);
                    }
                    // SAFETY: `Lanes::of` made them only where the CPU has AVX2.
                    let (got, _) = unsafe { lanes.trace(&rays, &mut rngs) };
                    for x in 0..n {
                        let ray = rays[x].unwrap();
                        let want = t.trace_path::<SPHERES, false>(
                            (x0 + x as u32, y),
                            ray,
                            None,
                            &mut scalar[x],
                        );
                        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
                        assert_eq!(
                            (bits(got[x].0), got[x].1),
                            (bits(want.0), want.1),
                            "pixel ({}, {y}), sample {sample}: {:?} against {:?}",
                            x0 + x as u32,
                            got[x],
                            want
                        );
                        assert_eq!(rngs[x].taken(), scalar[x].taken());
                        assert_eq!(rngs[x].rand().to_bits(), scalar[x].rand().to_bits());
                        paths += 1;
                    }
                }
            }
        }
        paths
    }

    #[test]
    fn lanes_trace_the_scalar_paths_bit_for_bit() {
        let shell = Scene::from_toml(SHELL, "shell").unwrap();
        for (scene, w, h, spp) in [
            (shell, 36, 20, 8),
            (Scene::load("basic").unwrap(), 36, 20, 8),
            (Scene::load("metal").unwrap(), 36, 20, 8),
        ] {
            let paths = same_paths(&scene, w, h, spp);
            assert!(paths == 0 || paths == (w * h * spp) as u64);
        }
    }

    #[test]
    fn lanes_leave_out_what_they_do_not_trace() {
        let settings = FrameSettings::new(16, 16, 8, 1);
        for name in [
            "weekend",
            "cornell",
            "lamp",
            "dielectric",
            "fuzz",
            "emissive",
            "outdoor",
        ] {
            let scene = Scene::load(name).unwrap();
            let s = CpuScene::new(&scene, &settings);
            assert!(Lanes::of(&s, Features::of(&scene)).is_none(), "{name}");
        }
        let shell = Scene::from_toml(SHELL, "shell").unwrap();
        let s = CpuScene::new(&shell, &settings);
        let has = std::arch::is_x86_feature_detected!("avx2");
        assert_eq!(Lanes::of(&s, Features::of(&shell)).is_some(), has);
    }
}
