//! Quadrics: pbrt-v4's spheres, disks and cylinders, each defined in its own object space
//! ([`PartialSphere`], [`Disk`], [`Cylinder`]) and placed in the world by an affine
//! transform, any transform (a non-uniform scale makes ellipsoids and elliptic cylinders).
//! Rays are intersected in object space, as pbrt-v4 does; hits are carried back to the
//! world with pbrt-v4's orientation (the object-space normal through the normal matrix,
//! flipped by ReverseOrientation xor a handedness-swapping transform).
//!
//! Whole spheres under similarity transforms, the common case, stay in
//! [`super::sphere::Sphere`], which samples the visible cone; everything here is sampled
//! uniformly by object-space area, with the density carried to world-space area through
//! the transform's area scale at the sampled point, so a scaled or sheared quadric is
//! sampled without bias.

use super::bilinear::BilinearPatch;
use super::cylinder::Cylinder;
use super::disk::Disk;
use super::local::LocalPoint;
use super::revolution::Strip;
use super::sphere::PartialSphere;
use super::{Geometry, SurfaceHit, SurfaceInfo};
use crate::math::Ray;
use glam::{Affine3A, DMat4, DVec3, Mat3A, Vec2, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;

/// The object-space shape of a quadric (or of a bilinear patch, which is intersected and
/// sampled in its own right as they are).
#[derive(Debug, Clone, PartialEq)]
pub enum QuadricShape {
    Sphere(PartialSphere),
    Disk(Disk),
    Cylinder(Cylinder),
    /// One sector of one strip of a surface of revolution.
    Strip(Strip),
    Patch(Box<BilinearPatch>),
}

impl QuadricShape {
    fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        match self {
            QuadricShape::Sphere(s) => s.intersect(o, d, tmin, tmax),
            QuadricShape::Disk(s) => s.intersect(o, d, tmin, tmax),
            QuadricShape::Cylinder(s) => s.intersect(o, d, tmin, tmax),
            QuadricShape::Strip(s) => s.intersect(o, d, tmin, tmax),
            QuadricShape::Patch(s) => s.intersect(o, d, tmin, tmax),
        }
    }

    /// The surface at the point of the shape nearest `p` (a hit, or a sample).
    pub fn local(&self, p: Vec3A) -> LocalPoint {
        let uniform = |l: LocalPoint| LocalPoint {
            pdf: 1.0 / self.area(),
            ..l
        };
        match self {
            QuadricShape::Sphere(s) => uniform(s.local(p)),
            QuadricShape::Disk(s) => uniform(s.local(p)),
            QuadricShape::Cylinder(s) => uniform(s.local(p)),
            QuadricShape::Strip(s) => uniform(s.local(p)),
            QuadricShape::Patch(s) => s.local(p),
        }
    }

    /// Object-space area (what pbrt-v4's "power" normalises by, whatever the transform).
    pub fn area(&self) -> f32 {
        match self {
            QuadricShape::Sphere(s) => s.area(),
            QuadricShape::Disk(s) => s.area(),
            QuadricShape::Cylinder(s) => s.area(),
            QuadricShape::Strip(s) => s.area(),
            QuadricShape::Patch(s) => s.area(),
        }
    }

    /// A point distributed over the object-space area, uniformly but for bilinear
    /// patches (whose density is [`LocalPoint::pdf`]).
    fn sample(&self, u: Vec2) -> Vec3A {
        match self {
            QuadricShape::Sphere(s) => s.sample(u),
            QuadricShape::Disk(s) => s.sample(u),
            QuadricShape::Cylinder(s) => s.sample(u),
            QuadricShape::Strip(s) => s.sample(u),
            QuadricShape::Patch(s) => s.sample(u),
        }
    }

    fn bounds(&self) -> (Vec3A, Vec3A) {
        match self {
            QuadricShape::Sphere(s) => s.bounds(),
            QuadricShape::Disk(s) => s.bounds(),
            QuadricShape::Cylinder(s) => s.bounds(),
            QuadricShape::Strip(s) => s.bounds(),
            QuadricShape::Patch(s) => s.bounds(),
        }
    }
}

