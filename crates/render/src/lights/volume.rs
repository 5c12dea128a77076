//! Seed 000's VolumeLight: emission inside a shape, seen through its dielectric surface.
//!
//! The radiance leaving surface point p in direction w is the emission integrated along
//! the interior segment that refracts into w at p, times the Fresnel transmittance and
//! the 1/eta^2 by which radiance shrinks on leaving a denser medium ([`volume_le`]). That
//! one function is used where paths hit the surface and by light sampling, so the two
//! strategies cannot drift apart. Each face of a VolumeLight mesh (or the whole sphere) is
//! one light, chosen by a power estimated when the scene is built ([`power_estimates`]).
//! The integrator also adds the emission of interior segments that paths travel after
//! reflecting inside ([`VolumeInterior::segment`]).

use super::{EmittedRay, LightContext, LightSample};
use crate::bsdfs::{fresnel_dielectric, refract};
use crate::math::{Color, Frame, Ray, luminance};
use crate::media::SampledGrid;
use crate::sampling::{
    MAX_SAMPLES_PER_PIXEL, PixelSampler, cosine_hemisphere, uniform_sphere, uniform_triangle,
};
use crate::shapes::Geometry;
use crate::shapes::sphere::{sample_sphere, sphere_pdf};
use crate::shapes::triangle::{sample_triangle, triangle_pdf};
use crate::spectral::Wavelengths;
use glam::{Affine3A, Vec2, Vec3A};
use rayon::prelude::*;
use std::f32::consts::PI;

/// One face of a VolumeLight mesh: sampled like a triangle light, its radiance comes from
/// the shape's interior. `power` is estimated when the scene is built.
#[derive(Debug, Clone)]
pub struct VolumeTriangleLight {
    pub p: [Vec3A; 3],
    pub n: Vec3A,
    pub area: f32,
    /// The triangle's index in the geometry, for its shading normal.
    pub tri: u32,
    /// Index into the scene's VolumeLight interiors.
    pub volume: u32,
    pub power: f32,
}

/// A VolumeLight sphere, one light for the whole sphere.
#[derive(Debug, Clone)]
pub struct VolumeSphereLight {
    pub center: Vec3A,
    pub radius: f32,
    pub volume: u32,
    pub power: f32,
}

/// A VolumeLight on a quadric piece (one sector of a surface of revolution's strip), sampled
/// by the quadric's area.
#[derive(Debug, Clone)]
pub struct VolumeQuadricLight {
    /// Index into the geometry's quadrics.
    pub quadric: u32,
    pub volume: u32,
    /// World-space area.
    pub area: f32,
    pub power: f32,
}

impl VolumeQuadricLight {
    pub fn le(&self, ctx: &LightContext, p: Vec3A, ng: Vec3A, ns: Vec3A, w: Vec3A) -> (Color, u64) {
        volume_le(ctx, self.volume, p, ng, ns, w)
    }

    pub fn sample(&self, ctx: &LightContext, p: Vec3A, u: Vec2) -> (Option<LightSample>, u64) {
        let quadric = &ctx.geometry.prims.quadrics[self.quadric as usize];
        let Some((q, point)) = quadric.sample_from(p, u) else {
            return (None, 0);
        };
        let (le, rays) = volume_le(ctx, self.volume, q.p, q.n, q.ns, -point.wi);
        (
            (le != Color::ZERO).then(|| LightSample::on_surface(point, le)),
            rays,
        )
    }

    pub fn pdf(&self, ctx: &LightContext, p: Vec3A, wi: Vec3A, q: Vec3A) -> f32 {
        ctx.geometry.prims.quadrics[self.quadric as usize].solid_angle_pdf(p, wi, q)
    }

    /// A photon as [`VolumeTriangleLight::emit`] gives one, from a point sampled by area.
    pub fn emit(&self, ctx: &LightContext, u: [Vec2; 2]) -> (Option<EmittedRay>, u64) {
        let (q, area_pdf) = ctx.geometry.prims.quadrics[self.quadric as usize].sample(u[0]);
        if area_pdf <= 0.0 {
            return (None, 0);
        }
        emit_outward(ctx, self.volume, q.p, q.n, q.ns, q.n, 1.0 / area_pdf, u[1])
    }
}

impl VolumeTriangleLight {
    pub fn le(&self, ctx: &LightContext, p: Vec3A, ng: Vec3A, ns: Vec3A, w: Vec3A) -> (Color, u64) {
        volume_le(ctx, self.volume, p, ng, ns, w)
    }

