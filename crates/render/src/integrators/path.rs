//! The (volumetric) path tracer: next-event estimation with multiple importance sampling,
//! Russian roulette, free-flight sampling through media, VolumeLight interiors, and the
//! caustic photon maps' gathers.
//!
//! A path is a small state ([`PathState`]) advanced by one step per segment: through the
//! medium the segment crosses ([`medium_step`]), along a VolumeLight's interior, to the
//! surface it reaches ([`surface_emission`], then [`surface_step`]) or off to the lights at
//! infinity ([`escape`]).

use super::direct::{Vertex, emission_weight, sample_direct, survives_roulette};
use super::{CAMERA_DIMENSIONS, DIMENSIONS_PER_BOUNCE, PathSettings, Prepass, pass_through};
use crate::gbuffer::{RHO_SAMPLES, VisibleSurface, rho_sample};
use crate::math::{Color, Frame, Ray, offset_origin};
use crate::media::subsurface::Walk;
use crate::media::{Emitted, MediumEvent};
use crate::nesting::Nesting;
use crate::sampling::{PixelSampler, TrackingRng};
use crate::scene::Scene;
use crate::shapes::SurfaceHit;
use crate::work::Work;
use glam::Vec3A;
use kiln_scene::LightStrategy;

/// What a path tracer step needs besides the path.
pub(super) struct PathContext<'a> {
    pub scene: &'a Scene,
    pub settings: &'a PathSettings,
    pub prepass: &'a Prepass,
    /// The scale of the camera's pixel footprint for texture filtering.
    pub footprint: f32,
}

/// Everything a path carries from one segment to the next.
struct PathState {
    /// Radiance gathered so far.
    l: Color,
    /// Throughput.
    beta: Color,
    /// The radiance scaling of refractions so far, which Russian roulette undoes.
    eta_scale: f32,
    /// Bounces so far, towards maxdepth. A subsurface walk is one: the refraction that
    /// entered it counts, and its scatterings and reflections inside do not (see `walk`).
    depth: u32,
    /// Scattering vertices so far, a walk's included: what the sampler's dimensions,
    /// the tracking numbers and Russian roulette go by.
    vertices: u32,
    /// What the previous scattering vertex knew, for weighting emission found by BSDF or
    /// phase sampling: whether it was the camera or specular, where it was, and the
    /// density it sampled the current direction with.
    first_or_specular: bool,
    prev_p: Vec3A,
    /// The previous vertex's shading normal (zero in a medium), which the light sampler's
    /// choice depends on.
    prev_n: Vec3A,
    prev_pdf: f32,
    /// Some bounce so far scattered non-specularly (pbrt-v4's regularize waits for one).
    any_non_specular: bool,
    /// Interface surfaces crossed without scattering.
    pass_throughs: u32,
    /// The VolumeLight whose interior the path is in, and whether the current segment's
    /// emission is still to be counted (it is not on the first segment after entering: the
    /// entry hit already counted it as the light's surface emission).
    inside: Option<(u32, bool)>,
    /// The participating medium the ray travels in, and how many medium segments so far
    /// (each gets its own tracking numbers).
    medium: Option<u32>,
    /// The subsurface walk the path is on: its events (scatterings, and reflections off the
    /// inside of its surface, up to the integrator's `walk_depth`) and its coefficients
    /// where they came from a texture.
    walk: Walk,
    /// The nested dielectric shapes the ray is inside.
    nesting: Nesting,
    segments: u32,
    /// With caustic photon maps: specular bounces since the last vertex that gathered
    /// photons (None before the first).
    specular_since_gather: Option<u32>,
    /// The path gathered a volume photon map's estimate at its last vertex: its current
    /// segment only collects emission, and it ends at the next scattering.
    ending: bool,
    /// For a G-buffer: whether to note the first surface with a BSDF, and what it was.
    want_visible: bool,
    visible: Option<VisibleSurface>,
}

