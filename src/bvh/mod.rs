//! The acceleration structure: a bounding volume hierarchy over every primitive, built on the
//! CPU with the binned surface area heuristic (Wald, "On fast Construction of SAH-based
//! Bounding Volume Hierarchies", IEEE RT 2007), subtrees in parallel (rayon), then flattened
//! so that siblings are adjacent, then collapsed to four-wide nodes for both tracers (`wide`).

use glam::{DMat4, DVec3};

pub mod wide;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    pub fn of_points(points: &[DVec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, p| b.grow(*p))
    }

    pub fn grow(self, p: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Half the surface area (the SAH only compares areas).
    pub fn half_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.max - self.min;
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    /// The box around this one's eight corners taken through the affine map `m` (a copy of a
    /// mesh placed in the world).
    pub fn transformed(&self, m: &DMat4) -> Aabb {
        let corners: Vec<DVec3> = (0..8)
            .map(|k| {
                let pick = |bit: usize, lo: f64, hi: f64| if k & bit == 0 { lo } else { hi };
                m.transform_point3(DVec3::new(
                    pick(1, self.min.x, self.max.x),
                    pick(2, self.min.y, self.max.y),
                    pick(4, self.min.z, self.max.z),
                ))
            })
            .collect();
        Aabb::of_points(&corners)
    }

    pub fn contains(&self, o: &Aabb) -> bool {
        self.min.cmple(o.min).all() && self.max.cmpge(o.max).all()
    }

    /// Slab test in f64 (host side, for tests): the entry distance if the ray hits within
    /// (0, t_max).
    pub fn hit(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<f64> {
        let inv = dir.recip();
        let t0 = (self.min - origin) * inv;
        let t1 = (self.max - origin) * inv;
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element().min(t_max);
        (near <= far).then_some(near)
    }
}

/// One node of the flattened tree. An inner node's children are `first` and `first + 1`;
/// a leaf holds `count > 0` primitives from `first` in the reference array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub bounds: Aabb,
    pub first: u32,
    pub count: u32,
}

/// A flattened BVH: nodes (the root first) and the primitive order its leaves refer to.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<Node>,
    /// Primitive ids (as given to [`Bvh::build`]) in leaf order.
    pub order: Vec<u32>,
}

/// Leaves never hold more than this many primitives.
pub const MAX_LEAF: usize = 8;
/// A node this small becomes a leaf without trying to split it.
const MIN_SPLIT: usize = 2;
/// SAH bins per axis.
const BINS: usize = 16;
/// Cost of a node visit relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
/// Subtrees with more primitives than this are built on another thread.
const PARALLEL_THRESHOLD: usize = 4096;
/// Deepest tree the traversal stacks can walk (`wide::STACK`; shaders/trace.wgsl: STACK_SIZE).
pub const MAX_DEPTH: usize = 64;

#[derive(Clone, Copy)]
struct Item {
    bounds: Aabb,
    centroid: DVec3,
    id: u32,
}

enum Tree {
    Leaf {
        bounds: Aabb,
        start: usize,
        count: usize,
    },
    Inner {
        bounds: Aabb,
        children: Box<[Tree; 2]>,
    },
}

impl Tree {
    fn bounds(&self) -> Aabb {
        match self {
            Tree::Leaf { bounds, .. } | Tree::Inner { bounds, .. } => *bounds,
        }
    }
}

/// The best binned-SAH split of `items`: (axis, bin boundary, cost), or None if every
/// centroid coincides.
fn best_split(items: &[Item], centroids: &Aabb) -> Option<(usize, usize, f64)> {
    let extent = centroids.max - centroids.min;
    let mut best: Option<(usize, usize, f64)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f64 / extent[axis];
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        for it in items {
            let b = (((it.centroid[axis] - centroids.min[axis]) * scale) as usize).min(BINS - 1);
            bins[b].0 = bins[b].0.union(it.bounds);
            bins[b].1 += 1;
        }
        // Sweep from the right to get the area and count right of every boundary.
        let mut right = [(0.0f64, 0usize); BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bins[b].0);
            n += bins[b].1;
            right[b] = (acc.half_area(), n);
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in 1..BINS {
            acc = acc.union(bins[b - 1].0);
            n += bins[b - 1].1;
            if n == 0 || right[b].1 == 0 {
                continue;
            }
            let cost = acc.half_area() * n as f64 + right[b].0 * right[b].1 as f64;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, b, cost));
            }
        }
    }
    best
}

