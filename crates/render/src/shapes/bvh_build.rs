//! Building a CWBVH over primitives, in bounded stack and time whatever they are.
//!
//! obvhs's PLOC builder clusters primitives in the order of their centroids' Morton codes,
//! merging each with its nearest neighbour. Primitives it cannot tell apart (the same
//! centroid, or centroids in one cell of its grid: 30,000 copies of a triangle or a sphere)
//! are all equally near one another, and it merges them one at a time into a chain as deep
//! as they are many: quadratic time, and a recursion in the conversion to CWBVH that
//! overflows the stack. Such inputs are found before building (`clustered`) and built by a
//! median split instead (`median_bvh2`): top down, with an explicit stack, depth log2 of the
//! count, the same tree on every machine. Every other input is built by PLOC as before, so
//! its BVH, and every image, is unchanged.

use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::cwbvh::CwBvh;
use obvhs::{Boundable, BvhBuildParams};
use std::time::{Duration, Instant};

/// The most primitives that may share one cell of a 2^21-per-axis grid over the
/// centroids before PLOC is not trusted with them.
pub const MAX_CLUSTER: usize = 256;

/// The primitives a median-split leaf holds: one, as the conversion to CWBVH expects (it
/// gathers up to three into a CWBVH leaf itself).
const LEAF_SIZE: usize = 1;

/// A CWBVH over `primitives`: PLOC, unless some cluster of them would defeat it.
pub fn build_cwbvh<T: Boundable>(
    primitives: &[T],
    params: BvhBuildParams,
    build_time: &mut Duration,
) -> CwBvh {
    let aabbs: Vec<Aabb> = primitives.iter().map(Boundable::aabb).collect();
    if clustered(&aabbs) {
        return median_cwbvh(&aabbs, params, build_time);
    }
    obvhs::cwbvh::builder::build_cwbvh(primitives, params, build_time)
}

/// Kiln's wide BVH over `triangles` (`rt[i]` is `triangles[i]` ready to intersect),
/// collapsed from Kiln's binned SAH build ([`super::wide::sah`]), or from a median split
/// where that tree is too deep for the walk's stack. On the snail's rays the SAH tree
/// measured 1.29x the closest hits per second of obvhs's PLOC tree (with or without its
/// spatial pre-splits, which cost 10% here: the floor's two large triangles cut into many
/// boxes), in 57 bytes per triangle against 73.
pub fn build_triangle_wide_bvh(
    triangles: &[obvhs::triangle::Triangle],
    rt: &[obvhs::rt_triangle::RtTriangle],
    build_time: &mut Duration,
) -> super::wide::WideBvh {
    use super::wide::{Binary, WideBvh, sah};
    let start = Instant::now();
    let aabbs: Vec<Aabb> = triangles.iter().map(|t| t.aabb()).collect();
    let ids: Vec<u32> = (0..triangles.len() as u32).collect();
    let (nodes, prims) = sah::build(&aabbs, &ids);
    let bvh = WideBvh::collapse(
        &Binary {
            nodes: &nodes,
            prims: &prims,
        },
        rt,
    )
    .unwrap_or_else(|| {
        WideBvh::collapse(&(&median_bvh2(&aabbs)).into(), rt)
            .expect("a median split is shallow enough for any count of triangles")
    });
    *build_time += start.elapsed();
    bvh
}

/// Whether more than [`MAX_CLUSTER`] boxes have their centres in one cell of a 2^21-per-
/// axis grid over the centres' bounds (or the same centre, where the bounds are a point).
pub fn clustered(aabbs: &[Aabb]) -> bool {
    if aabbs.len() <= MAX_CLUSTER {
        return false;
    }
    let mut bounds = Aabb::empty();
    for b in aabbs {
        bounds.extend(b.center());
    }
    let extent = (bounds.max - bounds.min).max(glam::Vec3A::splat(f32::MIN_POSITIVE));
    let cells = ((1u32 << 21) - 1) as f32;
    let mut keys: Vec<u64> = aabbs
        .iter()
        .map(|b| {
            let q = ((b.center() - bounds.min) / extent * cells)
                .clamp(glam::Vec3A::ZERO, glam::Vec3A::splat(cells));
            // Not finite (a NaN box): all in one cell, as PLOC would see them.
            let cell = |v: f32| if v.is_finite() { v as u64 } else { 0 };
            (cell(q.x) << 42) | (cell(q.y) << 21) | cell(q.z)
        })
        .collect();
    keys.sort_unstable();
    let mut run = 1;
    for pair in keys.windows(2) {
        run = if pair[0] == pair[1] { run + 1 } else { 1 };
        if run > MAX_CLUSTER {
            return true;
        }
    }
    false
}

