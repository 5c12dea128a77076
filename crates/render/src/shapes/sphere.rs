//! Spheres: whole spheres in world space (ray intersection, hit records, and sampling: the
//! visible cone from outside, the area from inside), and pbrt-v4's partial spheres in
//! object space ([`PartialSphere`]), which [`super::quadric`] places in the world.
//!
//! A whole sphere is intersected in world space, but parametrised as pbrt-v4 parametrises
//! it, in its object space: (u, v), dp/du and dp/dv follow the sphere's rotation, so that a
//! texture, a bump map or an anisotropic roughness turns with the sphere.

use super::local::LocalPoint;
use super::{Geometry, ShapeSample, SurfaceHit, SurfaceInfo};
use crate::math::{Frame, Ray};
use crate::math::{phi_of, solve_quadratic};
use crate::sampling::{uniform_cone, uniform_sphere};
use glam::{DVec3, Mat3A, Vec2, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;
use std::f32::consts::PI;

#[derive(Debug, Clone, Copy)]
pub struct Sphere {
    pub center: Vec3A,
    pub radius: f32,
    /// The rotation (a mirroring, perhaps) from the sphere's object space to the world.
    pub rotation: Rotation,
    pub surface: SurfaceInfo,
    /// Normals point inwards (ReverseOrientation).
    pub flip: bool,
}

/// An orthonormal map from a whole sphere's object space to the world: its object-to-world
/// transform without the translation and the uniform scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotation(Mat3A);

impl Rotation {
    pub const IDENTITY: Rotation = Rotation(Mat3A::IDENTITY);

    /// The rotation whose columns are the images of the object's axes, `columns` (each
    /// of unit length and at right angles to the others).
    pub fn from_columns(columns: [Vec3A; 3]) -> Rotation {
        Rotation(Mat3A::from_cols(columns[0], columns[1], columns[2]))
    }

    /// An object-space direction in the world.
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.0 * v
    }

    /// A world direction in object space (by the transpose, the inverse of a rotation).
    pub fn to_object(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(
            self.0.x_axis.dot(v),
            self.0.y_axis.dot(v),
            self.0.z_axis.dot(v),
        )
    }
}

impl Sphere {
    /// The nearest t in (tmin, tmax), or infinity.
    pub fn intersect(&self, origin: Vec3A, dir: Vec3A, tmin: f32, tmax: f32) -> f32 {
        // Solve with the origin moved near the sphere for precision (as in Ray Tracing Gems, ch. 7).
        let f = origin - self.center;
        let b = -f.dot(dir);
        let l = f + b * dir;
        let disc = self.radius * self.radius - l.length_squared();
        if disc < 0.0 {
            return f32::INFINITY;
        }
        let c = f.length_squared() - self.radius * self.radius;
        let q = b + b.signum() * disc.sqrt();
        let (t0, t1) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let a = c / q;
            (a.min(q), a.max(q))
        };
        if t0 > tmin && t0 < tmax {
            t0
        } else if t1 > tmin && t1 < tmax {
            t1
        } else {
            f32::INFINITY
        }
    }
}

impl Boundable for Sphere {
    fn aabb(&self) -> Aabb {
        Aabb::new(
            self.center - Vec3A::splat(self.radius),
            self.center + Vec3A::splat(self.radius),
        )
    }
}

