//! Scenes of a few quads and boxes (a Cornell box): where the eight-wide BVH is one node of
//! leaves, its walk is one slab test and then each leaf's primitives tested one by one. Here
//! the slab test is the walk's, and every quad is tested at once, eight to an AVX operation;
//! the nearest hit is then chosen as the walk chooses it, the first at the nearest distance
//! in its order (slot by slot, each leaf's references in turn): from the lanes hit, and the
//! boxes tested one by one. The quad test is `intersect::
//! hit_quad` term for term in the same order (glam's dot is (x + y) + z, its cross the
//! textbook one, and nothing is fused), so each distance is the scalar test's bit for bit, and
//! the hit is the walk's, ties included (a ray through the edge two quads share: tested on
//! the rays the scenes trace). Spheres stay with the walk: tested here in lanes, bit for bit,
//! they made `lamp` 24 % and `basic` 12 % slower (BENCHMARKS.md, "The peer measured again").

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

/// The quads in blocks (lanes in the walk's order), the boxes, and where each stands in the
/// walk's order (its step: the walk tests primitives slot by slot, each leaf's in turn).
pub struct Few {
    blocks: Vec<Block>,
    boxes: Vec<Cuboid>,
    /// Per quad lane: its reference and its step.
    quad_r: Vec<u32>,
    quad_step: Vec<u32>,
    /// Per box: its reference, its step and its root slot.
    box_r: Vec<u32>,
    box_step: Vec<u32>,
    box_slot: Vec<u32>,
    /// Per mask of root slots (the slab test's answer): the quad lanes and the steps whose
    /// slot it holds, as bits.
    lanes_in: Box<[u16; 256]>,
    steps_in: Box<[u32; 256]>,
}

