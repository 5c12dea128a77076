//! Closest-hit traversal of obvhs's compressed wide BVH (CWBVH), nearest child first: the
//! design before Kiln's own wide BVH ([`super::wide`]), which the scene no longer uses; kept
//! for `benches/traversal.rs` to compare the two on the same rays.
//!
//! obvhs walks a CWBVH as Ylitie et al. do on the GPU: children in the order of the ray's
//! octant, a group of siblings on the stack with no distances. For a ray that starts on a
//! dense surface (every bounce, every VolumeLight chord) that order is often far from
//! near-to-far, so the walk tests many boxes and triangles beyond the hit it will find. Here
//! every child that the ray enters goes on the stack with its entry distance, the nearest on
//! top, and an entry farther than the closest hit so far is dropped unopened, as CPU tracers
//! do. `benches/traversal.rs` measures the two.
//!
//! The box test is obvhs's own (the same quantised planes and the same float operations,
//! in the same order), so both walks test the same boxes the same way: they find the same
//! closest distance. Where two primitives lie at exactly that distance (a ray through a
//! shared edge), the one tested first wins, in either walk; the order is a function of the
//! ray and the BVH alone, so the choice is the same on every machine and thread.

use glam::Vec3A;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray;

/// Stack entries: a node pushes at most its 8 children and pops itself, so a BVH of depth
/// d needs at most 7d + 1. A deeper BVH falls back to obvhs's walk ([`fits`]).
const STACK: usize = 256;

/// obvhs's lower clamp on a box's entry distance (its `EPSILON`), kept so that both walks
/// open the same boxes.
const ENTRY_MIN: f32 = 0.0001;

/// A stack entry's target: a node, or a leaf's primitives (`LEAF` set: count in bits 29-30,
/// first primitive slot below).
const LEAF: u32 = 1 << 31;
const LEAF_START: u32 = (1 << 29) - 1;

/// Whether `bvh` can be walked here: shallow enough for the fixed stack, with primitive
/// slots that fit a stack entry. Where not, the caller uses obvhs's walk.
pub fn fits(bvh: &CwBvh) -> bool {
    bvh.primitive_indices.len() < LEAF_START as usize
        && !bvh.nodes.is_empty()
        && depth(bvh) * 7 < STACK
}

/// The number of node levels of `bvh`.
fn depth(bvh: &CwBvh) -> usize {
    let mut deepest = 0;
    let mut todo = vec![(0u32, 1usize)];
    while let Some((i, d)) = todo.pop() {
        deepest = deepest.max(d);
        let node = &bvh.nodes[i as usize];
        for slot in 0..8 {
            if node.child_meta[slot] != 0 && node.imask & (1 << slot) != 0 {
                todo.push((internal_child(node, slot), d + 1));
            }
        }
    }
    deepest
}

/// The node index of internal child `slot`: internal children are stored in slot order.
#[inline(always)]
fn internal_child(node: &CwBvhNode, slot: usize) -> u32 {
    node.child_base_idx + (node.imask as u32 & ((1u32 << slot) - 1)).count_ones()
}

