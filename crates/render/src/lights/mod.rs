//! Lights: what emits, how to sample a point or direction on it, and its density.
//!
//! [`Light`] is the closed set of light kinds and its dispatch; each kind lives in its own
//! file. Every kind answers every question itself ([`Light::sample`], [`Light::pdf`],
//! [`Light::le`], [`Light::power`]), given a [`LightContext`] with the parts of the scene
//! some kinds need (VolumeLights trace their interior chord through the geometry; a medium
//! light samples its medium's emission), so adding a kind makes the compiler list every
//! place that must learn it.
//!
//! Lights know nothing of integrators: they never see a path, only a reference point.

mod area;
mod bounds;
mod distant;
mod goniometric;
mod infinite;
mod medium;
mod point;
mod projection;
mod sampler;
mod spot;
pub mod volume;

pub use area::{EmissionImage, EmissionPoint, QuadricLight, SphereLight, TriangleLight};
pub use bounds::LightBounds;
pub use distant::DistantLight;
pub use goniometric::GoniometricLight;
pub use infinite::{DomeLight, ImageInfiniteLight, Portal, UniformInfiniteLight};
pub use medium::MediumLight;
pub use point::PointLight;
pub use projection::ProjectionLight;
pub use sampler::{LightBvh, LightSampler};
pub use spot::SpotLight;
pub use volume::{VolumeInterior, VolumeQuadricLight, VolumeSphereLight, VolumeTriangleLight};

use crate::math::{Color, Frame, rgb};
use crate::media::Medium;
use crate::shapes::{Geometry, ShapeSample};
use crate::spectral::Wavelengths;
use glam::{Affine3A, Mat3A, Vec2, Vec3A};
use kiln_scene::{EnvironmentLayout, LightKind};

/// The parts of a scene that sampling and evaluating some lights needs.
#[derive(Clone, Copy)]
pub struct LightContext<'a> {
    pub geometry: &'a Geometry,
    /// VolumeLight interiors, by `volume` index.
    pub volumes: &'a [VolumeInterior],
    pub media: &'a [Medium],
    /// A spectral path's wavelengths, at which samples' radiance is then given.
    pub waves: Option<&'a Wavelengths>,
}

#[derive(Debug, Clone)]
pub enum Light {
    Point(PointLight),
    Spot(SpotLight),
    Goniometric(GoniometricLight),
    Projection(ProjectionLight),
    Distant(DistantLight),
    Triangle(TriangleLight),
    Sphere(SphereLight),
    Quadric(QuadricLight),
    VolumeTriangle(VolumeTriangleLight),
    VolumeSphere(VolumeSphereLight),
    VolumeQuadric(VolumeQuadricLight),
    Medium(MediumLight),
    UniformInfinite(UniformInfiniteLight),
    ImageInfinite(Box<ImageInfiniteLight>),
    Dome(DomeLight),
}

/// A sampled point or direction on a light, seen from a reference point.
#[derive(Debug, Clone, Copy)]
pub struct LightSample {
    pub radiance: Color,
    pub wi: Vec3A,
    /// Solid-angle pdf (1 for delta lights; per unit solid angle and length for points in
    /// a medium).
    pub pdf: f32,
    /// Distance to the sampled point (infinite for lights at infinity).
    pub distance: f32,
    /// The sampled point's normal, for offsetting the shadow ray's far end (zero for
    /// points not on a surface).
    pub n: Vec3A,
    /// No scattering finds this light, so its sample counts whole: a delta light, or an
    /// invisible area light (see [`SphereLight::invisible`]).
    pub delta: bool,
    /// For a point in a medium: the medium the shadow ray must arrive in for it to emit.
    pub medium: Option<u32>,
    /// The rate at which scattering finds this point: what the scattering pdf is multiplied
    /// by in MIS weights (the majorant at a point in a medium; 1 on surfaces).
    pub scatter_rate: f32,
}

/// A sample of a point light at `position` whose intensity depends on direction: towards
/// `p`, the intensity `towards` gives for the direction light leaves in, over the squared
/// distance; None where it sends nothing.
fn shaped_point_sample(
    position: Vec3A,
    p: Vec3A,
    towards: impl Fn(Vec3A) -> Color,
) -> Option<LightSample> {
    let d = position - p;
    let dist2 = d.length_squared();
    let dist = dist2.sqrt();
    if dist == 0.0 {
        return None;
    }
    let wi = d / dist;
    let i = towards(-wi);
    (i != Color::ZERO).then(|| LightSample::delta(i / dist2, wi, dist))
}