    pub fn sample(&self, ctx: &LightContext, p: Vec3A, u: Vec2) -> (Option<LightSample>, u64) {
        let Some((point, b)) = sample_triangle(&self.p, self.n, self.area, p, u) else {
            return (None, 0);
        };
        let (q, ng, ns) = ctx.geometry.surface_point(self.tri, b);
        let (le, rays) = volume_le(ctx, self.volume, q, ng, ns, -point.wi);
        (
            (le != Color::ZERO).then(|| LightSample::on_surface(point, le)),
            rays,
        )
    }

    pub fn pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        triangle_pdf(self.area, p, wi, q, n)
    }

    /// A photon from a uniform point of the face in a cosine-distributed outward direction,
    /// carrying the radiance the interior sends that way (as [`volume_le`] gives it to
    /// camera paths) times the face's area and pi.
    pub fn emit(&self, ctx: &LightContext, u: [Vec2; 2]) -> (Option<EmittedRay>, u64) {
        let (q, ng, ns) = ctx.geometry.surface_point(self.tri, uniform_triangle(u[0]));
        emit_outward(ctx, self.volume, q, ng, ns, self.n, self.area, u[1])
    }
}

/// A photon leaving a VolumeLight's surface point `q` (normals `ng`, `ns` as hits have them;
/// `out` its outward normal) in a cosine-distributed outward direction.
#[allow(clippy::too_many_arguments)]
fn emit_outward(
    ctx: &LightContext,
    volume: u32,
    q: Vec3A,
    ng: Vec3A,
    ns: Vec3A,
    out: Vec3A,
    area: f32,
    u: Vec2,
) -> (Option<EmittedRay>, u64) {
    let dir = Frame::from_z(out).to_world(cosine_hemisphere(u));
    let (le, rays) = volume_le(ctx, volume, q, ng, ns, dir);
    let ray = (le != Color::ZERO).then(|| EmittedRay {
        origin: q,
        dir,
        n: out,
        flux: le * (area * PI),
    });
    (ray, rays)
}

impl VolumeSphereLight {
    pub fn le(&self, ctx: &LightContext, p: Vec3A, ng: Vec3A, ns: Vec3A, w: Vec3A) -> (Color, u64) {
        volume_le(ctx, self.volume, p, ng, ns, w)
    }

    pub fn sample(&self, ctx: &LightContext, p: Vec3A, u: Vec2) -> (Option<LightSample>, u64) {
        let Some(point) = sample_sphere(self.center, self.radius, p, u) else {
            return (None, 0);
        };
        let q = self.center + point.n * self.radius;
        let (le, rays) = volume_le(ctx, self.volume, q, point.n, point.n, -point.wi);
        (
            (le != Color::ZERO).then(|| LightSample::on_surface(point, le)),
            rays,
        )
    }

    pub fn pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        sphere_pdf(self.center, self.radius, p, wi, q, n)
    }

    /// A photon as [`VolumeTriangleLight::emit`] gives one, from a uniform point of the sphere.
    pub fn emit(&self, ctx: &LightContext, u: [Vec2; 2]) -> (Option<EmittedRay>, u64) {
        let n = uniform_sphere(u[0]);
        let area = 4.0 * PI * self.radius * self.radius;
        emit_outward(
            ctx,
            self.volume,
            self.center + n * self.radius,
            n,
            n,
            n,
            area,
            u[1],
        )
    }
}

/// One VolumeLight shape's interior: its emission field and absorption.
#[derive(Debug, Clone)]
pub struct VolumeInterior {
    /// Emitted radiance per unit length.
    pub le: Color,
    pub sigma_a: Color,
    pub grid: Option<SampledGrid>,
    /// World space to grid space ([0,1]^3 over the shape's object-space bounding box).
    pub world_to_grid: Affine3A,
    pub steps: u32,
    /// Index of refraction of the surface (1 for an interface).
    pub eta: f32,
    pub power_samples: u32,
}

impl VolumeInterior {
    /// The emission and absorption per unit length: in RGB, or with `waves` at a spectral
    /// path's wavelengths (light's spectrum and an unbounded one).
    fn colours(&self, waves: Option<&Wavelengths>) -> (Color, Color) {
        match waves {
            None => (self.le, self.sigma_a),
            Some(w) => (w.illuminant(self.le), w.unbounded(self.sigma_a)),
        }
    }

