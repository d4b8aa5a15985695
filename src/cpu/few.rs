//! Scenes of a few quads and boxes (a Cornell box): where the eight-wide BVH is one node of
//! leaves, its walk is one slab test and then each leaf's primitives tested one by one. Here
//! the slab test is the walk's, and every quad is tested at once, eight to an AVX operation;
//! the nearest hit is then chosen in the walk's order (slot by slot, each leaf's references
//! in turn), boxes tested there as the walk tests them. The quad test is `intersect::
//! hit_quad` term for term in the same order (glam's dot is (x + y) + z, its cross the
//! textbook one, and nothing is fused), so each distance is the scalar test's bit for bit, and
//! the hit is the walk's, ties included (a ray through the edge two quads share: tested on
//! the rays the scenes trace).

use super::bvh8::Bvh8;
use super::intersect::{Cuboid, NO_HIT, Quad, Ray, hit_box};
use crate::common::arrays::REF_INDEX;
use std::arch::x86_64::*;

/// The most quads and boxes a scene may have for this test (two blocks of eight quads).
pub const MAX_QUADS: usize = 16;
pub const MAX_BOXES: usize = 4;

/// Eight quads by component (a lane beyond the scene's quads has a zero normal: its
/// denominator is 0 and it is never hit).
#[derive(Clone, Copy)]
struct Block {
    q: [__m256; 3],
    u: [__m256; 3],
    v: [__m256; 3],
    n: [__m256; 3],
    w: [__m256; 3],
}

/// One primitive in the walk's order: the root slot of its leaf, its reference, and its
/// quad lane or box.
#[derive(Clone, Copy)]
struct Step {
    slot: u32,
    r: u32,
    what: What,
}

#[derive(Clone, Copy)]
enum What {
    Quad(usize),
    Box(usize),
}

/// The quads in blocks (lanes in the walk's order), the boxes, and the walk's order.
pub struct Few {
    blocks: Vec<Block>,
    boxes: Vec<Cuboid>,
    steps: Vec<Step>,
}

impl Few {
    /// The test for a scene of these primitives, where it applies: quads and boxes only, at
    /// most `MAX_QUADS` and `MAX_BOXES`, their tree one eight-wide node of leaves (`bvh8`,
    /// whose leaves index `refs`).
    pub fn of(bvh8: &Bvh8, refs: &[u32], quads: &[Quad], boxes: &[Cuboid]) -> Option<Few> {
        let leaves = bvh8.one_node_leaves()?;
        let (mut lane_quads, mut few_boxes, mut steps) = (Vec::new(), Vec::new(), Vec::new());
        for (slot, first, count) in leaves {
            for &r in &refs[first as usize..first as usize + count as usize] {
                let i = (r & REF_INDEX) as usize;
                let what = match r >> 30 {
                    1 => {
                        lane_quads.push(quads[i]);
                        What::Quad(lane_quads.len() - 1)
                    }
                    2 => {
                        few_boxes.push(boxes[i]);
                        What::Box(few_boxes.len() - 1)
                    }
                    _ => return None,
                };
                steps.push(Step { slot, r, what });
            }
        }
        if lane_quads.len() > MAX_QUADS || few_boxes.len() > MAX_BOXES {
            return None;
        }
        let lanes = |i: usize, f: fn(&Quad) -> glam::Vec3A| -> [[f32; 8]; 3] {
            let mut out = [[0.0f32; 8]; 3];
            for (lane, q) in lane_quads.iter().skip(i * 8).take(8).enumerate() {
                let v = f(q);
                out[0][lane] = v.x;
                out[1][lane] = v.y;
                out[2][lane] = v.z;
            }
            out
        };
        // SAFETY: `_mm256_loadu_ps` reads eight floats; the eight-wide tree exists only where
        // the CPU has AVX.
        let load = |a: [[f32; 8]; 3]| a.map(|c| unsafe { _mm256_loadu_ps(c.as_ptr()) });
        let blocks = (0..lane_quads.len().div_ceil(8))
            .map(|i| Block {
                q: load(lanes(i, |q| q.q)),
                u: load(lanes(i, |q| q.u)),
                v: load(lanes(i, |q| q.v)),
                n: load(lanes(i, |q| q.normal)),
                w: load(lanes(i, |q| q.w)),
            })
            .collect();
        Some(Few {
            blocks,
            boxes: few_boxes,
            steps,
        })
    }

