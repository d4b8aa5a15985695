//! The BVH as the CPU walks it: the four-wide nodes both tracers share (`bvh::wide`), their
//! bounds as `glam::Vec4` so that one node's four slab tests are one SSE operation each, and
//! the slots in use and the leaf slots as bit masks.
//!
//! Measured on `weekend` (BENCHMARKS.md, "A native CPU tracer"): 4.8 nodes visited per
//! segment, for about two primitive tests each.

use super::intersect::{Ray, safe_inverse};
use crate::bvh::wide::GpuBvhNode4;
use crate::bvh::wide::{EMPTY_SLOT, STACK};
use glam::Vec4;
use std::ops::ControlFlow;

/// Four children: their bounds by axis, and for each either an inner node (`child` its
/// index) or a leaf (`count` references from `child` on in `refs`); `valid` and `leaves`
/// are bit masks of the slots in use and of the leaf slots. 128 bytes, two cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node4 {
    pub(super) min_x: Vec4,
    pub(super) min_y: Vec4,
    pub(super) min_z: Vec4,
    pub(super) max_x: Vec4,
    pub(super) max_y: Vec4,
    pub(super) max_z: Vec4,
    pub(super) child: [u32; 4],
    pub(super) count: [u16; 4],
    pub(super) valid: u8,
    pub(super) leaves: u8,
}

#[derive(Default)]
pub struct Bvh4 {
    pub nodes: Vec<Node4>,
    /// Primitive references in leaf order (kind in the top two bits, as on the GPU).
    pub refs: Vec<u32>,
}

/// Node visits and primitive tests of one walk (benchmarks).
#[derive(Clone, Copy, Default)]
pub struct Tally {
    pub visits: u64,
    pub tests: u64,
}

/// The walk's stack of pending children, owned by the caller and reused from walk to walk
/// (zeroing a fresh one per ray cost 8 % of the time).
pub struct Stack(Box<[Entry; STACK]>);

impl Default for Stack {
    fn default() -> Stack {
        Stack(Box::new([Entry::default(); STACK]))
    }
}

#[derive(Clone, Copy, Default)]
pub struct Entry {
    pub(super) node: u32,
    pub(super) t: f32,
}

/// A closest-hit walk between node visits (the four- and the eight-wide walk share it): the
/// best hit so far and the children waiting on the stack.
pub(super) struct Walk<'s> {
    pub best: Option<(f32, u32)>,
    pub t_best: f32,
    stack: &'s mut [Entry],
    sp: usize,
}

impl<'s> Walk<'s> {
    #[inline(always)]
    pub fn new(stack: &'s mut [Entry], t_max: f32) -> Walk<'s> {
        Walk {
            best: None,
            t_best: t_max,
            stack,
            sp: 0,
        }
    }

    /// A node's children after their slab tests (`mask`: those entered; `near`: their entry
    /// distances; `child`, `count`, `leaves` as in `Node4`). Leaves hit are tested at once (a
    /// few primitives, which shorten the ray for what follows); the nearest inner child hit
    /// is the node to visit next and the others are pushed, nearest on top; with none, the
    /// nearest pending child still nearer than the best hit is. None: the walk is over.
    /// `test` gives a primitive's distance if nearer than its bound, else a value ≤ 0.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn visit(
        &mut self,
        mask: u32,
        leaves: u32,
        near: &[f32],
        child: &[u32],
        count: &[u16],
        refs: &[u32],
        tally: &mut Tally,
        test: &mut impl FnMut(u32, f32) -> f32,
    ) -> Option<usize> {
        let mut leaf = |first, n, t_best| nearest_in(&refs[first..first + n], t_best, test);
        self.visit_leaves(mask, leaves, near, child, count, tally, &mut leaf)
    }

    /// [`Walk::visit`], a leaf's primitives tested by `leaf` (its first reference, their
    /// count, the best distance so far): the first at the nearest distance below that, as
    /// [`nearest_in`] finds it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn visit_leaves(
        &mut self,
        mask: u32,
        leaves: u32,
        near: &[f32],
        child: &[u32],
        count: &[u16],
        tally: &mut Tally,
        leaf: &mut impl FnMut(usize, usize, f32) -> Option<(f32, u32)>,
    ) -> Option<usize> {
        for slot in slots(mask & leaves) {
            tally.tests += count[slot] as u64;
            if let Some((th, r)) = leaf(child[slot] as usize, count[slot] as usize, self.t_best) {
                self.t_best = th;
                self.best = Some((th, r));
            }
        }
        let mut next: Option<Entry> = None;
        let base = self.sp;
        for slot in slots(mask & !leaves) {
            if near[slot] >= self.t_best {
                continue;
            }
            let e = Entry {
                node: child[slot],
                t: near[slot],
            };
            nearest_next(&mut next, e, self.stack, base, &mut self.sp, |e| e.t);
        }
        if let Some(e) = next {
            return Some(e.node as usize);
        }
        while self.sp > 0 {
            self.sp -= 1;
            let e = self.stack[self.sp];
            if e.t < self.t_best {
                return Some(e.node as usize);
            }
        }
        None
    }
}

