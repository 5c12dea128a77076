//! The path tracer: next-event estimation with multiple importance sampling,
//! Russian roulette, and the light sampler's power-proportional choice.
//!
//! [`Integrator`] is the seam where other estimators slot in: a volumetric
//! path tracer becomes another variant, and a per-job pre-pass (a photon map)
//! becomes data the variant owns, built once before any tile renders.

use crate::bsdf::Bsdf;
use crate::geometry::SurfaceHit;
use crate::math::{Color, Frame, Ray, offset_origin};
use crate::sampler::PixelSampler;
use crate::sampling::power_heuristic;
use crate::scene::Scene;
use glam::Vec3A;
use kiln_scene::LightStrategy;

/// Settings of the path tracer that change the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSettings {
    /// pbrt's maxdepth: 1 is direct lighting only.
    pub max_depth: u32,
    /// The first bounce after which Russian roulette may end a path.
    pub rr_depth: u32,
    pub strategy: LightStrategy,
    /// Clamp each sample's radiance to this maximum component (0 disables it).
    pub max_radiance: f32,
}

/// Where each bounce's sample dimensions start: 4 for the film and lens, then 8 per bounce.
const CAMERA_DIMENSIONS: u32 = 4;
const DIMENSIONS_PER_BOUNCE: u32 = 8;

/// The estimator used for every camera ray of a render.
#[derive(Debug, Clone)]
pub enum Integrator {
    Path(PathSettings),
}

impl Integrator {
    /// Radiance arriving along `ray`; `rays` counts the rays traced.
    pub fn li(&self, scene: &Scene, ray: Ray, sampler: &mut PixelSampler, rays: &mut u64) -> Color {
        match self {
            Integrator::Path(settings) => path_li(scene, settings, ray, sampler, rays),
        }
    }
}

fn emission_weight(
    settings: &PathSettings,
    first_or_specular: bool,
    bsdf_pdf: f32,
    light_pdf: impl FnOnce() -> f32,
) -> f32 {
    if first_or_specular {
        return 1.0;
    }
    match settings.strategy {
        LightStrategy::BsdfOnly => 1.0,
        LightStrategy::LightOnly => 0.0,
        LightStrategy::Mis => power_heuristic(bsdf_pdf, light_pdf()),
    }
}

