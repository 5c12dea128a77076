use super::*;
use crate::shapes::bvh_build;
use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;

/// A small generator, so that the soups and the rays are the same every run.
fn rng(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    (*state >> 40) as f32 / (1u64 << 24) as f32
}

fn v(s: &mut u64) -> Vec3A {
    Vec3A::new(rng(s), rng(s), rng(s))
}

/// The BVH over `tris` as the renderer builds it, and the triangles ready to intersect.
fn build(tris: &[Triangle]) -> (WideBvh, Vec<RtTriangle>) {
    let rt: Vec<RtTriangle> = tris.iter().map(RtTriangle::from).collect();
    let bvh = bvh_build::build_triangle_wide_bvh(tris, &rt, &mut std::time::Duration::default());
    (bvh, rt)
}

/// The smallest (t, id) over every triangle `keep` keeps: what the walk must find.
fn brute(rt: &[RtTriangle], ray: &Ray, keep: impl Fn(u32) -> bool) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (id, tri) in rt.iter().enumerate() {
        let t = tri.intersect(ray);
        if t < f32::INFINITY
            && keep(id as u32)
            && best.is_none_or(|(bt, bid)| t < bt || (t == bt && (id as u32) < bid))
        {
            best = Some((t, id as u32));
        }
    }
    best
}

/// A soup of `n` small triangles in a 10-unit cube.
fn soup(n: usize, s: &mut u64) -> Vec<Triangle> {
    (0..n)
        .map(|_| {
            let c = v(s) * 10.0;
            let mut p = || c + v(s) * 0.4;
            Triangle {
                v0: p(),
                v1: p(),
                v2: p(),
            }
        })
        .collect()
}

/// A ray from inside, outside or on the soup, some with a bounded reach.
fn ray(k: usize, s: &mut u64, tris: &[Triangle]) -> Ray {
    let o = if k.is_multiple_of(7) {
        // On a triangle's edge: the start of every bounce.
        let t = &tris[k % tris.len()];
        (t.v0 + t.v1) * 0.5
    } else {
        v(s) * 14.0 - 2.0
    };
    let mut d = (v(s) - 0.5).normalize();
    if k.is_multiple_of(11) {
        d.x = 0.0; // parallel to a slab
        d = d.normalize();
    }
    let tmax = if k.is_multiple_of(3) {
        2.0
    } else {
        f32::INFINITY
    };
    Ray::new(o, d, 0.0, tmax)
}

/// Every ray's closest hit is the brute-force smallest (distance, id), to the bit, and
/// any-hit agrees with it, with every kernel this CPU runs.
fn agrees_with_brute_force(bvh: WideBvh, rt: &[RtTriangle], rays: &[Ray]) -> u32 {
    let mut hits = 0;
    for kernel in Kernel::available() {
        let bvh = WideBvh { ..bvh.clone() }.with_kernel(kernel);
        hits = 0;
        for (k, r) in rays.iter().enumerate() {
            let want = brute(rt, r, |_| true);
            let got = bvh.closest(r.origin, r.direction, r.tmax, |_, _| true);
            assert_eq!(
                got.map(|(t, id)| (t.to_bits(), id)),
                want.map(|(t, id)| (t.to_bits(), id)),
                "{kernel:?}, ray {k}: {r:?}"
            );
            assert_eq!(
                bvh.any(r.origin, r.direction, r.tmax, |_, _| true),
                want.is_some(),
                "{kernel:?}, ray {k}"
            );
            hits += want.is_some() as u32;
        }
    }
    hits
}

/// On a soup dense enough for deep trees and many overlaps.
#[test]
fn finds_the_smallest_distance_and_id_a_brute_force_search_finds() {
    let mut s = 7u64;
    let tris = soup(5_000, &mut s);
    let (bvh, rt) = build(&tris);
    let rays: Vec<Ray> = (0..4_000).map(|k| ray(k, &mut s, &tris)).collect();
    let hits = agrees_with_brute_force(bvh, &rt, &rays);
    assert!(hits > 400, "{hits} hits: the soup should stop many rays");
}