/// A CWBVH of a median-split BVH2 over `aabbs`.
fn median_cwbvh(aabbs: &[Aabb], params: BvhBuildParams, build_time: &mut Duration) -> CwBvh {
    let start = Instant::now();
    let bvh2 = median_bvh2(aabbs);
    let cwbvh = obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(
        &bvh2,
        params.max_prims_per_leaf.clamp(1, 3),
        true,
        false,
    );
    *build_time += start.elapsed();
    cwbvh
}

/// A BVH2 over `aabbs` split top down at the median centre along the longest axis of
/// each node's centres (ties ordered by index, so the tree is the same everywhere), into
/// leaves of [`LEAF_SIZE`]. Iterative: depth log2 of the count, no recursion.
pub fn median_bvh2(aabbs: &[Aabb]) -> Bvh2 {
    let n = aabbs.len();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut nodes: Vec<Bvh2Node> = Vec::with_capacity(2 * n);
    nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
    // (node, the range of `order` it holds, its depth)
    let mut stack = vec![(0usize, 0usize, n, 1usize)];
    let mut max_depth = 1;
    while let Some((node, lo, hi, depth)) = stack.pop() {
        max_depth = max_depth.max(depth);
        let mut bounds = Aabb::empty();
        let mut centres = Aabb::empty();
        for &i in &order[lo..hi] {
            bounds = bounds.union(&aabbs[i as usize]);
            centres.extend(aabbs[i as usize].center());
        }
        if hi - lo <= LEAF_SIZE {
            nodes[node] = Bvh2Node::new(bounds, (hi - lo) as u32, lo as u32);
            continue;
        }
        let size = centres.max - centres.min;
        let axis = if size.x >= size.y && size.x >= size.z {
            0
        } else if size.y >= size.z {
            1
        } else {
            2
        };
        let mid = lo + (hi - lo) / 2;
        // A total order (total_cmp, then the index): the same split everywhere, and
        // select_nth never meets an inconsistent comparison.
        let centre = |i: &u32| aabbs[*i as usize].center()[axis];
        order[lo..hi].select_nth_unstable_by(mid - lo, |a, b| {
            centre(a).total_cmp(&centre(b)).then(a.cmp(b))
        });
        let first = nodes.len();
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes[node] = Bvh2Node::new(bounds, 0, first as u32);
        stack.push((first + 1, mid, hi, depth + 1));
        stack.push((first, lo, mid, depth + 1));
    }
    Bvh2 {
        nodes,
        primitive_indices: order,
        children_are_ordered_after_parents: true,
        max_depth: max_depth.max(obvhs::bvh2::DEFAULT_MAX_STACK_DEPTH),
        ..Bvh2::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    fn unit_at(p: Vec3A) -> Aabb {
        Aabb {
            min: p - 0.5,
            max: p + 0.5,
        }
    }

    #[test]
    fn only_clusters_past_the_limit_count() {
        let spread: Vec<Aabb> = (0..10_000)
            .map(|i| unit_at(Vec3A::new(i as f32, (i * 7 % 13) as f32, 0.0)))
            .collect();
        assert!(!clustered(&spread));
        let mut same = spread.clone();
        same.extend((0..=MAX_CLUSTER).map(|_| unit_at(Vec3A::splat(3.0))));
        assert!(clustered(&same));
        let few: Vec<Aabb> = (0..MAX_CLUSTER).map(|_| unit_at(Vec3A::ZERO)).collect();
        assert!(!clustered(&few));
    }

    /// 100,000 copies of one box: a tree of depth log2, every box in exactly one leaf,
    /// every node's box holding its children's, in well under a second.
    #[test]
    fn coincident_boxes_make_a_shallow_complete_tree() {
        let boxes = vec![unit_at(Vec3A::ONE); 100_000];
        let start = Instant::now();
        let bvh = median_bvh2(&boxes);
        assert!(start.elapsed() < Duration::from_secs(1));
        let mut seen = vec![0u32; boxes.len()];
        let mut stack = vec![(0usize, 1usize)];
        let mut deepest = 0;
        while let Some((i, depth)) = stack.pop() {
            deepest = deepest.max(depth);
            let node = &bvh.nodes[i];
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                for &p in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                    seen[p as usize] += 1;
                }
            } else {
                for c in [node.first_index as usize, node.first_index as usize + 1] {
                    let (outer, inner) = (node.aabb(), bvh.nodes[c].aabb());
                    assert!(outer.min.cmple(inner.min).all() && outer.max.cmpge(inner.max).all());
                    stack.push((c, depth + 1));
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        assert!(deepest <= 18, "depth {deepest}");
        let cwbvh = obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh, 3, true, false);
        assert_eq!(cwbvh.primitive_indices.len(), boxes.len());
    }
}
