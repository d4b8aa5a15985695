//! Eight-wide BVH nodes for the single-ray walk on CPUs with AVX: the four-wide tree
//! (`cpu::bvh`) collapsed once more, each node opening its children with the largest surface
//! area until eight slots are full (as `bvh::wide` collapses the binary tree), so that one
//! node's eight slab tests are one AVX operation per term and a walk visits fewer nodes
//! (Wald, Benthin & Boulos, "Getting Rid of Packets", RT 2008; Embree's BVH8). The nearest
//! hit is the four-wide walk's bit for bit (the same primitive tests; tested).

use super::bvh::{AnyWalk, Bvh4, Entry, Node4, Tally, Walk, nearest_in, slots};
use super::intersect::{Ray, safe_inverse};
use super::tri8::{Leaves, Ray8};
use std::arch::x86_64::*;
use std::ops::ControlFlow;

/// Slots of a node.
const WIDE: usize = 8;
/// Pending entries a walk may need: each visit pushes at most seven more than it takes,
/// over at most as many levels as the four-wide tree has.
const STACK: usize = (WIDE - 1) * crate::bvh::wide::LEVELS + WIDE;

/// Eight children: their bounds by axis, and for each either an inner node or a leaf, as in
/// `Node4`. 256 bytes.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Node8 {
    min: [__m256; 3],
    max: [__m256; 3],
    child: [u32; WIDE],
    count: [u16; WIDE],
    valid: u8,
    leaves: u8,
}

/// The root node's slots: their boxes by axis, and for each an inner node or a leaf's first
/// reference and count (`Node8`'s fields).
pub struct Root {
    pub min: [[f32; WIDE]; 3],
    pub max: [[f32; WIDE]; 3],
    pub child: [u32; WIDE],
    pub count: [u16; WIDE],
    pub valid: u8,
    pub leaves: u8,
}

/// A ray's visit of the root made elsewhere (the lanes' first step of the walk), for
/// `Bvh8::closest_below_root`: the best hit among the root's leaves, the distance it sets,
/// and the inner slots the ray enters, with their entry distances (by slot).
pub struct AtRoot {
    pub best: Option<(f32, u32)>,
    pub t_best: f32,
    pub inner: u32,
    pub near: [f32; WIDE],
}

/// The eight-wide tree; leaf slots index the four-wide tree's references.
pub struct Bvh8 {
    nodes: Vec<Node8>,
}

/// The walk's stack, reused from walk to walk.
pub struct Stack8(Box<[Entry; STACK]>);

impl Default for Stack8 {
    fn default() -> Stack8 {
        Stack8(Box::new([Entry::default(); STACK]))
    }
}

/// A child being placed in a node: bounds, and a four-wide node to open or a leaf.
#[derive(Clone, Copy)]
struct Kid {
    min: [f32; 3],
    max: [f32; 3],
    inner: Option<u32>,
    first: u32,
    count: u16,
}

fn kids_of(n: &Node4) -> impl Iterator<Item = Kid> + '_ {
    let (lo, hi) = (
        [n.min_x, n.min_y, n.min_z].map(|v| v.to_array()),
        [n.max_x, n.max_y, n.max_z].map(|v| v.to_array()),
    );
    slots(n.valid as u32).map(move |s| Kid {
        min: [lo[0][s], lo[1][s], lo[2][s]],
        max: [hi[0][s], hi[1][s], hi[2][s]],
        inner: (n.leaves >> s & 1 == 0).then_some(n.child[s]),
        first: n.child[s],
        count: n.count[s],
    })
}

fn area(k: &Kid) -> f32 {
    crate::bvh::wide::half_area(&k.min, &k.max)
}

impl Bvh8 {
    /// `b4` collapsed to eight-wide nodes, the root first.
    pub fn new(b4: &Bvh4) -> Bvh8 {
        let mut b = Bvh8 { nodes: Vec::new() };
        if !b4.nodes.is_empty() {
            b.node(b4, 0);
        }
        b
    }

