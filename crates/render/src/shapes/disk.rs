//! pbrt-v4's disk in object space: the annulus `inner_radius ≤ r ≤ radius` of the plane
//! `z = height`, cut to `0 ≤ φ ≤ phi_max`, facing +z. [`super::quadric`] places it in the
//! world.

use super::local::LocalPoint;
use crate::math::phi_of;
use glam::{DVec3, Vec2, Vec3A};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disk {
    pub height: f32,
    pub radius: f32,
    pub inner_radius: f32,
    /// Radians, in [0, 2π].
    pub phi_max: f32,
}

impl Disk {
    /// The ray parameter of the hit in (tmin, tmax), or infinity.
    pub fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        if d.z == 0.0 {
            return f64::INFINITY;
        }
        let t = (f64::from(self.height) - o.z) / d.z;
        if !(t > tmin && t < tmax) {
            return f64::INFINITY;
        }
        let p = o + d * t;
        let r2 = p.x * p.x + p.y * p.y;
        let (r, ri) = (f64::from(self.radius), f64::from(self.inner_radius));
        if r2 > r * r || r2 < ri * ri || phi_of(p.x, p.y) > f64::from(self.phi_max) {
            return f64::INFINITY;
        }
        t
    }

    /// The surface at (the point nearest) `p`, parametrised as pbrt-v4 does: u = φ/φmax,
    /// v = (radius − r)/(radius − inner radius).
    pub fn local(&self, mut p: Vec3A) -> LocalPoint {
        p.z = self.height;
        let r = (p.x * p.x + p.y * p.y).sqrt();
        let phi = phi_of(f64::from(p.x), f64::from(p.y)) as f32;
        let dpdu = Vec3A::new(-self.phi_max * p.y, self.phi_max * p.x, 0.0);
        let radial = if r > 0.0 {
            Vec3A::new(p.x / r, p.y / r, 0.0)
        } else {
            Vec3A::X
        };
        LocalPoint {
            ns: None,
            pdf: 0.0,
            p,
            n: Vec3A::Z,
            dpdu,
            dpdv: radial * (self.inner_radius - self.radius),
            uv: Vec2::new(
                phi / self.phi_max,
                (self.radius - r) / (self.radius - self.inner_radius),
            ),
        }
    }

    pub fn area(&self) -> f32 {
        0.5 * self.phi_max * (self.radius * self.radius - self.inner_radius * self.inner_radius)
    }

    /// A point uniformly distributed over the disk's area.
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let (r2, ri2) = (
            self.radius * self.radius,
            self.inner_radius * self.inner_radius,
        );
        let r = (ri2 + u.x * (r2 - ri2)).max(0.0).sqrt();
        let phi = u.y * self.phi_max;
        Vec3A::new(r * libm::cosf(phi), r * libm::sinf(phi), self.height)
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (
            Vec3A::new(-self.radius, -self.radius, self.height),
            Vec3A::new(self.radius, self.radius, self.height),
        )
    }
}
