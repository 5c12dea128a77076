//! A path at the surface it reached: straight on through an interface, or a scattering
//! vertex (the caustic photons' gather, a light sample, the next direction by BSDF
//! sampling), with the first one noted for a G-buffer.

use super::super::direct::{Vertex, light_sample};
use super::super::{CAMERA_DIMENSIONS, DIMENSIONS_PER_BOUNCE};
use super::{Next, PathContext, PathState};
use crate::bsdfs::Bsdf;
use crate::features::Feature;
use crate::gbuffer::{RHO_SAMPLES, VisibleSurface, rho_sample};
use crate::math::{Color, Frame, Ray};
use crate::sampling::PixelSampler;
use crate::shapes::SurfaceHit;
use crate::spectral::Wavelengths;
use crate::work::Work;
use glam::Vec3A;
use kiln_scene::LightStrategy;

/// Scattering at a surface: caustic photons, a light sample, and the next direction by
/// BSDF sampling; or straight on through an interface.
pub(super) fn surface_step(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    hit: &mut SurfaceHit,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let (scene, settings) = (ctx.scene, ctx.settings);
    if state.feature.is_none() {
        state.travelled += (hit.p - ray.origin).length();
    }
    // Shading may perturb the normal (bump and normal maps), in the path's own record.
    let Some(mut bsdf) = scene.bsdf_nested(
        hit,
        ctx.footprint,
        ctx.waves.as_ref(),
        &state.travel.nesting,
        ray.dir,
    ) else {
        // An interface: continue straight through without counting a bounce.
        if !state.travel.pass_through(scene, hit, ray) {
            return Next::Stop;
        }
        return Next::Continue;
    };
    if state.gather.ending {
        return Next::Stop;
    }
    if let Bsdf::Dielectric(d) = &bsdf
        && d.dispersive
    {
        state.keep_hero_only();
    }
    if state.depth == 0 && state.want_visible {
        state.visible = Some(visible_surface(hit, &bsdf, -ray.dir, ctx.waves.as_ref()));
    }
    if state.feature.is_none() && !bsdf.is_specular() {
        state.feature = Some(feature_at(
            state,
            hit,
            &bsdf,
            ray,
            sampler,
            ctx.waves.as_ref(),
        ));
    }
    // Met from inside a subsurface walk, the surface is one of the walk's events.
    let in_walk = state.travel.in_walk(scene);
    if (state.depth == settings.max_depth && !in_walk) || bsdf.is_black() {
        return Next::Stop;
    }
    if settings.regularize && state.prev.any_non_specular {
        bsdf.regularize();
    }
    if in_walk {
        if !state.travel.walk.take_event(settings.walk_depth) {
            return Next::Stop;
        }
    } else {
        state.depth += 1;
    }
    state.vertices += 1;
    scatter(ctx, state, ray, hit, &bsdf, sampler, work)
}

