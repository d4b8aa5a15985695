//! A leaf's triangles tested eight at a time in the eight-wide walks (`cpu::bvh8`): the
//! triangles' corners and edges by component, in the order of the tree's references, so that
//! a leaf's are eight consecutive floats per term and one AVX operation tests them all
//! (Wald, Benthin & Boulos, "Getting Rid of Packets", RT 2008; Embree's Triangle4/8 leaves).
//! The test is `intersect::hit_triangle` term for term in the same order (glam's dot is
//! (x + y) + z, its cross the textbook one, and nothing is fused), so each lane's distance is
//! the scalar test's bit for bit; the hit chosen is the walk's, the first at the nearest
//! distance in the leaf's order (a ray through an edge two triangles share included: tested
//! here and with the paths, `lanes_trace_the_scalar_paths_bit_for_bit`).

use super::intersect::{TRIANGLE_SLACK, Triangle};
use crate::common::arrays::REF_INDEX;
use std::arch::x86_64::*;

/// Lanes of one test.
const WIDE: usize = 8;

/// The triangles of the tree's references by component (a reference to anything else has
/// zeros, which no test reads), and for each reference how many plain triangles follow from
/// it on (itself included, at most 255): a leaf is tested here where they are all of it.
pub struct Tri8 {
    /// v0, e1 and e2 by component, each padded with `WIDE` zeros so that the last leaf's
    /// eight loads stay inside.
    cols: [Vec<f32>; 9],
    /// The references, likewise padded (with ones no primitive has).
    refs: Vec<u32>,
    run: Vec<u8>,
}

/// A ray's origin and direction in every lane.
pub struct Ray8 {
    o: [__m256; 3],
    d: [__m256; 3],
}

impl Ray8 {
    /// # Safety
    /// The CPU must have AVX.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn of(ray: &super::intersect::Ray) -> Ray8 {
        let (o, d) = (ray.origin, ray.dir);
        Ray8 {
            o: [o.x, o.y, o.z].map(|x| _mm256_set1_ps(x)),
            d: [d.x, d.y, d.z].map(|x| _mm256_set1_ps(x)),
        }
    }
}

/// The distances of eight triangles, and the lanes they hit before their bound.
struct Hits {
    t: __m256,
    mask: u32,
}

impl Tri8 {
    /// The columns of the references `refs` (kind in the top bits: 3 a triangle, unless
    /// it is an instance's) to `triangles`; None where no reference is a plain triangle.
    pub fn new(refs: &[u32], triangles: &[Triangle]) -> Option<Tri8> {
        let plain = |r: u32| r >> 30 == 3 && r & crate::common::arrays::INSTANCE_BIT == 0;
        if !refs.iter().any(|&r| plain(r)) {
            return None;
        }
        let mut cols: [Vec<f32>; 9] =
            std::array::from_fn(|_| Vec::with_capacity(refs.len() + WIDE));
        for &r in refs {
            let t = plain(r).then(|| triangles[(r & REF_INDEX) as usize]);
            let v = t.map_or([0.0; 9], |t| {
                [
                    t.v0.x, t.v0.y, t.v0.z, t.e1.x, t.e1.y, t.e1.z, t.e2.x, t.e2.y, t.e2.z,
                ]
            });
            for (c, x) in cols.iter_mut().zip(v) {
                c.push(x);
            }
        }
        for c in &mut cols {
            c.extend([0.0; WIDE]);
        }
        let mut run = vec![0u8; refs.len()];
        for i in (0..refs.len()).rev() {
            if plain(refs[i]) {
                run[i] = run.get(i + 1).map_or(1, |&n| n.saturating_add(1));
            }
        }
        let mut padded = refs.to_vec();
        padded.extend([u32::MAX; WIDE]);
        Some(Tri8 {
            cols,
            refs: padded,
            run,
        })
    }

    /// Whether the `n` references from `first` on are all plain triangles.
    #[inline(always)]
    pub fn plain(&self, first: usize, n: usize) -> bool {
        self.run[first] as usize >= n
    }