/// An area light's sample, counted whole if the light is invisible (no ray meets it).
fn seen_if(sample: Option<LightSample>, invisible: bool) -> Option<LightSample> {
    sample.map(|s| LightSample {
        delta: s.delta || invisible,
        ..s
    })
}

impl LightSample {
    /// A sample of a delta light: one direction, no density.
    pub fn delta(radiance: Color, wi: Vec3A, distance: f32) -> LightSample {
        LightSample {
            radiance,
            wi,
            pdf: 1.0,
            distance,
            n: Vec3A::ZERO,
            delta: true,
            medium: None,
            scatter_rate: 1.0,
        }
    }

    /// A point sampled on a shape.
    pub fn on_surface(point: ShapeSample, radiance: Color) -> LightSample {
        LightSample {
            radiance,
            wi: point.wi,
            pdf: point.pdf,
            distance: point.distance,
            n: point.n,
            delta: false,
            medium: None,
            scatter_rate: 1.0,
        }
    }

    /// A direction towards a light at infinity.
    pub fn at_infinity(radiance: Color, wi: Vec3A, pdf: f32) -> LightSample {
        LightSample {
            radiance,
            wi,
            pdf,
            distance: f32::INFINITY,
            n: Vec3A::ZERO,
            delta: false,
            medium: None,
            scatter_rate: 1.0,
        }
    }
}

impl Light {
    /// Whether pbrt-v4's path tracers find this light only by BSDF sampling (a uniform
    /// light at infinity, whose `SampleLi` with `allowIncompletePDF` gives no sample).
    pub fn found_by_bsdf_alone(&self) -> bool {
        matches!(self, Light::UniformInfinite(_))
    }

    /// The light a scene description's LightSource makes.
    pub fn from_description(kind: &LightKind) -> Light {
        match kind {
            LightKind::Point {
                position,
                intensity,
            } => Light::Point(PointLight {
                position: position.as_vec3().into(),
                intensity: rgb(*intensity),
            }),
            LightKind::Spot {
                position,
                direction,
                intensity,
                cos_falloff_start,
                cos_falloff_end,
            } => Light::Spot(SpotLight {
                position: position.as_vec3().into(),
                frame: Frame::from_z(Vec3A::from(direction.as_vec3()).normalize()),
                intensity: rgb(*intensity),
                cos_start: *cos_falloff_start as f32,
                cos_end: *cos_falloff_end as f32,
            }),
            LightKind::Distant {
                direction,
                radiance,
            } => Light::Distant(DistantLight {
                direction: Vec3A::from(direction.as_vec3()).normalize(),
                radiance: rgb(*radiance),
            }),
            LightKind::UniformInfinite { radiance } => {
                Light::UniformInfinite(UniformInfiniteLight {
                    radiance: rgb(*radiance),
                })
            }
            LightKind::ImageInfinite {
                image,
                layout,
                scale,
                light_to_world,
                portal,
            } => {
                let pixels = image.pixels.iter().map(|p| rgb(*p) * *scale).collect();
                let portal = portal
                    .map(|p| Portal::new(p.map(|c| Vec3A::from(glam::DVec3::from(c).as_vec3()))));
                Light::ImageInfinite(Box::new(ImageInfiniteLight::new(
                    image.width as usize,
                    image.height as usize,
                    pixels,
                    *layout == EnvironmentLayout::EqualArea,
                    Affine3A::from_mat4(light_to_world.as_mat4()),
                    portal,
                )))
            }
            LightKind::Goniometric {
                light_to_world,
                intensity,
                image,
            } => Light::Goniometric(GoniometricLight {
                position: light_to_world
                    .transform_point3(glam::DVec3::ZERO)
                    .as_vec3()
                    .into(),
                to_light: Mat3A::from_mat4(light_to_world.inverse().as_mat4()),
                intensity: rgb(*intensity),
                values: image
                    .pixels
                    .iter()
                    .map(|p| (p[0] + p[1] + p[2]) / 3.0)
                    .collect(),
                resolution: image.width,
                mean: kiln_scene::photometry::goniometric_mean(image) as f32,
            }),
            LightKind::Projection {
                light_to_world,
                scale,
                fov,
                image,
            } => Light::Projection(ProjectionLight::new(
                light_to_world
                    .transform_point3(glam::DVec3::ZERO)
                    .as_vec3()
                    .into(),
                Mat3A::from_mat4(light_to_world.inverse().as_mat4()),
                *scale,
                *fov,
                image.clone(),
            )),
            LightKind::Dome { radiance, up } => Light::Dome(DomeLight {
                frame: Frame::from_z(Vec3A::from(up.as_vec3()).normalize()),
                radiance: rgb(*radiance),
            }),
        }
    }

