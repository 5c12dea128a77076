//! Shapes and the aggregate that holds them: scene geometry in world space, triangle meshes
//! ([`triangle`]), whole spheres ([`sphere`]) and pbrt-v4's other quadrics, partial or
//! transformed spheres, disks and cylinders ([`quadric`]) and curves ([`curve`]). Every
//! primitive of every kind, and every moving group (an object-space geometry of its own),
//! is in one hierarchy, Kiln's own wide BVH ([`wide`]: eight boxes and four triangles tested
//! at once, the same hit on every CPU), walked once per ray.
//!
//! A shape kind's file holds its intersection, its hit record, and its area sampling (the
//! solid-angle density of a point on it seen from another point), which area lights and
//! VolumeLights sample. Shapes know nothing of materials, lights or media beyond the
//! indices a [`SurfaceInfo`] carries.

mod alpha;
pub mod bilinear;
pub mod bvh_build;
pub mod curve;
pub mod cylinder;
pub mod disk;
pub mod displace;
pub mod local;
pub mod mover;
pub mod quadric;
pub mod revolution;
pub mod wide;
pub use alpha::hash_float;
pub mod sphere;
pub mod traverse;
pub mod triangle;

pub use quadric::{Quadric, QuadricShape};
pub use sphere::Sphere;
pub use triangle::barycentrics;

/// The bytes one quadric primitive takes (a surface of revolution's strip sector is one):
/// what a shape's primitive count costs in memory.
pub const QUADRIC_BYTES: usize = std::mem::size_of::<Quadric>();

use crate::math::Ray;
use crate::textures::FloatTexture;
use glam::{Affine3A, Vec2, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;
use obvhs::rt_triangle::RtTriangle;
use std::time::Duration;

/// What a primitive is made of and whether it emits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SurfaceInfo {
    pub material: u32,
    /// Index of the first light of this shape (triangle i of a mesh is light `light + i`).
    pub light: Option<u32>,
    /// The VolumeLight (index into `Scene::volumes`) whose surface this is.
    pub volume: Option<u32>,
    /// The media [inside, outside] when the surface separates two ([`NO_MEDIUM`] is vacuum).
    pub media: Option<[u32; 2]>,
    /// The alpha texture (index into `Primitives::alphas`) where rays may pass through.
    pub alpha: Option<u32>,
    /// The nested dielectric shape (index into `Scene::nested`) this surface bounds.
    pub nest: Option<u32>,
}

#[cfg(test)]
impl SurfaceInfo {
    /// Material 0 and nothing else: the surface the shapes' tests give their primitives.
    pub(crate) const PLAIN: SurfaceInfo = SurfaceInfo {
        material: 0,
        light: None,
        volume: None,
        media: None,
        alpha: None,
        nest: None,
    };
}

#[cfg(test)]
impl Primitives {
    /// One plain mesh (no normals, no uvs) of `triangles` over `positions`: the shapes'
    /// tests' geometry; other primitives may be added with struct update syntax.
    pub(crate) fn plain_mesh(positions: Vec<Vec3A>, triangles: Vec<[u32; 3]>) -> Primitives {
        Primitives {
            positions,
            meshes: vec![MeshInfo {
                surface: SurfaceInfo::PLAIN,
                first_triangle: 0,
                has_normals: false,
                has_uvs: false,
                flip: false,
            }],
            triangle_mesh: vec![0; triangles.len()],
            triangle_vertices: triangles,
            ..Primitives::default()
        }
    }
}

/// The closest hit of a ray, before its record: the distance, and which primitive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestHit {
    t: f32,
    kind: HitKind,
    id: u32,
}

/// Which kind of primitive a hit is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum HitKind {
    Triangle,
    Sphere,
    Quadric,
    Curve,
    Mover,
}

/// Vacuum, in [`SurfaceInfo::media`].
pub const NO_MEDIUM: u32 = u32::MAX;

impl SurfaceInfo {
    /// The medium a ray leaving in direction `dir` enters, if this surface is a medium
    /// boundary (`ng` is its geometric normal, pointing outside).
    pub fn medium_towards(&self, dir: Vec3A, ng: Vec3A) -> Option<Option<u32>> {
        self.media.map(|[inside, outside]| {
            let m = if dir.dot(ng) > 0.0 { outside } else { inside };
            (m != NO_MEDIUM).then_some(m)
        })
    }
}