impl Geometry {
    pub(super) fn sphere_hit(&self, ray: &Ray, t: f32, id: u32) -> SurfaceHit {
        let s = &self.prims.spheres[id as usize];
        let mut n = (ray.at(t) - s.center).normalize();
        // Put the point back on the surface to limit self-intersection.
        let p = s.center + n * s.radius;
        // pbrt-v4's parametrisation of a whole sphere, in its object space: u = φ / 2π,
        // v = 1 − θ / π (0 at the bottom), with dp/du and dp/dv to match, carried back to
        // the world by the sphere's rotation.
        use std::f32::consts::{PI, TAU};
        let q = s.rotation.to_object(p - s.center);
        let n_object = s.rotation.to_object(n);
        let r_xy = (q.x * q.x + q.y * q.y).sqrt();
        let (cos_phi, sin_phi) = if r_xy > 0.0 {
            (q.x / r_xy, q.y / r_xy)
        } else {
            (1.0, 0.0)
        };
        let theta = libm::acosf(n_object.z.clamp(-1.0, 1.0));
        let dpdu = s.rotation.to_world(Vec3A::new(-TAU * q.y, TAU * q.x, 0.0));
        let dpdv = s.rotation.to_world(
            -PI * Vec3A::new(q.z * cos_phi, q.z * sin_phi, -s.radius * libm::sinf(theta)),
        );
        let uv = sphere_uv(n_object);
        if s.flip {
            n = -n;
        }
        SurfaceHit {
            p,
            t,
            ng: n,
            ns: n,
            dpdu,
            dpdv,
            uv,
            surface: s.surface,
            light: s.surface.light,
            offset: crate::math::surface_epsilon(p),
        }
    }
}

/// pbrt-v4's (u, v) of the point of a whole sphere with outward normal `n` in the sphere's
/// object space: u = φ / 2π, v = 1 − θ / π (0 at the bottom).
pub fn sphere_uv(n: Vec3A) -> Vec2 {
    use std::f32::consts::{PI, TAU};
    Vec2::new(
        (libm::atan2f(n.y, n.x) / TAU).rem_euclid(1.0),
        1.0 - libm::acosf(n.z.clamp(-1.0, 1.0)) / PI,
    )
}

/// A point on a sphere seen from `p` (`n` outward): the visible cone uniformly in solid
/// angle from outside, the area uniformly from inside.
pub fn sample_sphere(center: Vec3A, radius: f32, p: Vec3A, u: Vec2) -> Option<ShapeSample> {
    let dc2 = (p - center).length_squared();
    let r2 = radius * radius;
    let (q, pdf) = if dc2 <= r2 * 1.0001 {
        let nq = uniform_sphere(u);
        let q = center + nq * radius;
        let d = q - p;
        let dist2 = d.length_squared();
        let cos = nq.dot(-d.normalize_or_zero()).abs();
        if cos == 0.0 || dist2 == 0.0 {
            return None;
        }
        (q, dist2 / (cos * 4.0 * PI * r2))
    } else {
        let dc = dc2.sqrt();
        let sin2_max = r2 / dc2;
        let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
        let one_minus_cos = sin2_max / (1.0 + cos_max);
        let frame = Frame::from_z((center - p) / dc);
        let w = frame.to_world(uniform_cone(u, cos_max));
        // Where that direction meets the sphere (the tangent point if rounding misses it).
        let b = (center - p).dot(w);
        let disc = (b * b - (dc2 - r2)).max(0.0);
        let t = b - disc.sqrt();
        (p + w * t, 1.0 / (2.0 * PI * one_minus_cos))
    };
    let d = q - p;
    let dist = d.length();
    if dist == 0.0 {
        return None;
    }
    Some(ShapeSample {
        wi: d / dist,
        pdf,
        distance: dist,
        n: (q - center).normalize(),
    })
}

/// The solid-angle density with which [`sample_sphere`] from `p` reaches point `q`
/// (normal `n`) in direction `wi`.
pub fn sphere_pdf(center: Vec3A, radius: f32, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
    let dc2 = (p - center).length_squared();
    let r2 = radius * radius;
    if dc2 <= r2 * 1.0001 {
        let dist2 = (q - p).length_squared();
        let cos = n.dot(wi).abs();
        if cos == 0.0 {
            0.0
        } else {
            dist2 / (cos * 4.0 * PI * r2)
        }
    } else {
        let sin2_max = r2 / dc2;
        let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
        1.0 / (2.0 * PI * (sin2_max / (1.0 + cos_max)))
    }
}

