//! Building the scene's hierarchy in bounded stack and time whatever its primitives are.
//!
//! Kiln's binned SAH ([`super::wide::sah`]) builds the tree the wide BVH collapses. Where
//! that tree is too deep for the walks' stack (30,000 copies of one triangle, which no split
//! can tell apart, are halved in the order they come, level after level, but clusters the
//! SAH keeps peeling could still run deep), a median split builds it instead
//! ([`median_bvh2`]): top down, with an explicit stack, depth log2 of the count, the same
//! tree on every machine.

use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use std::time::{Duration, Instant};

/// The primitives a median-split leaf holds.
const LEAF_SIZE: usize = 1;

/// Kiln's wide BVH over `triangles` (`rt[i]` is `triangles[i]` ready to intersect) and
/// other primitives bounded by `others` (ids `triangles.len()` on, in order), collapsed
/// from Kiln's binned SAH build ([`super::wide::sah`]), or from a median split where that
/// tree is too deep for the walk's stack. On the snail's rays the SAH tree measured 1.29x
/// the closest hits per second of obvhs's PLOC tree (with or without its spatial
/// pre-splits, which cost 10% here: the floor's two large triangles cut into many boxes),
/// in 57 bytes per triangle against 73.
pub fn build_wide_bvh(
    triangles: &[obvhs::triangle::Triangle],
    rt: &[obvhs::rt_triangle::RtTriangle],
    others: &[Aabb],
    build_time: &mut Duration,
) -> super::wide::WideBvh {
    use super::wide::{Binary, WideBvh, sah};
    let start = Instant::now();
    let aabbs: Vec<Aabb> = triangles
        .iter()
        .map(|t| t.aabb())
        .chain(others.iter().copied())
        .collect();
    let ids: Vec<u32> = (0..aabbs.len() as u32).collect();
    let (nodes, prims) = sah::build(&aabbs, &ids, triangles.len() as u32);
    let bvh = WideBvh::collapse(
        &Binary {
            nodes: &nodes,
            prims: &prims,
        },
        rt,
    )
    .unwrap_or_else(|| {
        WideBvh::collapse(&(&median_bvh2(&aabbs)).into(), rt)
            .expect("a median split is shallow enough for any count of primitives")
    });
    *build_time += start.elapsed();
    bvh
}

/// [`build_wide_bvh`] over triangles alone.
pub fn build_triangle_wide_bvh(
    triangles: &[obvhs::triangle::Triangle],
    rt: &[obvhs::rt_triangle::RtTriangle],
    build_time: &mut Duration,
) -> super::wide::WideBvh {
    build_wide_bvh(triangles, rt, &[], build_time)
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