    /// Lights at a point in space, which no ray can hit: only sampling them finds them.
    pub fn is_point(&self) -> bool {
        match self {
            Light::Point(_) | Light::Spot(_) | Light::Goniometric(_) | Light::Projection(_) => true,
            Light::Distant(_)
            | Light::Triangle(_)
            | Light::Sphere(_)
            | Light::Quadric(_)
            | Light::VolumeTriangle(_)
            | Light::VolumeSphere(_)
            | Light::VolumeQuadric(_)
            | Light::Medium(_)
            | Light::UniformInfinite(_)
            | Light::ImageInfinite(_)
            | Light::Dome(_) => false,
        }
    }

    /// Lights at infinity, whose radiance escaped rays collect.
    pub fn is_infinite(&self) -> bool {
        match self {
            Light::UniformInfinite(_) | Light::ImageInfinite(_) | Light::Dome(_) => true,
            Light::Point(_)
            | Light::Spot(_)
            | Light::Goniometric(_)
            | Light::Projection(_)
            | Light::Distant(_)
            | Light::Triangle(_)
            | Light::Sphere(_)
            | Light::Quadric(_)
            | Light::VolumeTriangle(_)
            | Light::VolumeSphere(_)
            | Light::VolumeQuadric(_)
            | Light::Medium(_) => false,
        }
    }

    /// Emitted power (luminance), used to choose lights in proportion to it.
    pub fn power(&self, scene_radius: f32) -> f32 {
        match self {
            Light::Point(l) => l.power(),
            Light::Spot(l) => l.power(),
            Light::Goniometric(l) => l.power(),
            Light::Projection(l) => l.power(),
            Light::Distant(l) => l.power(scene_radius),
            Light::Triangle(l) => l.power(),
            Light::Sphere(l) => l.power(),
            Light::Quadric(l) => l.power(),
            Light::VolumeTriangle(l) => l.power,
            Light::VolumeSphere(l) => l.power,
            Light::VolumeQuadric(l) => l.power,
            Light::Medium(l) => l.power,
            Light::UniformInfinite(l) => l.power(scene_radius),
            Light::ImageInfinite(l) => l.power(scene_radius),
            Light::Dome(l) => l.power(scene_radius),
        }
    }

    /// Where the light is and which way it shines, for the light hierarchy, with its
    /// `power` as [`Light::power`] gave it; None for lights at infinity and distant lights.
    /// Where a kind's emission has no simple cone, the bounds say every direction: they
    /// may be loose, never too tight.
    pub fn bounds(&self, ctx: &LightContext, power: f32) -> Option<LightBounds> {
        let at_point = |p: Vec3A| Some(LightBounds::everywhere(p, p, power));
        let in_box = |(lo, hi): (Vec3A, Vec3A)| Some(LightBounds::everywhere(lo, hi, power));
        match self {
            Light::Point(l) => at_point(l.position),
            Light::Goniometric(l) => at_point(l.position),
            Light::Projection(l) => at_point(l.position),
            Light::Spot(l) => Some(l.bounds()),
            Light::Triangle(l) => Some(l.bounds(power)),
            Light::Sphere(l) => in_box((l.center - l.radius, l.center + l.radius)),
            Light::Quadric(l) => in_box(ctx.geometry.prims.quadrics[l.quadric as usize].bounds()),
            Light::VolumeTriangle(l) => in_box((
                l.p[0].min(l.p[1]).min(l.p[2]),
                l.p[0].max(l.p[1]).max(l.p[2]),
            )),
            Light::VolumeSphere(l) => in_box((l.center - l.radius, l.center + l.radius)),
            Light::VolumeQuadric(l) => {
                in_box(ctx.geometry.prims.quadrics[l.quadric as usize].bounds())
            }
            // An unbounded medium is chosen as lights at infinity are.
            Light::Medium(l) => ctx.media[l.medium as usize].bounds().and_then(in_box),
            Light::Distant(_)
            | Light::UniformInfinite(_)
            | Light::ImageInfinite(_)
            | Light::Dome(_) => None,
        }
    }

