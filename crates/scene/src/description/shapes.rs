//! Shapes in object space with their placement: triangle meshes, curves, quadrics and
//! surfaces of revolution, what surrounds and emits from them, and object instancing.

use super::lights::AreaLightDesc;
use super::materials::MaterialId;
use super::media::MediumInterfaceDesc;
use crate::error::Loc;
use crate::textures::FloatValue;
use glam::DMat4;
use std::sync::Arc;

pub use crate::mesh::{PLANAR_QUAD_TOLERANCE, TriangleMeshData};

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