/// pbrt-v4's sphere in object space, centred at the origin, cut to `z_min ≤ z ≤ z_max` and
/// `0 ≤ φ ≤ phi_max`: partial spheres, and whole ones under transforms that are not
/// similarities. [`super::quadric`] places it in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PartialSphere {
    pub radius: f32,
    pub z_min: f32,
    pub z_max: f32,
    /// Radians, in [0, 2π].
    pub phi_max: f32,
}

impl PartialSphere {
    /// θ (from +z) at `z_min` and at `z_max`.
    fn theta_range(&self) -> (f32, f32) {
        (
            libm::acosf((self.z_min / self.radius).clamp(-1.0, 1.0)),
            libm::acosf((self.z_max / self.radius).clamp(-1.0, 1.0)),
        )
    }

    /// The ray parameter of the nearest hit in (tmin, tmax), or infinity.
    pub fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        let r = f64::from(self.radius);
        let a = d.length_squared();
        let b = 2.0 * d.dot(o);
        let c = o.length_squared() - r * r;
        // The discriminant from the ray's closest approach to the centre (pbrt-v4's form,
        // which keeps its precision for distant spheres).
        let len = (o - d * (b / (2.0 * a))).length();
        let Some((t0, t1)) = solve_quadratic(a, b, c, 4.0 * a * (r + len) * (r - len)) else {
            return f64::INFINITY;
        };
        let whole_z = self.z_min <= -self.radius && self.z_max >= self.radius;
        for t in [t0, t1] {
            if t <= tmin || t >= tmax {
                continue;
            }
            let p = o + d * t;
            let (x, y) = if p.x == 0.0 && p.y == 0.0 {
                (1e-5 * r, p.y)
            } else {
                (p.x, p.y)
            };
            if (whole_z || (p.z >= f64::from(self.z_min) && p.z <= f64::from(self.z_max)))
                && phi_of(x, y) <= f64::from(self.phi_max)
            {
                return t;
            }
        }
        f64::INFINITY
    }

    /// The surface at (the point nearest) `p`, parametrised as pbrt-v4 does: u = φ/φmax,
    /// v = (θ − θ(zmin))/(θ(zmax) − θ(zmin)).
    pub fn local(&self, p: Vec3A) -> LocalPoint {
        let n = p.normalize_or(Vec3A::Z);
        let mut p = n * self.radius;
        if p.x == 0.0 && p.y == 0.0 {
            p.x = 1e-5 * self.radius;
        }
        let phi = phi_of(f64::from(p.x), f64::from(p.y)) as f32;
        let (theta_min, theta_max) = self.theta_range();
        let cos_theta = (p.z / self.radius).clamp(-1.0, 1.0);
        let theta = libm::acosf(cos_theta);
        let r_xy = (p.x * p.x + p.y * p.y).sqrt();
        let (cos_phi, sin_phi) = (p.x / r_xy, p.y / r_xy);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        LocalPoint {
            ns: None,
            pdf: 0.0,
            p,
            n,
            dpdu: Vec3A::new(-self.phi_max * p.y, self.phi_max * p.x, 0.0),
            dpdv: (theta_max - theta_min)
                * Vec3A::new(p.z * cos_phi, p.z * sin_phi, -self.radius * sin_theta),
            uv: Vec2::new(
                phi / self.phi_max,
                (theta - theta_min) / (theta_max - theta_min),
            ),
        }
    }

    pub fn area(&self) -> f32 {
        self.phi_max * self.radius * (self.z_max - self.z_min)
    }

    /// A point uniformly distributed over the area (Archimedes: z is uniform).
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let z = self.z_min + u.x * (self.z_max - self.z_min);
        let r_xy = (self.radius * self.radius - z * z).max(0.0).sqrt();
        let phi = u.y * self.phi_max;
        Vec3A::new(r_xy * libm::cosf(phi), r_xy * libm::sinf(phi), z)
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (
            Vec3A::new(-self.radius, -self.radius, self.z_min),
            Vec3A::new(self.radius, self.radius, self.z_max),
        )
    }
}