    fn node(&mut self, b4: &Bvh4, i: usize) -> u32 {
        let mut kids: Vec<Kid> = kids_of(&b4.nodes[i]).collect();
        // Open the largest inner child while its children fit.
        loop {
            let open = kids
                .iter()
                .enumerate()
                .filter_map(|(j, k)| {
                    let n = &b4.nodes[k.inner? as usize];
                    (kids.len() - 1 + n.valid.count_ones() as usize <= WIDE).then_some(j)
                })
                .max_by(|&a, &b| area(&kids[a]).total_cmp(&area(&kids[b])));
            let Some(j) = open else { break };
            let k = kids.swap_remove(j);
            kids.extend(kids_of(
                &b4.nodes[k.inner.expect("an inner child") as usize],
            ));
        }
        let at = self.nodes.len();
        // SAFETY: all-zero bits are valid for every field.
        self.nodes.push(unsafe { std::mem::zeroed() });
        let mut lo = [[f32::INFINITY; WIDE]; 3];
        let mut hi = [[f32::NEG_INFINITY; WIDE]; 3];
        let (mut child, mut count) = ([0u32; WIDE], [0u16; WIDE]);
        let (mut valid, mut leaves) = (0u8, 0u8);
        for (s, k) in kids.iter().enumerate() {
            for c in 0..3 {
                lo[c][s] = k.min[c];
                hi[c][s] = k.max[c];
            }
            valid |= 1 << s;
            match k.inner {
                Some(inner) => child[s] = self.node(b4, inner as usize),
                None => {
                    (child[s], count[s]) = (k.first, k.count);
                    leaves |= 1 << s;
                }
            }
        }
        // SAFETY: unaligned loads of eight floats.
        let load = |a: &[f32; WIDE]| unsafe { _mm256_loadu_ps(a.as_ptr()) };
        self.nodes[at] = Node8 {
            min: lo.each_ref().map(load),
            max: hi.each_ref().map(load),
            child,
            count,
            valid,
            leaves,
        };
        at as u32
    }