fn build_rec(items: &mut [Item], start: usize, depth: usize) -> Tree {
    let bounds = items.iter().fold(Aabb::EMPTY, |b, it| b.union(it.bounds));
    let leaf = Tree::Leaf {
        bounds,
        start,
        count: items.len(),
    };
    if items.len() < MIN_SPLIT {
        return leaf;
    }
    let centroids = items.iter().fold(Aabb::EMPTY, |b, it| b.grow(it.centroid));
    let split = best_split(items, &centroids);
    let leaf_cost = items.len() as f64;
    let mid = match split {
        Some((axis, boundary, cost)) => {
            let split_cost = TRAVERSAL_COST + cost / bounds.half_area().max(f64::MIN_POSITIVE);
            if split_cost >= leaf_cost && items.len() <= MAX_LEAF {
                return leaf;
            }
            let scale = BINS as f64 / (centroids.max[axis] - centroids.min[axis]);
            let mut left = 0;
            for i in 0..items.len() {
                let b = (((items[i].centroid[axis] - centroids.min[axis]) * scale) as usize)
                    .min(BINS - 1);
                if b < boundary {
                    items.swap(i, left);
                    left += 1;
                }
            }
            left
        }
        // Coincident centroids cannot be binned: split the list in half (it must, above
        // MAX_LEAF, to keep leaves small).
        None if items.len() <= MAX_LEAF => return leaf,
        None => items.len() / 2,
    };
    if depth + 1 >= MAX_DEPTH {
        // Never deeper than the GPU's stack: a large leaf is slow, an overflow is wrong.
        return leaf;
    }
    let (l, r) = items.split_at_mut(mid);
    let (a, b) = if l.len() + r.len() > PARALLEL_THRESHOLD {
        rayon::join(
            || build_rec(l, start, depth + 1),
            || build_rec(r, start + mid, depth + 1),
        )
    } else {
        (
            build_rec(l, start, depth + 1),
            build_rec(r, start + mid, depth + 1),
        )
    };
    Tree::Inner {
        bounds,
        children: Box::new([a, b]),
    }
}

fn flatten(tree: &Tree, slot: usize, nodes: &mut Vec<Node>) {
    match tree {
        Tree::Leaf {
            bounds,
            start,
            count,
        } => {
            nodes[slot] = Node {
                bounds: *bounds,
                first: *start as u32,
                count: *count as u32,
            };
        }
        Tree::Inner { bounds, children } => {
            let first = nodes.len();
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: 0,
                count: 0,
            });
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: 0,
                count: 0,
            });
            nodes[slot] = Node {
                bounds: *bounds,
                first: first as u32,
                count: 0,
            };
            flatten(&children[0], first, nodes);
            flatten(&children[1], first + 1, nodes);
        }
    }
}

