//! Alpha cutouts (pbrt-v4's shape "alpha"): where a surface's alpha texture is 0 rays pass
//! through it, where it is 1 they stop, and in between they stop with that probability,
//! decided by a hash of the ray, so that the same ray always gets the same answer whatever
//! thread, tile or machine traces it. Camera, shadow and photon rays all see the same
//! surface. The texture is evaluated at the candidate hit with no footprint (pbrt-v4 too:
//! alpha is tested during traversal, before any differentials exist).

use super::Geometry;
use crate::textures::TextureEvalContext;
use glam::Vec3A;

impl Geometry {
    /// Whether a candidate hit at distance `t` on triangle `tri` stops the ray.
    pub(super) fn triangle_is_opaque_at(
        &self,
        tri: u32,
        origin: Vec3A,
        dir: Vec3A,
        t: f32,
    ) -> bool {
        let mesh = &self.prims.meshes[self.prims.triangle_mesh[tri as usize] as usize];
        let Some(alpha) = mesh.surface.alpha else {
            return true;
        };
        let p = origin + dir * t;
        let (uv, n) = self.triangle_uv_and_normal(tri, p);
        self.opaque(alpha, p, n, uv, origin, dir)
    }

    /// Whether a candidate hit at distance `t` on sphere `id` stops the ray.
    pub(super) fn sphere_is_opaque_at(&self, id: u32, origin: Vec3A, dir: Vec3A, t: f32) -> bool {
        let s = &self.prims.spheres[id as usize];
        let Some(alpha) = s.surface.alpha else {
            return true;
        };
        let p = origin + dir * t;
        let n = (p - s.center).normalize_or_zero();
        let uv = super::sphere::sphere_uv(s.rotation.to_object(n));
        self.opaque(alpha, p, n, uv, origin, dir)
    }

    pub(super) fn opaque(
        &self,
        alpha: u32,
        p: Vec3A,
        n: Vec3A,
        uv: glam::Vec2,
        origin: Vec3A,
        dir: Vec3A,
    ) -> bool {
        let ctx = TextureEvalContext {
            p,
            n,
            uv,
            ..Default::default()
        };
        let a = self.prims.alphas[alpha as usize].evaluate(&ctx);
        if a >= 1.0 {
            return true;
        }
        a > 0.0 && hash_float(origin, dir) <= a
    }
}

/// A number in [0, 1) from a ray's origin and direction (splitmix64 over their bits).
pub fn hash_float(origin: Vec3A, dir: Vec3A) -> f32 {
    let mut h: u64 = 0x9e37_79b9_7f4a_7c15;
    for v in [origin.x, origin.y, origin.z, dir.x, dir.y, dir.z] {
        h ^= v.to_bits() as u64;
        h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
        h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h ^= h >> 31;
    }
    (h >> 40) as f32 / (1u64 << 24) as f32
}
