//! The BVH as both tracers walk it: the binary SAH tree collapsed to four children per node,
//! their bounds stored as structure of arrays so that one node's four slab tests are four-wide
//! vector operations (`vec4f` in WGSL, SSE on the CPU), as Embree's BVH4 does (Wald et al.,
//! "Embree: A Kernel Framework for Efficient CPU Ray Tracing", SIGGRAPH 2014). Collapsing
//! opens, at each node, the child with the largest surface area until four remain (the "BVH4
//! by collapsing a BVH2" of Wald, Benthin & Boulos, "Getting Rid of Packets", RT 2008).
//!
//! On the GPU a walk is a chain of dependent loads, and a wide node makes the chain shorter:
//! `weekend` visits 4.8 four-wide nodes per segment against 11.7 binary ones (each of which
//! loaded its two children), which is what Ylitie, Karras & Laine ("Efficient Incoherent Ray
//! Traversal on GPUs Through Compressed Wide BVHs", HPG 2017) measure too (BENCHMARKS.md,
//! issue 12).

use super::{Aabb, Bvh};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

/// `count` of a slot that holds nothing.
pub const EMPTY_SLOT: u32 = u32::MAX;
/// The most references a leaf slot holds (a binary leaf with more, which only a degenerate
/// scene at the builder's depth limit makes, is split over inner nodes).
pub const MAX_SLOT_REFS: u32 = u16::MAX as u32;
/// Levels that splitting leaves too large for a slot can add below the binary tree's
/// deepest: each level divides a leaf by four, and 4^8 slots of `MAX_SLOT_REFS` hold any u32
/// count.
const SPLIT_LEVELS: usize = 8;
/// Pending entries a walk may need: each visit pushes at most three more than it takes, over
/// at most `super::MAX_DEPTH + SPLIT_LEVELS` levels (shaders/trace.wgsl: STACK_SIZE, checked
/// by a test).
pub const STACK: usize = 3 * LEVELS + 4;
/// The most levels a four-wide tree has.
pub const LEVELS: usize = super::MAX_DEPTH + SPLIT_LEVELS;

/// A four-wide node as both tracers read it (`BvhNode4` in shaders/common/types.wgsl):
/// the bounds of its four slots as structure of arrays; a slot is an inner node (`count` 0,
/// `child` its index), a leaf (`count` references from `child` on) or empty ([`EMPTY_SLOT`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuBvhNode4 {
    pub min_x: [f32; 4],
    pub min_y: [f32; 4],
    pub min_z: [f32; 4],
    pub max_x: [f32; 4],
    pub max_y: [f32; 4],
    pub max_z: [f32; 4],
    pub child: [u32; 4],
    pub count: [u32; 4],
}

/// A node of the binary tree with its bounds rounded outward to f32.
#[derive(Clone, Copy, Debug)]
struct Flat {
    min: [f32; 3],
    max: [f32; 3],
    first: u32,
    count: u32,
}

/// A child of a node being built: bounds and what it is.
#[derive(Clone, Copy)]
struct Kid {
    min: [f32; 3],
    max: [f32; 3],
    what: KidKind,
}

#[derive(Clone, Copy)]
enum KidKind {
    /// A binary inner node, to be collapsed.
    Inner(usize),
    /// A leaf's references: (first, count).
    Leaf(u32, u32),
}

/// f32 bounds that contain the f64 ones: padded by a millionth of their extent and
/// magnitude, far more than the rounding to f32 (2^-24 relative), so that no hit is lost to
/// rounding and a flat box (an axis-aligned quad) still has a thickness.
fn padded(b: &Aabb) -> ([f32; 3], [f32; 3]) {
    let extent = (b.max - b.min).max_element();
    let magnitude = b.min.abs().max(b.max.abs()).max_element();
    let pad = 1e-6 * (extent + magnitude) + 1e-30;
    let lo = (b.min - DVec3::splat(pad)).as_vec3();
    (
        lo.to_array(),
        (b.max + DVec3::splat(pad)).as_vec3().to_array(),
    )
}

