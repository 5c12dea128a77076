//! A path's segment through a participating medium: free-flight sampling up to the surface
//! it reaches, the medium's emission on the way, and a scattering event if one happens
//! (the photons' gather, a light sample, the phase function's next direction).

use super::super::direct::{Vertex, light_sample};
use super::super::{CAMERA_DIMENSIONS, DIMENSIONS_PER_BOUNCE};
use super::{Next, PathContext, PathState};
use crate::features::Feature;
use crate::math::{Color, Ray};
use crate::media::{Emitted, MediumEvent};
use crate::sampling::{PixelSampler, TrackingRng};
use crate::shapes::SurfaceHit;
use crate::work::Work;
use glam::Vec3A;
use kiln_scene::LightStrategy;

/// Free-flight sampling through the medium the ray is in, up to the surface `found` (or
/// infinity): the medium's emission on the way, and a scattering event if one happens.
pub(super) fn medium_step(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    found: Option<&SurfaceHit>,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let Some(m) = state.travel.medium else {
        return Next::Surface;
    };
    let t = match track(ctx, state, ray, m, found, sampler) {
        MediumEvent::Crossed => return Next::Surface,
        MediumEvent::Absorbed => return Next::Stop,
        MediumEvent::CutOff => {
            work.cut_walks += 1;
            return Next::Stop;
        }
        MediumEvent::Scattered(t) => t,
    };
    scatter(ctx, state, ray, m, t, sampler, work)
}

/// Tracks the segment through medium `m`: its emission (weighted against sampling the
/// medium as a light from the previous vertex) and absorption, and where it ends.
fn track(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &Ray,
    m: u32,
    found: Option<&SurfaceHit>,
    sampler: &mut PixelSampler,
) -> MediumEvent {
    let (scene, settings) = (ctx.scene, ctx.settings);
    let med = state.travel.walk.medium(&scene.media, m);
    let t_max = found.map_or(f32::INFINITY, |h| h.t);
    // Each bounce's tracking numbers are seeded from its unused eighth dimension.
    let seed_dim = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * state.vertices + 7;
    state.travel.segments += 1;
    let mut rng = TrackingRng::new(
        ((sampler.value(seed_dim).to_bits() as u64) << 32) | state.travel.segments as u64,
    );
    // Emission met at a tentative collision could also have been found by sampling the
    // medium as a light from the previous vertex.
    let light = scene.medium_lights[m as usize];
    let prev = &state.prev;
    // As in pbrt-v4, the segment after the last scattering (maxdepth) counts no emission;
    // nor does a segment reached through specular bounces from a vertex that gathered
    // caustic photons (the emissive media's photons counted it there).
    let counts = state.depth < settings.max_depth && !state.gather.after_caustic_gather();
    let l = &mut state.l;
    let waves = ctx.waves.as_ref();
    let (beta, lane_pdfs) = (&mut state.beta, &mut state.travel.lane_pdfs);
    med.sample_interaction(ray, t_max, &mut rng, beta, lane_pdfs, waves, |e| match e {
        _ if !counts => {}
        Emitted::Segment(c) => *l += c,
        Emitted::Collision {
            t,
            sigma_maj,
            radiance,
        } => {
            let x = ray.at(t);
            let w = match light {
                None => 1.0,
                Some(light) => {
                    prev.emission_weight(ctx, light, prev.pdf * sigma_maj, ray.dir, x, Vec3A::ZERO)
                }
            };
            *l += radiance * (w / sigma_maj);
        }
    })
}

/// A scattering event at distance `t` in medium `m` (an event of a subsurface walk, or a
/// bounce): the photons' gather, a light sample, and the phase function's next direction.
fn scatter(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    m: u32,
    t: f32,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let (scene, settings) = (ctx.scene, ctx.settings);
    let in_walk = scene.is_walk_medium(m);
    if in_walk {
        if !state.travel.walk.take_event(settings.walk_depth) {
            return Next::Stop;
        }
        state.gather.walked();
    } else {
        if state.depth == settings.max_depth || state.gather.ending {
            return Next::Stop;
        }
        state.depth += 1;
    }
    state.vertices += 1;
    let med = state.travel.walk.medium(&scene.media, m);
    let p = ray.at(t);
    if state.feature.is_none() {
        // Scattering in a medium before any non-specular surface: what the path carries
        // (the medium's albedo among it), facing where it came from.
        state.feature = Some(Feature {
            albedo: super::surface::reflectance_rgb(state.beta.min(Color::ONE), ctx.waves.as_ref()),
            normal: -ray.dir.normalize_or_zero(),
            depth: state.travelled + (p - ray.origin).length(),
        });
    }
    let phase = med.phase();
    let wo = -ray.dir;
    // (Not inside a subsurface material: its random walk goes on as a path.)
    if !in_walk && let Some(gathered) = state.gather.in_medium(ctx, med, phase, p, wo, state.beta) {
        state.l += gathered;
    }
    let base = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * (state.vertices - 1);
    sampler.set_dimension(base);
    let samples_lights = !in_walk || scene.walk_samples_lights;
    if samples_lights
        && settings.strategy != LightStrategy::BsdfOnly
        && !scene.light_sampler.is_empty()
    {
        let v = Vertex {
            p,
            surface: None,
            medium: state.travel.medium,
            time: ray.time,
            last: state.depth == settings.max_depth,
            waves: ctx.waves.as_ref(),
        };
        let direct = light_sample(
            scene,
            settings,
            &v,
            |wi| Color::splat(phase.p(wo, wi)),
            |wi| phase.p(wo, wi),
            sampler,
            work,
        );
        state.add_direct(direct);
    }
    sampler.set_dimension(base + 4);
    let (wi, pdf) = phase.sample(wo, sampler.get_2d());
    // Phase functions are sampled exactly: the value over the pdf is 1. (Emission found
    // from a vertex that sampled no light counts in full, as after a specular bounce.)
    state.prev.first_or_specular = !samples_lights;
    state.prev.any_non_specular = true;
    state.prev.pdf = pdf;
    state.prev.p = p;
    state.prev.n = Vec3A::ZERO;
    *ray = ray.spawn(p, wi);
    state.interior.scattered();
    state.roulette(settings, sampler)
}
