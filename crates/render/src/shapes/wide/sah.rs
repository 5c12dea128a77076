//! A binary BVH by the surface area heuristic, binned, top down, for the wide BVH to
//! collapse: each node splits where the expected cost of a ray through it is least (boxes
//! entered, packs of four triangles tested, other primitives tested one by one), or stays
//! a leaf of at most [`MAX_LEAF`] triangles (or [`MAX_OTHERS`] other primitives) where that
//! costs less. A leaf holds triangles or other
//! primitives, never both. Sequential and with a total order on every choice, so the tree
//! is the same on every machine.

use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;

/// Bins per axis.
const BINS: usize = 16;
/// The most triangles a leaf holds (two packs). Interleaved runs (Intel Xeon, 2026-11-28):
/// sixteen gave the snail's rays 1.02x the closest hits per second and the million-triangle
/// sphere's 0.94x; four was slower on both.
pub const MAX_LEAF: usize = 8;
/// The most other primitives a leaf holds.
pub const MAX_OTHERS: usize = 8;
/// The cost of entering a node, against testing a pack of four triangles.
const NODE_COST: f32 = 1.0;
const PACK_COST: f32 = 1.0;

/// Triangles and other primitives, counted apart.
#[derive(Clone, Copy, Default)]
struct Count {
    triangles: usize,
    others: usize,
}

impl Count {
    fn add(&mut self, c: Count) {
        self.triangles += c.triangles;
        self.others += c.others;
    }

    fn total(self) -> usize {
        self.triangles + self.others
    }

    /// Whether they may be one leaf: of one kind, and not too many.
    fn fits_a_leaf(self) -> bool {
        (self.others == 0 && self.triangles <= MAX_LEAF)
            || (self.triangles == 0 && self.others <= MAX_OTHERS)
    }

    /// The cost of testing them: the triangles' packs, and each other primitive.
    fn cost(self) -> f32 {
        (self.triangles.div_ceil(4) + self.others) as f32 * PACK_COST
    }
}

/// A binary BVH over `aabbs`, whose leaves index `ids` (`ids[i]` is the primitive `aabbs[i]`
/// bounds: a triangle may have several boxes, cut by spatial splits; ids below
/// `triangles` are triangles). Returns the nodes and the leaves' primitives.
pub fn build(aabbs: &[Aabb], ids: &[u32], triangles: u32) -> (Vec<Bvh2Node>, Vec<u32>) {
    let n = aabbs.len();
    let is_triangle = |i: u32| ids[i as usize] < triangles;
    let centres: Vec<glam::Vec3A> = aabbs.iter().map(Aabb::center).collect();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut nodes = vec![Bvh2Node::new(Aabb::empty(), 0, 0)];
    // (node, the range of `order` it holds)
    let mut todo = vec![(0usize, 0usize, n)];
    while let Some((node, lo, hi)) = todo.pop() {
        let mut bounds = Aabb::empty();
        let mut cb = Aabb::empty();
        let mut count = Count::default();
        for &i in &order[lo..hi] {
            bounds = bounds.union(&aabbs[i as usize]);
            cb.extend(centres[i as usize]);
            count.add(kind(is_triangle(i)));
        }
        let split = if count.total() > 1 {
            best_split(
                &order[lo..hi],
                aabbs,
                &centres,
                &cb,
                bounds.half_area(),
                count,
                is_triangle,
            )
        } else {
            None
        };
        let mid = match split {
            Some(s) => {
                let bins = Bins::new(&cb);
                partition(&mut order[lo..hi], |i| {
                    bins.of(centres[i as usize][s.axis], s.axis) < s.bins_left
                }) + lo
            }
            None if count.fits_a_leaf() => {
                nodes[node] = Bvh2Node::new(bounds, count.total() as u32, lo as u32);
                continue;
            }
            // A leaf is of one kind: the triangles on one side, the others on the other.
            None if count.triangles > 0 && count.others > 0 => {
                partition(&mut order[lo..hi], is_triangle) + lo
            }
            // Too many to be a leaf and nothing to split by (their centres in one bin):
            // halve them in the order they are in.
            None => lo + count.total() / 2,
        };
        let first = nodes.len();
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes[node] = Bvh2Node::new(bounds, 0, first as u32);
        todo.push((first + 1, mid, hi));
        todo.push((first, lo, mid));
    }
    let prims = order.iter().map(|&i| ids[i as usize]).collect();
    (nodes, prims)
}

/// A split: the axis and the number of bins on its left.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    bins_left: usize,
}

/// Which bin a centre falls in, per axis, over the centres' bounds `cb`: by one multiply
/// (the division by the extent done once per node).
struct Bins {
    min: glam::Vec3A,
    scale: glam::Vec3A,
}

impl Bins {
    fn new(cb: &Aabb) -> Bins {
        Bins {
            min: cb.min,
            scale: BINS as f32 / (cb.max - cb.min),
        }
    }

    #[inline]
    fn of(&self, c: f32, axis: usize) -> usize {
        (((c - self.min[axis]) * self.scale[axis]) as usize).min(BINS - 1)
    }
}

/// One primitive of its kind.
fn kind(triangle: bool) -> Count {
    Count {
        triangles: triangle as usize,
        others: !triangle as usize,
    }
}