/// Half the surface area of the box (min, max), the measure both collapses open children by.
pub fn half_area(min: &[f32; 3], max: &[f32; 3]) -> f32 {
    let d = [0, 1, 2].map(|c| (max[c] - min[c]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

fn area(k: &Kid) -> f32 {
    half_area(&k.min, &k.max)
}

/// Collapses `bvh` into four-wide nodes, the root first. A child slot is an inner node
/// (`count` 0, `child` its index), a leaf (`count` references from `child` on, in the order
/// of `bvh.order`) or empty (`count` [`EMPTY_SLOT`]). An empty tree gives no nodes.
pub fn collapse(bvh: &Bvh) -> Vec<GpuBvhNode4> {
    let bin: Vec<Flat> = bvh
        .nodes
        .iter()
        .map(|n| {
            let (min, max) = padded(&n.bounds);
            Flat {
                min,
                max,
                first: n.first,
                count: n.count,
            }
        })
        .collect();
    let mut b = Builder {
        bin: &bin,
        nodes: Vec::new(),
    };
    if !bin.is_empty() {
        let root = b.kid(0);
        match root.what {
            KidKind::Inner(_) => b.build(0),
            KidKind::Leaf(..) => b.node_of(&[root]),
        };
    }
    b.nodes
}

struct Builder<'a> {
    bin: &'a [Flat],
    nodes: Vec<GpuBvhNode4>,
}

impl Builder<'_> {
    fn kid(&self, k: usize) -> Kid {
        let n = &self.bin[k];
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
    fn node_of(&mut self, kids: &[Kid]) -> u32 {
        let index = self.nodes.len();
        self.nodes.push(GpuBvhNode4 {
            count: [EMPTY_SLOT; 4],
            ..GpuBvhNode4::default()
        });
        let mut n = self.nodes[index];
        for (slot, k) in kids.iter().enumerate() {
            for (c, (lo, hi)) in [
                (&mut n.min_x, &mut n.max_x),
                (&mut n.min_y, &mut n.max_y),
                (&mut n.min_z, &mut n.max_z),
            ]
            .into_iter()
            .enumerate()
            {
                lo[slot] = k.min[c];
                hi[slot] = k.max[c];
            }
            (n.child[slot], n.count[slot]) = match k.what {
                KidKind::Leaf(first, count) if count <= MAX_SLOT_REFS => (first, count),
                KidKind::Leaf(first, count) => (self.split_leaf(k, first, count), 0),
                KidKind::Inner(b) => (self.build(b), 0),
            };
        }
        self.nodes[index] = n;
        index as u32
    }

    /// Inner nodes over a leaf too large for one slot: its references in slot-sized pieces,
    /// each with the leaf's bounds.
    fn split_leaf(&mut self, k: &Kid, first: u32, count: u32) -> u32 {
        let piece = count.div_ceil(4).max(1);
        let kids: Vec<Kid> = (0..4)
            .map(|i| {
                (
                    first + i * piece,
                    piece.min(count.saturating_sub(i * piece)),
                )
            })
            .filter(|&(_, n)| n > 0)
            .map(|(f, n)| Kid {
                what: KidKind::Leaf(f, n),
                ..*k
            })
            .collect();
        self.node_of(&kids)
    }

    /// The four-wide node for binary inner node `b`: its children, the inner child of
    /// largest area opened until there are four.
    fn build(&mut self, b: usize) -> u32 {
        let first = self.bin[b].first as usize;
        let mut kids = vec![self.kid(first), self.kid(first + 1)];
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter(|(_, k)| matches!(k.what, KidKind::Inner(_)))
                .max_by(|a, b| area(a.1).total_cmp(&area(b.1)));
            let Some((
                i,
                &Kid {
                    what: KidKind::Inner(b),
                    ..
                },
            )) = open
            else {
                break;
            };
            let f = self.bin[b].first as usize;
            kids[i] = self.kid(f);
            kids.insert(i + 1, self.kid(f + 1));
        }
        self.node_of(&kids)
    }
}

/// Depth of the four-wide tree (the root alone: 1).
pub fn depth(nodes: &[GpuBvhNode4]) -> usize {
    fn walk(nodes: &[GpuBvhNode4], i: usize) -> usize {
        let n = &nodes[i];
        1 + (0..4)
            .filter(|&s| n.count[s] == 0)
            .map(|s| walk(nodes, n.child[s] as usize))
            .max()
            .unwrap_or(0)
    }
    if nodes.is_empty() { 0 } else { walk(nodes, 0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut s = seed;
        let mut r = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let c = DVec3::new(r(), r(), r()) * 100.0;
                let h = DVec3::splat(0.1 + r());
                Aabb {
                    min: c - h,
                    max: c + h,
                }
            })
            .collect()
    }

    fn bounds_of(n: &GpuBvhNode4, s: usize) -> Aabb {
        Aabb {
            min: DVec3::new(n.min_x[s] as f64, n.min_y[s] as f64, n.min_z[s] as f64),
            max: DVec3::new(n.max_x[s] as f64, n.max_y[s] as f64, n.max_z[s] as f64),
        }
    }

    /// Every primitive is referenced once, inside the bounds of every slot above it; inner
    /// slots point forward; the four-wide tree is no deeper than the binary one.
    #[test]
    fn collapse_keeps_every_primitive_inside_its_slots() {
        for n in [1usize, 2, 3, 5, 17, 1000] {
            let boxes = random_boxes(n, n as u64);
            let bvh = Bvh::build(&boxes);
            let wide = collapse(&bvh);
            let mut seen = vec![0u32; n];
            let mut todo = vec![(0usize, Aabb::EMPTY, false)];
            while let Some((i, parent, bounded)) = todo.pop() {
                let node = &wide[i];
                for s in 0..4 {
                    if node.count[s] == EMPTY_SLOT {
                        continue;
                    }
                    let b = bounds_of(node, s);
                    assert!(!bounded || parent.contains(&b), "slot outside its parent");
                    if node.count[s] == 0 {
                        assert!(node.child[s] as usize > i);
                        todo.push((node.child[s] as usize, b, true));
                    } else {
                        let first = node.child[s] as usize;
                        for &id in &bvh.order[first..first + node.count[s] as usize] {
                            let p = boxes[id as usize];
                            assert!(b.contains(&p), "primitive outside its leaf slot");
                            seen[id as usize] += 1;
                        }
                    }
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{n}: {seen:?}");
            assert!(depth(&wide) <= bvh.depth().max(1));
            if n >= 17 {
                assert!(
                    wide.len() * 2 < bvh.nodes.len(),
                    "{} {}",
                    wide.len(),
                    bvh.nodes.len()
                );
            }
        }
    }

    /// The WGSL walk's stack is as deep as the CPU's, which the bound above sizes.
    #[test]
    fn the_shader_stack_has_the_bound_of_the_tree() {
        let n = crate::common::wgsl::u32_constant("trace.wgsl", "STACK_SIZE");
        assert_eq!(n as usize, STACK);
    }

    /// A leaf far too large for one slot (which only a degenerate scene at the builder's depth
    /// limit makes) is split over inner nodes, every reference kept once.
    #[test]
    fn a_huge_leaf_is_split_over_slots() {
        let bvh = Bvh {
            nodes: vec![crate::bvh::Node {
                bounds: Aabb {
                    min: DVec3::ZERO,
                    max: DVec3::ONE,
                },
                first: 0,
                count: 300_000,
            }],
            order: (0..300_000).collect(),
        };
        let wide = collapse(&bvh);
        let mut covered = 0u64;
        for n in &wide {
            for s in 0..4 {
                if n.count[s] != EMPTY_SLOT && n.count[s] > 0 {
                    assert!(n.count[s] <= MAX_SLOT_REFS);
                    covered += n.count[s] as u64;
                }
            }
        }
        assert_eq!(covered, 300_000);
        assert!(depth(&wide) <= 1 + SPLIT_LEVELS);
    }

    #[test]
    fn empty_tree_has_no_nodes() {
        assert!(collapse(&Bvh::build(&[])).is_empty());
    }
}