/// A quadric placed in the world.
#[derive(Debug, Clone)]
pub struct Quadric {
    pub shape: QuadricShape,
    to_world: Affine3A,
    to_object: Affine3A,
    /// The inverse transpose of `to_world`'s linear part, which carries normals.
    normal_matrix: Mat3A,
    /// |det| of `to_world`'s linear part.
    det: f32,
    pub surface: SurfaceInfo,
    /// Normals point opposite the object-space outward normal: ReverseOrientation xor a
    /// handedness-swapping transform, as pbrt-v4 orients quadrics.
    pub flip: bool,
    lo: Vec3A,
    hi: Vec3A,
}

/// A point on a quadric in world space.
#[derive(Debug, Clone, Copy)]
pub struct QuadricPoint {
    pub p: Vec3A,
    /// Unit normal, oriented as hits are (see [`Quadric::flip`]).
    pub n: Vec3A,
    /// The shading normal (the normal where the shape has none).
    pub ns: Vec3A,
    /// The density per unit object-space area of the shape's sampling here.
    pub object_pdf: f32,
    pub dpdu: Vec3A,
    pub dpdv: Vec3A,
    pub uv: Vec2,
    /// World area per object-space area at this point.
    pub area_scale: f32,
}

impl Quadric {
    /// `shape` under `to_world`; None when the transform cannot be inverted.
    pub fn new(
        shape: QuadricShape,
        to_world: DMat4,
        surface: SurfaceInfo,
        reverse_orientation: bool,
    ) -> Option<Quadric> {
        let to_object = to_world.inverse();
        let det = to_world.determinant();
        if !(to_object.is_finite() && det != 0.0 && det.is_finite()) {
            return None;
        }
        let world = Affine3A::from_mat4(to_world.as_mat4());
        let (olo, ohi) = shape.bounds();
        let (lo, hi) = super::transformed_bounds(&world, olo, ohi);
        Some(Quadric {
            shape,
            to_world: world,
            to_object: Affine3A::from_mat4(to_object.as_mat4()),
            normal_matrix: world.matrix3.inverse().transpose(),
            det: det.abs() as f32,
            surface,
            flip: reverse_orientation ^ (det < 0.0),
            lo,
            hi,
        })
    }

    /// World-space bounds.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (self.lo, self.hi)
    }

    /// The ray parameter of the nearest hit of the world-space ray in (tmin, tmax), or
    /// infinity. (An affine map keeps the parameter, so no direction is renormalised.)
    pub fn intersect(&self, origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32) -> f32 {
        let o = self.to_object.transform_point3a(origin);
        let d = self.to_object.transform_vector3a(dir);
        self.shape.intersect(
            DVec3::from(o.to_array().map(f64::from)),
            DVec3::from(d.to_array().map(f64::from)),
            f64::from(tmin),
            f64::from(tmax),
        ) as f32
    }

    /// The surface at the point nearest the world-space point `p`.
    pub fn point_at(&self, p: Vec3A) -> QuadricPoint {
        self.world_point(self.shape.local(self.to_object.transform_point3a(p)))
    }

    fn world_point(&self, l: LocalPoint) -> QuadricPoint {
        let m = self.normal_matrix * l.n;
        let len = m.length();
        let n = if len > 0.0 { m / len } else { l.n };
        let mut n = if self.flip { -n } else { n };
        // With shading normals the geometric normal turns to their side, as pbrt-v4's
        // bilinear patches do.
        let ns = l.ns.map_or(n, |s| {
            let s = (self.normal_matrix * s).normalize_or(n);
            if s.dot(n) < 0.0 {
                n = -n;
            }
            s
        });
        QuadricPoint {
            p: self.to_world.transform_point3a(l.p),
            n,
            ns,
            object_pdf: l.pdf,
            dpdu: self.to_world.transform_vector3a(l.dpdu),
            dpdv: self.to_world.transform_vector3a(l.dpdv),
            uv: l.uv,
            area_scale: self.det * len,
        }
    }

    /// A point sampled on the quadric and its density per unit world-space area.
    pub fn sample(&self, u: Vec2) -> (QuadricPoint, f32) {
        let q = self.world_point(self.shape.local(self.shape.sample(u)));
        (q, self.area_density(&q))
    }

    /// The density per unit world area with which [`Quadric::sample`] reaches `q`.
    pub fn area_density(&self, q: &QuadricPoint) -> f32 {
        if q.area_scale > 0.0 && q.object_pdf.is_finite() {
            q.object_pdf / q.area_scale
        } else {
            0.0
        }
    }

    /// A point sampled on the quadric as seen from `p`: the point, and the direction,
    /// distance and solid-angle density (both sides count); None where the sample is
    /// degenerate (at `p`, edge-on, or of zero density).
    pub fn sample_from(&self, p: Vec3A, u: Vec2) -> Option<(QuadricPoint, super::ShapeSample)> {
        let (q, area_pdf) = self.sample(u);
        let d = q.p - p;
        let dist2 = d.length_squared();
        if dist2 == 0.0 || area_pdf == 0.0 {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos = q.n.dot(wi).abs();
        if cos == 0.0 {
            return None;
        }
        let sample = super::ShapeSample {
            wi,
            pdf: area_pdf * dist2 / cos,
            distance: dist,
            n: q.n,
        };
        Some((q, sample))
    }

    /// The solid-angle density with which [`Quadric::sample_from`] gives direction `wi`
    /// from `p` towards the quadric's point `q`.
    pub fn solid_angle_pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A) -> f32 {
        let at = self.point_at(q);
        let cos = at.n.dot(wi).abs();
        if cos == 0.0 {
            return 0.0;
        }
        self.area_density(&at) * (q - p).length_squared() / cos
    }

    /// The world-space area: the area scale integrated over the object-space surface, as
    /// the mean of the area scale over the sampling density at a fixed 64 x 64 grid of
    /// samples (exact for similarity transforms of uniformly sampled shapes; the same on
    /// every machine).
    pub fn world_area(&self) -> f32 {
        let n = 64;
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let q = self.world_point(self.shape.local(self.shape.sample(u)));
                if q.object_pdf > 0.0 {
                    sum += f64::from(q.area_scale / q.object_pdf);
                }
            }
        }
        (sum / f64::from(n * n)) as f32
    }
}