impl PathState {
    /// Whether the path reached its current segment through one or more specular bounces
    /// from a vertex that gathered caustic photons, which counted the light it would find.
    fn after_caustic_gather(&self) -> bool {
        matches!(self.specular_since_gather, Some(k) if k > 0)
    }

    /// Russian roulette after a scattering event: the path goes on, or stops.
    fn roulette(&mut self, settings: &PathSettings, sampler: &mut PixelSampler) -> Next {
        if survives_roulette(
            &mut self.beta,
            self.eta_scale,
            self.vertices,
            settings,
            sampler,
        ) {
            Next::Continue
        } else {
            Next::Stop
        }
    }
}

/// What the path does after a step.
enum Next {
    /// Trace the next segment.
    Continue,
    /// Go on to the surface the segment reached.
    Surface,
    /// The path ends.
    Stop,
}

/// Radiance arriving along `ray`; `work` counts what it cost.
pub(super) fn path_li(
    ctx: &PathContext,
    mut ray: Ray,
    sampler: &mut PixelSampler,
    work: &mut Work,
    visible: Option<&mut Option<VisibleSurface>>,
) -> Color {
    let mut state = PathState {
        l: Color::ZERO,
        beta: Color::ONE,
        eta_scale: 1.0,
        depth: 0,
        vertices: 0,
        first_or_specular: true,
        prev_p: ray.origin,
        prev_n: Vec3A::ZERO,
        prev_pdf: 0.0,
        any_non_specular: false,
        pass_throughs: 0,
        inside: None,
        medium: ctx.scene.camera_medium,
        walk: Walk::default(),
        nesting: Nesting::default(),
        segments: 0,
        specular_since_gather: None,
        ending: false,
        want_visible: visible.is_some(),
        visible: None,
    };
    loop {
        work.rays += 1;
        let found = ctx.scene.geometry.intersect(&ray, f32::INFINITY);
        if state.medium.is_some() {
            match medium_step(ctx, &mut state, &mut ray, found.as_ref(), sampler, work) {
                Next::Continue => continue,
                Next::Stop => break,
                Next::Surface => {}
            }
        }
        interior_segment(ctx.scene, &mut state, &ray, found.as_ref());
        let Some(hit) = found else {
            escape(ctx, &mut state, &ray);
            break;
        };
        surface_emission(ctx, &mut state, &ray, &hit, work);
        match surface_step(ctx, &mut state, &mut ray, &hit, sampler, work) {
            Next::Continue | Next::Surface => {}
            Next::Stop => break,
        }
    }
    if let Some(out) = visible {
        *out = state.visible;
    }
    state.l
}