    /// The root node as plain numbers, for the lanes' first step of the walk (`cpu::lanes`).
    pub fn root(&self) -> Option<Root> {
        let n = self.nodes.first()?;
        // SAFETY: an `__m256` is eight floats (a copy; no instruction needs AVX).
        let floats = |v: __m256| unsafe { std::mem::transmute::<__m256, [f32; WIDE]>(v) };
        Some(Root {
            min: n.min.map(floats),
            max: n.max.map(floats),
            child: n.child,
            count: n.count,
            valid: n.valid,
            leaves: n.leaves,
        })
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Where the tree is one node whose children are all leaves (a scene of a few
    /// primitives), its leaf slots in the order the walk tests them: (slot, first reference,
    /// count).
    pub fn one_node_leaves(&self) -> Option<Vec<(u32, u32, u16)>> {
        let n = self.nodes.first()?;
        (self.nodes.len() == 1 && n.leaves == n.valid).then(|| {
            slots(n.valid as u32)
                .map(|s| (s as u32, n.child[s], n.count[s]))
                .collect()
        })
    }

    /// The root's slots whose boxes `ray` enters before t_max, as `closest` tests them.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub unsafe fn root_mask(&self, ray: &Ray, t_max: f32) -> u32 {
        let n = &self.nodes[0];
        let (o, inv) = Self::ray_terms(ray);
        Self::slab(n, &o, &inv, t_max).1
    }

    /// The ray's origin and inverse direction in every slot (`Bvh4::ray_terms`, eight wide).
    #[inline]
    #[target_feature(enable = "avx")]
    fn ray_terms(ray: &Ray) -> ([__m256; 3], [__m256; 3]) {
        let inv = safe_inverse(ray.dir);
        (
            [ray.origin.x, ray.origin.y, ray.origin.z].map(|x| _mm256_set1_ps(x)),
            [inv.x, inv.y, inv.z].map(|x| _mm256_set1_ps(x)),
        )
    }

    /// The slab test of `n`'s eight boxes (one AVX operation per term) for the ray from `o`
    /// with inverse direction `inv`: each slot's entry distance, and the slots entered before
    /// `t_best`.
    #[target_feature(enable = "avx")]
    fn slab(n: &Node8, o: &[__m256; 3], inv: &[__m256; 3], t_best: f32) -> (__m256, u32) {
        let slab = |k: usize| {
            let t0 = _mm256_mul_ps(_mm256_sub_ps(n.min[k], o[k]), inv[k]);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(n.max[k], o[k]), inv[k]);
            (_mm256_min_ps(t0, t1), _mm256_max_ps(t0, t1))
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (slab(0), slab(1), slab(2));
        let near = _mm256_max_ps(
            _mm256_max_ps(nx, ny),
            _mm256_max_ps(nz, _mm256_setzero_ps()),
        );
        let far = _mm256_min_ps(
            _mm256_min_ps(fx, fy),
            _mm256_min_ps(fz, _mm256_set1_ps(t_best)),
        );
        let mask =
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32 & n.valid as u32;
        (near, mask)
    }

    /// `Bvh4::closest` over the eight-wide nodes (`refs` the four-wide tree's references).
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub unsafe fn closest(
        &self,
        refs: &[u32],
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack8,
        test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        let mut one_by_one = Leaves::one_by_one();
        // SAFETY: as this function's.
        unsafe { self.closest_in(refs, ray, t_max, tally, stack, &mut one_by_one, test) }
    }

    /// `closest`, the leaves of plain triangles tested eight at a time where `leaves` has
    /// their columns (`Tri8::closest`: the same hit), primitive `leaves.skip` left out.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx")]
    pub unsafe fn closest_in(
        &self,
        refs: &[u32],
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack8,
        leaves: &mut Leaves<'_>,
        test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let w = Walk::new(&mut *stack.0, t_max);
        let r8 = Ray8::of(ray);
        let mut leaf = closest_leaf(refs, leaves, &r8, test);
        self.walk_from(ray, w, Some(0), tally, &mut leaf)
    }

    /// `closest_in` where the root has been visited already, its leaves tested (by the lanes,
    /// `cpu::lanes`): `at` holds the best hit they found and the root's inner slots to enter,
    /// with their entry distances. The walk goes on from there as `closest`'s would: the
    /// same nodes in the same order, so the same hit bit for bit.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx")]
    pub unsafe fn closest_below_root(
        &self,
        refs: &[u32],
        ray: &Ray,
        at: &AtRoot,
        tally: &mut Tally,
        stack: &mut Stack8,
        leaves: &mut Leaves<'_>,
        test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        let Some(n) = self.nodes.first() else {
            return at.best;
        };
        let mut w = Walk::new(&mut *stack.0, at.t_best);
        w.best = at.best;
        let inner = at.inner & !(n.leaves as u32);
        let r8 = Ray8::of(ray);
        let mut leaf = closest_leaf(refs, leaves, &r8, test);
        let next = w.visit_leaves(inner, 0, &at.near, &n.child, &n.count, tally, &mut leaf);
        self.walk_from(ray, w, next, tally, &mut leaf)
    }

    /// The closest-hit walk from node `node` on (none: the walk is over), each leaf's
    /// primitives tested by `leaf` (`Walk::visit_leaves`).
    #[inline]
    #[target_feature(enable = "avx")]
    fn walk_from(
        &self,
        ray: &Ray,
        mut w: Walk<'_>,
        mut node: Option<usize>,
        tally: &mut Tally,
        leaf: &mut impl FnMut(usize, usize, f32) -> Option<(f32, u32)>,
    ) -> Option<(f32, u32)> {
        let (o, inv) = Self::ray_terms(ray);
        while let Some(at) = node {
            let n = &self.nodes[at];
            tally.visits += 1;
            let (near, mask) = Self::slab(n, &o, &inv, w.t_best);
            let mut t = [0.0f32; WIDE];
            // SAFETY: eight floats.
            unsafe { _mm256_storeu_ps(t.as_mut_ptr(), near) };
            let leaves = n.leaves as u32;
            node = w.visit_leaves(mask, leaves, &t, &n.child, &n.count, tally, leaf);
        }
        w.best
    }

    /// `Bvh4::any` over the eight-wide nodes: whether `test` finds any primitive before
    /// `t_max` (shadow rays: any order, the first blocker ends the walk).
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub unsafe fn any(
        &self,
        refs: &[u32],
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack8,
        test: impl FnMut(u32) -> bool,
    ) -> bool {
        let one_by_one = Leaves::one_by_one();
        self.any_given(refs, ray, (t_max, None), tally, stack, &one_by_one, test)
    }

    /// `any`, the leaves of plain triangles tested eight at a time where `leaves` has their
    /// columns (`Tri8::any`), primitives `leaves.skip` and `leaves.from` left out.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx")]
    pub unsafe fn any_in(
        &self,
        refs: &[u32],
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack8,
        leaves: &Leaves<'_>,
        test: impl FnMut(u32) -> bool,
    ) -> bool {
        self.any_given(refs, ray, (t_max, None), tally, stack, leaves, test)
    }

    /// `any_in` where the root has been visited already (by the lanes, `cpu::lanes`): `slots`
    /// are the root's slots the ray enters before t_max, less the leaves already tested.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx")]
    pub unsafe fn any_below_root(
        &self,
        refs: &[u32],
        ray: &Ray,
        (t_max, slots): (f32, u32),
        tally: &mut Tally,
        stack: &mut Stack8,
        leaves: &Leaves<'_>,
        test: impl FnMut(u32) -> bool,
    ) -> bool {
        self.any_given(refs, ray, (t_max, Some(slots)), tally, stack, leaves, test)
    }

    /// `any_in`, the root's slots entered `given` where they are (`any_below_root`).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    #[target_feature(enable = "avx")]
    fn any_given(
        &self,
        refs: &[u32],
        ray: &Ray,
        (t_max, given): (f32, Option<u32>),
        tally: &mut Tally,
        stack: &mut Stack8,
        leaves: &Leaves<'_>,
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let w = AnyWalk::new(&mut *stack.0);
        let r8 = Ray8::of(ray);
        let mut leaf = |first: usize, n: usize| match leaves.tris {
            Some(tris) if tris.plain(first, n) => {
                tris.any((first, n), &r8, t_max, (leaves.skip, leaves.from))
            }
            _ => any_in(&refs[first..first + n], &mut test),
        };
        // (The root's slots given, not tested: `leaf` called from one place stays inline.)
        self.any_from(ray, t_max, w, (0, given), tally, &mut leaf)
    }

    /// The any-hit walk from node `node` on (its slots entered `given`, where they are),
    /// each leaf's primitives tested by `leaf` (`AnyWalk::visit_leaves`).
    #[inline]
    #[target_feature(enable = "avx")]
    fn any_from(
        &self,
        ray: &Ray,
        t_max: f32,
        mut w: AnyWalk<'_>,
        (mut node, mut given): (usize, Option<u32>),
        tally: &mut Tally,
        leaf: &mut impl FnMut(usize, usize) -> bool,
    ) -> bool {
        let (o, inv) = Self::ray_terms(ray);
        loop {
            let n = &self.nodes[node];
            let mask = given.take().unwrap_or_else(|| {
                tally.visits += 1;
                Self::slab(n, &o, &inv, t_max).1
            });
            let leaves = n.leaves as u32;
            match w.visit_leaves(mask, leaves, &n.child, &n.count, tally, leaf) {
                ControlFlow::Continue(next) => node = next,
                ControlFlow::Break(blocked) => return blocked,
            }
        }
    }
}

/// The closest-hit walks' test of a leaf (`Walk::visit_leaves`): eight at a time where
/// `leaves` has the columns of its plain triangles (`Tri8::closest`, the ray `r8`), else one
/// by one with `test`.
#[inline]
#[target_feature(enable = "avx")]
fn closest_leaf<'a>(
    refs: &'a [u32],
    leaves: &'a mut Leaves<'_>,
    r8: &'a Ray8,
    mut test: impl FnMut(u32, f32) -> f32 + 'a,
) -> impl FnMut(usize, usize, f32) -> Option<(f32, u32)> + 'a {
    move |first, n, t_best| match leaves.tris {
        Some(tris) if tris.plain(first, n) => {
            let skip = (leaves.skip, &mut leaves.skipped);
            tris.closest((first, n), r8, t_best, skip)
        }
        _ => nearest_in(&refs[first..first + n], t_best, &mut test),
    }
}

