//! Sampling: warps from the unit square to shapes and directions (here), discrete and
//! piecewise-constant distributions, the per-pixel Sobol sampler and its tables, and the
//! generator that tracking through media draws from.
//!
//! Nothing here knows about scenes: these are pure functions of their arguments.

mod alias;
mod distribution;
mod pixel_sampler;
mod sobol;
mod tracking_rng;
mod warp2d;

pub use alias::AliasTable;
pub use distribution::{Distribution1D, Distribution2D, Distribution3D};
pub use pixel_sampler::{MAX_SAMPLES_PER_PIXEL, PixelSampler, pixel_seed};
pub use tracking_rng::TrackingRng;
pub use warp2d::Warp2D;

use glam::{Vec2, Vec3A};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// A cosine-weighted direction on the +z hemisphere (Malley's method).
pub fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let d = concentric_disk(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3A::new(d.x, d.y, z)
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// Shirley and Chiu's concentric map from the square to the unit disk.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(libm::cosf(theta), libm::sinf(theta))
}

pub fn uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(r * libm::cosf(phi), r * libm::sinf(phi), z)
}

/// A uniform direction on the +z hemisphere.
pub fn uniform_hemisphere(u: Vec2) -> Vec3A {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(r * libm::cosf(phi), r * libm::sinf(phi), z)
}

/// A uniform direction inside the cone of half-angle acos(cos_max) around +z.
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3A {
    let cos_theta = (1.0 - u.x) + u.x * cos_max;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    Vec3A::new(
        libm::cosf(phi) * sin_theta,
        libm::sinf(phi) * sin_theta,
        cos_theta,
    )
}

/// Barycentrics (b0, b1, b2) of a uniform point on a triangle (the low-distortion square-to-triangle map).
pub fn uniform_triangle(u: Vec2) -> [f32; 3] {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    [b0, b1, 1.0 - b0 - b1]
}

/// Veach's power heuristic with beta = 2, for one sample from each strategy.
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a.is_infinite() {
        return 1.0;
    }
    if a + b == 0.0 { 0.0 } else { a / (a + b) }
}

/// Clarberg's equal-area map from the unit square to the sphere, as pbrt-v4 uses for environment maps.
pub fn equal_area_square_to_sphere(p: Vec2) -> Vec3A {
    let u = 2.0 * p.x - 1.0;
    let v = 2.0 * p.y - 1.0;
    let up = u.abs();
    let vp = v.abs();
    let signed_distance = 1.0 - (up + vp);
    let d = signed_distance.abs();
    let r = 1.0 - d;
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * PI / 4.0;
    let z = (1.0 - r * r).copysign(signed_distance);
    let cos_phi = libm::cosf(phi).copysign(u);
    let sin_phi = libm::sinf(phi).copysign(v);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3A::new(cos_phi * s, sin_phi * s, z)
}

/// The inverse of [`equal_area_square_to_sphere`].
pub fn equal_area_sphere_to_square(d: Vec3A) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = x.min(y);
    let b = if a == 0.0 { 0.0 } else { b / a };
    let mut phi = libm::atanf(b) * 2.0 / PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    u = u.copysign(d.x);
    v = v.copysign(d.y);
    Vec2::new((u + 1.0) / 2.0, (v + 1.0) / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_area_map_round_trips() {
        for i in 0..400 {
            let uv = Vec2::new(
                (i % 20) as f32 / 20.0 + 0.025,
                (i / 20) as f32 / 20.0 + 0.025,
            );
            let d = equal_area_square_to_sphere(uv);
            assert!((d.length() - 1.0).abs() < 1e-4);
            let back = equal_area_sphere_to_square(d);
            assert!((back - uv).length() < 1e-4, "{uv} -> {d} -> {back}");
        }
    }

    #[test]
    fn warps_land_where_they_should() {
        for i in 0..100 {
            let u = Vec2::new((i as f32 * 0.618_034) % 1.0, (i as f32 + 0.5) / 100.0);
            let d = cosine_hemisphere(u);
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-5);
            let c = uniform_cone(u, 0.9);
            assert!(c.z >= 0.9 - 1e-6);
            let b = uniform_triangle(u);
            assert!(b.iter().all(|&x| (-1e-6..=1.0 + 1e-6).contains(&x)));
        }
    }
}
