//! A scene ready to render: world-space geometry in BVHs, materials, lights and the light
//! sampler, media, camera and filter. [`Scene::build`] (in [`build`]) turns a
//! [`kiln_scene::SceneDescription`] into one; integrators then only read it.
//!
//! The scene knows nothing of integrators or their pre-passes (photon maps live in the
//! integrator's `Prepass`), and nothing of files.

mod build;

pub use build::{BuildError, MediaPolicy};

use crate::bsdfs::{Bsdf, DielectricBxdf, TrowbridgeReitz};
use crate::camera::Camera;
use crate::filter::Filter;
use crate::lights::{Light, LightContext, LightSampler, VolumeInterior};
use crate::materials::{Material, Model};
use crate::math::{Color, Ray};
use crate::media::Medium;
use crate::media::subsurface::{TexturedInterior, Walk};
use crate::nesting::{Crossing, NestedShape, Nesting};
use crate::sampling::TrackingRng;
use crate::shapes::{Geometry, SurfaceHit};
use crate::spectral::{LightSpectrum, Wavelengths};
use crate::textures::TextureEvalContext;
use crate::work::Work;
use glam::Vec3A;
use std::sync::Arc;

/// A scene ready to trace.
pub struct Scene {
    pub geometry: Geometry,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Chooses the light to sample from a shading point.
    pub light_sampler: LightSampler,
    /// Lights at infinity, whose radiance escaped rays collect.
    pub infinite_lights: Vec<u32>,
    pub camera: Camera,
    pub filter: Filter,
    /// The film's pixel sensor (ISO, clamp, white balance).
    pub sensor: crate::sensor::Sensor,
    pub resolution: (u32, u32),
    /// The camera's shutter interval: each camera sample's time lies in it.
    pub shutter: [f32; 2],
    /// Some shape moves over the shutter (motion blur).
    pub has_motion: bool,
    /// Radius of the scene's bounding sphere.
    pub radius: f32,
    /// The interiors of VolumeLights, referred to by `SurfaceInfo::volume`.
    pub volumes: Vec<VolumeInterior>,
    /// Participating media, referred to by `SurfaceInfo::media`.
    pub media: Vec<Medium>,
    pub camera_medium: Option<u32>,
    /// The light of each medium that is one (an emissive grid).
    pub medium_lights: Vec<Option<u32>>,
    /// The media on either side of each area light's surface (inside, outside), by light
    /// index; for photons leaving it.
    pub light_media: Vec<Option<[u32; 2]>>,
    /// For a spectral render, the spectrum of each light whose emission was given as one (a
    /// blackbody, a scene's spectrum), by light index; None: its RGB's illuminant spectrum.
    pub light_spectra: Vec<Option<Arc<LightSpectrum>>>,
    /// Nested dielectric shapes, referred to by `SurfaceInfo::nest`.
    pub nested: Vec<NestedShape>,
    /// Media from this index on are the interiors of "subsurface" materials: random walks,
    /// which photon maps neither store photons in nor shortcut with gathers.
    pub first_walk_medium: u32,
    /// For each subsurface interior (from `first_walk_medium` on), the texture its walks take
    /// their coefficients from where they enter, if its reflectance is textured.
    pub walk_textures: Vec<Option<TexturedInterior>>,
    /// Whether paths sample lights at the scattering events of subsurface walks. A shadow ray
    /// from inside a walk reaches only what lies inside its shape, as the shape's dielectric
    /// surface blocks it: a light there is found as well by the walk's own scattering, unless
    /// it is a light at a point, which no ray can hit. Without such lights the walk samples
    /// none, and counts the emission its scattering finds in full.
    pub walk_samples_lights: bool,
}