impl Boundable for Quadric {
    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo, self.hi)
    }
}

impl Geometry {
    pub(super) fn quadric_hit(&self, ray: &Ray, t: f32, id: u32) -> SurfaceHit {
        let q = &self.prims.quadrics[id as usize];
        let w = q.point_at(ray.at(t));
        SurfaceHit {
            p: w.p,
            t,
            ng: w.n,
            ns: w.ns,
            dpdu: w.dpdu,
            dpdv: w.dpdv,
            uv: w.uv,
            surface: q.surface,
            light: q.surface.light,
            offset: crate::math::surface_epsilon(w.p),
        }
    }

    /// Whether a candidate hit at distance `t` on quadric `id` stops the ray.
    pub(super) fn quadric_is_opaque_at(&self, id: u32, origin: Vec3A, dir: Vec3A, t: f32) -> bool {
        let q = &self.prims.quadrics[id as usize];
        let Some(alpha) = q.surface.alpha else {
            return true;
        };
        let w = q.point_at(origin + dir * t);
        self.opaque(alpha, origin + dir * t, w.n, w.uv, origin, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{PI, TAU};

    fn surface() -> SurfaceInfo {
        SurfaceInfo::PLAIN
    }

    fn shapes() -> Vec<QuadricShape> {
        vec![
            QuadricShape::Sphere(PartialSphere {
                radius: 1.5,
                z_min: -0.5,
                z_max: 1.0,
                phi_max: 4.0,
            }),
            QuadricShape::Disk(Disk {
                height: 0.3,
                radius: 2.0,
                inner_radius: 0.5,
                phi_max: 5.0,
            }),
            QuadricShape::Cylinder(Cylinder {
                radius: 0.7,
                z_min: -1.0,
                z_max: 2.0,
                phi_max: 3.0,
            }),
        ]
    }

    /// Closed forms: a whole sphere's 4πr², a disk's πr², a cylinder's 2πrh, and their
    /// pieces.
    #[test]
    fn areas_are_the_closed_forms() {
        let a = shapes().iter().map(|s| s.area()).collect::<Vec<_>>();
        assert!((a[0] - 4.0 * 1.5 * 1.5).abs() < 1e-5);
        assert!((a[1] - 0.5 * 5.0 * (4.0 - 0.25)).abs() < 1e-5);
        assert!((a[2] - 3.0 * 0.7 * 3.0).abs() < 1e-5);
        let whole = PartialSphere {
            radius: 2.0,
            z_min: -2.0,
            z_max: 2.0,
            phi_max: TAU,
        };
        assert!((whole.area() - 16.0 * PI).abs() < 1e-4);
    }

    /// Every sampled point lies on the shape (a ray towards it from outside hits it
    /// there) and its normal is the object-space one carried to the world.
    #[test]
    fn samples_lie_on_the_surface_and_rays_find_them() {
        let to_world = DMat4::from_translation(glam::DVec3::new(1.0, -2.0, 0.5))
            * DMat4::from_rotation_x(0.4)
            * DMat4::from_scale(glam::DVec3::new(1.0, 2.0, 0.5));
        for shape in shapes() {
            let q = Quadric::new(shape.clone(), to_world, surface(), false).unwrap();
            for i in 0..64 {
                let u = Vec2::new((i % 8) as f32 / 8.0 + 0.06, (i / 8) as f32 / 8.0 + 0.06);
                let (p, pdf) = q.sample(u);
                assert!(pdf > 0.0);
                // Approach along the normal from outside, and from inside.
                for side in [1.0f32, -1.0] {
                    let origin = p.p + p.n * side * 0.01;
                    let t = q.intersect(origin, -p.n * side, 0.0, 1.0);
                    assert!((t - 0.01).abs() < 1e-4, "{shape:?}: {t} at {:?}", p.p);
                }
                // The geometric normal is perpendicular to both tangents.
                assert!(
                    p.n.dot(p.dpdu.normalize_or_zero()).abs() < 1e-3,
                    "{shape:?}"
                );
                assert!(
                    p.n.dot(p.dpdv.normalize_or_zero()).abs() < 1e-3,
                    "{shape:?}"
                );
            }
        }
    }

    /// The world area from the area scale: exact under a uniform scale, and a stretched
    /// cylinder's (an elliptic cylinder) by its perimeter, Ramanujan's approximation.
    #[test]
    fn world_area_follows_the_transform() {
        let cyl = QuadricShape::Cylinder(Cylinder {
            radius: 1.0,
            z_min: 0.0,
            z_max: 1.0,
            phi_max: TAU,
        });
        let q = Quadric::new(
            cyl.clone(),
            DMat4::from_scale(glam::DVec3::splat(2.0)),
            surface(),
            false,
        )
        .unwrap();
        assert!(
            (q.world_area() - 4.0 * TAU).abs() < 1e-3,
            "{}",
            q.world_area()
        );
        let q = Quadric::new(
            cyl,
            DMat4::from_scale(glam::DVec3::new(3.0, 1.0, 1.0)),
            surface(),
            false,
        )
        .unwrap();
        let (a, b) = (3.0f32, 1.0f32);
        let h = ((a - b) / (a + b)).powi(2);
        let perimeter = PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()));
        assert!(
            (q.world_area() - perimeter).abs() < 1e-3 * perimeter,
            "{} vs {perimeter}",
            q.world_area()
        );
    }