/// The closest primitive along `ray` within `ray.tmax`: `hit(ray, slot)` gives a BVH
/// slot's distance (infinite on a miss) for a ray whose `tmax` is the closest so far.
/// Returns the distance and the slot.
#[inline(always)]
pub fn closest(
    bvh: &CwBvh,
    ray: Ray,
    mut hit: impl FnMut(&Ray, usize) -> f32,
) -> Option<(f32, u32)> {
    let mut r = ray;
    let mut best = None;
    // Left uninitialised: a ray touches a few entries of it, and zeroing it all cost more
    // than the walk saved.
    let mut stack = [std::mem::MaybeUninit::<(u32, f32)>::uninit(); STACK];
    stack[0].write((0, 0.0));
    let mut sp = 1;
    while sp > 0 {
        sp -= 1;
        // SAFETY: entries below `sp` were written before `sp` passed them.
        let (target, entry) = unsafe { stack[sp].assume_init() };
        if entry > r.tmax {
            continue;
        }
        if target & LEAF != 0 {
            let start = target & LEAF_START;
            let count = (target >> 29) & 3;
            for slot in start..start + count {
                let t = hit(&r, slot as usize);
                if t < r.tmax {
                    r.tmax = t;
                    best = Some(slot);
                }
            }
            continue;
        }
        let node = &bvh.nodes[target as usize];
        let (entries, mask) = child_entries(node, &r);
        // The children entered, farthest first onto the stack so the nearest is on top;
        // equal distances keep slot order (the later slot below).
        let mut order = [(0f32, 0u32); 8];
        let mut n = 0;
        for (slot, &e) in entries.iter().enumerate() {
            if mask & (1 << slot) == 0 {
                continue;
            }
            let meta = node.child_meta[slot] as u32;
            let target = if node.imask & (1 << slot) != 0 {
                internal_child(node, slot)
            } else {
                LEAF | ((meta >> 5).count_ones() << 29) | (node.primitive_base_idx + (meta & 0x1f))
            };
            // Insertion sort, descending by distance.
            let mut k = n;
            while k > 0 && order[k - 1].0 < e {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = (e, target);
            n += 1;
        }
        for &(e, target) in &order[..n] {
            stack[sp].write((target, e));
            sp += 1;
        }
    }
    best.map(|slot| (r.tmax, slot))
}

/// obvhs's box test of a node's eight children (`CwBvhNode::intersect_ray_simd`, the same
/// operations in the same order, four children at a time), returning each child's entry
/// distance and the mask of non-empty children the ray enters within `ray.tmax`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn child_entries(node: &CwBvhNode, ray: &Ray) -> ([f32; 8], u8) {
    use std::arch::x86_64::*;
    let adj_dir_inv = node.compute_extent() * ray.inv_direction;
    let adj_origin = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let mut entries = [0f32; 8];
    let mut mask = 0u32;
    // SAFETY: SSE2 is part of every x86-64 CPU; the loads read 4 of 8 bytes in bounds.
    unsafe {
        let q = |v: &[u8; 8], i: usize| {
            _mm_set_ps(
                v[i * 4 + 3] as f32,
                v[i * 4 + 2] as f32,
                v[i * 4 + 1] as f32,
                v[i * 4] as f32,
            )
        };
        let axis = |lo: &[u8; 8], hi: &[u8; 8], neg: bool, d: f32, o: f32, i: usize| {
            let (a, b) = if neg {
                (q(hi, i), q(lo, i))
            } else {
                (q(lo, i), q(hi, i))
            };
            let d = _mm_set1_ps(d);
            let o = _mm_set1_ps(o);
            (
                _mm_add_ps(_mm_mul_ps(a, d), o),
                _mm_add_ps(_mm_mul_ps(b, d), o),
            )
        };
        let planes = [
            (&node.child_min_x, &node.child_max_x, ray.direction.x < 0.0),
            (&node.child_min_y, &node.child_max_y, ray.direction.y < 0.0),
            (&node.child_min_z, &node.child_max_z, ray.direction.z < 0.0),
        ];
        for i in 0..2 {
            let [(nx, fx), (ny, fy), (nz, fz)] = std::array::from_fn(|a| {
                let (lo, hi, neg) = planes[a];
                axis(lo, hi, neg, adj_dir_inv[a], adj_origin[a], i)
            });
            let tmin = _mm_max_ps(nx, _mm_max_ps(ny, nz));
            let tmax = _mm_min_ps(fx, _mm_min_ps(fy, fz));
            let tmin = _mm_max_ps(tmin, _mm_set1_ps(ENTRY_MIN));
            let tmax = _mm_min_ps(tmax, _mm_set1_ps(ray.tmax));
            _mm_storeu_ps(entries.as_mut_ptr().add(i * 4), tmin);
            mask |= (_mm_movemask_ps(_mm_cmple_ps(tmin, tmax)) as u32) << (i * 4);
        }
    }
    let occupied = u64::from_le_bytes(node.child_meta);
    let mut nonempty = 0u32;
    for c in 0..8 {
        if (occupied >> (c * 8)) & 0xff != 0 {
            nonempty |= 1 << c;
        }
    }
    (entries, (mask & nonempty) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::BvhBuildParams;
    use obvhs::ray::RayHit;
    use obvhs::rt_triangle::RtTriangle;
    use obvhs::triangle::Triangle;

    /// A small generator, so the soup and the rays are the same every run.
    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Nearest child first finds, for every ray, the distance obvhs's own walk finds and a
    /// primitive at that distance, on a soup dense enough for deep trees and many overlaps,
    /// with rays from inside it, outside it and with bounded reach; the stack never
    /// overflows (the BVH fits).
    #[test]
    fn finds_what_obvhs_finds() {
        let mut s = 7u64;
        let mut tris = Vec::new();
        for _ in 0..20_000 {
            let c = Vec3A::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 10.0;
            let mut v = || c + Vec3A::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 0.3;
            tris.push(Triangle {
                v0: v(),
                v1: v(),
                v2: v(),
            });
        }
        let params = BvhBuildParams {
            pre_split: true,
            ..BvhBuildParams::medium_build()
        };
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            params,
            &mut std::time::Duration::default(),
        );
        assert!(fits(&bvh));
        let rt: Vec<RtTriangle> = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                RtTriangle::new(t.v0, t.v1, t.v2)
            })
            .collect();
        let mut hits = 0;
        for k in 0..20_000 {
            let o = Vec3A::new(rng(&mut s), rng(&mut s), rng(&mut s)) * 14.0 - 2.0;
            let d =
                (Vec3A::new(rng(&mut s), rng(&mut s), rng(&mut s)) - 0.5).normalize() + Vec3A::ZERO;
            let tmax = if k % 3 == 0 { 2.0 } else { f32::INFINITY };
            let ray = Ray::new(o, d, 0.0, tmax);
            let mut h = RayHit::none();
            let theirs = bvh
                .ray_traverse(ray, &mut h, |r, slot| rt[slot].intersect(r))
                .then_some(h.t);
            let ours = closest(&bvh, ray, |r, slot| rt[slot].intersect(r));
            assert_eq!(ours.map(|(t, _)| t), theirs, "ray {k}");
            if let Some((t, slot)) = ours {
                assert_eq!(
                    rt[slot as usize].intersect(&ray),
                    t,
                    "ray {k}: the slot is at t"
                );
                hits += 1;
            }
        }
        assert!(hits > 2_000, "{hits} hits: the soup should stop many rays");
    }
}