/// A scattering vertex at `hit` with `bsdf`: the caustic photons' gather, a light sample,
/// and the next direction by BSDF sampling.
fn scatter(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &mut Ray,
    hit: &SurfaceHit,
    bsdf: &Bsdf,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Next {
    let (scene, settings) = (ctx.scene, ctx.settings);
    let frame = Frame::new(hit.ns, hit.dpdu);
    let wo = frame.to_local(-ray.dir);
    if let Some(gathered) = state
        .gather
        .at_surface(ctx, hit, bsdf, &frame, ray.dir, state.beta)
    {
        state.l += gathered;
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
            medium: state.travel.medium,
            time: ray.time,
            last: state.depth == settings.max_depth,
            waves: ctx.waves.as_ref(),
        };
        let f = |wi: Vec3A| bsdf.f(wo, frame.to_local(wi)) * wi.dot(hit.ns).abs();
        let pdf = |wi: Vec3A| bsdf.pdf(wo, frame.to_local(wi));
        let direct = light_sample(scene, settings, &v, f, pdf, sampler, work);
        state.add_direct(direct);
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
    state.prev.first_or_specular = bs.specular;
    state.prev.any_non_specular |= !bs.specular;
    state.prev.pdf = bs.pdf;
    state.prev.p = hit.p;
    state.prev.n = hit.ns;
    if bs.eta != 1.0 {
        state.eta_scale *= bs.eta * bs.eta;
    }
    if !state.travel.scatter(scene, hit, ray.dir, wi) {
        return Next::Stop;
    }
    *ray = ray.spawn(hit.origin_towards(wi), wi);
    state.interior.crossed(hit.surface.volume, hit.ng, wi);
    state.roulette(settings, sampler)
}

/// The first surface a camera ray reached, for a G-buffer: its normals turned toward the
/// camera and its reflectance toward it estimated as pbrt-v4 does, from fixed BSDF samples.
/// A spectral path's reflectance is recorded as pbrt-v4's G-buffer records it: its colour
/// under the colour space's white (D65), through the film.
fn visible_surface(
    hit: &SurfaceHit,
    bsdf: &Bsdf,
    toward_camera: Vec3A,
    waves: Option<&Wavelengths>,
) -> VisibleSurface {
    // Both normals face the camera, as pbrt-v4's VisibleSurface turns them.
    let facing = |n: Vec3A| if n.dot(toward_camera) < 0.0 { -n } else { n };
    VisibleSurface {
        p: hit.p,
        ng: facing(hit.ng),
        ns: facing(hit.ns),
        uv: hit.uv,
        albedo: reflectance_rgb(rho(hit, bsdf, toward_camera), waves),
        dpdx: Vec3A::ZERO,
        dpdy: Vec3A::ZERO,
    }
}

/// The BSDF's directional reflectance toward `wo_world`, estimated as pbrt-v4 does from
/// fixed samples (exact for a Lambertian surface).
fn rho(hit: &SurfaceHit, bsdf: &Bsdf, wo_world: Vec3A) -> Color {
    reflectance_estimate(hit, bsdf, wo_world, (0..RHO_SAMPLES).map(rho_sample))
}

/// The mean of f cos / pdf over the BSDF samples `samples` (each a lobe choice and a
/// direction's two numbers) toward `wo_world`.
fn reflectance_estimate(
    hit: &SurfaceHit,
    bsdf: &Bsdf,
    wo_world: Vec3A,
    samples: impl ExactSizeIterator<Item = (f32, glam::Vec2)>,
) -> Color {
    let frame = Frame::new(hit.ns, hit.dpdu);
    let wo = frame.to_local(wo_world);
    let count = samples.len();
    let mut albedo = Color::ZERO;
    for (uc, u) in samples {
        if let Some(bs) = bsdf.sample(wo, uc, u)
            && bs.pdf > 0.0
        {
            albedo += bs.f * bs.wi.z.abs() / bs.pdf;
        }
    }
    albedo / count as f32
}

/// A reflectance as RGB: a spectral path's as pbrt-v4's G-buffer records it, its colour
/// under the colour space's white (D65), through the film.
pub(super) fn reflectance_rgb(r: Color, waves: Option<&Wavelengths>) -> Color {
    match waves {
        None => r,
        Some(w) => w.to_rgb(r * w.d65()),
    }
}

/// The sampler dimension the feature's reflectance estimate is rotated by: far from the
/// path's own and the camera's (time 0x4000_0000, wavelengths 0x4000_0001), so the path's
/// numbers are the same with or without it.
const FEATURE_DIMENSION: u32 = 0x4000_0002;

/// The denoiser's feature reflectance of `bsdf` toward `wo`: exact for the diffuse kinds
/// (their reflectance and transmittance), else two BSDF samples of a fixed pair rotated by
/// a number of the camera sample's own (so a pixel's samples average over many directions
/// while each costs two samples, not [`RHO_SAMPLES`]; the number is drawn only then).
fn feature_reflectance(
    hit: &SurfaceHit,
    bsdf: &Bsdf,
    wo_world: Vec3A,
    sampler: &PixelSampler,
) -> Color {
    match bsdf {
        Bsdf::Diffuse(d) => d.r,
        Bsdf::DiffuseTransmission(d) => d.r + d.t,
        _ => {
            let rotation = sampler.value(FEATURE_DIMENSION);
            let shift = |v: f32| (v + rotation).fract();
            let pair = (0..2).map(|i| {
                let (uc, u) = rho_sample(i * (RHO_SAMPLES / 2));
                let u = glam::Vec2::new(shift(u.x), (u.y + rotation * 0.618_034).fract());
                (shift(uc), u)
            });
            reflectance_estimate(hit, bsdf, wo_world, pair)
        }
    }
}

/// The denoiser's feature at the path's first non-specular vertex: its reflectance (white
/// on an emitter) seen through the specular bounces before it (their throughput, at most
/// 1), its shading normal facing the path, and how far the path came.
fn feature_at(
    state: &PathState,
    hit: &SurfaceHit,
    bsdf: &Bsdf,
    ray: &Ray,
    sampler: &PixelSampler,
    waves: Option<&Wavelengths>,
) -> Feature {
    let through = state.beta.min(Color::ONE);
    let n = if hit.ns.dot(ray.dir) > 0.0 {
        -hit.ns
    } else {
        hit.ns
    };
    // An emitter's own light is no reflection of anything: dividing it by its reflectance
    // (a lamp's is often black) would make its pixels noise, so it notes white.
    let reflectance = if hit.light.is_some() {
        Color::ONE
    } else {
        feature_reflectance(hit, bsdf, -ray.dir, sampler)
    };
    Feature {
        albedo: reflectance_rgb(through * reflectance, waves),
        normal: n,
        depth: state.travelled,
    }
}