/// On a bumpy grid of triangles sharing edges and vertices, with rays aimed exactly at the
/// shared vertices and edge midpoints: where two triangles meet, both may claim the ray at
/// distances an ulp apart, and the nearer (then the first declared) must win whatever the
/// tree's boxes say.
#[test]
fn rays_through_shared_edges_find_the_nearer_triangle() {
    let mut s = 5u64;
    let n = 40;
    let height: Vec<f32> = (0..(n + 1) * (n + 1)).map(|_| rng(&mut s) * 0.3).collect();
    let at =
        |i: usize, j: usize| Vec3A::new(i as f32 * 0.25, j as f32 * 0.25, height[i * (n + 1) + j]);
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            tris.push(Triangle {
                v0: a,
                v1: b,
                v2: c,
            });
            tris.push(Triangle {
                v0: a,
                v1: c,
                v2: d,
            });
        }
    }
    let (bvh, rt) = build(&tris);
    let rays: Vec<Ray> = (0..6_000)
        .map(|k| {
            let (i, j) = (1 + k % (n - 1), 1 + (k / 7) % (n - 1));
            let target = match k % 3 {
                0 => at(i, j),
                1 => (at(i, j) + at(i + 1, j)) * 0.5,
                _ => (at(i, j) + at(i + 1, j + 1)) * 0.5,
            };
            let origin = target + (v(&mut s) - 0.5) * 4.0 + Vec3A::new(0.0, 0.0, 3.0);
            Ray::new(origin, (target - origin).normalize(), 0.0, f32::INFINITY)
        })
        .collect();
    let hits = agrees_with_brute_force(bvh, &rt, &rays);
    assert!(hits > 5_000, "{hits} of 6000 rays hit the grid they aim at");
}

/// What `opaque` refuses (an alpha cutout) is passed through by both walks.
#[test]
fn refused_candidates_are_passed_through() {
    let mut s = 11u64;
    let tris = soup(3_000, &mut s);
    let (bvh, rt) = build(&tris);
    let keep = |id: u32| !id.is_multiple_of(3);
    for k in 0..2_000 {
        let r = ray(k, &mut s, &tris);
        let want = brute(&rt, &r, keep);
        let got = bvh.closest(r.origin, r.direction, r.tmax, |id, _| keep(id));
        assert_eq!(got, want, "ray {k}");
        assert_eq!(
            bvh.any(r.origin, r.direction, r.tmax, |id, _| keep(id)),
            want.is_some()
        );
    }
}

/// Thousands of copies of one triangle (which PLOC cannot tell apart) build by median split
/// into a shallow tree, and the copy the scene declared first is the one hit.
#[test]
fn coincident_triangles_build_shallow_and_the_first_declared_wins() {
    let t = Triangle {
        v0: Vec3A::new(0.0, 0.0, 0.0),
        v1: Vec3A::new(1.0, 0.0, 0.0),
        v2: Vec3A::new(0.0, 1.0, 0.0),
    };
    let mut tris = vec![t; 20_000];
    tris.push(Triangle {
        v0: Vec3A::new(0.0, 0.0, -1.0),
        v1: Vec3A::new(1.0, 0.0, -1.0),
        v2: Vec3A::new(0.0, 1.0, -1.0),
    });
    let (bvh, _) = build(&tris);
    // A median split of 20,001 is 15 binary levels; the stack needs 3 per wide level.
    assert!(bvh.depth() <= 15, "depth {}", bvh.depth());
    let hit = bvh.closest(
        Vec3A::new(0.2, 0.2, 1.0),
        Vec3A::new(0.0, 0.0, -1.0),
        f32::INFINITY,
        |_, _| true,
    );
    assert_eq!(hit, Some((1.0, 0)));
    // Refusing the copies, the ray goes on to the last triangle.
    let hit = bvh.closest(
        Vec3A::new(0.2, 0.2, 1.0),
        Vec3A::new(0.0, 0.0, -1.0),
        f32::INFINITY,
        |id, _| id == 20_000,
    );
    assert_eq!(hit, Some((2.0, 20_000)));
}