/// Free-flight sampling through the medium the ray is in, up to the surface `found` (or
/// infinity): the medium's emission on the way, and a scattering event if one happens.
fn medium_step(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    found: Option<&SurfaceHit>,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let (scene, settings) = (ctx.scene, ctx.settings);
    let Some(m) = state.medium else {
        return Next::Surface;
    };
    let med = state.walk.medium(&scene.media, m);
    let t_max = found.map_or(f32::INFINITY, |h| h.t);
    // Each bounce's tracking numbers are seeded from its unused eighth dimension.
    let seed_dim = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * state.vertices + 7;
    state.segments += 1;
    let mut rng = TrackingRng::new(
        ((sampler.value(seed_dim).to_bits() as u64) << 32) | state.segments as u64,
    );
    // Emission met at a tentative collision could also have been found by sampling the
    // medium as a light from the previous vertex.
    let light = scene.medium_lights[m as usize];
    let (first_or_specular, prev_p, prev_n, prev_pdf) = (
        state.first_or_specular,
        state.prev_p,
        state.prev_n,
        state.prev_pdf,
    );
    // As in pbrt-v4, the segment after the last scattering (maxdepth) counts no emission;
    // nor does a segment reached through specular bounces from a vertex that gathered
    // caustic photons (the emissive media's photons counted it there).
    let counts = state.depth < settings.max_depth && !state.after_caustic_gather();
    let l = &mut state.l;
    let event = med.sample_interaction(ray, t_max, &mut rng, &mut state.beta, |e| match e {
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
                    emission_weight(settings, first_or_specular, prev_pdf * sigma_maj, || {
                        scene.light_pdf(light, prev_p, prev_n, ray.dir, x, Vec3A::ZERO)
                    })
                }
            };
            *l += radiance * (w / sigma_maj);
        }
    });
    let t = match event {
        MediumEvent::Crossed => return Next::Surface,
        MediumEvent::Absorbed => return Next::Stop,
        MediumEvent::CutOff => {
            work.cut_walks += 1;
            return Next::Stop;
        }
        MediumEvent::Scattered(t) => t,
    };
    let in_walk = scene.is_walk_medium(m);
    if in_walk {
        if !state.walk.take_event(settings.walk_depth) {
            return Next::Stop;
        }
    } else {
        if state.depth == settings.max_depth || state.ending {
            return Next::Stop;
        }
        state.depth += 1;
    }
    state.vertices += 1;
    let med = state.walk.medium(&scene.media, m);
    let p = ray.at(t);
    let phase = med.phase();
    let wo = -ray.dir;
    // With a volume map the path ends here: the map holds all light scattered here but the
    // direct, which next-event estimation adds with full weight.
    let mut ends_here = false;
    // (Not inside a subsurface material: its random walk goes on as a path.)
    if let Some(maps) = &ctx.prepass.photons
        && (maps.has_volume_map() || maps.caustics)
        && !in_walk
    {
        // Light scattered here from the photons; the throughput already holds sigma_s, the
        // estimate divides it out.
        let sigma_s = med.sigma_s_at(p);
        let lv = maps.medium_radiance(p, wo, |a, b| phase.p(a, b));
        let inv = Color::select(
            sigma_s.cmpgt(Color::ZERO),
            Color::ONE / sigma_s,
            Color::ZERO,
        );
        state.l += state.beta * lv * inv;
        state.specular_since_gather = Some(0);
        ends_here = maps.has_volume_map();
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
            medium: state.medium,
            time: ray.time,
            last: state.depth == settings.max_depth,
        };
        state.l += state.beta
            * sample_direct(
                scene,
                settings,
                &v,
                |wi| Color::splat(phase.p(wo, wi)),
                |wi| phase.p(wo, wi),
                sampler,
                work,
            );
    }
    sampler.set_dimension(base + 4);
    let (wi, pdf) = phase.sample(wo, sampler.get_2d());
    // Phase functions are sampled exactly: the value over the pdf is 1. (Emission found
    // from a vertex that sampled no light counts in full, as after a specular bounce.)
    state.first_or_specular = !samples_lights;
    state.any_non_specular = true;
    state.prev_pdf = pdf;
    state.prev_p = p;
    state.prev_n = Vec3A::ZERO;
    *ray = ray.spawn(p, wi);
    if let Some((volume, _)) = state.inside {
        state.inside = Some((volume, true));
    }
    // After a volume map's gather, the phase-sampled segment only looks for the light the
    // map leaves out (the direct light, weighed against the light sample as usual).
    state.ending |= ends_here;
    state.roulette(settings, sampler)
}

/// Inside a VolumeLight: the interior's emission along the segment (unless the entry hit
/// counted it) and its absorption.
fn interior_segment(scene: &Scene, state: &mut PathState, ray: &Ray, found: Option<&SurfaceHit>) {
    let Some((volume, count)) = state.inside else {
        return;
    };
    let interior = &scene.volumes[volume as usize];
    let t = found.map_or(0.0, |h| h.t);
    if count {
        state.l += state.beta * interior.segment(ray.origin, ray.dir, t);
    }
    state.beta *= interior.transmittance(t);
    if found.is_none() {
        // Only rounding lets a ray out of a closed shape without a hit.
        state.inside = None;
    }
}

