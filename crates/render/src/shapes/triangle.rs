//! Triangles of meshes: hit records, points at barycentrics, and uniform area sampling.

use super::{Geometry, MeshInfo, ShapeSample, SurfaceHit};
use crate::math::{Frame, Ray};
use crate::sampling::uniform_triangle;
use glam::{Vec2, Vec3A};

impl Geometry {
    /// Triangle `tri`'s vertex indices, its mesh and its vertex positions.
    fn triangle(&self, tri: u32) -> ([u32; 3], &MeshInfo, [Vec3A; 3]) {
        let v = self.prims.triangle_vertices[tri as usize];
        let mesh = &self.prims.meshes[self.prims.triangle_mesh[tri as usize] as usize];
        (v, mesh, v.map(|i| self.prims.positions[i as usize]))
    }

    pub(super) fn triangle_hit(&self, ray: &Ray, t: f32, tri: u32) -> SurfaceHit {
        let ([i0, i1, i2], mesh, [p0, p1, p2]) = self.triangle(tri);
        let b = barycentrics(ray.at(t), p0, p1, p2);
        // The point from its barycentrics, in the triangle's plane up to rounding.
        let p = p0 * b[0] + p1 * b[1] + p2 * b[2];
        let (ng, ns) = self.oriented_normals(mesh, [i0, i1, i2], [p0, p1, p2], b);
        let (uv0, uv1, uv2) = if mesh.has_uvs {
            (
                self.prims.uvs[i0 as usize],
                self.prims.uvs[i1 as usize],
                self.prims.uvs[i2 as usize],
            )
        } else {
            (Vec2::ZERO, Vec2::X, Vec2::ONE)
        };
        let uv = uv0 * b[0] + uv1 * b[1] + uv2 * b[2];
        let (duv02, duv12) = (uv0 - uv2, uv1 - uv2);
        let (dp02, dp12) = (p0 - p2, p1 - p2);
        let det = duv02.x * duv12.y - duv02.y * duv12.x;
        let (mut dpdu, mut dpdv) = (Vec3A::ZERO, Vec3A::ZERO);
        if det.abs() >= 1e-9 {
            dpdu = (dp02 * duv12.y - dp12 * duv02.y) / det;
            dpdv = (dp12 * duv02.x - dp02 * duv12.x) / det;
        }
        if det.abs() < 1e-9 || dpdu.cross(dpdv).length_squared() == 0.0 {
            // Degenerate uvs: any frame of the plane (pbrt-v4 does the same).
            let f = Frame::from_z((p2 - p0).cross(p1 - p0).normalize_or_zero());
            (dpdu, dpdv) = (f.x, f.y);
        }
        let local = tri - mesh.first_triangle;
        SurfaceHit {
            p,
            t,
            ng,
            ns,
            dpdu,
            dpdv,
            uv,
            surface: mesh.surface,
            light: mesh.surface.light.map(|l| l + local),
            offset: leaving_offset(
                [p0, p1, p2],
                b,
                p,
                ng,
                self.triangle_test_error[tri as usize],
            ),
        }
    }

    /// The surface coordinates and geometric normal at point `p` on triangle `tri`.
    pub(super) fn triangle_uv_and_normal(&self, tri: u32, p: Vec3A) -> (Vec2, Vec3A) {
        let ([i0, i1, i2], mesh, [p0, p1, p2]) = self.triangle(tri);
        let b = barycentrics(p, p0, p1, p2);
        let uv = if mesh.has_uvs {
            self.prims.uvs[i0 as usize] * b[0]
                + self.prims.uvs[i1 as usize] * b[1]
                + self.prims.uvs[i2 as usize] * b[2]
        } else {
            Vec2::X * b[1] + Vec2::ONE * b[2]
        };
        (uv, (p0 - p2).cross(p1 - p2).normalize_or_zero())
    }

    /// Position, geometric and shading normal at barycentrics `b` of triangle `tri`,
    /// oriented as a hit there would be.
    pub fn surface_point(&self, tri: u32, b: [f32; 3]) -> (Vec3A, Vec3A, Vec3A) {
        let ([i0, i1, i2], mesh, [p0, p1, p2]) = self.triangle(tri);
        let p = p0 * b[0] + p1 * b[1] + p2 * b[2];
        let (ng, ns) = self.oriented_normals(mesh, [i0, i1, i2], [p0, p1, p2], b);
        (p, ng, ns)
    }