    /// Radiance leaving the light's surface point `p` (geometric and shading normals `ng`,
    /// `ns`, oriented as hits are) in direction `w`, with the rays traced to find it.
    pub fn le(&self, ctx: &LightContext, p: Vec3A, ng: Vec3A, ns: Vec3A, w: Vec3A) -> (Color, u64) {
        match self {
            Light::Triangle(l) => (l.le(ctx.geometry, p, ng, w), 0),
            Light::Sphere(l) => (l.le(ctx.geometry, p, ng, w), 0),
            Light::Quadric(l) => (l.le(ctx.geometry, p, ng, w), 0),
            Light::VolumeTriangle(l) => l.le(ctx, p, ng, ns, w),
            Light::VolumeSphere(l) => l.le(ctx, p, ng, ns, w),
            Light::VolumeQuadric(l) => l.le(ctx, p, ng, ns, w),
            Light::Point(_)
            | Light::Spot(_)
            | Light::Goniometric(_)
            | Light::Projection(_)
            | Light::Distant(_)
            | Light::Medium(_)
            | Light::UniformInfinite(_)
            | Light::ImageInfinite(_)
            | Light::Dome(_) => (Color::ZERO, 0),
        }
    }

    /// Radiance arriving along a ray that escaped the scene in direction `w`.
    pub fn infinite_le(&self, origin: Vec3A, w: Vec3A) -> Color {
        match self {
            Light::UniformInfinite(l) => l.radiance,
            Light::ImageInfinite(l) => l.le(origin, w),
            Light::Dome(l) => l.le(w),
            Light::Point(_)
            | Light::Spot(_)
            | Light::Goniometric(_)
            | Light::Projection(_)
            | Light::Distant(_)
            | Light::Triangle(_)
            | Light::Sphere(_)
            | Light::Quadric(_)
            | Light::VolumeTriangle(_)
            | Light::VolumeSphere(_)
            | Light::VolumeQuadric(_)
            | Light::Medium(_) => Color::ZERO,
        }
    }

    /// Samples a point or direction on the light from `p`; returns the sample (None where
    /// the light sends nothing towards `p`) and the rays traced to find it.
    /// Samples a point of the light seen from `p`: its radiance, and the rays traced to
    /// find it. The radiance is RGB (see [`Scene::light_radiance`](crate::scene::Scene::light_radiance)),
    /// except an emissive medium's and a VolumeLight's, at `ctx`'s wavelengths for a
    /// spectral path (a temperature's blackbody is no RGB colour; a VolumeLight's interior
    /// absorbs per wavelength).
    pub fn sample(&self, ctx: &LightContext, p: Vec3A, u: Vec2) -> (Option<LightSample>, u64) {
        match self {
            Light::Point(l) => (l.sample(p), 0),
            Light::Spot(l) => (l.sample(p), 0),
            Light::Goniometric(l) => (l.sample(p), 0),
            Light::Projection(l) => (l.sample(p), 0),
            Light::Distant(l) => (l.sample(), 0),
            Light::Triangle(l) => (seen_if(l.sample(ctx.geometry, p, u), l.invisible), 0),
            Light::Sphere(l) => (seen_if(l.sample(ctx.geometry, p, u), l.invisible), 0),
            Light::Quadric(l) => (seen_if(l.sample(ctx.geometry, p, u), l.invisible), 0),
            Light::VolumeTriangle(l) => l.sample(ctx, p, u),
            Light::VolumeSphere(l) => l.sample(ctx, p, u),
            Light::VolumeQuadric(l) => l.sample(ctx, p, u),
            Light::Medium(l) => (l.sample(ctx, p, u), 0),
            Light::UniformInfinite(l) => (l.sample(u), 0),
            Light::ImageInfinite(l) => (l.sample(p, u), 0),
            Light::Dome(l) => (l.sample(u), 0),
        }
    }

    /// The density with which choosing this light with probability `pmf` and sampling it
    /// from `p` gives direction `wi` towards the point `q` (normal `n`) on it: per unit
    /// solid angle (and length, for a medium); 0 for delta lights; `q` and `n` are unused
    /// for lights at infinity.
    pub fn pdf(
        &self,
        ctx: &LightContext,
        pmf: f32,
        p: Vec3A,
        wi: Vec3A,
        q: Vec3A,
        n: Vec3A,
    ) -> f32 {
        match self {
            Light::Point(_)
            | Light::Spot(_)
            | Light::Goniometric(_)
            | Light::Projection(_)
            | Light::Distant(_) => 0.0,
            Light::Triangle(l) => pmf * l.pdf(p, wi, q, n),
            Light::Sphere(l) => pmf * l.pdf(p, wi, q, n),
            Light::Quadric(l) => pmf * l.pdf(ctx.geometry, p, wi, q),
            Light::VolumeTriangle(l) => pmf * l.pdf(p, wi, q, n),
            Light::VolumeSphere(l) => pmf * l.pdf(p, wi, q, n),
            Light::VolumeQuadric(l) => pmf * l.pdf(ctx, p, wi, q),
            Light::Medium(l) => l.pdf(ctx, pmf, p, q),
            Light::UniformInfinite(l) => pmf * l.pdf(),
            Light::ImageInfinite(l) => pmf * l.pdf(p, wi),
            Light::Dome(l) => pmf * l.pdf(wi),
        }
    }

