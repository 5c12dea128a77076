//! Shapes in object space with their placement: triangle meshes, curves, quadrics and
//! surfaces of revolution, what surrounds and emits from them, and object instancing.

use super::lights::AreaLightDesc;
use super::materials::MaterialId;
use super::media::MediumInterfaceDesc;
use crate::error::Loc;
use crate::textures::FloatValue;
use glam::DMat4;
use std::sync::Arc;

/// Triangle mesh data in object space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMeshData {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Three per triangle.
    pub indices: Vec<u32>,
    /// pbrt-v4's bilinear patches whose corners are not in one plane: four per patch, in
    /// its corner order p00, p10, p01, p11 (planar quads are two triangles in `indices`).
    pub quads: Vec<u32>,
}

/// How far, relative to its size, a quad's corners may stray from one plane and still be
/// two triangles (exported meshes round their planar quads' corners).
pub const PLANAR_QUAD_TOLERANCE: f64 = 1e-4;

impl TriangleMeshData {
    /// Every face as triangles: the mesh's own, then each bilinear patch as two (split
    /// along p00-p11), for what works on triangles only (displacement).
    pub fn triangulated_indices(&self) -> Vec<u32> {
        let mut all = self.indices.clone();
        for q in self.quads.chunks_exact(4) {
            all.extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
        }
        all
    }

    /// The mesh with `quads` (four indices each, p00 p10 p01 p11) added: planar ones as two
    /// triangles split along p00-p11, the others as bilinear patches.
    pub fn with_quads(mut self, quads: &[u32]) -> TriangleMeshData {
        let at = |i: u32| self.positions[i as usize].map(f64::from);
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let mut kept = Vec::new();
        for q in quads.chunks_exact(4) {
            let [p00, p10, p01, p11] = [at(q[0]), at(q[1]), at(q[2]), at(q[3])];
            let a = cross(sub(p10, p00), sub(p01, p00));
            let b = cross(sub(p11, p10), sub(p11, p01));
            let n = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
            let len = dot(n, n).sqrt();
            let size = dot(sub(p11, p00), sub(p11, p00))
                .max(dot(sub(p10, p01), sub(p10, p01)))
                .sqrt();
            let planar = len == 0.0
                || size == 0.0
                || [p10, p01, p11]
                    .iter()
                    .all(|p| (dot(sub(*p, p00), n) / len).abs() <= PLANAR_QUAD_TOLERANCE * size);
            if planar {
                self.indices
                    .extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
            } else {
                kept.extend_from_slice(q);
            }
        }
        self.quads.extend(kept);
        self
    }

    /// Whether the mesh clearly faces inward: the volume its faces enclose, oriented as
    /// pbrt-v4 orients them (by their winding, or by the vertex normals where the mesh has
    /// them, which the geometric normals then follow), is negative and at least a quarter of
    /// the unsigned volume its faces sweep from the mesh's centre. A closed mesh facing out
    /// encloses a positive volume; an open sheet rarely passes the quarter. Bilinear patches
    /// count as their two triangles.
    pub fn faces_inward(&self) -> bool {
        let at = |i: u32| glam::DVec3::from(self.positions[i as usize].map(f64::from));
        let (mut lo, mut hi) = (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY);
        for p in &self.positions {
            let p = glam::DVec3::from(p.map(f64::from));
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        let centre = (lo + hi) / 2.0;
        let (mut signed, mut swept, mut agreement) = (0.0, 0.0, 0.0);
        for t in self.triangulated_indices().chunks_exact(3) {
            let [a, b, c] = [at(t[0]) - centre, at(t[1]) - centre, at(t[2]) - centre];
            let v = a.dot(b.cross(c));
            signed += v;
            swept += v.abs();
            if let Some(n) = &self.normals {
                let n = t
                    .iter()
                    .map(|&i| glam::DVec3::from(n[i as usize].map(f64::from)))
                    .sum::<glam::DVec3>();
                agreement += (b - a).cross(c - a).dot(n);
            }
        }
        if agreement < 0.0 {
            signed = -signed;
        }
        signed < 0.0 && -signed >= 0.25 * swept
    }
}

/// How a curve is drawn (pbrt-v4's "type").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurveType {
    /// A ribbon that always faces the ray.
    Flat,
    /// A flat ribbon shaded as if it were a cylinder (its normal turns across the width).
    Cylinder,
    /// A ribbon oriented by normals given at the segments' ends.
    Ribbon,
}