    /// Emission per unit length at a world-space point, in RGB.
    pub fn emission_at(&self, p: Vec3A) -> Color {
        self.le * self.field_at(p)
    }

    /// What the grid multiplies the emission by at a world-space point (1 without one).
    fn field_at(&self, p: Vec3A) -> f32 {
        match &self.grid {
            None => 1.0,
            Some(g) => g.lookup_clamped(self.world_to_grid.transform_point3a(p)),
        }
    }

    /// Emission gathered along `origin + dir * s` for s in [0, t], each point attenuated
    /// by absorption over its distance from `origin`: in RGB, or at `waves`.
    pub fn segment(&self, origin: Vec3A, dir: Vec3A, t: f32, waves: Option<&Wavelengths>) -> Color {
        if t <= 0.0 || !t.is_finite() {
            return Color::ZERO;
        }
        let (le, sigma_a) = self.colours(waves);
        let absorbs = sigma_a != Color::ZERO;
        if self.grid.is_none() {
            // A uniform field integrates in closed form.
            return if absorbs {
                let s = sigma_a.max(Color::splat(1e-12));
                le * (Color::ONE - (-s * t).exp()) / s
            } else {
                le * t
            };
        }
        // The midpoint rule, as the seed integrates the voxel grid.
        let dt = t / self.steps as f32;
        let mut sum = Color::ZERO;
        for k in 0..self.steps {
            let s = (k as f32 + 0.5) * dt;
            let e = le * self.field_at(origin + dir * s);
            sum += if absorbs { e * (-sigma_a * s).exp() } else { e };
        }
        sum * dt
    }

    /// Absorption over a distance `t`: in RGB, or at `waves`.
    pub fn transmittance(&self, t: f32, waves: Option<&Wavelengths>) -> Color {
        if self.sigma_a == Color::ZERO || !t.is_finite() {
            Color::ONE
        } else {
            (-self.colours(waves).1 * t).exp()
        }
    }

    /// The factor by which interior radiance leaving at cosine `cos_o` (outside, against
    /// the shading normal) reaches the outside: Fresnel transmittance over eta^2.
    pub fn exit_factor(&self, cos_o: f32) -> f32 {
        (1.0 - fresnel_dielectric(cos_o, self.eta)) / (self.eta * self.eta)
    }
}

/// Radiance leaving VolumeLight `volume` at surface point `p` (normals `ng`, `ns`,
/// outward) in direction `w`: the interior emission along the segment that refracts
/// into `w`, through the surface. Returns it with the number of rays traced (0 or 1).
pub fn volume_le(
    ctx: &LightContext,
    volume: u32,
    p: Vec3A,
    ng: Vec3A,
    ns: Vec3A,
    w: Vec3A,
) -> (Color, u64) {
    let interior = &ctx.volumes[volume as usize];
    let cos_o = w.dot(ns);
    if cos_o <= 0.0 || w.dot(ng) <= 0.0 {
        return (Color::ZERO, 0);
    }
    let Some((inward, _)) = refract(w, ns, interior.eta) else {
        return (Color::ZERO, 0);
    };
    let t = interior_length(ctx.geometry, p, ng, inward);
    (
        interior.segment(p, inward, t, ctx.waves) * interior.exit_factor(cos_o),
        1,
    )
}

/// How far the ray from surface point `p` (geometric normal `ng`) along the inward
/// `dir` goes before it meets a surface again (0 if it escapes: a leak).
///
/// The ray starts a little way along `dir` itself rather than off along the normal:
/// a sideways offset would change a grazing chord's length by far more than the offset.
fn interior_length(geometry: &Geometry, p: Vec3A, ng: Vec3A, dir: Vec3A) -> f32 {
    let eps = 2e-4 * (1.0 + p.abs().max_element());
    let step = eps / dir.dot(ng).abs().max(0.05);
    geometry
        .hit_distance(&Ray::new(p + dir * step, dir), f32::INFINITY)
        .map_or(0.0, |t| t + step)
}

/// The seed of the Sobol points that VolumeLight power estimates draw.
pub const VOLUME_POWER_SEED: u32 = 0x766f_6c75;

