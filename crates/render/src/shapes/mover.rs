//! Moving geometry (motion blur): shapes whose transform changes over the shutter, each
//! group built once in its own object space (with its own BVHs) and placed in the world at
//! each ray's time by an [`AnimatedTransform`]. A ray is carried into the group's object
//! space at its time, traced there, and the hit carried back (positions as points, dp/du
//! and dp/dv as vectors, normals through the normal matrix). The group's world bounds cover
//! its whole motion, so the BVH over groups is built once.

use super::{Geometry, SurfaceHit};
use crate::math::Ray;
use crate::motion::{AnimatedTransform, normal_matrix};
use glam::{Affine3A, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;

#[derive(Clone)]
pub struct Mover {
    pub geometry: std::sync::Arc<Geometry>,
    pub motion: AnimatedTransform,
    /// What places the moving group in the world after its motion.
    outer: Outer,
    lo: Vec3A,
    hi: Vec3A,
}

/// A transform after a group's own motion: a shape moving inside an object instance.
#[derive(Clone)]
pub enum Outer {
    /// The group's motion is in world space.
    None,
    /// An instance placed by a still transform (world from the motion's space, and its
    /// inverse).
    Still(Affine3A, Affine3A),
    /// An instance that moves too: its motion at the ray's time, after the group's.
    Moving(AnimatedTransform),
}

impl std::fmt::Debug for Mover {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mover")
            .field("triangles", &self.geometry.triangle_count())
            .field("bounds", &(self.lo, self.hi))
            .finish()
    }
}

impl Mover {
    pub fn new(geometry: Geometry, motion: AnimatedTransform) -> Mover {
        Mover::placed(geometry, motion, Outer::None)
    }

    /// A moving group placed in the world by `outer` after its motion. Its bounds cover
    /// every place its motion takes it, and every place the outer motion takes those.
    pub fn placed(geometry: Geometry, motion: AnimatedTransform, outer: Outer) -> Mover {
        let (lo, hi) = geometry.bounds();
        let (mut lo, mut hi) = motion.motion_bounds(lo, hi);
        match &outer {
            Outer::None => {}
            Outer::Still(m, _) => (lo, hi) = super::transformed_bounds(m, lo, hi),
            Outer::Moving(m) => (lo, hi) = m.motion_bounds(lo, hi),
        }
        Mover {
            geometry: std::sync::Arc::new(geometry),
            motion,
            outer,
            lo,
            hi,
        }
    }

    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (self.lo, self.hi)
    }

    /// The ray in object space at its time (unit direction), the world transform then,
    /// and object length per world length along the ray.
    fn local(&self, origin: Vec3A, dir: Vec3A, time: f32) -> Option<(Ray, Affine3A, f32)> {
        let (mut to_world, mut to_object) = self.motion.affine_at(time);
        let (world_from, from_world) = match &self.outer {
            Outer::None => (Affine3A::IDENTITY, Affine3A::IDENTITY),
            Outer::Still(m, inverse) => (*m, *inverse),
            Outer::Moving(m) => m.affine_at(time),
        };
        if !matches!(self.outer, Outer::None) {
            to_world = world_from * to_world;
            to_object *= from_world;
        }
        let d = to_object.transform_vector3a(dir);
        let len = d.length();
        (len > 0.0 && len.is_finite()).then(|| {
            (
                Ray::at_time(to_object.transform_point3a(origin), d / len, time),
                to_world,
                len,
            )
        })
    }

    /// The world distance to the nearest hit within `tmax`, or infinity.
    pub fn hit_t(&self, origin: Vec3A, dir: Vec3A, tmax: f32, time: f32) -> f32 {
        let Some((ray, _, len)) = self.local(origin, dir, time) else {
            return f32::INFINITY;
        };
        self.geometry
            .hit_distance(&ray, tmax * len)
            .map_or(f32::INFINITY, |t| t / len)
    }

    /// The nearest hit within `tmax`, in world space.
    pub fn intersect(&self, world: &Ray, tmax: f32) -> Option<SurfaceHit> {
        let (ray, to_world, len) = self.local(world.origin, world.dir, world.time)?;
        let hit = self.geometry.intersect(&ray, tmax * len)?;
        let nm = normal_matrix(&to_world);
        let normal = |n: Vec3A| (nm * n).normalize_or(n);
        let p = to_world.transform_point3a(hit.p);
        Some(SurfaceHit {
            p,
            offset: crate::math::surface_epsilon(p),
            t: hit.t / len,
            ng: normal(hit.ng),
            ns: normal(hit.ns),
            dpdu: to_world.transform_vector3a(hit.dpdu),
            dpdv: to_world.transform_vector3a(hit.dpdv),
            ..hit
        })
    }
}

impl Boundable for Mover {
    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo, self.hi)
    }
}