    /// pbrt-v4's orientation: outwards, inwards under ReverseOrientation, and inwards under
    /// a mirroring transform.
    #[test]
    fn normals_are_oriented_as_pbrt_v4_orients_quadrics() {
        let disk = QuadricShape::Disk(Disk {
            height: 0.0,
            radius: 1.0,
            inner_radius: 0.0,
            phi_max: TAU,
        });
        let up = |m: DMat4, ro: bool| {
            let q = Quadric::new(disk.clone(), m, surface(), ro).unwrap();
            q.point_at(Vec3A::new(0.1, 0.1, 0.0)).n
        };
        assert!((up(DMat4::IDENTITY, false) - Vec3A::Z).length() < 1e-6);
        assert!((up(DMat4::IDENTITY, true) + Vec3A::Z).length() < 1e-6);
        let mirror = DMat4::from_scale(glam::DVec3::new(-1.0, 1.0, 1.0));
        assert!((up(mirror, false) + Vec3A::Z).length() < 1e-6);
    }

    /// A ray that grazes nothing and one parallel to the disk miss.
    #[test]
    fn misses_are_misses() {
        for shape in shapes() {
            let q = Quadric::new(shape, DMat4::IDENTITY, surface(), false).unwrap();
            assert_eq!(
                q.intersect(Vec3A::new(10.0, 10.0, 10.0), Vec3A::X, 0.0, f32::INFINITY),
                f32::INFINITY
            );
        }
        let q = Quadric::new(shapes()[1].clone(), DMat4::IDENTITY, surface(), false).unwrap();
        assert_eq!(
            q.intersect(Vec3A::new(-5.0, 0.0, 0.3), Vec3A::X, 0.0, f32::INFINITY),
            f32::INFINITY
        );
    }
}