impl Scene {
    /// The BSDF of the surface at `hit`; None for an interface. A textured material is
    /// evaluated with the hit's footprint as the camera sees it, scaled by `footprint`; a
    /// bump or normal map replaces the hit's shading normal and dp/du. With `waves`, its
    /// colours are spectra at those wavelengths.
    pub fn bsdf(
        &self,
        hit: &mut SurfaceHit,
        footprint: f32,
        waves: Option<&Wavelengths>,
    ) -> Option<Bsdf<'_>> {
        let mut material = &self.materials[hit.surface.material as usize];
        let mut ctx = if material.is_textured() {
            let (dpdx, dpdy) = self.camera.approximate_dp_dxy(hit.p, hit.ng, footprint);
            TextureEvalContext::with_footprint(
                hit.p, hit.ng, hit.uv, hit.dpdu, hit.dpdv, dpdx, dpdy,
            )
        } else {
            TextureEvalContext::default()
        };
        ctx.waves = waves.copied();
        // A mix material stands for one of two materials at each point (mixes may nest;
        // they refer only to materials defined before them, so this ends).
        while let Model::Mix(mix) = &material.model {
            material = &self.materials[mix.choose(&ctx) as usize];
        }
        material.normal.apply(hit, &ctx);
        material.bsdf(&ctx)
    }

    /// Whether medium `m` is a subsurface material's interior (see `first_walk_medium`).
    pub fn is_walk_medium(&self, m: u32) -> bool {
        m >= self.first_walk_medium
    }

    /// Notes that a path at `hit` leaving along `wi` went from medium `before` into `after`.
    /// Out of every subsurface interior, its walk's count starts afresh. Entering an interior
    /// whose reflectance is a texture through its own surface, the walk takes the
    /// coefficients the texture gives there. (Entering it some other way, out of a shape
    /// nested inside it, the walk crosses the interior's untextured stand-in.)
    #[inline]
    pub fn enter_walk(
        &self,
        hit: &SurfaceHit,
        wi: Vec3A,
        before: Option<u32>,
        after: Option<u32>,
        walk: &mut Walk,
    ) {
        if before == after {
            return;
        }
        let Some(m) = after.filter(|&m| self.is_walk_medium(m)) else {
            walk.left();
            return;
        };
        if self.walk_textures.is_empty() {
            return;
        }
        let through_own_surface = hit.surface.medium_towards(wi, hit.ng) == Some(Some(m));
        let textured = self.walk_textures[(m - self.first_walk_medium) as usize].as_ref();
        walk.set(
            m,
            textured.filter(|_| through_own_surface).map(|t| {
                t.at(&TextureEvalContext::with_footprint(
                    hit.p,
                    hit.ng,
                    hit.uv,
                    hit.dpdu,
                    hit.dpdv,
                    Vec3A::ZERO,
                    Vec3A::ZERO,
                ))
            }),
        );
    }

    /// What lights need of the scene to be sampled and evaluated.
    pub fn light_context(&self) -> LightContext<'_> {
        LightContext {
            geometry: &self.geometry,
            volumes: &self.volumes,
            media: &self.media,
            waves: None,
        }
    }

    /// The emission of light `light` whose RGB is `rgb`, at a spectral path's `waves`: the
    /// light's own spectrum where it was given one, otherwise its RGB's illuminant spectrum;
    /// an emissive medium's and a VolumeLight's are spectral already (they were given the
    /// wavelengths). `rgb` itself in RGB.
    pub fn light_radiance(&self, light: u32, rgb: Color, waves: Option<&Wavelengths>) -> Color {
        let Some(w) = waves else {
            return rgb;
        };
        match (
            &self.lights[light as usize],
            &self.light_spectra[light as usize],
        ) {
            (
                Light::Medium(_)
                | Light::VolumeTriangle(_)
                | Light::VolumeSphere(_)
                | Light::VolumeQuadric(_),
                _,
            ) => rgb,
            (_, Some(s)) => s.at(w, rgb),
            (_, None) => w.illuminant(rgb),
        }
    }

    /// [`Scene::light_context`] for a path at `waves` (None: RGB).
    pub fn light_context_at<'a>(&'a self, waves: Option<&'a Wavelengths>) -> LightContext<'a> {
        LightContext {
            waves,
            ..self.light_context()
        }
    }

    /// The density with which the light sampler chooses light `light` from `p` (shading
    /// normal `ns`, zero in a medium) and samples direction `wi` towards its point `q`
    /// (normal `n`): what multiple importance sampling weighs emission found by BSDF or
    /// phase sampling against.
    pub fn light_pdf(&self, light: u32, p: Vec3A, ns: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        let pmf = self.light_sampler.pmf(p, ns, light as usize);
        self.lights[light as usize].pdf(&self.light_context(), pmf, p, wi, q, n)
    }

    /// Transmittance along `ray` (at its time) over `tmax`, starting in `medium`, through
    /// media and the interface surfaces that bound them; zero if any other surface blocks it.
    /// Also returns the medium the segment ends in. Grid media are crossed by ratio
    /// tracking, with numbers from `rng`.
    pub fn transmittance(
        &self,
        ray: Ray,
        tmax: f32,
        mut medium: Option<u32>,
        rng: &mut TrackingRng,
        work: &mut Work,
        waves: Option<&Wavelengths>,
    ) -> (Color, Option<u32>) {
        let Ray {
            origin, dir, time, ..
        } = ray;
        if self.media.is_empty() {
            work.rays += 1;
            let tr = if self.geometry.unoccluded(origin, dir, tmax, time) {
                Color::ONE
            } else {
                Color::ZERO
            };
            return (tr, None);
        }
        let mut tr = Color::ONE;
        let mut o = origin;
        let mut remaining = tmax;
        for _ in 0..64 {
            work.rays += 1;
            let hit = self
                .geometry
                .intersect(&Ray::at_time(o, dir, time), remaining);
            let seg = hit.as_ref().map_or(remaining, |h| h.t);
            if let Some(m) = medium {
                let Some(t) = self.media[m as usize].transmittance(o, dir, seg, rng, waves) else {
                    work.cut_walks += 1;
                    return (Color::ZERO, medium);
                };
                tr *= t;
                if tr == Color::ZERO {
                    return (tr, medium);
                }
            }
            let Some(h) = hit else {
                return (tr, medium);
            };
            if !self.materials[h.surface.material as usize].is_interface() {
                return (Color::ZERO, medium);
            }
            // An interface: cross it into the medium on its other side.
            if let Some(next) = h.surface.medium_towards(dir, h.ng) {
                medium = next;
            }
            o = h.origin_towards(dir);
            remaining -= h.t;
        }
        (Color::ZERO, medium)
    }
}