/// The power estimate of every VolumeLight face in `lights` (None for other lights),
/// drawn with `seed`; the scene uses [`VOLUME_POWER_SEED`].
///
/// Seed 000's estimate: the interior radiance averaged over `powersamples` segments
/// from uniform points on the face in cosine-weighted inward directions, times the
/// face's area and pi (exitance times area). The points come from each face's own
/// Owen-scrambled Sobol sequence, which measured ten times steadier per face than
/// reusing the segments' far ends as samples of the faces they land on (a trick that
/// halves the rays but loses the stratification); and since each face draws its own
/// points, the estimates do not depend on the thread count.
pub fn power_estimates(lights: &[super::Light], ctx: &LightContext, seed: u32) -> Vec<Option<f32>> {
    lights
        .par_iter()
        .enumerate()
        .map(|(i, light)| match light {
            super::Light::VolumeTriangle(f) => {
                Some(face_power(ctx, i as u32, f.volume, seed, f.area, |u| {
                    let b = uniform_triangle(u);
                    (f.p[0] * b[0] + f.p[1] * b[1] + f.p[2] * b[2], f.n)
                }))
            }
            super::Light::VolumeSphere(s) => {
                let area = 4.0 * PI * s.radius * s.radius;
                Some(face_power(ctx, i as u32, s.volume, seed, area, |u| {
                    let n = uniform_sphere(u);
                    (s.center + n * s.radius, n)
                }))
            }
            super::Light::VolumeQuadric(l) => {
                let quadric = &ctx.geometry.prims.quadrics[l.quadric as usize];
                Some(face_power(ctx, i as u32, l.volume, seed, l.area, |u| {
                    let (q, _) = quadric.sample(u);
                    (q.p, q.n)
                }))
            }
            super::Light::Point(_)
            | super::Light::Spot(_)
            | super::Light::Goniometric(_)
            | super::Light::Projection(_)
            | super::Light::Distant(_)
            | super::Light::Triangle(_)
            | super::Light::Sphere(_)
            | super::Light::Quadric(_)
            | super::Light::Medium(_)
            | super::Light::UniformInfinite(_)
            | super::Light::ImageInfinite(_)
            | super::Light::Dome(_) => None,
        })
        .collect()
}

/// One face's power; `point` maps a 2D sample to a point on the face and its outward normal.
fn face_power(
    ctx: &LightContext,
    light: u32,
    volume: u32,
    seed: u32,
    area: f32,
    point: impl Fn(Vec2) -> (Vec3A, Vec3A),
) -> f32 {
    let interior = &ctx.volumes[volume as usize];
    let samples = interior.power_samples.min(MAX_SAMPLES_PER_PIXEL);
    let mut sum = 0.0f64;
    for i in 0..samples {
        let mut s = PixelSampler::new(light, volume, i, seed);
        let (q, n) = point(s.get_2d());
        let dir = Frame::from_z(-n).to_world(cosine_hemisphere(s.get_2d()));
        let t = interior_length(ctx.geometry, q, n, dir);
        sum += luminance(interior.segment(q, dir, t, None)) as f64;
    }
    (sum / samples.max(1) as f64) as f32 * area * PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::media::voxel_grid::grid_from_fn;

    #[test]
    fn uniform_segments_integrate_exactly() {
        let e = VolumeInterior {
            le: crate::math::rgb3(1.0, 2.0, 3.0),
            sigma_a: Color::ZERO,
            grid: None,
            world_to_grid: Affine3A::IDENTITY,
            steps: 4,
            eta: 1.0,
            power_samples: 1,
        };
        assert_eq!(
            e.segment(Vec3A::ZERO, Vec3A::X, 2.0, None),
            crate::math::rgb3(2.0, 4.0, 6.0)
        );
        let absorbing = VolumeInterior {
            sigma_a: Color::splat(0.5),
            ..e.clone()
        };
        let s = absorbing.segment(Vec3A::ZERO, Vec3A::X, 2.0, None);
        assert!((s.x - (1.0 - libm::expf(-1.0f32)) / 0.5).abs() < 1e-5);
        // A grid of ones with many midpoint steps agrees with the closed form.
        let gridded = VolumeInterior {
            grid: Some(SampledGrid::new(&grid_from_fn([2, 2, 2], |_, _, _| 1.0))),
            steps: 4000,
            ..absorbing.clone()
        };
        let m = gridded.segment(Vec3A::ZERO, Vec3A::X, 2.0, None);
        assert!((m - s).abs().max_element() < 1e-4, "{m} vs {s}");
    }
}
