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
        let p = ray.at(t);
        let b = barycentrics(p, p0, p1, p2);
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