/// One mesh's attributes; its vertices live in the shared vertex arrays.
#[derive(Debug, Clone)]
pub struct MeshInfo {
    pub surface: SurfaceInfo,
    /// First triangle of this mesh in `Geometry::triangle_vertices`.
    pub first_triangle: u32,
    pub has_normals: bool,
    pub has_uvs: bool,
    /// Flip the geometric normal (ReverseOrientation xor a handedness-swapping transform).
    pub flip: bool,
}

/// A ray hit on a surface, with everything shading needs.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceHit {
    pub p: Vec3A,
    pub t: f32,
    /// Geometric normal, oriented as pbrt orients it (emission leaves on this side).
    pub ng: Vec3A,
    /// Shading normal, on the same side as `ng`.
    pub ns: Vec3A,
    /// dp/du and dp/dv, as pbrt-v4 defines them for the shape (for anisotropic materials
    /// and texture filtering).
    pub dpdu: Vec3A,
    pub dpdv: Vec3A,
    pub uv: Vec2,
    pub surface: SurfaceInfo,
    /// The light this point emits as, if any.
    pub light: Option<u32>,
    /// How far along `ng` a ray leaving `p` starts, so that it cannot meet this surface
    /// again at its start: a bound on `p`'s rounding error where the shape gives one
    /// (triangles), [`crate::math::surface_epsilon`] elsewhere.
    pub offset: f32,
}

impl SurfaceHit {
    /// Where a ray leaving this point in direction `dir` starts (pbrt-v4's
    /// `SpawnRay`): moved off the surface by its error bound, to `dir`'s side.
    #[inline]
    pub fn origin_towards(&self, dir: Vec3A) -> Vec3A {
        crate::math::offset_origin(self.p, self.ng, self.offset, dir)
    }
}

/// A scene's primitives in world space, as the scene builder gathers them, before their
/// BVHs are built. Normals and uvs are either empty or one per position.
#[derive(Debug, Clone, Default)]
pub struct Primitives {
    pub positions: Vec<Vec3A>,
    pub normals: Vec<Vec3A>,
    pub uvs: Vec<Vec2>,
    pub meshes: Vec<MeshInfo>,
    /// Vertex indices per triangle, in the order the scene declared them.
    pub triangle_vertices: Vec<[u32; 3]>,
    /// The mesh each triangle belongs to.
    pub triangle_mesh: Vec<u32>,
    pub spheres: Vec<Sphere>,
    pub quadrics: Vec<Quadric>,
    pub curve_segments: Vec<curve::CurveSegment>,
    /// The BVH's curve primitives: pieces of the segments.
    pub curve_pieces: Vec<curve::CurvePiece>,
    /// Moving groups of shapes, each already built in its own object space.
    pub movers: Vec<mover::Mover>,
    /// Alpha textures, referred to by `SurfaceInfo::alpha`.
    pub alphas: Vec<FloatTexture>,
}

/// All the geometry of a scene, ready to trace.
pub struct Geometry {
    /// The primitives, in the order the scene declared them.
    pub prims: Primitives,
    /// The one hierarchy over every primitive: ids are the triangles', then the spheres',
    /// quadrics', curve pieces' and moving groups' after them ([`Geometry::kind_of`]).
    bvh: Option<wide::WideBvh>,
    /// Where each kind's ids start: spheres, quadrics, curve pieces, moving groups, and the
    /// end.
    first: [u32; 5],
    /// Some surface has an alpha texture: candidate hits must be tested against it.
    any_alpha: bool,
    /// Per triangle, the part of a leaving ray's offset that its own shape sets
    /// ([`triangle::test_error`]).
    triangle_test_error: Vec<f32>,
    /// Time spent building BVHs.
    pub build_time: Duration,
}

/// The box holding the box `lo`..`hi` carried by `m` (the bounds of its eight corners).
pub fn transformed_bounds(m: &Affine3A, lo: Vec3A, hi: Vec3A) -> (Vec3A, Vec3A) {
    let (mut a, mut b) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for k in 0..8 {
        let c = Vec3A::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let w = m.transform_point3a(c);
        a = a.min(w);
        b = b.max(w);
    }
    (a, b)
}