impl Scene {
    /// The BSDF at `hit` for a ray arriving along `dir` inside the nested shapes of
    /// `nesting`: as [`Scene::bsdf`] gives it, but on a nested shape's surface none where
    /// the boundary is hidden (the ray goes straight on), and a dielectric of the relative
    /// index where it is true.
    #[inline]
    pub fn bsdf_nested(
        &self,
        hit: &mut SurfaceHit,
        footprint: f32,
        waves: Option<&Wavelengths>,
        nesting: &Nesting,
        dir: Vec3A,
    ) -> Option<Bsdf<'_>> {
        match hit.surface.nest {
            None => self.bsdf(hit, footprint, waves),
            Some(id) => self.nested_bsdf(id, hit, footprint, waves, nesting, dir),
        }
    }

    /// [`Scene::bsdf_nested`] on nested shape `id`'s surface.
    #[inline(never)]
    fn nested_bsdf(
        &self,
        id: u32,
        hit: &mut SurfaceHit,
        footprint: f32,
        waves: Option<&Wavelengths>,
        nesting: &Nesting,
        dir: Vec3A,
    ) -> Option<Bsdf<'_>> {
        match nesting.crossing(&self.nested, id, hit, dir) {
            Crossing::Through => None,
            Crossing::Interface { eta } => match self.bsdf(hit, footprint, waves) {
                Some(Bsdf::Dielectric(d)) => Some(Bsdf::Dielectric(DielectricBxdf { eta, ..d })),
                // An interface between media of different indices refracts, smoothly.
                _ => Some(Bsdf::Dielectric(DielectricBxdf {
                    eta,
                    distrib: TrowbridgeReitz::new(0.0, 0.0),
                    dispersive: false,
                })),
            },
        }
    }
}
