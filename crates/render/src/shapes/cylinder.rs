//! pbrt-v4's cylinder in object space: radius `radius` about the z axis between `z_min`
//! and `z_max`, cut to `0 ≤ φ ≤ phi_max`, open at both ends, facing outwards.
//! [`super::quadric`] places it in the world.

use super::local::LocalPoint;
use crate::math::{phi_of, solve_quadratic};
use glam::{DVec3, Vec2, Vec3A};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    pub radius: f32,
    pub z_min: f32,
    pub z_max: f32,
    /// Radians, in [0, 2π].
    pub phi_max: f32,
}

impl Cylinder {
    /// The ray parameter of the nearest hit in (tmin, tmax), or infinity.
    pub fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        let r = f64::from(self.radius);
        let a = d.x * d.x + d.y * d.y;
        if a == 0.0 {
            return f64::INFINITY;
        }
        // The distance from the axis of the ray's closest approach, for a discriminant
        // that keeps its precision far from the cylinder (as pbrt-v4 computes it).
        let b = 2.0 * (d.x * o.x + d.y * o.y);
        let f = b / (2.0 * a);
        let (vx, vy) = (o.x - f * d.x, o.y - f * d.y);
        let len = (vx * vx + vy * vy).sqrt();
        let c = o.x * o.x + o.y * o.y - r * r;
        let Some((t0, t1)) = solve_quadratic(a, b, c, 4.0 * a * (r + len) * (r - len)) else {
            return f64::INFINITY;
        };
        for t in [t0, t1] {
            if t <= tmin || t >= tmax {
                continue;
            }
            let p = o + d * t;
            if p.z >= f64::from(self.z_min)
                && p.z <= f64::from(self.z_max)
                && phi_of(p.x, p.y) <= f64::from(self.phi_max)
            {
                return t;
            }
        }
        f64::INFINITY
    }

    /// The surface at (the point nearest) `p`: u = φ/φmax, v = (z − zmin)/(zmax − zmin).
    pub fn local(&self, mut p: Vec3A) -> LocalPoint {
        let r = (p.x * p.x + p.y * p.y).sqrt();
        let n = if r > 0.0 {
            Vec3A::new(p.x / r, p.y / r, 0.0)
        } else {
            Vec3A::X
        };
        p.x = n.x * self.radius;
        p.y = n.y * self.radius;
        let phi = phi_of(f64::from(p.x), f64::from(p.y)) as f32;
        LocalPoint {
            ns: None,
            pdf: 0.0,
            p,
            n,
            dpdu: Vec3A::new(-self.phi_max * p.y, self.phi_max * p.x, 0.0),
            dpdv: Vec3A::new(0.0, 0.0, self.z_max - self.z_min),
            uv: Vec2::new(
                phi / self.phi_max,
                (p.z - self.z_min) / (self.z_max - self.z_min),
            ),
        }
    }

    pub fn area(&self) -> f32 {
        (self.z_max - self.z_min) * self.radius * self.phi_max
    }

    /// A point uniformly distributed over the cylinder's area.
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let z = self.z_min + u.x * (self.z_max - self.z_min);
        let phi = u.y * self.phi_max;
        Vec3A::new(
            self.radius * libm::cosf(phi),
            self.radius * libm::sinf(phi),
            z,
        )
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (
            Vec3A::new(-self.radius, -self.radius, self.z_min),
            Vec3A::new(self.radius, self.radius, self.z_max),
        )
    }
}