/// A point sampled on a shape as seen from a reference point.
#[derive(Debug, Clone, Copy)]
pub struct ShapeSample {
    /// Unit direction from the reference point to the sampled point.
    pub wi: Vec3A,
    /// Solid-angle density at the reference point.
    pub pdf: f32,
    pub distance: f32,
    /// The sampled point's normal, for offsetting a shadow ray's far end.
    pub n: Vec3A,
}

impl Geometry {
    /// Builds the hierarchy over `primitives`.
    pub fn new(primitives: Primitives) -> Geometry {
        let Primitives {
            positions,
            triangle_vertices,
            spheres,
            quadrics,
            curve_pieces,
            movers,
            ..
        } = &primitives;
        let mut build_time = Duration::ZERO;
        let tris: Vec<RtTriangle> = triangle_vertices
            .iter()
            .map(|v| {
                RtTriangle::new(
                    positions[v[0] as usize],
                    positions[v[1] as usize],
                    positions[v[2] as usize],
                )
            })
            .collect();
        let plain: Vec<obvhs::triangle::Triangle> = triangle_vertices
            .iter()
            .map(|v| obvhs::triangle::Triangle {
                v0: positions[v[0] as usize],
                v1: positions[v[1] as usize],
                v2: positions[v[2] as usize],
            })
            .collect();
        // The other primitives' boxes, kind after kind, in the order of their ids.
        let mut others: Vec<Aabb> = Vec::new();
        let mut first = [0u32; 5];
        others.extend(spheres.iter().map(Boundable::aabb));
        first[0] = tris.len() as u32;
        first[1] = first[0] + spheres.len() as u32;
        others.extend(quadrics.iter().map(Boundable::aabb));
        first[2] = first[1] + quadrics.len() as u32;
        others.extend(curve_pieces.iter().map(Boundable::aabb));
        first[3] = first[2] + curve_pieces.len() as u32;
        others.extend(movers.iter().map(Boundable::aabb));
        first[4] = first[3] + movers.len() as u32;
        let bvh = (first[4] > 0)
            .then(|| bvh_build::build_wide_bvh(&plain, &tris, &others, &mut build_time));
        let triangle_test_error = triangle_vertices
            .iter()
            .map(|v| triangle::test_error(v.map(|i| positions[i as usize])))
            .collect();
        Geometry {
            any_alpha: !primitives.alphas.is_empty(),
            triangle_test_error,
            prims: primitives,
            bvh,
            first,
            build_time,
        }
    }

    /// The kind of primitive `id` (an id of the hierarchy) and its index among its kind.
    #[inline(always)]
    fn kind_of(&self, id: u32) -> (HitKind, u32) {
        let f = &self.first;
        if id < f[0] {
            (HitKind::Triangle, id)
        } else if id < f[1] {
            (HitKind::Sphere, id - f[0])
        } else if id < f[2] {
            (HitKind::Quadric, id - f[1])
        } else if id < f[3] {
            (HitKind::Curve, id - f[2])
        } else {
            (HitKind::Mover, id - f[3])
        }
    }

    /// Where a primitive other than a triangle stops the ray from `origin` along `dir`
    /// before `limit` (at `time`, for moving groups), alpha considered.
    #[inline(always)]
    fn other_t(&self, id: u32, origin: Vec3A, dir: Vec3A, limit: f32, time: f32) -> Option<f32> {
        let (kind, i) = self.kind_of(id);
        let t = match kind {
            HitKind::Sphere => self.sphere_t(origin, dir, i, limit),
            HitKind::Quadric => self.quadric_t(origin, dir, i, limit),
            HitKind::Curve => self.curve_t(origin, dir, i, limit),
            HitKind::Mover => self.prims.movers[i as usize].hit_t(origin, dir, limit, time),
            HitKind::Triangle => unreachable!("triangles are tested in the walk"),
        };
        (t < limit).then_some(t)
    }

    /// The kernel that walks the hierarchy, if there is anything in it.
    pub fn bvh_kernel(&self) -> Option<wide::Kernel> {
        self.bvh.as_ref().map(wide::WideBvh::kernel)
    }