    /// A triangle's geometric and shading normals at barycentrics `b`, oriented as pbrt
    /// orients them: flipped by ReverseOrientation or a handedness-swapping transform, and
    /// with per-vertex normals, the geometric normal on the shading normal's side.
    fn oriented_normals(
        &self,
        mesh: &MeshInfo,
        v: [u32; 3],
        p: [Vec3A; 3],
        b: [f32; 3],
    ) -> (Vec3A, Vec3A) {
        let mut ng = (p[0] - p[2]).cross(p[1] - p[2]).normalize_or_zero();
        if mesh.flip {
            ng = -ng;
        }
        let mut ns = ng;
        if mesh.has_normals {
            let n = self.prims.normals[v[0] as usize] * b[0]
                + self.prims.normals[v[1] as usize] * b[1]
                + self.prims.normals[v[2] as usize] * b[2];
            if n.length_squared() > 0.0 {
                ns = n.normalize();
                if ng.dot(ns) < 0.0 {
                    ng = -ng;
                }
            }
        }
        (ng, ns)
    }
}

/// How far along the unit normal `ng` a ray leaving the point `p` at barycentrics `b` of
/// triangle `v` must start so that the intersection test cannot find this triangle again.
///
/// Two bounds add up. The point's own rounding error, pbrt-v4's γ(7)·Σ|bᵢ·vᵢ| per
/// coordinate projected on the normal, and one rounding more for the sum that moves it
/// ([`crate::math::offset_origin`]): γ(8). And the error of Kiln's triangle test (Möller and
/// Trumbore's, which unlike pbrt-v4's watertight test has no conservative check on the
/// sign of t): the distance from a ray's origin to the plane it computes errs by a few
/// roundings of the triangle's size, magnified by one over the sine of the angle its
/// edge vectors make. Both are far below the old fixed 2·10⁻⁴·(1 + |p|), which stepped
/// over a 0.2 mm sheet of the scenes' blinds; that stays the bound's ceiling. The test's
/// term depends on the triangle alone: [`test_error`], computed once when the geometry is
/// built.
pub fn leaving_offset(v: [Vec3A; 3], b: [f32; 3], p: Vec3A, ng: Vec3A, test_error: f32) -> f32 {
    use crate::math::{gamma, surface_epsilon};
    let point_error = ((v[0] * b[0]).abs() + (v[1] * b[1]).abs() + (v[2] * b[2]).abs()) * gamma(8);
    (ng.abs().dot(point_error) + test_error).min(surface_epsilon(p))
}

/// The Möller-Trumbore term of [`leaving_offset`] for triangle `v`: γ(8) times its size
/// over the sine of its corner angle (infinite or NaN for a degenerate triangle, which
/// the bound's ceiling then holds).
pub fn test_error(v: [Vec3A; 3]) -> f32 {
    let (e1, e2, e3) = (v[0] - v[1], v[2] - v[0], v[2] - v[1]);
    let (l1, l2) = (e1.length_squared(), e2.length_squared());
    let size2 = l1.max(l2).max(e3.length_squared());
    // size / sine, with sine = |e1 × e2| / (|e1| |e2|): one square root.
    let cross2 = e1.cross(e2).length_squared();
    crate::math::gamma(8) * (size2 * (l1 * l2 / cross2)).sqrt()
}