/// Whether `test` finds any of primitives `refs` (a loop, not `Iterator::any`, which the
/// compiler left out of line).
#[inline(always)]
fn any_in(refs: &[u32], test: &mut impl FnMut(u32) -> bool) -> bool {
    for &r in refs {
        if test(r) {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::bvh::Stack;
    use crate::cpu::trace::{ANY, T_FAR, hit_primitive, recorded};

    #[test]
    fn the_eight_wide_walks_find_what_the_four_wide_ones_find_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("no AVX: nothing to compare");
            return;
        }
        // Spheres; triangles; quads, boxes and a light.
        for name in ["weekend", "mesh", "cornell"] {
            let (s, segments) = recorded(name, 64, 36, 1);
            let rays: Vec<Ray> = segments.into_iter().map(|(_, r)| r).collect();
            let b8 = Bvh8::new(&s.bvh);
            let n4 = s.bvh.nodes.len();
            eprintln!(
                "{name}: {n4} four-wide nodes, {} eight-wide",
                b8.node_count()
            );
            assert!(b8.node_count() < n4 || n4 == 1, "{name}: nothing collapsed");
            let (mut tally, mut stack, mut stack8) =
                (Tally::default(), Stack::default(), Stack8::default());
            let (mut hits, mut blocked) = (0, 0);
            for ray in &rays {
                let test = |r, t| hit_primitive::<ANY>(&s, r, ray, t);
                let want = s.bvh.closest(ray, T_FAR, &mut tally, &mut stack, test);
                // SAFETY: AVX is present (checked above).
                let got =
                    unsafe { b8.closest(&s.bvh.refs, ray, T_FAR, &mut tally, &mut stack8, test) };
                let bits = |h: Option<(f32, u32)>| h.map(|(t, r)| (t.to_bits(), r));
                assert_eq!(bits(want), bits(got), "{name}: {ray:?}");
                hits += want.is_some() as u32;
                // The any-hit walks, up to the hit and just short of it, and unbounded.
                for t_max in want.map_or(vec![T_FAR], |(t, _)| vec![t, t * 0.999, T_FAR]) {
                    let test = |r| hit_primitive::<ANY>(&s, r, ray, t_max) > 0.0;
                    let want = s.bvh.any(ray, t_max, &mut tally, &mut stack, test);
                    // SAFETY: AVX is present (checked above).
                    let got =
                        unsafe { b8.any(&s.bvh.refs, ray, t_max, &mut tally, &mut stack8, test) };
                    assert_eq!(want, got, "{name}: {ray:?} before {t_max}");
                    blocked += want as u32;
                }
            }
            assert!(hits > 1000, "{name}: only {hits} hits compared");
            assert!(
                blocked > 1000,
                "{name}: only {blocked} blocked any-hit walks compared"
            );
        }
    }
}