    /// Per lane of `b`, the distance to its quad if in (0, t_max), else NO_HIT: `hit_quad`
    /// in lanes.
    #[target_feature(enable = "avx")]
    fn block(b: &Block, o: &[__m256; 3], d: &[__m256; 3], t_max: __m256) -> __m256 {
        let dot = |a: &[__m256; 3], c: &[__m256; 3]| {
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(a[0], c[0]), _mm256_mul_ps(a[1], c[1])),
                _mm256_mul_ps(a[2], c[2]),
            )
        };
        let cross = |a: &[__m256; 3], c: &[__m256; 3]| {
            [
                _mm256_sub_ps(_mm256_mul_ps(a[1], c[2]), _mm256_mul_ps(a[2], c[1])),
                _mm256_sub_ps(_mm256_mul_ps(a[2], c[0]), _mm256_mul_ps(a[0], c[2])),
                _mm256_sub_ps(_mm256_mul_ps(a[0], c[1]), _mm256_mul_ps(a[1], c[0])),
            ]
        };
        let denom = dot(&b.n, d);
        let abs = _mm256_andnot_ps(_mm256_set1_ps(-0.0), denom);
        let facing = _mm256_cmp_ps::<_CMP_GE_OQ>(abs, _mm256_set1_ps(1e-20));
        let qo = [0, 1, 2].map(|k| _mm256_sub_ps(b.q[k], o[k]));
        let t = _mm256_div_ps(dot(&b.n, &qo), denom);
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let in_range = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(t, t_max),
        );
        let p =
            [0, 1, 2].map(|k| _mm256_sub_ps(_mm256_add_ps(o[k], _mm256_mul_ps(t, d[k])), b.q[k]));
        let alpha = dot(&b.w, &cross(&p, &b.v));
        let beta = dot(&b.w, &cross(&b.u, &p));
        let inside = |x: __m256| {
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(x, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(x, one),
            )
        };
        let hit = _mm256_and_ps(
            _mm256_and_ps(facing, in_range),
            _mm256_and_ps(inside(alpha), inside(beta)),
        );
        _mm256_blendv_ps(_mm256_set1_ps(NO_HIT), t, hit)
    }

    /// Every quad's distance along `ray` (NO_HIT where it is missed or not before t_max).
    #[target_feature(enable = "avx")]
    fn distances(&self, ray: &Ray, t_max: f32) -> [f32; MAX_QUADS] {
        let o = [ray.origin.x, ray.origin.y, ray.origin.z].map(|x| _mm256_set1_ps(x));
        let d = [ray.dir.x, ray.dir.y, ray.dir.z].map(|x| _mm256_set1_ps(x));
        let t_max = _mm256_set1_ps(t_max);
        let mut out = [NO_HIT; MAX_QUADS];
        for (i, b) in self.blocks.iter().enumerate() {
            let t = Self::block(b, &o, &d, t_max);
            // SAFETY: eight floats at 8·i, within MAX_QUADS (at most two blocks).
            unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(8 * i), t) };
        }
        out
    }

    /// The nearest primitive along `ray` before t_max (its distance and reference), `skip`
    /// left out, and the primitives tested: `Bvh8::closest`'s answer.
    ///
    /// # Safety
    /// The CPU must have AVX (the eight-wide tree `bvh8` exists only there).
    #[target_feature(enable = "avx")]
    pub unsafe fn closest(
        &self,
        bvh8: &Bvh8,
        ray: &Ray,
        t_max: f32,
        skip: u32,
    ) -> (Option<(f32, u32)>, u64) {
        // SAFETY: AVX is present (this function's contract).
        let mask = unsafe { bvh8.root_mask(ray, t_max) };
        if mask == 0 {
            return (None, 0);
        }
        let ts = self.distances(ray, t_max);
        let (mut best, mut t_best, mut tests) = (None, t_max, 0);
        for step in self.steps.iter().filter(|s| mask >> s.slot & 1 != 0) {
            if step.r == skip {
                continue;
            }
            tests += 1;
            let t = match step.what {
                What::Quad(lane) if ts[lane] < t_best => ts[lane],
                What::Quad(_) => NO_HIT,
                What::Box(i) => hit_box(&self.boxes[i], ray, t_best),
            };
            if t > 0.0 {
                t_best = t;
                best = Some((t, step.r));
            }
        }
        (best, tests)
    }

    /// Whether a primitive but `skip` and `from` lies on `ray` before t_max, and the
    /// primitives tested.
    ///
    /// # Safety
    /// The CPU must have AVX (the eight-wide tree `bvh8` exists only there).
    #[target_feature(enable = "avx")]
    pub unsafe fn any(
        &self,
        bvh8: &Bvh8,
        ray: &Ray,
        t_max: f32,
        skip: u32,
        from: u32,
    ) -> (bool, u64) {
        // SAFETY: AVX is present (this function's contract).
        let mask = unsafe { bvh8.root_mask(ray, t_max) };
        if mask == 0 {
            return (false, 0);
        }
        let ts = self.distances(ray, t_max);
        let mut tests = 0;
        for step in self.steps.iter().filter(|s| mask >> s.slot & 1 != 0) {
            tests += 1;
            if step.r == skip || step.r == from {
                continue;
            }
            let hit = match step.what {
                What::Quad(lane) => ts[lane] > 0.0,
                What::Box(i) => hit_box(&self.boxes[i], ray, t_max) > 0.0,
            };
            if hit {
                return (true, tests);
            }
        }
        (false, tests)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::bvh::{Stack, Tally};
    use crate::cpu::trace::{ANY, T_FAR, hit_primitive, recorded};

    #[test]
    fn all_at_once_finds_what_the_walk_finds_bit_for_bit() {
        let (s, segments) = recorded("cornell", 320, 192, 64);
        let (Some(few), Some(b8)) = (&s.few, &s.bvh8) else {
            eprintln!("no AVX: nothing to compare");
            return;
        };
        let (mut tally, mut stack) = (Tally::default(), Stack::default());
        let bits = |h: Option<(f32, u32)>| h.map(|(t, r)| (t.to_bits(), r));
        let (mut hits, mut blocked) = (0, 0);
        for (_, ray) in &segments {
            let test = |r, t| hit_primitive::<ANY>(&s, r, ray, t);
            let want = s.bvh.closest(ray, T_FAR, &mut tally, &mut stack, test);
            // SAFETY: `few` exists only where the CPU has AVX.
            let got = unsafe { few.closest(b8, ray, T_FAR, u32::MAX) }.0;
            assert_eq!(bits(want), bits(got), "{ray:?}");
            let Some((t, r)) = want else { continue };
            hits += 1;
            // The same ray leaving the primitive it hit: the next one along it.
            let test = |q, t| {
                if q == r {
                    NO_HIT
                } else {
                    hit_primitive::<ANY>(&s, q, ray, t)
                }
            };
            let want = s.bvh.closest(ray, T_FAR, &mut tally, &mut stack, test);
            // SAFETY: as above.
            let got = unsafe { few.closest(b8, ray, T_FAR, r) }.0;
            assert_eq!(bits(want), bits(got), "{ray:?} leaving {r}");
            // Shadow rays stopped short of the hit, just past it, and far past it.
            for t_max in [t * 0.5, t * 1.001, 1e30] {
                let want = s.bvh.any(ray, t_max, &mut tally, &mut stack, |q| {
                    q != r && hit_primitive::<ANY>(&s, q, ray, t_max) > 0.0
                });
                // SAFETY: as above.
                let got = unsafe { few.any(b8, ray, t_max, r, u32::MAX) }.0;
                assert_eq!(want, got, "{ray:?} before {t_max}");
                blocked += want as u32;
            }
        }
        assert!(
            hits > 1000 && blocked > 100,
            "only {hits} hits, {blocked} blocked"
        );
    }

    #[test]
    fn it_applies_to_quads_and_boxes_only() {
        let (s, _) = recorded("cornell", 8, 8, 1);
        assert_eq!(s.few.is_some(), std::arch::is_x86_feature_detected!("avx"));
        for name in ["weekend", "mesh", "lamp"] {
            let (s, _) = recorded(name, 8, 8, 1);
            assert!(s.few.is_none(), "{name}");
        }
    }
}