/// An any-hit walk between node visits (the four- and the eight-wide walk share it): the
/// children waiting on the stack, in no order (the first blocker ends the walk).
pub(super) struct AnyWalk<'s> {
    stack: &'s mut [Entry],
    sp: usize,
}

impl<'s> AnyWalk<'s> {
    #[inline(always)]
    pub fn new(stack: &'s mut [Entry]) -> AnyWalk<'s> {
        AnyWalk { stack, sp: 0 }
    }

    /// A node's children after their slab tests (`mask`: those entered; `child`, `count`,
    /// `leaves` as in `Node4`): the leaves' primitives tested (`test`: whether one blocks),
    /// the inner children pushed. `Break(true)` where one blocks, `Break(false)` where nothing
    /// is left to visit, else `Continue` with the node to visit next.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn visit(
        &mut self,
        mask: u32,
        leaves: u32,
        child: &[u32],
        count: &[u16],
        refs: &[u32],
        tally: &mut Tally,
        test: &mut impl FnMut(u32) -> bool,
    ) -> ControlFlow<bool, usize> {
        // (A loop, not `Iterator::any`, which the compiler left out of line.)
        let mut leaf = |first: usize, n: usize| {
            for &r in &refs[first..first + n] {
                if test(r) {
                    return true;
                }
            }
            false
        };
        self.visit_leaves(mask, leaves, child, count, tally, &mut leaf)
    }

    /// [`AnyWalk::visit`], a leaf's primitives tested by `leaf` (its first reference and
    /// their count): whether one blocks.
    #[inline(always)]
    pub fn visit_leaves(
        &mut self,
        mask: u32,
        leaves: u32,
        child: &[u32],
        count: &[u16],
        tally: &mut Tally,
        leaf: &mut impl FnMut(usize, usize) -> bool,
    ) -> ControlFlow<bool, usize> {
        for slot in slots(mask & leaves) {
            tally.tests += count[slot] as u64;
            if leaf(child[slot] as usize, count[slot] as usize) {
                return ControlFlow::Break(true);
            }
        }
        for slot in slots(mask & !leaves) {
            self.stack[self.sp] = Entry {
                node: child[slot],
                t: 0.0,
            };
            self.sp += 1;
        }
        if self.sp == 0 {
            return ControlFlow::Break(false);
        }
        self.sp -= 1;
        ControlFlow::Continue(self.stack[self.sp].node as usize)
    }
}

/// The first of primitives `refs` at the nearest distance below `t_best` (`test` as in
/// [`Walk::visit`]), tested in order, each against the best so far.
#[inline(always)]
pub(super) fn nearest_in(
    refs: &[u32],
    mut t_best: f32,
    test: &mut impl FnMut(u32, f32) -> f32,
) -> Option<(f32, u32)> {
    let mut best = None;
    for &r in refs {
        let th = test(r, t_best);
        if th > 0.0 {
            t_best = th;
            best = Some((th, r));
        }
    }
    best
}

/// The slots whose bits are set in `mask`, lowest first.
#[inline(always)]
pub(super) fn slots(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let slot = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            slot
        })
    })
}

/// Orders a node's children hit: the nearest so far stays in `next`, the others go onto the
/// stack above `base` (this node's entries), sorted so that the nearest of them is on top.
/// `t` gives an entry's distance.
#[inline(always)]
pub(super) fn nearest_next<E: Copy>(
    next: &mut Option<E>,
    e: E,
    stack: &mut [E],
    base: usize,
    sp: &mut usize,
    t: impl Fn(&E) -> f32,
) {
    let far = match *next {
        Some(cur) if t(&cur) <= t(&e) => e,
        Some(cur) => {
            *next = Some(e);
            cur
        }
        None => {
            *next = Some(e);
            return;
        }
    };
    // Below the entries of this node nearer than it.
    let mut j = *sp;
    while j > base && t(&stack[j - 1]) < t(&far) {
        stack[j] = stack[j - 1];
        j -= 1;
    }
    stack[j] = far;
    *sp += 1;
}