/// The estimate behind BENCHMARKS.md "Paths in SIMD lanes, walked each on its own": the
/// loads of one step of sixteen rays each at its own binary node (its two children's boxes:
/// twelve AVX-512 gathers), in a chain where the next nodes depend on what was loaded.
/// `cargo test --release --lib gather_step_cost -- --ignored --nocapture`.
#[cfg(test)]
mod gather_estimate {
    use std::arch::x86_64::*;
    use std::time::Instant;

    #[target_feature(enable = "avx512f")]
    fn steps(nodes: &[f32], steps: usize) -> f32 {
        let last = (nodes.len() / 16 - 1) as i32;
        let mut node = _mm512_setr_epi32(
            0, 37, 74, 111, 148, 185, 222, 259, 296, 333, 370, 407, 444, 481, 6, 43,
        );
        let mut acc = _mm512_setzero_ps();
        for _ in 0..steps {
            for k in 0..12 {
                let at = _mm512_add_epi32(_mm512_slli_epi32::<4>(node), _mm512_set1_epi32(k));
                // SAFETY: every index is below nodes.len() (masked to `last` nodes of 16).
                acc = _mm512_add_ps(acc, unsafe { _mm512_i32gather_ps::<4>(at, nodes.as_ptr()) });
            }
            let next = _mm512_add_epi32(node, _mm512_cvttps_epi32(acc));
            node = _mm512_and_si512(
                _mm512_add_epi32(next, _mm512_set1_epi32(7)),
                _mm512_set1_epi32(last),
            );
        }
        _mm512_reduce_add_ps(acc)
    }

    #[test]
    #[ignore]
    fn gather_step_cost() {
        assert!(std::arch::is_x86_feature_detected!("avx512f"), "no AVX-512");
        // 512 nodes of 64 bytes (weekend's binary tree is about that size), all zero so that
        // the chain stays in range.
        let nodes = vec![0.0f32; 512 * 16];
        let n = 2_000_000;
        let start = Instant::now();
        // SAFETY: AVX-512F is present (asserted above).
        let sum = unsafe { steps(&nodes, n) };
        let ns = start.elapsed().as_secs_f64() * 1e9 / n as f64;
        eprintln!(
            "{ns:.1} ns per step of 16 rays, {:.2} ns per ray ({sum})",
            ns / 16.0
        );
    }
}