    /// The hierarchy's nodes, packs of four triangles, and lanes holding one.
    pub fn bvh_counts(&self) -> (usize, usize, usize) {
        self.bvh.as_ref().map_or((0, 0, 0), wide::WideBvh::counts)
    }

    /// The bytes the hierarchy holds (its nodes, its packed triangles and its leaves of
    /// other primitives).
    pub fn bvh_bytes(&self) -> usize {
        self.bvh.as_ref().map_or(0, wide::WideBvh::bytes)
    }

    pub fn triangle_count(&self) -> usize {
        self.prims.triangle_vertices.len()
    }

    /// The closest hit along `ray` within (0, tmax).
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<SurfaceHit> {
        self.closest_hit(ray, tmax)
            .and_then(|found| self.record(ray, tmax, found))
    }

    /// Where the closest hit along `ray` within (0, tmax) is, without its record: what a
    /// wave's traversal stage keeps for each path, [`Geometry::record`] making the record
    /// when the path reaches it.
    #[inline]
    pub fn closest_hit(&self, ray: &Ray, tmax: f32) -> Option<ClosestHit> {
        let (t, kind, id) = self.closest(ray, tmax)?;
        Some(ClosestHit { t, kind, id })
    }

    /// The record of `found`, the closest hit along `ray` within (0, tmax):
    /// [`Geometry::intersect`]'s, bit for bit. (None only where a moving group's hit is not
    /// found again when traced for its record.)
    pub fn record(&self, ray: &Ray, tmax: f32, found: ClosestHit) -> Option<SurfaceHit> {
        let ClosestHit { t, kind, id } = found;
        Some(match kind {
            HitKind::Triangle => self.triangle_hit(ray, t, id),
            HitKind::Sphere => self.sphere_hit(ray, t, id),
            HitKind::Quadric => self.quadric_hit(ray, t, id),
            HitKind::Curve => self.curve_hit(ray, t, id),
            HitKind::Mover => {
                let mover = &self.prims.movers[id as usize];
                // Traced again for the whole record, a hair beyond the distance found.
                return mover
                    .intersect(ray, t * (1.0 + 1e-5) + 1e-30)
                    .or_else(|| mover.intersect(ray, tmax));
            }
        })
    }

    /// The distance to the closest hit along `ray`, without the hit record.
    pub fn hit_distance(&self, ray: &Ray, tmax: f32) -> Option<f32> {
        self.closest(ray, tmax).map(|(t, _, _)| t)
    }

    /// Distance, kind and index of the closest hit.
    fn closest(&self, ray: &Ray, tmax: f32) -> Option<(f32, HitKind, u32)> {
        let (origin, dir) = (ray.origin, ray.dir);
        let (t, id) = self.bvh.as_ref()?.closest_with(
            origin,
            dir,
            tmax,
            |id, t| self.triangle_is_opaque(id, origin, dir, t),
            |id, limit| self.other_t(id, origin, dir, limit, ray.time),
        )?;
        let (kind, index) = self.kind_of(id);
        Some((t, kind, index))
    }

    /// The distance to quadric `id` along `dir` from `origin` in (1e-7, `tmax`), alpha
    /// considered, or infinity. (A -0.0 direction component is taken as +0.0, as the
    /// hierarchies before Kiln's own needed it.)
    #[inline(always)]
    fn quadric_t(&self, origin: Vec3A, dir: Vec3A, id: u32, tmax: f32) -> f32 {
        let dir = dir + Vec3A::ZERO;
        let q = &self.prims.quadrics[id as usize];
        let t = q.intersect(origin, dir, 1e-7, tmax);
        if self.any_alpha && t < f32::INFINITY && !self.quadric_is_opaque_at(id, origin, dir, t) {
            return f32::INFINITY;
        }
        t
    }

    /// Whether a candidate hit at distance `t` on triangle `id` stops the ray (always, unless
    /// its alpha lets the ray through).
    #[inline(always)]
    fn triangle_is_opaque(&self, id: u32, origin: Vec3A, dir: Vec3A, t: f32) -> bool {
        !self.any_alpha || self.triangle_is_opaque_at(id, origin, dir, t)
    }