impl Few {
    /// The test for a scene of these primitives, where it applies: quads and boxes only, at
    /// most `MAX_QUADS` and `MAX_BOXES`, their tree one eight-wide node of leaves (`bvh8`,
    /// whose leaves index `refs`).
    pub fn of(bvh8: &Bvh8, refs: &[u32], quads: &[Quad], boxes: &[Cuboid]) -> Option<Few> {
        let leaves = bvh8.one_node_leaves()?;
        let (mut lane_quads, mut few_boxes) = (Vec::new(), Vec::new());
        let (mut quad_r, mut quad_step, mut quad_slot) = (Vec::new(), Vec::new(), Vec::new());
        let (mut box_r, mut box_step, mut box_slot) = (Vec::new(), Vec::new(), Vec::new());
        let mut step_slot = Vec::new();
        for (slot, first, count) in leaves {
            for &r in &refs[first as usize..first as usize + count as usize] {
                let i = (r & REF_INDEX) as usize;
                let step = step_slot.len() as u32;
                match r >> 30 {
                    1 => {
                        lane_quads.push(quads[i]);
                        quad_r.push(r);
                        quad_step.push(step);
                        quad_slot.push(slot);
                    }
                    2 => {
                        few_boxes.push(boxes[i]);
                        box_r.push(r);
                        box_step.push(step);
                        box_slot.push(slot);
                    }
                    _ => return None,
                }
                step_slot.push(slot);
            }
        }
        if lane_quads.len() > MAX_QUADS || few_boxes.len() > MAX_BOXES {
            return None;
        }
        let bits_in = |slots: &[u32], mask: usize| {
            slots
                .iter()
                .enumerate()
                .filter(|(_, s)| mask >> **s & 1 != 0)
                .fold(0u32, |b, (i, _)| b | 1 << i)
        };
        let lanes_in = Box::new(std::array::from_fn(|m| bits_in(&quad_slot, m) as u16));
        let steps_in = Box::new(std::array::from_fn(|m| bits_in(&step_slot, m)));
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
            quad_r,
            quad_step,
            box_r,
            box_step,
            box_slot,
            lanes_in,
            steps_in,
        })
    }

    /// Per lane of `b`, the distance to its quad if in (0, t_max), else NO_HIT: `hit_quad`
    /// in lanes; and the lanes hit, as bits.
    #[target_feature(enable = "avx")]
    fn block(b: &Block, o: &[__m256; 3], d: &[__m256; 3], t_max: __m256) -> (__m256, u32) {
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
        (
            _mm256_blendv_ps(_mm256_set1_ps(NO_HIT), t, hit),
            _mm256_movemask_ps(hit) as u32,
        )
    }

    /// Every quad's distance along `ray` (NO_HIT where it is missed or not before t_max), and
    /// the lanes hit, as bits.
    #[target_feature(enable = "avx")]
    fn distances(&self, ray: &Ray, t_max: f32) -> ([f32; MAX_QUADS], u32) {
        let o = [ray.origin.x, ray.origin.y, ray.origin.z].map(|x| _mm256_set1_ps(x));
        let d = [ray.dir.x, ray.dir.y, ray.dir.z].map(|x| _mm256_set1_ps(x));
        let t_max = _mm256_set1_ps(t_max);
        let (mut out, mut hits) = ([NO_HIT; MAX_QUADS], 0);
        for (i, b) in self.blocks.iter().enumerate() {
            let (t, hit) = Self::block(b, &o, &d, t_max);
            // SAFETY: eight floats at 8·i, within MAX_QUADS (at most two blocks).
            unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(8 * i), t) };
            hits |= hit << (8 * i);
        }
        (out, hits)
    }

    /// The bits of the quad lanes and of the boxes whose reference is one of `rs`.
    fn named(&self, rs: [u32; 2]) -> (u32, u32) {
        let of = |refs: &[u32]| {
            refs.iter()
                .enumerate()
                .filter(|(_, r)| rs.contains(r))
                .fold(0u32, |b, (i, _)| b | 1 << i)
        };
        (of(&self.quad_r), of(&self.box_r))
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
        let (ts, hits) = self.distances(ray, t_max);
        let (skip_lane, skip_box) = self.named([skip, skip]);
        // The walk keeps the first primitive at the nearest distance, in its order: the
        // quads hit, lowest lane (earliest step) first, then the boxes at their steps.
        let (mut best, mut t_best, mut best_step) = (None, t_max, u32::MAX);
        let mut lanes = hits & u32::from(self.lanes_in[mask as usize]) & !skip_lane;
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            if ts[l] < t_best {
                (t_best, best_step) = (ts[l], self.quad_step[l]);
                best = Some((ts[l], self.quad_r[l]));
            }
        }
        for (i, bx) in self.boxes.iter().enumerate() {
            if mask >> self.box_slot[i] & 1 == 0 || skip_box >> i & 1 != 0 {
                continue;
            }
            let t = hit_box(bx, ray, t_max);
            if t > 0.0 && (t < t_best || (t == t_best && self.box_step[i] < best_step)) {
                (t_best, best_step) = (t, self.box_step[i]);
                best = Some((t, self.box_r[i]));
            }
        }
        // The walk tests every primitive of the slots entered but the one left.
        let in_mask = self.steps_in[mask as usize];
        let skipped = if skip_lane != 0 {
            in_mask >> self.quad_step[skip_lane.trailing_zeros() as usize] & 1
        } else if skip_box != 0 {
            in_mask >> self.box_step[skip_box.trailing_zeros() as usize] & 1
        } else {
            0
        };
        (best, u64::from(in_mask.count_ones() - skipped))
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
        let (_, hits) = self.distances(ray, t_max);
        let (left_lanes, left_boxes) = self.named([skip, from]);
        // The walk stops at the first primitive in its order that blocks the ray: the
        // lowest lane hit, or a box before it.
        let lanes = hits & u32::from(self.lanes_in[mask as usize]) & !left_lanes;
        let mut first = if lanes != 0 {
            self.quad_step[lanes.trailing_zeros() as usize]
        } else {
            u32::MAX
        };
        for (i, bx) in self.boxes.iter().enumerate() {
            if self.box_step[i] < first
                && mask >> self.box_slot[i] & 1 != 0
                && left_boxes >> i & 1 == 0
                && hit_box(bx, ray, t_max) > 0.0
            {
                first = self.box_step[i];
                break;
            }
        }
        // The walk counts every primitive of the slots entered up to where it stops.
        let in_mask = self.steps_in[mask as usize];
        let counted = if first == u32::MAX {
            in_mask
        } else {
            in_mask & (u32::MAX >> (31 - first))
        };
        (first != u32::MAX, u64::from(counted.count_ones()))
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