    /// `hit_triangle` of the eight references from `first` on, against bound `t_max`.
    #[inline]
    #[target_feature(enable = "avx")]
    fn hits(&self, first: usize, ray: &Ray8, t_max: f32) -> Hits {
        // SAFETY: the columns hold `WIDE` floats past the last reference.
        let col = |k: usize| unsafe { _mm256_loadu_ps(self.cols[k].as_ptr().add(first)) };
        let (v0, e1, e2) = (
            [col(0), col(1), col(2)],
            [col(3), col(4), col(5)],
            [col(6), col(7), col(8)],
        );
        let (o, d) = (&ray.o, &ray.d);
        let p = cross(d, &e2);
        let det = dot(&e1, &p);
        // `det == 0.0` misses (a NaN goes on, to miss at u).
        let mut ok = _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, _mm256_setzero_ps());
        let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
        let s = [0, 1, 2].map(|k| _mm256_sub_ps(o[k], v0[k]));
        let u = _mm256_mul_ps(dot(&s, &p), inv);
        let (lo, hi) = (
            _mm256_set1_ps(-TRIANGLE_SLACK),
            _mm256_set1_ps(1.0 + TRIANGLE_SLACK),
        );
        ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_GE_OQ>(u, lo));
        ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_LE_OQ>(u, hi));
        let q = cross(&s, &e1);
        let v = _mm256_mul_ps(dot(d, &q), inv);
        let out = _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(v, lo),
            _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_add_ps(u, v), hi),
        );
        ok = _mm256_andnot_ps(out, ok);
        let t = _mm256_mul_ps(dot(&e2, &q), inv);
        ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_setzero_ps()));
        ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(t_max)));
        Hits {
            t,
            mask: _mm256_movemask_ps(ok) as u32,
        }
    }

    /// The first of the `n` triangles from reference `first` on (all plain: `plain`) at the
    /// nearest distance below `t_best`, as `bvh::nearest_in` finds it with `hit_triangle`,
    /// `skip` left out (and counted in `skipped`).
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn closest(
        &self,
        (first, n): (usize, usize),
        ray: &Ray8,
        mut t_best: f32,
        (skip, skipped): (u32, &mut u64),
    ) -> Option<(f32, u32)> {
        let mut best = None;
        let (mut at, end) = (first, first + n);
        while at < end {
            let lanes = lanes_below(end - at);
            let skips = self.lanes_of(at, skip) & lanes;
            *skipped += skips.count_ones() as u64;
            let h = self.hits(at, ray, t_best);
            let mut mask = h.mask & lanes & !skips;
            if mask != 0 {
                let mut t = [0.0f32; WIDE];
                // SAFETY: eight floats.
                unsafe { _mm256_storeu_ps(t.as_mut_ptr(), h.t) };
                // In the leaf's order, each against the best so far: ties go to the first.
                while mask != 0 {
                    let j = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if t[j] < t_best {
                        t_best = t[j];
                        best = Some((t[j], self.refs[at + j]));
                    }
                }
            }
            at += WIDE;
        }
        best
    }

    /// Whether any of the `n` triangles from reference `first` on (all plain) but `skip` and
    /// `from` lies on the ray before `t_max` (`trace::blocks` with `hit_triangle`).
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn any(
        &self,
        (first, n): (usize, usize),
        ray: &Ray8,
        t_max: f32,
        (skip, from): (u32, u32),
    ) -> bool {
        let (mut at, end) = (first, first + n);
        while at < end {
            let lanes =
                lanes_below(end - at) & !(self.lanes_of(at, skip) | self.lanes_of(at, from));
            if self.hits(at, ray, t_max).mask & lanes != 0 {
                return true;
            }
            at += WIDE;
        }
        false
    }

    /// The lanes of the eight references from `at` on that are `r`. (Compared as floats: a
    /// triangle's reference, its top bits set, is a normal negative float, which equals only
    /// the same bits.)
    #[inline]
    #[target_feature(enable = "avx")]
    fn lanes_of(&self, at: usize, r: u32) -> u32 {
        // SAFETY: the references hold `WIDE` more past the last.
        let refs = unsafe { _mm256_loadu_ps(self.refs.as_ptr().add(at) as *const f32) };
        let eq = _mm256_cmp_ps::<_CMP_EQ_OQ>(refs, _mm256_set1_ps(f32::from_bits(r)));
        _mm256_movemask_ps(eq) as u32
    }
}

/// The lanes of a block with `left` references left in the leaf.
#[inline(always)]
fn lanes_below(left: usize) -> u32 {
    if left >= WIDE {
        (1 << WIDE) - 1
    } else {
        (1 << left) - 1
    }
}

/// glam's dot, (x + y) + z, eight lanes at a time.
#[inline]
#[target_feature(enable = "avx")]
fn dot(a: &[__m256; 3], b: &[__m256; 3]) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
        _mm256_mul_ps(a[2], b[2]),
    )
}

/// glam's (the textbook) cross product, eight lanes at a time.
#[inline]
#[target_feature(enable = "avx")]
fn cross(a: &[__m256; 3], b: &[__m256; 3]) -> [__m256; 3] {
    let term =
        |i: usize, j: usize| _mm256_sub_ps(_mm256_mul_ps(a[i], b[j]), _mm256_mul_ps(a[j], b[i]));
    [term(1, 2), term(2, 0), term(0, 1)]
}

/// How a walk tests its leaves: those of plain triangles eight at a time where `tris` has
/// their columns, the rest one by one; `skip` (the primitive a ray leaves, whose tests are
/// counted in `skipped`) and for shadow rays `from` left out.
pub struct Leaves<'a> {
    pub tris: Option<&'a Tri8>,
    pub skip: u32,
    pub from: u32,
    pub skipped: u64,
}

