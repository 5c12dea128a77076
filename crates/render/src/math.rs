//! Rays, colours and orthonormal frames.
//!
//! A [`Color`] is four lanes, one SIMD register. In RGB mode they are linear sRGB's red,
//! green and blue, and the fourth lane repeats green: every colour is made by [`rgb`], and
//! lane-wise arithmetic (products, sums, quotients, exponentials, selects) then keeps the
//! fourth lane a copy of the second, so the largest and smallest lanes are the colour's and
//! its three lanes are computed exactly as three would be. In spectral mode the four lanes
//! are a path's four wavelengths.

use glam::{Vec3A, Vec4};

/// Linear sRGB radiance or throughput (the fourth lane repeating green), or their values at
/// a path's four wavelengths.
pub type Color = Vec4;

/// The luminance of an RGB colour.
pub fn luminance(c: Color) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The RGB colour `c` (its fourth lane repeating green).
pub fn rgb(c: [f32; 3]) -> Color {
    Vec4::new(c[0], c[1], c[2], c[1])
}

/// The RGB colour (r, g, b).
pub fn rgb3(r: f32, g: f32, b: f32) -> Color {
    Vec4::new(r, g, b, g)
}

/// The red, green and blue of an RGB colour.
pub fn rgb_of(c: Color) -> [f32; 3] {
    [c.x, c.y, c.z]
}

/// An RGB colour as a vector (for matrices on colours).
pub fn rgb_vec(c: Color) -> Vec3A {
    Vec3A::new(c.x, c.y, c.z)
}

/// The RGB colour of a vector's three lanes.
pub fn vec_rgb(v: Vec3A) -> Color {
    rgb3(v.x, v.y, v.z)
}

/// The sum of an RGB colour's three lanes, ((r + g) + b).
pub fn rgb_sum(c: Color) -> f32 {
    (c.x + c.y) + c.z
}

#[derive(Debug, Clone, Copy)]
pub struct Ray {
    pub origin: Vec3A,
    /// Unit length.
    pub dir: Vec3A,
    /// The instant within the shutter the ray travels at (moving shapes are where they
    /// are then); 0 for rays outside any camera path.
    pub time: f32,
}

impl Ray {
    pub fn new(origin: Vec3A, dir: Vec3A) -> Ray {
        Ray {
            origin,
            dir,
            time: 0.0,
        }
    }

    /// A ray at `time`.
    pub fn at_time(origin: Vec3A, dir: Vec3A, time: f32) -> Ray {
        Ray { origin, dir, time }
    }

    /// A ray leaving from `origin` towards `dir` at this ray's time (a path's next segment).
    pub fn spawn(&self, origin: Vec3A, dir: Vec3A) -> Ray {
        Ray {
            origin,
            dir,
            time: self.time,
        }
    }

    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}

/// An orthonormal basis with `z` along a normal.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    pub x: Vec3A,
    pub y: Vec3A,
    pub z: Vec3A,
}

impl Frame {
    /// A frame around `n` (unit), with x along `tangent` projected onto the plane when that is usable.
    pub fn new(n: Vec3A, tangent: Vec3A) -> Frame {
        let t = tangent - n * n.dot(tangent);
        let x = if t.length_squared() > 1e-12 {
            t.normalize()
        } else {
            any_perpendicular(n)
        };
        Frame {
            x,
            y: n.cross(x),
            z: n,
        }
    }

    pub fn from_z(n: Vec3A) -> Frame {
        let x = any_perpendicular(n);
        Frame {
            x,
            y: n.cross(x),
            z: n,
        }
    }

    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

/// Duff et al.'s branchless orthonormal basis.
fn any_perpendicular(n: Vec3A) -> Vec3A {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x)
}

/// pbrt-v4's γ(n): a bound on the relative error that n roundings of float arithmetic
/// make, n·ε / (1 − n·ε) with ε half an ulp of 1.
pub const fn gamma(n: u32) -> f32 {
    let e = f32::EPSILON * 0.5 * n as f32;
    e / (1.0 - e)
}

/// How far a point that carries no error bound of its own (a point on a quadric, a curve,
/// a moving shape, or sampled on a light) is moved off its surface: a fixed fraction of
/// its distance from the origin, generous enough for every shape Kiln intersects.
pub fn surface_epsilon(p: Vec3A) -> f32 {
    2e-4 * (1.0 + p.abs().max_element())
}

/// Moves a point off a surface along its geometric normal by `distance`, to the side `dir`
/// leaves towards (pbrt-v4's `OffsetRayOrigin`). Rounding the sum moves each coordinate by
/// at most half an ulp of it, so `distance` must hold that too (pbrt-v4 steps one float
/// further instead, three branches per ray that Kiln's bounds make unnecessary).
pub fn offset_origin(p: Vec3A, ng: Vec3A, distance: f32, dir: Vec3A) -> Vec3A {
    let d = if ng.dot(dir) >= 0.0 {
        distance
    } else {
        -distance
    };
    p + ng * d
}

/// The azimuth of (x, y) in [0, 2π).
pub fn phi_of(x: f64, y: f64) -> f64 {
    let phi = libm::atan2(y, x);
    if phi < 0.0 {
        phi + std::f64::consts::TAU
    } else {
        phi
    }
}

/// The roots, in order, of a t² + b t + c given its discriminant (computed by the caller
/// in whichever form keeps precision), by the form that avoids cancellation.
pub fn solve_quadratic(a: f64, b: f64, c: f64, discriminant: f64) -> Option<(f64, f64)> {
    if discriminant.is_nan() || discriminant < 0.0 || a == 0.0 {
        return None;
    }
    let root = discriminant.sqrt();
    let q = if b < 0.0 {
        -0.5 * (b - root)
    } else {
        -0.5 * (b + root)
    };
    let t0 = q / a;
    let t1 = if q != 0.0 { c / q } else { t0 };
    Some((t0.min(t1), t0.max(t1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal() {
        for n in [
            Vec3A::Z,
            -Vec3A::Z,
            Vec3A::new(0.3, -0.4, 0.866).normalize(),
            Vec3A::X,
        ] {
            let f = Frame::from_z(n);
            assert!(f.x.dot(f.y).abs() < 1e-6 && f.x.dot(f.z).abs() < 1e-6);
            assert!((f.x.length() - 1.0).abs() < 1e-5 && (f.y.length() - 1.0).abs() < 1e-5);
            let v = Vec3A::new(0.1, 0.2, 0.3);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }
}