    /// A ray leaving the light, for photon tracing: a point and direction drawn from two 2D
    /// samples and one 1D sample, with the flux it carries (emitted radiance times cosine
    /// over the density of the point and direction: each kind's photons together carry its
    /// power), and the rays traced to find it. Lights at infinity shine onto a disk as wide
    /// as `sphere`, the scene's bounding sphere. None where the sample emits nothing.
    pub fn emit(
        &self,
        ctx: &LightContext,
        sphere: SceneSphere,
        u: [Vec2; 2],
        uc: f32,
    ) -> (Option<EmittedRay>, u64) {
        match self {
            Light::Point(l) => (point_emission(l.position, u[0], |p| l.sample(p)), 0),
            Light::Spot(l) => (l.emit(u[0]), 0),
            Light::Goniometric(l) => (point_emission(l.position, u[0], |p| l.sample(p)), 0),
            Light::Projection(l) => (point_emission(l.position, u[0], |p| l.sample(p)), 0),
            Light::Distant(l) => (Some(sphere.parallel(l.direction, u[0], l.radiance)), 0),
            Light::Triangle(l) => (l.emission_point(ctx.geometry, u[0]).emit(u[1], uc), 0),
            Light::Sphere(l) => (l.emission_point(ctx.geometry, u[0]).emit(u[1], uc), 0),
            Light::Quadric(l) => (l.emission_point(ctx.geometry, u[0]).emit(u[1], uc), 0),
            Light::VolumeTriangle(l) => l.emit(ctx, u),
            Light::VolumeSphere(l) => l.emit(ctx, u),
            Light::VolumeQuadric(l) => l.emit(ctx, u),
            Light::Medium(l) => (l.emit(ctx, u, uc), 0),
            Light::UniformInfinite(l) => (at_infinity(sphere, l.sample(u[0]), u[1]), 0),
            Light::ImageInfinite(l) => (at_infinity(sphere, l.sample_direction(u[0]), u[1]), 0),
            Light::Dome(l) => (at_infinity(sphere, l.sample(u[0]), u[1]), 0),
        }
    }
}

/// A ray that leaves a light, for photon tracing (see [`Light::emit`]).
#[derive(Debug, Clone, Copy)]
pub struct EmittedRay {
    pub origin: Vec3A,
    pub dir: Vec3A,
    /// The normal of the surface it leaves, on the side it leaves by (zero for points, media
    /// and lights at infinity).
    pub n: Vec3A,
    /// Flux: radiance times cosine over the sample's density.
    pub flux: Color,
}

/// The scene's bounding sphere.
#[derive(Debug, Clone, Copy)]
pub struct SceneSphere {
    pub center: Vec3A,
    pub radius: f32,
}

impl SceneSphere {
    /// A ray of a parallel beam arriving from direction `wi` (towards the light) with
    /// `radiance`: from a uniform point of the disk that covers the sphere, across it.
    fn parallel(&self, wi: Vec3A, u: Vec2, radiance: Color) -> EmittedRay {
        let frame = Frame::from_z(wi);
        let d = crate::sampling::concentric_disk(u) * self.radius;
        let origin = self.center + wi * self.radius + frame.x * d.x + frame.y * d.y;
        EmittedRay {
            origin,
            dir: -wi,
            n: Vec3A::ZERO,
            flux: radiance * (std::f32::consts::PI * self.radius * self.radius),
        }
    }
}

/// A photon from a light at infinity: its sampled direction, then a parallel beam.
fn at_infinity(sphere: SceneSphere, s: Option<LightSample>, u: Vec2) -> Option<EmittedRay> {
    let s = s.filter(|s| s.pdf > 0.0 && s.radiance != Color::ZERO)?;
    Some(sphere.parallel(s.wi, u, s.radiance / s.pdf))
}

/// A photon from a point light, in a uniform direction; `sample` is the light's own sampling
/// from a reference point, here one unit away, which gives the intensity that way.
fn point_emission(
    position: Vec3A,
    u: Vec2,
    sample: impl Fn(Vec3A) -> Option<LightSample>,
) -> Option<EmittedRay> {
    let dir = crate::sampling::uniform_sphere(u);
    let intensity = sample(position + dir)?.radiance;
    (intensity != Color::ZERO).then(|| EmittedRay {
        origin: position,
        dir,
        n: Vec3A::ZERO,
        flux: intensity * (4.0 * std::f32::consts::PI),
    })
}
