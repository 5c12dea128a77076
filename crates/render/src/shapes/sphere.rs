//! Spheres: ray intersection, hit records, and sampling (the visible cone from outside,
//! the area from inside).

use super::{Geometry, ShapeSample, SurfaceHit, SurfaceInfo};
use crate::math::{Frame, Ray};
use crate::sampling::{uniform_cone, uniform_sphere};
use glam::{Vec2, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;
use std::f32::consts::PI;

#[derive(Debug, Clone, Copy)]
pub struct Sphere {
    pub center: Vec3A,
    pub radius: f32,
    pub surface: SurfaceInfo,
    /// Normals point inwards (ReverseOrientation).
    pub flip: bool,
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
        // pbrt-v4's parametrisation of a whole sphere: u = φ / 2π, v = 1 − θ / π (0 at the
        // bottom), with dp/du and dp/dv to match.
        use std::f32::consts::{PI, TAU};
        let q = p - s.center;
        let r_xy = (q.x * q.x + q.y * q.y).sqrt();
        let (cos_phi, sin_phi) = if r_xy > 0.0 {
            (q.x / r_xy, q.y / r_xy)
        } else {
            (1.0, 0.0)
        };
        let theta = n.z.clamp(-1.0, 1.0).acos();
        let dpdu = Vec3A::new(-TAU * q.y, TAU * q.x, 0.0);
        let dpdv = -PI * Vec3A::new(q.z * cos_phi, q.z * sin_phi, -s.radius * theta.sin());
        let uv = Vec2::new((n.y.atan2(n.x) / TAU).rem_euclid(1.0), 1.0 - theta / PI);
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
        }
    }
}

/// pbrt-v4's (u, v) of the point of a whole sphere with outward normal `n`: u = φ / 2π,
/// v = 1 − θ / π (0 at the bottom).
pub fn sphere_uv(n: Vec3A) -> Vec2 {
    use std::f32::consts::{PI, TAU};
    Vec2::new(
        (n.y.atan2(n.x) / TAU).rem_euclid(1.0),
        1.0 - n.z.clamp(-1.0, 1.0).acos() / PI,
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