/// A single triangle, and rays along axes (zero and negative-zero components).
#[test]
fn one_triangle_and_axis_aligned_rays() {
    let tris = [Triangle {
        v0: Vec3A::new(-1.0, -1.0, 0.0),
        v1: Vec3A::new(1.0, -1.0, 0.0),
        v2: Vec3A::new(0.0, 1.0, 0.0),
    }];
    let (bvh, _) = build(&tris);
    for d in [Vec3A::new(0.0, 0.0, -1.0), Vec3A::new(-0.0, -0.0, -1.0)] {
        let hit = bvh.closest(Vec3A::new(0.0, 0.0, 3.0), d, f32::INFINITY, |_, _| true);
        assert_eq!(hit, Some((3.0, 0)), "{d}");
        assert!(bvh.any(Vec3A::new(0.0, 0.0, 3.0), d, 3.0, |_, _| true));
        assert!(!bvh.any(Vec3A::new(0.0, 0.0, 3.0), d, 2.5, |_, _| true));
    }
    // In the triangle's plane, beside it: a miss, not a NaN hit.
    let hit = bvh.closest(
        Vec3A::new(5.0, 0.0, 0.0),
        Vec3A::new(0.0, 1.0, 0.0),
        f32::INFINITY,
        |_, _| true,
    );
    assert_eq!(hit, None);
}

/// Where a ray meets a sphere beyond 1e-7 and before `limit`.
fn sphere_t(c: Vec3A, r: f32, o: Vec3A, d: Vec3A, limit: f32) -> Option<f32> {
    let f = o - c;
    let b = f.dot(d);
    let disc = b * b - (f.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    [-b - s, -b + s]
        .into_iter()
        .find(|&t| t > 1e-7 && t < limit)
}

/// Spheres in the same hierarchy as triangles, handed to the caller's test: the closest
/// hit of either kind is the brute-force smallest (distance, id), a sphere declared twice
/// is hit under its smaller id, and any-hit agrees, with every kernel.
#[test]
fn other_primitives_share_the_hierarchy_and_ties_go_to_the_smaller_id() {
    let mut s = 3u64;
    let tris = soup(2_000, &mut s);
    let rt: Vec<RtTriangle> = tris.iter().map(RtTriangle::from).collect();
    let mut spheres: Vec<(Vec3A, f32)> = (0..200)
        .map(|_| (v(&mut s) * 10.0, 0.05 + rng(&mut s) * 0.3))
        .collect();
    for k in (0..200).step_by(3) {
        spheres.push(spheres[k]);
    }
    let boxes: Vec<Aabb> = spheres
        .iter()
        .map(|&(c, r)| Aabb::new(c - r, c + r))
        .collect();
    let bvh = bvh_build::build_wide_bvh(&tris, &rt, &boxes, &mut std::time::Duration::default());
    let base = tris.len() as u32;
    let (mut sphere_hits, mut twins) = (0, 0);
    for kernel in Kernel::available() {
        let bvh = bvh.clone().with_kernel(kernel);
        for k in 0..4_000 {
            let r = ray(k, &mut s, &tris);
            let mut want = brute(&rt, &r, |_| true);
            for (i, &(c, rad)) in spheres.iter().enumerate() {
                let id = base + i as u32;
                if let Some(t) = sphere_t(c, rad, r.origin, r.direction, r.tmax)
                    && want.is_none_or(|(bt, bid)| t < bt || (t == bt && id < bid))
                {
                    want = Some((t, id));
                }
            }
            let other = |id: u32, limit: f32| {
                let (c, rad) = spheres[(id - base) as usize];
                sphere_t(c, rad, r.origin, r.direction, limit)
            };
            let got = bvh.closest_with(r.origin, r.direction, r.tmax, |_, _| true, other);
            assert_eq!(
                got.map(|(t, id)| (t.to_bits(), id)),
                want.map(|(t, id)| (t.to_bits(), id)),
                "{kernel:?}, ray {k}"
            );
            let any = bvh.any_with(
                r.origin,
                r.direction,
                r.tmax,
                |_, _| true,
                |id, limit| other(id, limit).is_some(),
            );
            assert_eq!(any, want.is_some(), "{kernel:?}, ray {k}");
            if let Some((_, id)) = want
                && id >= base
            {
                sphere_hits += 1;
                twins += ((id - base).is_multiple_of(3) && id - base < 200) as u32;
            }
        }
    }
    assert!(sphere_hits > 200, "{sphere_hits} rays hit a sphere first");
    assert!(twins > 50, "{twins} rays hit a sphere declared twice");
}
