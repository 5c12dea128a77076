//! Four triangles tested against a ray at once. Each lane does what `RtTriangle::intersect`
//! (obvhs's Möller-Trumbore, the test Kiln's images were made with) does for one triangle,
//! operation for operation, so a lane's distance is that test's distance to the bit.

use crate::simd::{F4, Lanes, Mask};
use glam::Vec3A;
use obvhs::rt_triangle::RtTriangle;

/// Four triangles, component by component: a leaf's unit. Lanes with no triangle hold NaN
/// and never hit.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    v0: [[f32; 4]; 3],
    /// `v0 - v1`.
    e1: [[f32; 4]; 3],
    /// `v2 - v0`.
    e2: [[f32; 4]; 3],
    /// Each lane's triangle, as the scene declared it (`u32::MAX` where none).
    pub id: [u32; 4],
}

/// A ray as the lanes take it: each component splatted.
#[derive(Clone, Copy)]
pub struct Ray4 {
    pub o: [F4; 3],
    pub d: [F4; 3],
}

impl Ray4 {
    #[inline(always)]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Ray4 {
        Ray4 {
            o: [0, 1, 2].map(|a| F4::splat(origin[a])),
            d: [0, 1, 2].map(|a| F4::splat(dir[a])),
        }
    }
}

impl Tri4 {
    /// Up to four triangles with their ids.
    pub fn pack(tris: &[(RtTriangle, u32)]) -> Tri4 {
        assert!(tris.len() <= 4, "a pack holds four triangles");
        let mut p = Tri4 {
            v0: [[f32::NAN; 4]; 3],
            e1: [[f32::NAN; 4]; 3],
            e2: [[f32::NAN; 4]; 3],
            id: [u32::MAX; 4],
        };
        for (lane, (t, id)) in tris.iter().enumerate() {
            for a in 0..3 {
                p.v0[a][lane] = t.v0[a];
                p.e1[a][lane] = t.e1[a];
                p.e2[a][lane] = t.e2[a];
            }
            p.id[lane] = *id;
        }
        p
    }

    /// Each lane's distance along `ray` (NaN or out of range where it misses) and the lanes
    /// that hit within `[tmin, tmax]`.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray4, tmin: F4, tmax: F4) -> ([f32; 4], Mask) {
        let l = |v: &[[f32; 4]; 3]| [F4::load(&v[0]), F4::load(&v[1]), F4::load(&v[2])];
        let (t, mask) = hit(
            l(&self.v0),
            l(&self.e1),
            l(&self.e2),
            ray.o,
            ray.d,
            tmin,
            tmax,
        );
        (t.store(), mask)
    }

    /// [`Tri4::intersect`] of `self` (lanes 0-3) and `other` (lanes 4-7) at once, with AVX2:
    /// only for code compiled for it.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub fn intersect_pair(
        &self,
        other: &Tri4,
        origin: [f32; 3],
        dir: [f32; 3],
        tmin: f32,
        tmax: f32,
    ) -> ([f32; 8], Mask) {
        use crate::simd::F8;
        let l = |a: &[[f32; 4]; 3], b: &[[f32; 4]; 3]| [0, 1, 2].map(|k| F8::halves(&a[k], &b[k]));
        let (t, mask) = hit(
            l(&self.v0, &other.v0),
            l(&self.e1, &other.e1),
            l(&self.e2, &other.e2),
            origin.map(F8::splat),
            dir.map(F8::splat),
            F8::splat(tmin),
            F8::splat(tmax),
        );
        (t.store(), mask)
    }
}

/// obvhs's Möller-Trumbore on every lane: the distances, and the lanes that hit within
/// `[tmin, tmax]`.
#[inline(always)]
fn hit<L: Lanes>(
    v0: [L; 3],
    e1: [L; 3],
    e2: [L; 3],
    o: [L; 3],
    d: [L; 3],
    tmin: L,
    tmax: L,
) -> (L, Mask) {
    let dot = |a: [L; 3], b: [L; 3]| a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]));
    // ng = e1 x e2, as RtTriangle::new makes it: the same bits, not stored.
    let ng = [
        e1[1].mul(e2[2]).sub(e1[2].mul(e2[1])),
        e1[2].mul(e2[0]).sub(e1[0].mul(e2[2])),
        e1[0].mul(e2[1]).sub(e1[1].mul(e2[0])),
    ];
    let c = [v0[0].sub(o[0]), v0[1].sub(o[1]), v0[2].sub(o[2])];
    // r = d x c
    let r = [
        d[1].mul(c[2]).sub(d[2].mul(c[1])),
        d[2].mul(c[0]).sub(d[0].mul(c[2])),
        d[0].mul(c[1]).sub(d[1].mul(c[0])),
    ];
    let inv_det = L::splat(1.0).div(dot(ng, d));
    let u = dot(r, e2).mul(inv_det);
    let v = dot(r, e1).mul(inv_det);
    let w = L::splat(1.0).sub(u).sub(v);
    let inside = !u.or(v).or(w).signs() & inv_det.nonzero();
    let t = dot(ng, c).mul(inv_det);
    // RtTriangle's infinite distance is its miss (a ray in the triangle's plane).
    let within = tmin.le(t) & t.le(tmax.min(L::splat(f32::MAX)));
    (t, inside & within)
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::ray::Ray;

    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Every lane gives obvhs's distance to the bit, hit for hit and miss for miss, over
    /// random triangles and rays (many grazing, many from the triangles' own planes).
    #[test]
    fn each_lane_is_the_scalar_test_to_the_bit() {
        let mut s = 3u64;
        let v = |s: &mut u64| Vec3A::new(rng(s), rng(s), rng(s)) * 2.0 - 1.0;
        let (mut hits, mut checked) = (0, 0);
        for k in 0..50_000usize {
            let tris: Vec<(RtTriangle, u32)> = (0..1 + k % 4)
                .map(|i| (RtTriangle::new(v(&mut s), v(&mut s), v(&mut s)), i as u32))
                .collect();
            let pack = Tri4::pack(&tris);
            let origin = if k.is_multiple_of(5) {
                tris[0].0.v0 - tris[0].0.e1 * 0.5
            } else {
                v(&mut s) * 3.0
            };
            let dir = (v(&mut s) + Vec3A::ZERO).normalize();
            let tmax = if k.is_multiple_of(3) {
                1.0
            } else {
                f32::INFINITY
            };
            let ray = Ray::new(origin, dir, 0.0, tmax);
            let (t, mask) =
                pack.intersect(&Ray4::new(origin, dir), F4::splat(0.0), F4::splat(tmax));
            for (lane, (tri, _)) in tris.iter().enumerate() {
                let want = tri.intersect(&ray);
                let got = if mask & (1 << lane) != 0 {
                    t[lane]
                } else {
                    f32::INFINITY
                };
                assert_eq!(got.to_bits(), want.to_bits(), "ray {k}, lane {lane}");
                hits += (want < f32::INFINITY) as u32;
                checked += 1;
            }
            assert_eq!(mask >> tris.len(), 0, "empty lanes never hit");
        }
        assert!(hits > 2_000, "{hits} of {checked} hit");
    }
}
