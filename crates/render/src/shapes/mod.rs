//! Shapes and the aggregate that holds them: scene geometry in world space, triangle meshes
//! ([`triangle`]), whole spheres ([`sphere`]) and pbrt-v4's other quadrics, partial or
//! transformed spheres, disks and cylinders ([`quadric`]) and curves ([`curve`]). Triangles
//! are in Kiln's own wide BVH ([`wide`]: four boxes and four triangles tested at once, the
//! same hit on every CPU); each other kind is in an obvhs compressed wide BVH (CWBVH).
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
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as BvhRay, RayHit};
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
    triangle_bvh: Option<wide::WideBvh>,
    sphere_bvh: Option<CwBvh>,
    quadric_bvh: Option<CwBvh>,
    curve_bvh: Option<CwBvh>,
    mover_bvh: Option<CwBvh>,
    /// Whether each CWBVH (spheres, quadrics, curves, movers) can be walked nearest child
    /// first ([`traverse`]); obvhs's own walk where not.
    walks: [bool; 4],
    /// Some surface has an alpha texture: candidate hits must be tested against it.
    any_alpha: bool,
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

/// obvhs's CWBVH traversal misses everything when a direction component is -0.0
/// (see shared/CRATES.md); adding +0.0 turns -0.0 into +0.0 and changes nothing else.
fn bvh_ray(origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32) -> BvhRay {
    BvhRay::new(origin, dir + Vec3A::ZERO, tmin, tmax)
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
    /// Builds the BVHs over `primitives`.
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
        // Build on one thread: the BVH must be the same whatever the machine, so that
        // ties between equally distant hits always resolve the same way.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().ok();
        let build = |f: &mut (dyn FnMut() + Send)| match &pool {
            Some(p) => p.install(f),
            None => f(),
        };
        let mut triangle_bvh = None;
        if !tris.is_empty() {
            build(&mut || {
                let plain: Vec<obvhs::triangle::Triangle> = triangle_vertices
                    .iter()
                    .map(|v| obvhs::triangle::Triangle {
                        v0: positions[v[0] as usize],
                        v1: positions[v[1] as usize],
                        v2: positions[v[2] as usize],
                    })
                    .collect();
                triangle_bvh = Some(bvh_build::build_triangle_wide_bvh(
                    &plain,
                    &tris,
                    &mut build_time,
                ));
            });
        }
        let mut sphere_bvh = None;
        if !spheres.is_empty() {
            build(&mut || {
                sphere_bvh = Some(bvh_build::build_cwbvh(
                    spheres,
                    BvhBuildParams::medium_build(),
                    &mut build_time,
                ));
            });
        }
        let mut quadric_bvh = None;
        if !quadrics.is_empty() {
            build(&mut || {
                quadric_bvh = Some(bvh_build::build_cwbvh(
                    quadrics,
                    BvhBuildParams::medium_build(),
                    &mut build_time,
                ));
            });
        }
        let mut curve_bvh = None;
        if !curve_pieces.is_empty() {
            build(&mut || {
                curve_bvh = Some(bvh_build::build_cwbvh(
                    curve_pieces,
                    BvhBuildParams::medium_build(),
                    &mut build_time,
                ));
            });
        }
        let mut mover_bvh = None;
        if !movers.is_empty() {
            build(&mut || {
                mover_bvh = Some(bvh_build::build_cwbvh(
                    movers,
                    BvhBuildParams::medium_build(),
                    &mut build_time,
                ));
            });
        }
        let walk = |b: &Option<CwBvh>| b.as_ref().is_some_and(traverse::fits);
        let walks = [
            walk(&sphere_bvh),
            walk(&quadric_bvh),
            walk(&curve_bvh),
            walk(&mover_bvh),
        ];
        Geometry {
            walks,
            any_alpha: !primitives.alphas.is_empty(),
            prims: primitives,
            triangle_bvh,
            sphere_bvh,
            quadric_bvh,
            curve_bvh,
            mover_bvh,
            build_time,
        }
    }

    /// The same geometry walked by obvhs's own closest-hit traversal (octant order), for
    /// benchmarks to compare with Kiln's nearest-child-first walk.
    pub fn with_obvhs_walk(mut self) -> Geometry {
        self.walks = [false; 4];
        self
    }

    /// The kernel that walks the triangles' BVH, if there are triangles.
    pub fn bvh_kernel(&self) -> Option<wide::Kernel> {
        self.triangle_bvh.as_ref().map(wide::WideBvh::kernel)
    }

    /// The triangles' BVH's nodes, packs of four triangles, and lanes holding one.
    pub fn triangle_bvh_counts(&self) -> (usize, usize, usize) {
        self.triangle_bvh
            .as_ref()
            .map_or((0, 0, 0), wide::WideBvh::counts)
    }

    /// The bytes the triangles' BVH holds (its nodes and its packed triangles).
    pub fn triangle_bvh_bytes(&self) -> usize {
        self.triangle_bvh.as_ref().map_or(0, wide::WideBvh::bytes)
    }

    pub fn triangle_count(&self) -> usize {
        self.prims.triangle_vertices.len()
    }

    /// The closest hit along `ray` within (0, tmax).
    pub fn intersect(&self, ray: &Ray, tmax: f32) -> Option<SurfaceHit> {
        let (t, kind, id) = self.closest(ray, tmax)?;
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
        let mut best_t = tmax;
        let mut best: Option<(HitKind, u32)> = None;
        // Each BVH in turn, within the closest distance the ones before it found.
        let bray = |best_t: f32| bvh_ray(ray.origin, ray.dir, 0.0, best_t);
        if let Some(bvh) = &self.triangle_bvh
            && let Some((t, id)) = bvh.closest(ray.origin, ray.dir, best_t, |id, t| {
                self.triangle_is_opaque(id, ray.origin, ray.dir, t)
            })
            && t < best_t
        {
            best_t = t;
            best = Some((HitKind::Triangle, id));
        }
        if let Some(bvh) = &self.sphere_bvh
            && let Some((t, slot)) = self.nearest_in(0, bvh, bray(best_t), |r, slot| {
                self.sphere_t(r, bvh.primitive_indices[slot], r.tmin.max(1e-7))
            })
            && t < best_t
        {
            best_t = t;
            best = Some((HitKind::Sphere, bvh.primitive_indices[slot as usize]));
        }
        if let Some(bvh) = &self.quadric_bvh
            && let Some((t, slot)) = self.nearest_in(1, bvh, bray(best_t), |r, slot| {
                self.quadric_t(r, bvh.primitive_indices[slot], r.tmin.max(1e-7))
            })
            && t < best_t
        {
            best_t = t;
            best = Some((HitKind::Quadric, bvh.primitive_indices[slot as usize]));
        }
        if let Some(bvh) = &self.curve_bvh
            && let Some((t, slot)) = self.nearest_in(2, bvh, bray(best_t), |r, slot| {
                self.curve_t(r.origin, r.direction, bvh.primitive_indices[slot], r.tmax)
            })
            && t < best_t
        {
            best_t = t;
            best = Some((HitKind::Curve, bvh.primitive_indices[slot as usize]));
        }
        if let Some(bvh) = &self.mover_bvh
            && let Some((t, slot)) = self.nearest_in(3, bvh, bray(best_t), |r, slot| {
                self.prims.movers[bvh.primitive_indices[slot] as usize].hit_t(
                    r.origin,
                    r.direction,
                    r.tmax,
                    ray.time,
                )
            })
            && t < best_t
        {
            best_t = t;
            best = Some((HitKind::Mover, bvh.primitive_indices[slot as usize]));
        }
        let (kind, id) = best?;
        Some((best_t, kind, id))
    }

    /// The closest hit in CWBVH `k` of [`Self::walks`]: distance and BVH slot.
    #[inline(always)]
    fn nearest_in(
        &self,
        k: usize,
        bvh: &CwBvh,
        ray: BvhRay,
        hit: impl Fn(&BvhRay, usize) -> f32,
    ) -> Option<(f32, u32)> {
        if self.walks[k] {
            traverse::closest(bvh, ray, hit)
        } else {
            let mut h = RayHit::none();
            bvh.ray_traverse(ray, &mut h, hit)
                .then_some((h.t, h.primitive_id))
        }
    }

    /// The distance to quadric `id` along `r` beyond `tmin`, as [`Self::triangle_t`].
    #[inline(always)]
    fn quadric_t(&self, r: &BvhRay, id: u32, tmin: f32) -> f32 {
        let q = &self.prims.quadrics[id as usize];
        let t = q.intersect(r.origin, r.direction, tmin, r.tmax);
        if self.any_alpha
            && t < f32::INFINITY
            && !self.quadric_is_opaque_at(id, r.origin, r.direction, t)
        {
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

    /// The distance to sphere `id` along `r` beyond `tmin`, as [`Self::triangle_t`].
    #[inline(always)]
    fn sphere_t(&self, r: &BvhRay, id: u32, tmin: f32) -> f32 {
        let s = &self.prims.spheres[id as usize];
        let t = s.intersect(r.origin, r.direction, tmin, r.tmax);
        if self.any_alpha
            && t < f32::INFINITY
            && !self.sphere_is_opaque_at(id, r.origin, r.direction, t)
        {
            return f32::INFINITY;
        }
        t
    }

    /// True when nothing blocks the segment from `origin` along `dir` up to `tmax`. Shadow
    /// rays walk in no order and stop at the first opaque hit: sorting children by distance,
    /// which pays for itself when the nearest hit is wanted, made them 1.9x slower on the
    /// headline snail.
    pub fn unoccluded(&self, origin: Vec3A, dir: Vec3A, tmax: f32, time: f32) -> bool {
        if let Some(bvh) = &self.triangle_bvh
            && bvh.any(origin, dir, tmax, |id, t| {
                self.triangle_is_opaque(id, origin, dir, t)
            })
        {
            return false;
        }
        let bray = bvh_ray(origin, dir, 0.0, tmax);
        if let Some(bvh) = &self.sphere_bvh
            && !bvh.ray_traverse_miss(bray, |r, id| {
                self.sphere_t(r, bvh.primitive_indices[id], 1e-7)
            })
        {
            return false;
        }
        if let Some(bvh) = &self.quadric_bvh
            && !bvh.ray_traverse_miss(bray, |r, id| {
                self.quadric_t(r, bvh.primitive_indices[id], 1e-7)
            })
        {
            return false;
        }
        if let Some(bvh) = &self.curve_bvh
            && !bvh.ray_traverse_miss(bray, |r, id| {
                self.curve_t(r.origin, r.direction, bvh.primitive_indices[id], r.tmax)
            })
        {
            return false;
        }
        if let Some(bvh) = &self.mover_bvh
            && !bvh.ray_traverse_miss(bray, |r, id| {
                self.prims.movers[bvh.primitive_indices[id] as usize].hit_t(
                    r.origin,
                    r.direction,
                    r.tmax,
                    time,
                )
            })
        {
            return false;
        }
        true
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
        let surface = SurfaceInfo {
            material: 0,
            light: None,
            volume: None,
            media: None,
            alpha: None,
            nest: None,
        };
        let meshes = vec![MeshInfo {
            surface,
            first_triangle: 0,
            has_normals: false,
            has_uvs: false,
            flip: false,
        }];
        Geometry::new(Primitives {
            positions,
            meshes,
            triangle_vertices: vec![[0, 1, 2], [0, 2, 3]],
            triangle_mesh: vec![0, 0],
            spheres: vec![Sphere {
                center: Vec3A::new(0.0, 0.0, 5.0),
                radius: 1.0,
                rotation: sphere::Rotation::IDENTITY,
                surface,
                flip: false,
            }],
            ..Primitives::default()
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