/// A ray that left the scene: the lights at infinity.
fn escape(ctx: &PathContext, state: &mut PathState, ray: &Ray) {
    let scene = ctx.scene;
    // The caustic photons of the lights at infinity counted this path's light.
    if state.after_caustic_gather() {
        return;
    }
    for &i in &scene.infinite_lights {
        let le = scene.lights[i as usize].infinite_le(ray.origin, ray.dir);
        if le != Color::ZERO {
            let w = emission_weight(
                ctx.settings,
                state.first_or_specular,
                state.prev_pdf,
                || {
                    scene.light_pdf(
                        i,
                        state.prev_p,
                        state.prev_n,
                        ray.dir,
                        Vec3A::ZERO,
                        Vec3A::ZERO,
                    )
                },
            );
            state.l += state.beta * le * w;
        }
    }
}

/// Emission of the light whose surface the ray reached, weighted against light sampling.
fn surface_emission(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &Ray,
    hit: &SurfaceHit,
    work: &mut Work,
) {
    let scene = ctx.scene;
    let Some(light_id) = hit.light else {
        return;
    };
    let light = &scene.lights[light_id as usize];
    // Reached through specular bounces from a vertex that gathered caustic photons: the
    // photon map has already counted it (every light shoots photons).
    if state.after_caustic_gather() {
        return;
    }
    let (le, traced) = light.le(&scene.light_context(), hit.p, hit.ng, hit.ns, -ray.dir);
    work.rays += traced;
    if le != Color::ZERO {
        let w = emission_weight(
            ctx.settings,
            state.first_or_specular,
            state.prev_pdf,
            || scene.light_pdf(light_id, state.prev_p, state.prev_n, ray.dir, hit.p, hit.ng),
        );
        state.l += state.beta * le * w;
    }
}

/// The first surface a camera ray reached, for a G-buffer: its normals turned toward the
/// camera and its reflectance toward it estimated as pbrt-v4 does, from fixed BSDF samples.
fn visible_surface(
    hit: &SurfaceHit,
    bsdf: &crate::bsdfs::Bsdf,
    toward_camera: Vec3A,
) -> VisibleSurface {
    let frame = Frame::new(hit.ns, hit.dpdu);
    let wo = frame.to_local(toward_camera);
    let mut albedo = Color::ZERO;
    for i in 0..RHO_SAMPLES {
        let (uc, u) = rho_sample(i);
        if let Some(bs) = bsdf.sample(wo, uc, u)
            && bs.pdf > 0.0
        {
            albedo += bs.f * bs.wi.z.abs() / bs.pdf;
        }
    }
    // Both normals face the camera, as pbrt-v4's VisibleSurface turns them.
    let facing = |n: Vec3A| if n.dot(toward_camera) < 0.0 { -n } else { n };
    VisibleSurface {
        p: hit.p,
        ng: facing(hit.ng),
        ns: facing(hit.ns),
        uv: hit.uv,
        albedo: albedo / RHO_SAMPLES as f32,
        dpdx: Vec3A::ZERO,
        dpdy: Vec3A::ZERO,
    }
}

