//! The path tracer: next-event estimation with multiple importance sampling,
//! Russian roulette, and the light sampler's power-proportional choice.
//!
//! [`Integrator`] is the seam where other estimators slot in: a volumetric
//! path tracer becomes another variant, and a per-job pre-pass (a photon map)
//! becomes data the variant owns, built once before any tile renders.

use crate::geometry::SurfaceHit;
use crate::lights::Light;
use crate::math::{Color, Frame, Ray, offset_origin};
use crate::media::{Medium, MediumEvent, TrackingRng};
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
    // The participating medium the ray travels in, and how many medium segments so far
    // (each gets its own tracking numbers).
    let mut medium = scene.camera_medium;
    let mut segments = 0u32;
    // With caustic photon maps: specular bounces since the last vertex that gathered
    // photons (None before the first).
    let mut specular_since_gather: Option<u32> = None;
    loop {
        *rays += 1;
        let found = scene.geometry.intersect(&ray, f32::INFINITY);
        if let Some(m) = medium {
            let med = &scene.media[m as usize];
            let t_max = found.as_ref().map_or(f32::INFINITY, |h| h.t);
            // Each bounce's tracking numbers are seeded from its unused eighth dimension.
            let seed_dim = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * depth + 7;
            segments += 1;
            let mut rng = TrackingRng::new(
                ((sampler.value(seed_dim).to_bits() as u64) << 32) | segments as u64,
            );
            let event = match med {
                Medium::Grid(g) => {
                    // Emission met at a tentative collision could also have been found by
                    // sampling the medium as a light from the previous vertex.
                    let light = scene.medium_lights[m as usize];
                    let weight = |x: Vec3A, sigma_maj: f32| match light {
                        None => 1.0,
                        Some(light) => emission_weight(
                            settings,
                            first_or_specular,
                            prev_pdf * sigma_maj,
                            || {
                                scene.light_sampler.pmf(light as usize)
                                    * g.emission_pdf(x)
                                    * (x - prev_p).length_squared()
                            },
                        ),
                    };
                    med.sample_interaction(&ray, t_max, &mut rng, &mut beta, |t, sigma_maj, c| {
                        l += c * (weight(ray.at(t), sigma_maj) / sigma_maj)
                    })
                }
                Medium::Homogeneous { .. } => {
                    // The medium's own emission along the segment, in closed form; tracking
                    // then estimates only what is scattered into the ray and what lies beyond.
                    l += beta * med.segment_emission(t_max);
                    med.sample_interaction(&ray, t_max, &mut rng, &mut beta, |_, _, _| {})
                }
            };
            match event {
                MediumEvent::Crossed => {}
                MediumEvent::Absorbed => break,
                MediumEvent::Scattered(t) => {
                    if depth == settings.max_depth {
                        break;
                    }
                    depth += 1;
                    let p = ray.at(t);
                    let phase = med.phase();
                    let wo = -ray.dir;
                    if let Some(maps) = &scene.caustics {
                        // Caustic light scattered here, from the volume photon map; the
                        // throughput already holds sigma_s, the estimate divides it out.
                        let sigma_s = match med {
                            Medium::Grid(g) => g.sigma_s * g.density(g.to_box(p)),
                            Medium::Homogeneous { sigma_s, .. } => *sigma_s,
                        };
                        let lv = maps.volume_radiance(p, wo, |a, b| phase.p(a, b));
                        let inv = Color::select(
                            sigma_s.cmpgt(Color::ZERO),
                            Color::ONE / sigma_s,
                            Color::ZERO,
                        );
                        l += beta * lv * inv;
                        specular_since_gather = Some(0);
                    }
                    let base = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * (depth - 1);
                    sampler.set_dimension(base);
                    if settings.strategy != LightStrategy::BsdfOnly
                        && !scene.light_sampler.is_empty()
                    {
                        let v = Vertex {
                            p,
                            surface: None,
                            medium,
                        };
                        l += beta
                            * sample_direct(
                                scene,
                                settings,
                                &v,
                                |wi| Color::splat(phase.p(wo, wi)),
                                |wi| phase.p(wo, wi),
                                sampler,
                                rays,
                            );
                    }
                    sampler.set_dimension(base + 4);
                    let (wi, pdf) = phase.sample(wo, sampler.get_2d());
                    // HG is sampled exactly: the phase value over its pdf is 1.
                    first_or_specular = false;
                    prev_pdf = pdf;
                    prev_p = p;
                    ray = Ray::new(p, wi);
                    if let Some((volume, _)) = inside {
                        inside = Some((volume, true));
                    }
                    if !survives_roulette(&mut beta, eta_scale, depth, settings, sampler) {
                        break;
                    }
                    continue;
                }
            }
        }
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
        } else if let Some(light_id) = hit.light
            // Reached through specular bounces from a vertex that gathered caustic photons:
            // the photon map has already counted this light.
            && !matches!(specular_since_gather, Some(k) if k > 0)
        {
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
            if let Some(next) = hit.surface.medium_towards(ray.dir, hit.ng) {
                medium = next;
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
        if let Some(maps) = &scene.caustics {
            if bsdf.is_specular() {
                specular_since_gather = specular_since_gather.map(|k| k + 1);
            } else {
                // Caustic light reflected here, from the surface photon map.
                let side = if ray.dir.dot(hit.ns) < 0.0 {
                    hit.ns
                } else {
                    -hit.ns
                };
                l += beta * maps.surface_radiance(hit.p, side, |wi| bsdf.f(wo, frame.to_local(wi)));
                specular_since_gather = Some(0);
            }
        }
        let base = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * (depth - 1);
        sampler.set_dimension(base);
        if !bsdf.is_specular()
            && settings.strategy != LightStrategy::BsdfOnly
            && !scene.light_sampler.is_empty()
        {
            let v = Vertex {
                p: hit.p,
                surface: Some(&hit),
                medium,
            };
            let f = |wi: Vec3A| bsdf.f(wo, frame.to_local(wi)) * wi.dot(hit.ns).abs();
            let pdf = |wi: Vec3A| bsdf.pdf(wo, frame.to_local(wi));
            l += beta * sample_direct(scene, settings, &v, f, pdf, sampler, rays);
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
        if let Some(next) = hit.surface.medium_towards(wi, hit.ng) {
            medium = next;
        }
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
        if !survives_roulette(&mut beta, eta_scale, depth, settings, sampler) {
            break;
        }
    }
    l
}

/// Russian roulette from `settings.rr_depth` on, on the throughput with the radiance scaling
/// of refraction undone; false ends the path, and a survivor's throughput is scaled up.
fn survives_roulette(
    beta: &mut Color,
    eta_scale: f32,
    depth: u32,
    settings: &PathSettings,
    sampler: &mut PixelSampler,
) -> bool {
    let rr = (*beta * eta_scale).max_element();
    if rr < 1.0 && depth >= settings.rr_depth {
        let q = (1.0 - rr).max(0.05);
        if sampler.get_1d() < q {
            return false;
        }
        *beta /= 1.0 - q;
    }
    true
}

/// Where next-event estimation starts: a point, the surface it lies on (none inside a
/// medium), and the medium the path is in there.
struct Vertex<'a> {
    p: Vec3A,
    surface: Option<&'a SurfaceHit>,
    medium: Option<u32>,
}