/// The cheapest split of `items` if it is cheaper than a leaf of them (a leaf is not an
/// option past [`MAX_LEAF`] or [`MAX_OTHERS`], nor for a mix of triangles and other
/// primitives).
fn best_split(
    items: &[u32],
    aabbs: &[Aabb],
    centres: &[glam::Vec3A],
    cb: &Aabb,
    area: f32,
    count: Count,
    is_triangle: impl Fn(u32) -> bool,
) -> Option<Split> {
    let mut best: Option<(f32, Split)> = None;
    // Every axis binned in one pass over the items.
    let mut boxes = [[Aabb::empty(); BINS]; 3];
    let mut counts = [[Count::default(); BINS]; 3];
    let live: [bool; 3] = std::array::from_fn(|a| cb.max[a] - cb.min[a] > 0.0);
    let bins = Bins::new(cb);
    for &i in items {
        let (c, b) = (centres[i as usize], &aabbs[i as usize]);
        let one = kind(is_triangle(i));
        for axis in 0..3 {
            if live[axis] {
                let k = bins.of(c[axis], axis);
                boxes[axis][k] = boxes[axis][k].union(b);
                counts[axis][k].add(one);
            }
        }
    }
    for axis in (0..3).filter(|&a| live[a]) {
        let (boxes, counts) = (&boxes[axis], &counts[axis]);
        // Right to left: the area and count of bins k.. for each k.
        let mut right = [(0f32, Count::default()); BINS];
        let (mut acc, mut n) = (Aabb::empty(), Count::default());
        for k in (1..BINS).rev() {
            acc = acc.union(&boxes[k]);
            n.add(counts[k]);
            right[k] = (acc.half_area(), n);
        }
        let (mut acc, mut n) = (Aabb::empty(), Count::default());
        for k in 1..BINS {
            acc = acc.union(&boxes[k - 1]);
            n.add(counts[k - 1]);
            let (ra, rn) = right[k];
            if n.total() == 0 || rn.total() == 0 {
                continue;
            }
            let cost = acc.half_area() * n.cost() + ra * rn.cost();
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, Split { axis, bins_left: k }));
            }
        }
    }
    let (cost, split) = best?;
    let split_cost = NODE_COST + cost / area.max(f32::MIN_POSITIVE);
    (!count.fits_a_leaf() || split_cost < count.cost()).then_some(split)
}

/// Puts the items `left` takes first; returns how many they are.
fn partition(items: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let (mut a, mut b) = (0, items.len());
    while a < b {
        if left(items[a]) {
            a += 1;
        } else {
            b -= 1;
            items.swap(a, b);
        }
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// Every primitive is in exactly one leaf, every node's box holds its children's and its
    /// primitives', leaves hold at most MAX_LEAF triangles or MAX_OTHERS others unless their
    /// centres coincide, and no leaf
    /// mixes triangles with other primitives.
    fn check(aabbs: &[Aabb]) -> usize {
        let ids: Vec<u32> = (0..aabbs.len() as u32).collect();
        let (nodes, prims) = build(aabbs, &ids, aabbs.len() as u32 / 2);
        let mut seen = vec![0u32; aabbs.len()];
        let mut todo = vec![0usize];
        let mut leaves = 0;
        let contains = |outer: &Aabb, inner: &Aabb| {
            outer.min.cmple(inner.min).all() && inner.max.cmple(outer.max).all()
        };
        while let Some(n) = todo.pop() {
            let node = &nodes[n];
            if node.prim_count > 0 {
                leaves += 1;
                let range =
                    node.first_index as usize..(node.first_index + node.prim_count) as usize;
                let mut centres = Aabb::empty();
                // The first half of the ids are triangles, the rest other primitives.
                let half = aabbs.len() as u32 / 2;
                let leaf = &prims[range.clone()];
                assert!(
                    leaf.iter().all(|&p| p < half) || leaf.iter().all(|&p| p >= half),
                    "a leaf of triangles and other primitives: {leaf:?}"
                );
                for &p in &prims[range] {
                    seen[p as usize] += 1;
                    assert!(contains(&node.aabb, &aabbs[p as usize]));
                    centres.extend(aabbs[p as usize].center());
                }
                let limit = if prims[node.first_index as usize] < half {
                    MAX_LEAF
                } else {
                    MAX_OTHERS
                };
                assert!(
                    node.prim_count as usize <= limit || centres.min == centres.max,
                    "a leaf of {}",
                    node.prim_count
                );
            } else {
                for c in [node.first_index as usize, node.first_index as usize + 1] {
                    assert!(contains(&node.aabb, &nodes[c].aabb));
                    todo.push(c);
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1), "each primitive in one leaf");
        leaves
    }

    #[test]
    fn every_primitive_in_one_leaf_under_boxes_that_hold_it() {
        let mut s = 1u64;
        let mut r = || {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let boxes: Vec<Aabb> = (0..10_000)
            .map(|_| {
                let c = Vec3A::new(r(), r(), r()) * 100.0;
                let e = Vec3A::new(r(), r(), r()) * (if r() < 0.01 { 50.0 } else { 0.5 });
                Aabb::new(c - e, c + e)
            })
            .collect();
        let leaves = check(&boxes);
        assert!(leaves >= 10_000 / MAX_LEAF, "{leaves} leaves");
        // Coincident boxes: halved until leaves, not one leaf of all.
        let same = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); 1_000];
        assert!(check(&same) >= 1_000 / MAX_LEAF);
        // One box.
        assert_eq!(check(&boxes[..1]), 1);
    }
}