/// Scattering at a surface: caustic photons, a light sample, and the next direction by
/// BSDF sampling; or straight on through an interface.
fn surface_step(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    hit: &SurfaceHit,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let (scene, settings) = (ctx.scene, ctx.settings);
    // Shading may perturb the normal (bump and normal maps): shade a copy of the hit.
    let hit = &mut hit.clone();
    let Some(mut bsdf) = scene.bsdf_nested(hit, ctx.footprint, &state.nesting, ray.dir) else {
        // An interface: continue straight through without counting a bounce.
        let before = state.medium;
        if !pass_through(
            scene,
            hit,
            ray,
            &mut state.medium,
            &mut state.nesting,
            &mut state.pass_throughs,
        ) {
            return Next::Stop;
        }
        scene.enter_walk(hit, ray.dir, before, state.medium, &mut state.walk);
        return Next::Continue;
    };
    if state.ending {
        return Next::Stop;
    }
    if state.depth == 0 && state.want_visible {
        state.visible = Some(visible_surface(hit, &bsdf, -ray.dir));
    }
    // Met from inside a subsurface walk, the surface is one of the walk's events.
    let in_walk = state.medium.is_some_and(|m| scene.is_walk_medium(m));
    if (state.depth == settings.max_depth && !in_walk) || bsdf.is_black() {
        return Next::Stop;
    }
    if settings.regularize && state.any_non_specular {
        bsdf.regularize();
    }
    if in_walk {
        if !state.walk.take_event(settings.walk_depth) {
            return Next::Stop;
        }
    } else {
        state.depth += 1;
    }
    state.vertices += 1;
    let frame = Frame::new(hit.ns, hit.dpdu);
    let wo = frame.to_local(-ray.dir);
    if let Some(maps) = ctx.prepass.photons.as_ref().filter(|m| m.caustics) {
        if bsdf.is_specular() {
            state.specular_since_gather = state.specular_since_gather.map(|k| k + 1);
        } else {
            // Caustic light reflected here, from the surface photon map.
            let side = if ray.dir.dot(hit.ns) < 0.0 {
                hit.ns
            } else {
                -hit.ns
            };
            state.l += state.beta
                * maps.surface_radiance(hit.p, side, |wi| bsdf.f(wo, frame.to_local(wi)));
            state.specular_since_gather = Some(0);
        }
    }
    let base = CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * (state.vertices - 1);
    sampler.set_dimension(base);
    if !bsdf.is_specular()
        && settings.strategy != LightStrategy::BsdfOnly
        && !scene.light_sampler.is_empty()
    {
        let v = Vertex {
            p: hit.p,
            surface: Some(hit),
            medium: state.medium,
            time: ray.time,
            last: state.depth == settings.max_depth,
        };
        let f = |wi: Vec3A| bsdf.f(wo, frame.to_local(wi)) * wi.dot(hit.ns).abs();
        let pdf = |wi: Vec3A| bsdf.pdf(wo, frame.to_local(wi));
        state.l += state.beta * sample_direct(scene, settings, &v, f, pdf, sampler, work);
    }
    sampler.set_dimension(base + 3);
    let uc = sampler.get_1d();
    let u = sampler.get_2d();
    let Some(bs) = bsdf.sample(wo, uc, u) else {
        return Next::Stop;
    };
    let wi = frame.to_world(bs.wi);
    state.beta *= bs.f * wi.dot(hit.ns).abs() / bs.pdf;
    if !state.beta.is_finite() || state.beta == Color::ZERO {
        return Next::Stop;
    }
    state.first_or_specular = bs.specular;
    state.any_non_specular |= !bs.specular;
    state.prev_pdf = bs.pdf;
    state.prev_p = hit.p;
    state.prev_n = hit.ns;
    if bs.eta != 1.0 {
        state.eta_scale *= bs.eta * bs.eta;
    }
    let before = state.medium;
    if !state
        .nesting
        .cross(&scene.nested, hit, ray.dir, wi, &mut state.medium)
    {
        return Next::Stop;
    }
    scene.enter_walk(hit, wi, before, state.medium, &mut state.walk);
    *ray = ray.spawn(offset_origin(hit.p, hit.ng, wi), wi);
    if let Some(volume) = hit.surface.volume {
        state.inside = if wi.dot(hit.ng) < 0.0 {
            // Entering (not counted again) or reflecting inside (counted).
            let entering = state.inside.is_none();
            Some((volume, !entering))
        } else {
            None
        };
    } else if let Some((volume, _)) = state.inside {
        // Scattered off something inside the shape: the next segment emits too.
        state.inside = Some((volume, true));
    }
    state.roulette(settings, sampler)
}