impl Leaves<'_> {
    /// Every leaf tested one by one, by the walk's own test (which leaves out what it will).
    pub fn one_by_one() -> Leaves<'static> {
        Leaves {
            tris: None,
            skip: u32::MAX,
            from: u32::MAX,
            skipped: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::bvh::Tally;
    use crate::cpu::bvh8::{Bvh8, Stack8};
    use crate::cpu::intersect::{Ray, hit_triangle};
    use crate::cpu::trace::{ANY, T_FAR, hit_primitive, recorded};
    use glam::Vec3A;

    /// The walks with the leaves of triangles tested eight at a time find what they find
    /// testing them one by one, bit for bit, and count the same tests: on the segments the
    /// paths trace (the primitive a segment leaves skipped), and on rays through the edges
    /// two triangles share, where both are hit at the same distance and the first in the
    /// leaf's order must win.
    #[test]
    fn leaves_eight_at_a_time_find_what_one_by_one_finds_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("no AVX: nothing to compare");
            return;
        }
        for name in ["mesh", "tests/assets/obj/cube-pets/animal-dog.obj"] {
            let (s, segments) = recorded(name, 48, 27, 1);
            let b8 = Bvh8::new(&s.bvh);
            let tris = Tri8::new(&s.bvh.refs, &s.triangles).expect("a scene of triangles");
            let mut rays: Vec<(u32, Ray)> = segments;
            // Through each triangle's corners and edges' midpoints, from off the surface:
            // where neighbours tie.
            let n = s.triangles.len();
            for (i, t) in s.triangles.iter().enumerate().step_by((n / 400).max(1)) {
                let normal = t.e1.cross(t.e2).normalize();
                for p in [t.v0, t.v0 + t.e1, t.v0 + 0.5 * t.e1, t.v0 + 0.5 * t.e2] {
                    for side in [1.0f32, -1.0] {
                        let origin = p + side * 0.37 * normal + Vec3A::new(0.011, 0.007, -0.013);
                        let ray = Ray {
                            origin,
                            dir: (p - origin).normalize(),
                        };
                        rays.push((i as u32 | 3 << 30, ray));
                    }
                }
            }
            let (mut tally, mut stack8) = (Tally::default(), Stack8::default());
            let (mut hits, mut ties, mut blocked) = (0, 0, 0);
            for (skip, ray) in &rays {
                let skip = *skip;
                // One by one: the walk's own test, `skip` left out and not counted.
                let mut skipped = 0;
                let mut one = Tally::default();
                let want = unsafe {
                    b8.closest(&s.bvh.refs, ray, T_FAR, &mut one, &mut stack8, |r, t| {
                        if r == skip {
                            skipped += 1;
                            return -1.0;
                        }
                        hit_primitive::<ANY>(&s, r, ray, t)
                    })
                };
                let (mut eight, mut skipped_too) = (Tally::default(), 0);
                let mut leaves = Leaves {
                    tris: Some(&tris),
                    skip,
                    from: u32::MAX,
                    skipped: 0,
                };
                let got = unsafe {
                    b8.closest_in(
                        &s.bvh.refs,
                        ray,
                        T_FAR,
                        &mut eight,
                        &mut stack8,
                        &mut leaves,
                        |r, t| {
                            if r == skip {
                                skipped_too += 1;
                                return -1.0;
                            }
                            hit_primitive::<ANY>(&s, r, ray, t)
                        },
                    )
                };
                let bits = |h: Option<(f32, u32)>| h.map(|(t, r)| (t.to_bits(), r));
                assert_eq!(bits(want), bits(got), "{name}: {ray:?} skipping {skip}");
                assert_eq!(
                    (one.visits, one.tests - skipped),
                    (eight.visits, eight.tests - leaves.skipped - skipped_too),
                    "{name}: {ray:?}"
                );
                if let Some((t, r)) = want {
                    hits += 1;
                    // Another triangle at the very same distance: a tie the order settles.
                    let same = |q: &u32| {
                        *q != r
                            && *q >> 30 == 3
                            && hit_triangle(&s.triangles[(*q & REF_INDEX) as usize], ray, T_FAR)
                                .to_bits()
                                == t.to_bits()
                    };
                    ties += s.bvh.refs.iter().any(same) as u32;
                }
                for t_max in want.map_or(vec![T_FAR], |(t, _)| vec![t, t * 0.999, T_FAR]) {
                    let from = want.map_or(u32::MAX, |h| h.1);
                    let test =
                        |r| r != skip && r != from && hit_primitive::<ANY>(&s, r, ray, t_max) > 0.0;
                    let want =
                        unsafe { b8.any(&s.bvh.refs, ray, t_max, &mut tally, &mut stack8, test) };
                    let leaves = Leaves {
                        tris: Some(&tris),
                        skip,
                        from,
                        skipped: 0,
                    };
                    let got = unsafe {
                        b8.any_in(
                            &s.bvh.refs,
                            ray,
                            t_max,
                            &mut tally,
                            &mut stack8,
                            &leaves,
                            test,
                        )
                    };
                    assert_eq!(want, got, "{name}: {ray:?} before {t_max}");
                    blocked += want as u32;
                }
            }
            eprintln!(
                "{name}: {} rays, {hits} hits, {ties} ties, {blocked} blocked",
                rays.len()
            );
            assert!(hits > 1000, "{name}: only {hits} hits compared");
            assert!(ties > 10, "{name}: only {ties} ties compared");
            assert!(blocked > 1000, "{name}: only {blocked} blocked compared");
        }
    }
}