impl Vertex<'_> {
    fn medium_towards(&self, dir: Vec3A) -> Option<u32> {
        match self.surface {
            Some(h) => h.surface.medium_towards(dir, h.ng).unwrap_or(self.medium),
            None => self.medium,
        }
    }
}

/// One light sample for next-event estimation from `v`; `f` is the scattering function
/// (times the cosine at surfaces) and `pdf` the density of sampling `wi` by it.
fn sample_direct(
    scene: &Scene,
    settings: &PathSettings,
    v: &Vertex,
    f: impl Fn(Vec3A) -> Color,
    pdf: impl Fn(Vec3A) -> f32,
    sampler: &mut PixelSampler,
    rays: &mut u64,
) -> Color {
    let u_light = sampler.get_1d();
    let u = sampler.get_2d();
    let Some((index, pmf)) = scene.light_sampler.sample(u_light) else {
        return Color::ZERO;
    };
    let (sample, traced) = scene.sample_light(index, v.p, u);
    *rays += traced;
    let Some(ls) = sample else {
        return Color::ZERO;
    };
    if ls.pdf <= 0.0 || ls.radiance == Color::ZERO {
        return Color::ZERO;
    }
    let f = f(ls.wi);
    if f == Color::ZERO {
        return Color::ZERO;
    }
    let origin = v.surface.map_or(v.p, |h| offset_origin(v.p, h.ng, ls.wi));
    let medium = v.medium_towards(ls.wi);
    let mut rng = TrackingRng::from_values(&[u_light, u.x, u.y], 2);
    let tr = if ls.distance.is_finite() {
        // Aim at the light's point moved off its surface towards us, and stop short of it:
        // following ls.wi for the full distance would graze the light's own surface.
        let target = if ls.n == Vec3A::ZERO {
            v.p + ls.wi * ls.distance
        } else {
            offset_origin(v.p + ls.wi * ls.distance, ls.n, -ls.wi)
        };
        let d = target - origin;
        let len = d.length();
        if len > 0.0 {
            scene.transmittance(origin, d / len, len * (1.0 - 1e-4), medium, &mut rng, rays)
        } else {
            (Color::ZERO, medium)
        }
    } else {
        scene.transmittance(origin, ls.wi, f32::INFINITY, medium, &mut rng, rays)
    };
    let (tr, end_medium) = tr;
    if tr == Color::ZERO {
        return Color::ZERO;
    }
    // A point sampled in a grid medium emits only if the medium fills it, that is if the
    // shadow ray arrives in that medium (the grid's box may reach beyond its boundary).
    // The other strategy would find it at a tentative collision, at the majorant's rate.
    let mut medium_rate = 1.0;
    if let Light::Medium { medium: lm, .. } = &scene.lights[index] {
        if end_medium != Some(*lm) {
            return Color::ZERO;
        }
        if let Medium::Grid(g) = &scene.media[*lm as usize] {
            medium_rate = g.majorant_at(g.to_box(v.p + ls.wi * ls.distance));
        }
    }
    let light_pdf = pmf * ls.pdf;
    if ls.delta {
        return f * tr * ls.radiance / light_pdf;
    }
    let w = match settings.strategy {
        LightStrategy::Mis => power_heuristic(light_pdf, pdf(ls.wi) * medium_rate),
        _ => 1.0,
    };
    f * tr * ls.radiance * (w / light_pdf)
}