    /// The distance to sphere `id`, as [`Self::quadric_t`].
    #[inline(always)]
    fn sphere_t(&self, origin: Vec3A, dir: Vec3A, id: u32, tmax: f32) -> f32 {
        let dir = dir + Vec3A::ZERO;
        let s = &self.prims.spheres[id as usize];
        let t = s.intersect(origin, dir, 1e-7, tmax);
        if self.any_alpha && t < f32::INFINITY && !self.sphere_is_opaque_at(id, origin, dir, t) {
            return f32::INFINITY;
        }
        t
    }

    /// True when nothing blocks the segment from `origin` along `dir` up to `tmax`. Shadow
    /// rays walk in no order and stop at the first opaque hit: sorting children by distance,
    /// which pays for itself when the nearest hit is wanted, made them 1.9x slower on the
    /// headline snail.
    pub fn unoccluded(&self, origin: Vec3A, dir: Vec3A, tmax: f32, time: f32) -> bool {
        let Some(bvh) = &self.bvh else {
            return true;
        };
        !bvh.any_with(
            origin,
            dir,
            tmax,
            |id, t| self.triangle_is_opaque(id, origin, dir, t),
            |id, tmax| self.other_t(id, origin, dir, tmax, time).is_some(),
        )
    }

    /// Bounding box of everything.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        for p in &self.prims.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        for s in &self.prims.spheres {
            lo = lo.min(s.center - Vec3A::splat(s.radius));
            hi = hi.max(s.center + Vec3A::splat(s.radius));
        }
        for m in &self.prims.movers {
            let (a, b) = m.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        for c in &self.prims.curve_pieces {
            let (a, b) = c.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        for q in &self.prims.quadrics {
            let (a, b) = q.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if lo.x > hi.x {
            (Vec3A::ZERO, Vec3A::ZERO)
        } else {
            (lo, hi)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad_geometry() -> Geometry {
        let positions = vec![
            Vec3A::new(-1.0, -1.0, 0.0),
            Vec3A::new(1.0, -1.0, 0.0),
            Vec3A::new(1.0, 1.0, 0.0),
            Vec3A::new(-1.0, 1.0, 0.0),
        ];
        Geometry::new(Primitives {
            spheres: vec![Sphere {
                center: Vec3A::new(0.0, 0.0, 5.0),
                radius: 1.0,
                rotation: sphere::Rotation::IDENTITY,
                surface: SurfaceInfo::PLAIN,
                flip: false,
            }],
            ..Primitives::plain_mesh(positions, vec![[0, 1, 2], [0, 2, 3]])
        })
    }

    /// Guards the obvhs CWBVH miss on -0.0 direction components (shared/CRATES.md).
    #[test]
    fn negative_zero_direction_still_hits() {
        let g = quad_geometry();
        let ray = Ray::new(Vec3A::new(0.2, 0.3, 2.0), Vec3A::new(-0.0, -0.0, -1.0));
        let hit = g
            .intersect(&ray, f32::INFINITY)
            .expect("the quad is right below");
        assert!((hit.t - 2.0).abs() < 1e-5);
        assert!(!g.unoccluded(ray.origin, ray.dir, 10.0, 0.0));
    }

    #[test]
    fn closest_of_sphere_and_triangle_wins() {
        let g = quad_geometry();
        let ray = Ray::new(Vec3A::new(0.0, 0.0, 10.0), Vec3A::new(0.0, 0.0, -1.0));
        let hit = g.intersect(&ray, f32::INFINITY).unwrap();
        assert!((hit.t - 4.0).abs() < 1e-4, "{}", hit.t);
        assert!((hit.ng - Vec3A::Z).length() < 1e-5);
        let inside = Ray::new(Vec3A::new(0.0, 0.0, 5.0), Vec3A::new(0.0, 0.0, -1.0));
        let hit = g.intersect(&inside, f32::INFINITY).unwrap();
        assert!((hit.t - 1.0).abs() < 1e-4);
        assert!(g.unoccluded(Vec3A::new(3.0, 3.0, 3.0), Vec3A::X, 100.0, 0.0));
    }
}