impl Bvh {
    /// Builds over primitives given by their bounds; primitive `i` has id `i`.
    pub fn build(bounds: &[Aabb]) -> Bvh {
        if bounds.is_empty() {
            return Bvh::default();
        }
        let mut items: Vec<Item> = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| Item {
                bounds: *b,
                centroid: b.center(),
                id: i as u32,
            })
            .collect();
        let tree = build_rec(&mut items, 0, 0);
        let mut nodes = vec![Node {
            bounds: tree.bounds(),
            first: 0,
            count: 0,
        }];
        flatten(&tree, 0, &mut nodes);
        Bvh {
            nodes,
            order: items.iter().map(|it| it.id).collect(),
        }
    }

    /// Depth of the tree (a single leaf has depth 1).
    pub fn depth(&self) -> usize {
        fn rec(nodes: &[Node], i: usize) -> usize {
            let n = nodes[i];
            if n.count > 0 {
                1
            } else {
                1 + rec(nodes, n.first as usize).max(rec(nodes, n.first as usize + 1))
            }
        }
        if self.nodes.is_empty() {
            0
        } else {
            rec(&self.nodes, 0)
        }
    }

    /// Ids of the primitives whose node boxes a ray passes through, nearest-first traversal
    /// as on the GPU (host side, for tests and tools): calls `hit(id, t_max)` for each
    /// candidate, which returns the primitive's hit distance if nearer than `t_max`.
    pub fn closest_hit(
        &self,
        origin: DVec3,
        dir: DVec3,
        mut hit: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        let mut stack = vec![0usize];
        if self.nodes.is_empty() {
            return None;
        }
        while let Some(i) = stack.pop() {
            let n = self.nodes[i];
            let t_max = best.map_or(f64::INFINITY, |b| b.1);
            if n.bounds.hit(origin, dir, t_max).is_none() {
                continue;
            }
            if n.count > 0 {
                for &id in &self.order[n.first as usize..(n.first + n.count) as usize] {
                    let t_max = best.map_or(f64::INFINITY, |b| b.1);
                    if let Some(t) = hit(id, t_max) {
                        best = Some((id, t));
                    }
                }
            } else {
                stack.push(n.first as usize + 1);
                stack.push(n.first as usize);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generate::SplitMix64;

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                let c = DVec3::new(
                    rng.range(-50.0, 50.0),
                    rng.range(-5.0, 5.0),
                    rng.range(-50.0, 50.0),
                );
                let h = DVec3::splat(rng.range(0.01, 1.0));
                Aabb {
                    min: c - h,
                    max: c + h,
                }
            })
            .collect()
    }

    fn check_structure(bvh: &Bvh, bounds: &[Aabb]) {
        let mut seen = vec![0u32; bounds.len()];
        for n in &bvh.nodes {
            if n.count > 0 {
                assert!(n.count as usize <= MAX_LEAF.max(1) || bvh.depth() >= MAX_DEPTH);
                for &id in &bvh.order[n.first as usize..(n.first + n.count) as usize] {
                    seen[id as usize] += 1;
                    assert!(n.bounds.contains(&bounds[id as usize]));
                }
            } else {
                for c in [n.first, n.first + 1] {
                    assert!(n.bounds.contains(&bvh.nodes[c as usize].bounds));
                }
            }
        }
        assert!(
            seen.iter().all(|&s| s == 1),
            "every primitive in exactly one leaf"
        );
        assert!(bvh.depth() <= MAX_DEPTH);
    }

    #[test]
    fn every_primitive_in_one_leaf_and_bounds_nest() {
        for n in [1, 2, 3, 9, 100, 10_000] {
            let b = random_boxes(n, n as u64);
            check_structure(&Bvh::build(&b), &b);
        }
    }

    #[test]
    fn coincident_primitives_still_make_small_leaves() {
        let b = vec![
            Aabb {
                min: DVec3::ZERO,
                max: DVec3::ONE
            };
            1000
        ];
        let bvh = Bvh::build(&b);
        check_structure(&bvh, &b);
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
    }

    #[test]
    fn traversal_finds_what_brute_force_finds() {
        let b = random_boxes(2000, 7);
        let bvh = Bvh::build(&b);
        let mut rng = SplitMix64::new(99);
        for _ in 0..500 {
            let o = DVec3::new(
                rng.range(-60.0, 60.0),
                rng.range(-10.0, 10.0),
                rng.range(-60.0, 60.0),
            );
            let d = DVec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize();
            let hit = |id: u32, t_max: f64| b[id as usize].hit(o, d, t_max).filter(|t| *t < t_max);
            let brute = (0..b.len() as u32)
                .filter_map(|id| b[id as usize].hit(o, d, f64::INFINITY).map(|t| (id, t)))
                .min_by(|x, y| x.1.total_cmp(&y.1));
            let found = bvh.closest_hit(o, d, hit);
            assert_eq!(found.map(|f| f.1), brute.map(|f| f.1));
        }
    }

    #[test]
    fn sah_beats_a_median_split_on_clustered_input() {
        // Two far clusters: the SAH must separate them at the root.
        let mut b = random_boxes(500, 1);
        for x in b.iter_mut().take(250) {
            x.min += DVec3::splat(1000.0);
            x.max += DVec3::splat(1000.0);
        }
        let bvh = Bvh::build(&b);
        let root = bvh.nodes[0];
        let (l, r) = (
            bvh.nodes[root.first as usize].bounds,
            bvh.nodes[root.first as usize + 1].bounds,
        );
        assert!(
            l.union(r).half_area() > 10.0 * (l.half_area() + r.half_area()),
            "root did not split the clusters"
        );
    }
}
