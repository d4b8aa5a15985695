//! The BVH as the CPU walks it: the GPU's binary BVH (`bvh::Bvh`, the same nodes and leaves)
//! collapsed to four children per node, their bounds stored as structure of arrays so that
//! one node's four slab tests are one SSE operation each (`glam::Vec4`), as Embree's BVH4
//! does (Wald et al., "Embree: A Kernel Framework for Efficient CPU Ray Tracing", SIGGRAPH
//! 2014). Collapsing opens, at each node, the child with the largest surface area until four
//! remain (the "BVH4 by collapsing a BVH2" of Wald, Benthin & Boulos, "Getting Rid of
//! Packets", RT 2008).
//!
//! Measured on `weekend` (BENCHMARKS.md, "A native CPU tracer"): 4.8 nodes visited per
//! segment against the binary BVH's 11.6 on the GPU, for about two primitive tests each.

use super::intersect::{NO_HIT, Ray, safe_inverse};
use crate::gpu::layout::GpuBvhNode;
use glam::Vec4;

/// A slot of a node that holds nothing.
const EMPTY: u32 = u32::MAX;
/// Pending entries: each visit pushes at most four and pops one, over at most
/// `bvh::MAX_DEPTH` levels.
const STACK: usize = 3 * crate::bvh::MAX_DEPTH + 4;

/// Four children: their bounds by axis, and for each either an inner node (`count` 0,
/// `child` its index) or a leaf (`count` references from `child` on in `refs`); a leaf hit
/// is tested at once, an inner child pushed.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node4 {
    min_x: Vec4,
    min_y: Vec4,
    min_z: Vec4,
    max_x: Vec4,
    max_y: Vec4,
    max_z: Vec4,
    child: [u32; 4],
    count: [u32; 4],
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
    child: u32,
    t: f32,
}