/// A curve in object space: cubic Bézier segments, each with its widths at its two ends
/// (the curve's "width0" to "width1" spread evenly over the segments) and, for ribbons,
/// its normals there.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveData {
    pub segments: Vec<[[f32; 3]; 4]>,
    pub widths: Vec<[f32; 2]>,
    pub normals: Option<Vec<[[f32; 3]; 2]>>,
    pub kind: CurveType,
    /// Each segment is split into 2^split_depth pieces for the BVH (pbrt-v4's "splitdepth").
    pub split_depth: u32,
}

/// A plymesh's displacement: a float texture and the longest edge to refine to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshDisplacement {
    pub texture: FloatValue,
    pub edge_length: f32,
}

#[derive(Debug, Clone)]
pub enum ShapeKind {
    Mesh(Arc<TriangleMeshData>),
    /// pbrt-v4's sphere about the object-space origin, cut to `z_min ≤ z ≤ z_max` and
    /// `0 ≤ φ ≤ phi_max` (radians; a whole sphere has `z_min = -radius`, `z_max = radius`,
    /// `phi_max = 2π`).
    Sphere {
        radius: f64,
        z_min: f64,
        z_max: f64,
        phi_max: f64,
    },
    /// pbrt-v4's disk: the annulus `inner_radius ≤ r ≤ radius` in the plane `z = height`,
    /// facing +z, cut to `0 ≤ φ ≤ phi_max` (radians).
    Disk {
        height: f64,
        radius: f64,
        inner_radius: f64,
        phi_max: f64,
    },
    /// pbrt-v4's "curve": cubic Bézier segments (b-splines and quadratics converted).
    Curve(Arc<CurveData>),
    /// pbrt-v4's cylinder about the z axis, open at both ends, facing outwards.
    Cylinder {
        radius: f64,
        z_min: f64,
        z_max: f64,
        phi_max: f64,
    },
    /// Kiln's surface of revolution: a contour in the (r, z) half-plane turned about z.
    Revolution(Arc<RevolutionDesc>),
}

/// `Shape "revolution"`: the contour `"point2 contour" [r z ...]` swept about the object's
/// z axis through `phi_max` radians. Its normal faces to the right of the contour's
/// direction of travel in the (r, z) plane; a contour whose last point is its first is closed.
#[derive(Debug, Clone, PartialEq)]
pub struct RevolutionDesc {
    pub contour: Vec<[f32; 2]>,
    /// `"vector2 normals"`: a shading normal (nr, nz) per point; without them, neighbouring
    /// strips' normals are averaged where the contour turns by less than `crease`.
    pub normals: Option<Vec<[f32; 2]>>,
    /// `"float creaseangle"` (degrees in the file, radians here; 30° by default).
    pub crease: f64,
    pub phi_max: f64,
}

impl ShapeKind {
    /// A whole sphere of `radius`.
    pub fn sphere(radius: f64) -> ShapeKind {
        ShapeKind::Sphere {
            radius,
            z_min: -radius,
            z_max: radius,
            phi_max: std::f64::consts::TAU,
        }
    }
}

#[derive(Debug, Clone)]
pub struct ShapeDesc {
    pub kind: ShapeKind,
    /// The transform at the start of the transform times.
    pub object_to_world: DMat4,
    /// The transform at their end, where it differs (ActiveTransform): the shape moves,
    /// and is motion-blurred over the shutter.
    pub object_to_world_end: Option<DMat4>,
    /// ReverseOrientation was in effect when the shape was declared. (Whether the
    /// transform swaps handedness is the renderer's to derive from `object_to_world`.)
    pub reverse_orientation: bool,
    pub material: MaterialId,
    pub area_light: Option<AreaLightDesc>,
    /// The media inside and outside the shape, when they differ (a medium boundary).
    pub media: Option<MediumInterfaceDesc>,
    /// pbrt-v4's "alpha": where it is below 1 rays pass through the surface (stochastically
    /// between 0 and 1). None when the shape is opaque everywhere.
    pub alpha: Option<FloatValue>,
    /// pbrt-v4's plymesh "displacement": the mesh refined to edges shorter than
    /// `edge_length` (world space) and moved along its normals by the texture.
    pub displacement: Option<MeshDisplacement>,
    /// Kiln's `"integer priority"` for nested dielectrics: 0 (the default) for a shape as
    /// pbrt-v4 has it; 1 or more makes it a nested shape, whose boundary is ignored where it
    /// lies inside a shape of higher priority.
    pub priority: u32,
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct ObjectDesc {
    pub name: String,
    /// Shapes in the object's own space.
    pub shapes: Vec<ShapeDesc>,
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct InstanceDesc {
    pub object: usize,
    pub instance_to_world: DMat4,
    /// As [`ShapeDesc::object_to_world_end`].
    pub instance_to_world_end: Option<DMat4>,
    pub loc: Loc,
}
