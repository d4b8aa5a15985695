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

use super::intersect::{Ray, safe_inverse};
use crate::gpu::layout::GpuBvhNode;
use glam::Vec4;

/// Pending entries: each visit pushes at most three and descends into one, over at most
/// `bvh::MAX_DEPTH` levels.
const STACK: usize = 3 * crate::bvh::MAX_DEPTH + 4;
/// The most references a leaf slot holds (a binary leaf with more, which only a degenerate
/// scene at the builder's depth limit makes, is split over inner nodes).
const MAX_SLOT_REFS: usize = u16::MAX as usize;

/// Four children: their bounds by axis, and for each either an inner node (`child` its
/// index) or a leaf (`count` references from `child` on in `refs`); `valid` and `leaves`
/// are bit masks of the slots in use and of the leaf slots. 128 bytes, two cache lines.
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
    count: [u16; 4],
    valid: u8,
    leaves: u8,
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
    node: u32,
    t: f32,
}

/// The slots whose bits are set in `mask`, lowest first.
#[inline(always)]
fn slots(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let slot = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            slot
        })
    })
}

fn area(n: &GpuBvhNode) -> f32 {
    let d = [0, 1, 2].map(|c| (n.max[c] - n.min[c]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// A child of a node being built: bounds and what it is.
#[derive(Clone, Copy)]
struct Kid {
    min: [f32; 3],
    max: [f32; 3],
    /// A binary node to collapse, or a leaf's (first, count).
    what: KidKind,
}

#[derive(Clone, Copy)]
enum KidKind {
    Inner(usize),
    Leaf(u32, u32),
}

impl Bvh4 {
    /// Collapses the binary BVH `bin` (inner nodes' children at `first`, `first + 1`).
    pub fn collapse(bin: &[GpuBvhNode], refs: Vec<u32>) -> Bvh4 {
        let mut b = Bvh4 {
            nodes: Vec::new(),
            refs,
        };
        if !bin.is_empty() {
            let root = b.kid(bin, 0);
            match root.what {
                KidKind::Inner(_) => {
                    b.build(bin, 0);
                }
                KidKind::Leaf(..) => {
                    b.node_of(bin, &[root]);
                }
            }
        }
        b
    }

    fn kid(&self, bin: &[GpuBvhNode], k: usize) -> Kid {
        let n = &bin[k];
        Kid {
            min: n.min,
            max: n.max,
            what: if n.count > 0 {
                KidKind::Leaf(n.first, n.count)
            } else {
                KidKind::Inner(k)
            },
        }
    }

    /// Adds the node holding `kids` and returns its index.
    fn node_of(&mut self, bin: &[GpuBvhNode], kids: &[Kid]) -> u32 {
        let index = self.nodes.len();
        let mut n = Node4 {
            min_x: Vec4::ZERO,
            min_y: Vec4::ZERO,
            min_z: Vec4::ZERO,
            max_x: Vec4::ZERO,
            max_y: Vec4::ZERO,
            max_z: Vec4::ZERO,
            child: [0; 4],
            count: [0; 4],
            valid: 0,
            leaves: 0,
        };
        self.nodes.push(n);
        let (mut lo, mut hi) = ([[0.0f32; 4]; 3], [[0.0f32; 4]; 3]);
        for (slot, k) in kids.iter().enumerate() {
            for c in 0..3 {
                lo[c][slot] = k.min[c];
                hi[c][slot] = k.max[c];
            }
            n.valid |= 1 << slot;
            match k.what {
                KidKind::Leaf(first, count) if count as usize <= MAX_SLOT_REFS => {
                    n.child[slot] = first;
                    n.count[slot] = count as u16;
                    n.leaves |= 1 << slot;
                }
                KidKind::Leaf(first, count) => {
                    n.child[slot] = self.split_leaf(bin, k, first, count);
                }
                KidKind::Inner(b) => n.child[slot] = self.build(bin, b),
            }
        }
        [n.min_x, n.min_y, n.min_z] = lo.map(Vec4::from_array);
        [n.max_x, n.max_y, n.max_z] = hi.map(Vec4::from_array);
        self.nodes[index] = n;
        index as u32
    }

    /// Inner nodes over a leaf too large for one slot: its references in slot-sized pieces,
    /// each with the leaf's bounds.
    fn split_leaf(&mut self, bin: &[GpuBvhNode], k: &Kid, first: u32, count: u32) -> u32 {
        let piece = (count as usize).div_ceil(4).max(1) as u32;
        let kids: Vec<Kid> = (0..4)
            .map(|i| {
                (
                    first + i * piece,
                    piece.min((first + count).saturating_sub(first + i * piece)),
                )
            })
            .filter(|&(_, n)| n > 0)
            .map(|(f, n)| Kid {
                what: KidKind::Leaf(f, n),
                ..*k
            })
            .collect();
        self.node_of(bin, &kids)
    }

    /// The four-wide node for binary inner node `b`: its children, the inner child of
    /// largest area opened until there are four.
    fn build(&mut self, bin: &[GpuBvhNode], b: usize) -> u32 {
        let first = bin[b].first as usize;
        let mut kids = vec![self.kid(bin, first), self.kid(bin, first + 1)];
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter_map(|(i, k)| match k.what {
                    KidKind::Inner(b) => Some((i, b)),
                    KidKind::Leaf(..) => None,
                })
                .max_by(|a, b| area(&bin[a.1]).total_cmp(&area(&bin[b.1])));
            let Some((i, b)) = open else { break };
            let f = bin[b].first as usize;
            kids[i] = self.kid(bin, f);
            kids.insert(i + 1, self.kid(bin, f + 1));
        }
        self.node_of(bin, &kids)
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

    /// The references of leaf slot `slot` of `n`.
    #[inline(always)]
    fn leaf(&self, n: &Node4, slot: usize, tally: &mut Tally) -> &[u32] {
        let first = n.child[slot] as usize;
        tally.tests += n.count[slot] as u64;
        &self.refs[first..first + n.count[slot] as usize]
    }

    /// The nearest hit before `t_max`: (t, reference). `test` gives a primitive's distance
    /// if nearer than its bound, else a value ≤ 0. Leaves hit are tested at once (a few
    /// primitives, which shorten the ray for what follows); the nearest inner child hit is
    /// entered next and the others pushed, nearest on top, and skipped when popped once a
    /// nearer hit is known.
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
        let mut best: Option<(f32, u32)> = None;
        let mut t_best = t_max;
        let stack = &mut *stack.0;
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            tally.visits += 1;
            let (mask, t) = Self::slabs(n, &o, &inv, t_best);
            for slot in slots(mask & n.leaves as u32) {
                for &r in self.leaf(n, slot, tally) {
                    let th = test(r, t_best);
                    if th > 0.0 {
                        t_best = th;
                        best = Some((th, r));
                    }
                }
            }
            // The nearest inner child hit (still nearer than the best hit) comes next; the
            // others wait on the stack, the nearest of them on top.
            let mut next: Option<Entry> = None;
            let base = sp;
            for slot in slots(mask & !(n.leaves as u32)) {
                if t[slot] >= t_best {
                    continue;
                }
                let e = Entry {
                    node: n.child[slot],
                    t: t[slot],
                };
                let far = match next {
                    Some(cur) if cur.t <= e.t => e,
                    Some(cur) => {
                        next = Some(e);
                        cur
                    }
                    None => {
                        next = Some(e);
                        continue;
                    }
                };
                // Below the entries of this node nearer than it.
                let mut j = sp;
                while j > base && stack[j - 1].t < far.t {
                    stack[j] = stack[j - 1];
                    j -= 1;
                }
                stack[j] = far;
                sp += 1;
            }
            if let Some(e) = next {
                node = e.node as usize;
                continue;
            }
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let e = stack[sp];
                if e.t < t_best {
                    node = e.node as usize;
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
            let (mask, _) = Self::slabs(n, &o, &inv, t_max);
            for slot in slots(mask & n.leaves as u32) {
                if self.leaf(n, slot, tally).iter().any(|&r| test(r)) {
                    return true;
                }
            }
            for slot in slots(mask & !(n.leaves as u32)) {
                stack[sp] = Entry {
                    node: n.child[slot],
                    t: 0.0,
                };
                sp += 1;
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            node = stack[sp].node as usize;
        }
    }
}