fn area(n: &GpuBvhNode) -> f32 {
    let d = [0, 1, 2].map(|c| (n.max[c] - n.min[c]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

impl Bvh4 {
    /// Collapses the binary BVH `bin` (inner nodes' children at `first`, `first + 1`).
    pub fn collapse(bin: &[GpuBvhNode], refs: Vec<u32>) -> Bvh4 {
        let mut b = Bvh4 {
            nodes: Vec::new(),
            refs,
        };
        if !bin.is_empty() {
            if bin[0].count > 0 {
                b.node_of(bin, &[0]);
            } else {
                b.build(bin, 0);
            }
        }
        b
    }

    /// Adds the node holding `kids` (binary node indices) and returns its index.
    fn node_of(&mut self, bin: &[GpuBvhNode], kids: &[usize]) -> u32 {
        let index = self.nodes.len();
        let mut n = Node4 {
            min_x: Vec4::ZERO,
            min_y: Vec4::ZERO,
            min_z: Vec4::ZERO,
            max_x: Vec4::ZERO,
            max_y: Vec4::ZERO,
            max_z: Vec4::ZERO,
            child: [EMPTY; 4],
            count: [0; 4],
        };
        self.nodes.push(n);
        let (mut lo, mut hi) = ([[0.0f32; 4]; 3], [[0.0f32; 4]; 3]);
        for (slot, &k) in kids.iter().enumerate() {
            let b = &bin[k];
            for c in 0..3 {
                lo[c][slot] = b.min[c];
                hi[c][slot] = b.max[c];
            }
            if b.count > 0 {
                n.child[slot] = b.first;
                n.count[slot] = b.count;
            } else {
                n.child[slot] = self.build(bin, k);
            }
        }
        [n.min_x, n.min_y, n.min_z] = lo.map(Vec4::from_array);
        [n.max_x, n.max_y, n.max_z] = hi.map(Vec4::from_array);
        self.nodes[index] = n;
        index as u32
    }

    /// The four-wide node for binary inner node `b`.
    fn build(&mut self, bin: &[GpuBvhNode], b: usize) -> u32 {
        let first = bin[b].first as usize;
        let mut kids = vec![first, first + 1];
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| bin[**k].count == 0)
                .max_by(|a, b| area(&bin[*a.1]).total_cmp(&area(&bin[*b.1])))
                .map(|(i, _)| i);
            let Some(i) = open else { break };
            let f = bin[kids[i]].first as usize;
            kids[i] = f;
            kids.insert(i + 1, f + 1);
        }
        self.node_of(bin, &kids)
    }

    /// Entry distances of a node's four children (NO_HIT where missed or empty), nearest
    /// first clamped at 0: the slab test (Kay & Kajiya 1986; Williams et al., JGT 2005).
    #[inline(always)]
    fn slabs(n: &Node4, o: [Vec4; 3], inv: [Vec4; 3], t_max: f32) -> [f32; 4] {
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
        let mut out = Vec4::select(near.cmple(far), near, Vec4::splat(NO_HIT)).to_array();
        for (t, c) in out.iter_mut().zip(n.child) {
            if c == EMPTY {
                *t = NO_HIT;
            }
        }
        out
    }

    fn ray_terms(ray: &Ray) -> ([Vec4; 3], [Vec4; 3]) {
        let inv = safe_inverse(ray.dir);
        (
            [ray.origin.x, ray.origin.y, ray.origin.z].map(Vec4::splat),
            [inv.x, inv.y, inv.z].map(Vec4::splat),
        )
    }

    /// The nearest hit before `t_max`: (t, reference), or (`t_max`, `EMPTY`). `test` gives a
    /// primitive's distance if nearer than its bound, else a value ≤ 0. Children are visited
    /// nearest first, and a pending one is skipped once a nearer hit is found.
    #[inline(always)]
    pub fn closest(
        &self,
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
        let mut best = (t_max, EMPTY);
        let stack = &mut *stack.0;
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            tally.visits += 1;
            let t = Self::slabs(n, o, inv, best.0);
            // Leaves hit are tested at once (a few primitives, which shorten the ray for
            // what follows); inner children hit are ordered farthest first.
            let mut hits = [(0.0f32, 0u32); 4];
            let mut k = 0;
            for (slot, &ts) in t.iter().enumerate() {
                if ts < 0.0 {
                    continue;
                }
                if n.count[slot] > 0 {
                    let first = n.child[slot] as usize;
                    tally.tests += n.count[slot] as u64;
                    for &r in &self.refs[first..first + n.count[slot] as usize] {
                        let th = test(r, best.0);
                        if th > 0.0 {
                            best = (th, r);
                        }
                    }
                    continue;
                }
                let mut j = k;
                while j > 0 && hits[j - 1].0 < ts {
                    hits[j] = hits[j - 1];
                    j -= 1;
                }
                hits[j] = (ts, n.child[slot]);
                k += 1;
            }
            // Descend into the nearest; push the others, the nearest of them on top.
            if k > 0 && hits[k - 1].0 < best.0 {
                for &(ts, child) in &hits[..k - 1] {
                    stack[sp] = Entry { child, t: ts };
                    sp += 1;
                }
                node = hits[k - 1].1 as usize;
                continue;
            }
            loop {
                if sp == 0 {
                    return (best.1 != EMPTY).then_some(best);
                }
                sp -= 1;
                let e = stack[sp];
                if e.t < best.0 {
                    node = e.child as usize;
                    break;
                }
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
        let stack = &mut *stack.0;
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            tally.visits += 1;
            let t = Self::slabs(n, o, inv, t_max);
            let mut next = None;
            for (slot, &ts) in t.iter().enumerate() {
                if ts < 0.0 {
                    continue;
                }
                if n.count[slot] > 0 {
                    let first = n.child[slot] as usize;
                    tally.tests += n.count[slot] as u64;
                    if self.refs[first..first + n.count[slot] as usize]
                        .iter()
                        .any(|&r| test(r))
                    {
                        return true;
                    }
                } else if let Some(c) = next.replace(n.child[slot]) {
                    stack[sp] = Entry { child: c, t: ts };
                    sp += 1;
                }
            }
            node = match next {
                Some(c) => c as usize,
                None if sp > 0 => {
                    sp -= 1;
                    stack[sp].child as usize
                }
                None => return false,
            };
        }
    }
}