fn path_li(
    scene: &Scene,
    settings: &PathSettings,
    mut ray: Ray,
    sampler: &mut PixelSampler,
    rays: &mut u64,
) -> Color {
    let mut l = Color::ZERO;
    let mut beta = Color::ONE;
    let mut eta_scale = 1.0f32;
    let mut depth = 0u32;
    // What the previous bounce knew, for weighting emission found by BSDF sampling.
    let mut first_or_specular = true;
    let mut prev_p = ray.origin;
    let mut prev_pdf = 0.0f32;
    let mut pass_throughs = 0;
    // The VolumeLight whose interior the path is in, and whether the current segment's
    // emission is still to be counted (it is not on the first segment after entering:
    // the entry hit already counted it as the light's surface emission).
    let mut inside: Option<(u32, bool)> = None;
    loop {
        *rays += 1;
        let found = scene.geometry.intersect(&ray, f32::INFINITY);
        if let Some((volume, count)) = inside {
            let emitter = &scene.volumes[volume as usize];
            let t = found.as_ref().map_or(0.0, |h| h.t);
            if count {
                l += beta * emitter.segment(ray.origin, ray.dir, t);
            }
            beta *= emitter.transmittance(t);
            if found.is_none() {
                // Only rounding lets a ray out of a closed shape without a hit.
                inside = None;
            }
        }
        let Some(hit) = found else {
            for &i in &scene.infinite_lights {
                let light = &scene.lights[i as usize];
                let le = light.infinite_le(ray.dir);
                if le != Color::ZERO {
                    let w = emission_weight(settings, first_or_specular, prev_pdf, || {
                        scene.light_sampler.pmf(i as usize)
                            * light.pdf(prev_p, ray.dir, Vec3A::ZERO, Vec3A::ZERO)
                    });
                    l += beta * le * w;
                }
            }
            break;
        };
        if let (Some(volume), Some(light_id)) = (hit.surface.volume, hit.light) {
            // A VolumeLight seen from outside emits what its interior sends through the surface.
            if ray.dir.dot(hit.ng) < 0.0 {
                let (le, traced) = scene.volume_le(volume, hit.p, hit.ng, hit.ns, -ray.dir);
                *rays += traced;
                if le != Color::ZERO {
                    let light = &scene.lights[light_id as usize];
                    let w = emission_weight(settings, first_or_specular, prev_pdf, || {
                        scene.light_sampler.pmf(light_id as usize)
                            * light.pdf(prev_p, ray.dir, hit.p, hit.ng)
                    });
                    l += beta * le * w;
                }
            }
        } else if let Some(light_id) = hit.light {
            let light = &scene.lights[light_id as usize];
            let le = light.area_le(hit.ng, -ray.dir);
            if le != Color::ZERO {
                let w = emission_weight(settings, first_or_specular, prev_pdf, || {
                    scene.light_sampler.pmf(light_id as usize)
                        * light.pdf(prev_p, ray.dir, hit.p, hit.ng)
                });
                l += beta * le * w;
            }
        }
        let Some(bsdf) = scene.materials[hit.surface.material as usize].bsdf() else {
            // An interface: continue straight through without counting a bounce.
            pass_throughs += 1;
            if pass_throughs > 256 {
                break;
            }
            ray = Ray::new(offset_origin(hit.p, hit.ng, ray.dir), ray.dir);
            continue;
        };
        if depth == settings.max_depth || bsdf.is_black() {
            break;
        }
        depth += 1;
        let frame = Frame::new(hit.ns, hit.dpdu);
        let wo = frame.to_local(-ray.dir);
        let base = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * (depth - 1);
        sampler.set_dimension(base);
        if !bsdf.is_specular()
            && settings.strategy != LightStrategy::BsdfOnly
            && !scene.light_sampler.is_empty()
        {
            l += beta * sample_direct(scene, settings, bsdf, &hit, &frame, wo, sampler, rays);
        }
        sampler.set_dimension(base + 3);
        let uc = sampler.get_1d();
        let u = sampler.get_2d();
        let Some(bs) = bsdf.sample(wo, uc, u) else {
            break;
        };
        let wi = frame.to_world(bs.wi);
        beta *= bs.f * wi.dot(hit.ns).abs() / bs.pdf;
        if !beta.is_finite() || beta == Color::ZERO {
            break;
        }
        first_or_specular = bs.specular;
        prev_pdf = bs.pdf;
        prev_p = hit.p;
        if bs.eta != 1.0 {
            eta_scale *= bs.eta * bs.eta;
        }
        ray = Ray::new(offset_origin(hit.p, hit.ng, wi), wi);
        if let Some(volume) = hit.surface.volume {
            inside = if wi.dot(hit.ng) < 0.0 {
                // Entering (not counted again) or reflecting inside (counted).
                let entering = inside.is_none();
                Some((volume, !entering))
            } else {
                None
            };
        } else if let Some((volume, _)) = inside {
            // Scattered off something inside the shape: the next segment emits too.
            inside = Some((volume, true));
        }
        // Russian roulette, on throughput with the radiance scaling of refraction undone.
        let rr = (beta * eta_scale).max_element();
        if rr < 1.0 && depth >= settings.rr_depth {
            let q = (1.0 - rr).max(0.05);
            if sampler.get_1d() < q {
                break;
            }
            beta /= 1.0 - q;
        }
    }
    l
}

/// One light sample for next-event estimation from `hit`.
#[allow(clippy::too_many_arguments)]
fn sample_direct(
    scene: &Scene,
    settings: &PathSettings,
    bsdf: &Bsdf,
    hit: &SurfaceHit,
    frame: &Frame,
    wo: Vec3A,
    sampler: &mut PixelSampler,
    rays: &mut u64,
) -> Color {
    let u_light = sampler.get_1d();
    let u = sampler.get_2d();
    let Some((index, pmf)) = scene.light_sampler.sample(u_light) else {
        return Color::ZERO;
    };
    let (sample, traced) = scene.sample_light(index, hit.p, u);
    *rays += traced;
    let Some(ls) = sample else {
        return Color::ZERO;
    };
    if ls.pdf <= 0.0 || ls.radiance == Color::ZERO {
        return Color::ZERO;
    }
    let wi_local = frame.to_local(ls.wi);
    let f = bsdf.f(wo, wi_local) * ls.wi.dot(hit.ns).abs();
    if f == Color::ZERO {
        return Color::ZERO;
    }
    let origin = offset_origin(hit.p, hit.ng, ls.wi);
    *rays += 1;
    let visible = if ls.distance.is_finite() {
        // Aim at the light's point moved off its surface towards us, and stop short of it:
        // following ls.wi for the full distance would graze the light's own surface.
        let target = offset_origin(hit.p + ls.wi * ls.distance, ls.n, -ls.wi);
        let d = target - origin;
        let len = d.length();
        len > 0.0
            && scene
                .geometry
                .unoccluded(origin, d / len, len * (1.0 - 1e-4))
    } else {
        scene.geometry.unoccluded(origin, ls.wi, f32::INFINITY)
    };
    if !visible {
        return Color::ZERO;
    }
    let light_pdf = pmf * ls.pdf;
    if ls.delta {
        return f * ls.radiance / light_pdf;
    }
    let w = match settings.strategy {
        LightStrategy::Mis => power_heuristic(light_pdf, bsdf.pdf(wo, wi_local)),
        _ => 1.0,
    };
    f * ls.radiance * (w / light_pdf)
}
