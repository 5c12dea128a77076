//! A point on a shape in the shape's own object space: what quadrics, bilinear patches and
//! surfaces of revolution give for a hit or a sample, before it is placed in the world.

use glam::{Vec2, Vec3A};

/// A point on a quadric in its object space: position, unit outward normal, pbrt-v4's
/// dp/du and dp/dv, and (u, v).
#[derive(Debug, Clone, Copy)]
pub struct LocalPoint {
    pub p: Vec3A,
    pub n: Vec3A,
    /// A shading normal, where the shape has one (a bilinear patch with normals).
    pub ns: Option<Vec3A>,
    /// The density per unit object-space area with which the shape's `sample` reaches
    /// this point (uniform, 1 / area, for all but bilinear patches).
    pub pdf: f32,
    pub dpdu: Vec3A,
    pub dpdv: Vec3A,
    pub uv: Vec2,
}