/// Barycentric coordinates of `p` (assumed in the triangle's plane).
pub fn barycentrics(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> [f32; 3] {
    let v0 = b - a;
    let v1 = c - a;
    let v2 = p - a;
    let d00 = v0.dot(v0);
    let d01 = v0.dot(v1);
    let d11 = v1.dot(v1);
    let d20 = v2.dot(v0);
    let d21 = v2.dot(v1);
    let denom = d00 * d11 - d01 * d01;
    if denom == 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    [1.0 - v - w, v, w]
}

/// A uniform point on triangle `v` (normal `n`, area `area`) seen from `p`: the sample and
/// its barycentrics.
pub fn sample_triangle(
    v: &[Vec3A; 3],
    n: Vec3A,
    area: f32,
    p: Vec3A,
    u: Vec2,
) -> Option<(ShapeSample, [f32; 3])> {
    let b = uniform_triangle(u);
    let q = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
    let d = q - p;
    let dist2 = d.length_squared();
    if dist2 == 0.0 {
        return None;
    }
    let dist = dist2.sqrt();
    let wi = d / dist;
    let cos_l = n.dot(-wi).abs();
    if cos_l == 0.0 {
        return None;
    }
    let sample = ShapeSample {
        wi,
        pdf: dist2 / (cos_l * area),
        distance: dist,
        n,
    };
    Some((sample, b))
}

/// The solid-angle density with which [`sample_triangle`] from `p` reaches point `q`
/// (normal `n`) in direction `wi`.
pub fn triangle_pdf(area: f32, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
    let dist2 = (q - p).length_squared();
    let cos_l = n.dot(wi).abs();
    if cos_l == 0.0 {
        0.0
    } else {
        dist2 / (cos_l * area)
    }
}

#[cfg(test)]
mod tests {
    use super::super::Primitives;
    use super::*;

    fn mesh(positions: Vec<Vec3A>, triangles: Vec<[u32; 3]>) -> Geometry {
        Geometry::new(Primitives::plain_mesh(positions, triangles))
    }

    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    fn unit(s: &mut u64) -> Vec3A {
        loop {
            let v = Vec3A::new(rng(s), rng(s), rng(s)) * 2.0 - 1.0;
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// A ray that leaves a triangle's hit point, to either side and at any angle, never
    /// meets that triangle again: over triangles of sizes from 1 mm to 100 m, up to 1 km
    /// from the origin, slivers among them.
    #[test]
    fn a_ray_leaving_a_triangle_never_meets_it_again() {
        let mut s = 7u64;
        let (mut leaving, mut returned) = (0, Vec::new());
        for k in 0..4_000 {
            let size = libm::powf(10.0, rng(&mut s) * 5.0 - 3.0);
            let centre = unit(&mut s) * libm::powf(10.0, rng(&mut s) * 3.0) * (k % 2) as f32;
            let a = centre + unit(&mut s) * size;
            let b = centre + unit(&mut s) * size;
            // Every fourth triangle a sliver: its third corner near the line of the others.
            let c = if k % 4 == 0 {
                a + (b - a) * rng(&mut s) + unit(&mut s) * size * 1e-3
            } else {
                centre + unit(&mut s) * size
            };
            let g = mesh(vec![a, b, c], vec![[0, 1, 2]]);
            let bary = uniform_triangle(Vec2::new(rng(&mut s), rng(&mut s)));
            let target = a * bary[0] + b * bary[1] + c * bary[2];
            let from = target + unit(&mut s) * size * 2.0;
            let Some(hit) = g.intersect(&Ray::new(from, (target - from).normalize()), f32::MAX)
            else {
                continue;
            };
            for _ in 0..16 {
                let dir = unit(&mut s);
                leaving += 1;
                let ray = Ray::new(hit.origin_towards(dir), dir);
                if let Some(again) = g.intersect(&ray, f32::MAX) {
                    returned.push((k, again.t, hit.offset));
                }
            }
        }
        assert!(leaving > 50_000, "{leaving} rays left a hit");
        assert!(
            returned.is_empty(),
            "{} of {leaving} rays met their triangle again: (triangle, t, offset) {:?}",
            returned.len(),
            &returned[..returned.len().min(5)]
        );
    }

    /// A sheet 0.1 mm thick, 3 m from the origin (a blind's slat): a ray that crosses its
    /// front face meets its back face. The old fixed offset, 2·10⁻⁴·(1 + |p|) = 0.8 mm
    /// here, started the ray beyond the back face.
    #[test]
    fn a_ray_through_a_thin_sheet_meets_its_back_face() {
        let (z0, z1) = (3.0, 3.0 - 1e-4);
        let quad = |z: f32| {
            [
                Vec3A::new(-0.5, 2.0, z),
                Vec3A::new(0.5, 2.0, z),
                Vec3A::new(0.5, 2.2, z),
                Vec3A::new(-0.5, 2.2, z),
            ]
        };
        let positions = [quad(z0), quad(z1)].concat();
        let g = mesh(positions, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]);
        let dir = Vec3A::new(0.1, 0.05, -1.0).normalize();
        let front = g
            .intersect(&Ray::new(Vec3A::new(0.0, 2.05, 4.0), dir), f32::MAX)
            .expect("the ray meets the front face");
        assert!((front.p.z - z0).abs() < 1e-6, "{}", front.p);
        assert!(
            front.offset < 1e-5,
            "offset {} at a well-shaped triangle",
            front.offset
        );
        let back = g
            .intersect(&Ray::new(front.origin_towards(dir), dir), f32::MAX)
            .expect("the ray crossing the front face meets the back face");
        assert!((back.p.z - z1).abs() < 1e-6, "met z = {} instead", back.p.z);
    }
}