impl Node4 {
    fn of(n: &GpuBvhNode4) -> Node4 {
        let mask = |f: &dyn Fn(u32) -> bool| {
            (0..4)
                .filter(|&s| f(n.count[s]))
                .fold(0u8, |m, s| m | 1 << s)
        };
        Node4 {
            min_x: Vec4::from_array(n.min_x),
            min_y: Vec4::from_array(n.min_y),
            min_z: Vec4::from_array(n.min_z),
            max_x: Vec4::from_array(n.max_x),
            max_y: Vec4::from_array(n.max_y),
            max_z: Vec4::from_array(n.max_z),
            child: n.child,
            count: n.count.map(|c| if c == EMPTY_SLOT { 0 } else { c as u16 }),
            valid: mask(&|c| c != EMPTY_SLOT),
            leaves: mask(&|c| c != EMPTY_SLOT && c > 0),
        }
    }
}

impl Bvh4 {
    /// The shared four-wide nodes (their leaf slots hold at most `wide::MAX_SLOT_REFS`).
    pub fn new(nodes: &[GpuBvhNode4], refs: Vec<u32>) -> Bvh4 {
        Bvh4 {
            nodes: nodes.iter().map(Node4::of).collect(),
            refs,
        }
    }

    /// The slots whose boxes the ray enters before `t_max` (a bit mask) and the entry
    /// distances (clamped at 0): four slab tests at once (Kay & Kajiya 1986; Williams et
    /// al., JGT 2005).
    #[inline(always)]
    fn slabs(n: &Node4, o: &[Vec4; 3], inv: &[Vec4; 3], t_max: f32) -> (u32, [f32; 4]) {
        let tx0 = (n.min_x - o[0]) * inv[0];
        let tx1 = (n.max_x - o[0]) * inv[0];
        let ty0 = (n.min_y - o[1]) * inv[1];
        let ty1 = (n.max_y - o[1]) * inv[1];
        let tz0 = (n.min_z - o[2]) * inv[2];
        let tz1 = (n.max_z - o[2]) * inv[2];
        let near = tx0
            .min(tx1)
            .max(ty0.min(ty1))
            .max(tz0.min(tz1).max(Vec4::ZERO));
        let far = tx0
            .max(tx1)
            .min(ty0.max(ty1))
            .min(tz0.max(tz1).min(Vec4::splat(t_max)));
        (near.cmple(far).bitmask() & n.valid as u32, near.to_array())
    }

    fn ray_terms(ray: &Ray) -> ([Vec4; 3], [Vec4; 3]) {
        let inv = safe_inverse(ray.dir);
        (
            [ray.origin.x, ray.origin.y, ray.origin.z].map(Vec4::splat),
            [inv.x, inv.y, inv.z].map(Vec4::splat),
        )
    }

    /// The nearest hit before `t_max`: (t, reference). `test` gives a primitive's distance
    /// if nearer than its bound, else a value ≤ 0 (the order of the walk: `Walk::visit`).
    #[inline(always)]
    pub fn closest(
        &self,
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack,
        test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        self.closest_from(0, ray, t_max, tally, stack, test)
    }

    /// [`Bvh4::closest`] in the tree whose root is node `root` (an instanced mesh's).
    #[inline(always)]
    pub fn closest_from(
        &self,
        root: usize,
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack,
        mut test: impl FnMut(u32, f32) -> f32,
    ) -> Option<(f32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let (o, inv) = Self::ray_terms(ray);
        let mut w = Walk::new(&mut *stack.0, t_max);
        let mut node = root;
        loop {
            let n = &self.nodes[node];
            tally.visits += 1;
            let (mask, t) = Self::slabs(n, &o, &inv, w.t_best);
            let leaves = n.leaves as u32;
            match w.visit(
                mask, leaves, &t, &n.child, &n.count, &self.refs, tally, &mut test,
            ) {
                Some(next) => node = next,
                None => return w.best,
            }
        }
    }

    /// Whether `test` finds any primitive before `t_max` (shadow rays: any order, first
    /// blocker ends the walk).
    #[inline(always)]
    pub fn any(
        &self,
        ray: &Ray,
        t_max: f32,
        tally: &mut Tally,
        stack: &mut Stack,
        mut test: impl FnMut(u32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let (o, inv) = Self::ray_terms(ray);
        let mut w = AnyWalk::new(&mut *stack.0);
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            tally.visits += 1;
            let (mask, _) = Self::slabs(n, &o, &inv, t_max);
            let leaves = n.leaves as u32;
            match w.visit(
                mask, leaves, &n.child, &n.count, &self.refs, tally, &mut test,
            ) {
                ControlFlow::Continue(next) => node = next,
                ControlFlow::Break(blocked) => return blocked,
            }
        }
    }
}
