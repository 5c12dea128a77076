//! Next-event estimation and the weights that combine it with BSDF and phase sampling
//! (multiple importance sampling), shared by every vertex of a path, on surfaces and in
//! media; and Russian roulette.

use super::PathSettings;
use crate::math::{Color, Ray, offset_origin, surface_epsilon};
use crate::sampling::{PixelSampler, TrackingRng, power_heuristic};
use crate::scene::Scene;
use crate::shapes::SurfaceHit;
use crate::spectral::Wavelengths;
use crate::work::Work;
use glam::Vec3A;
use kiln_scene::LightStrategy;

/// The weight of emission found by BSDF or phase sampling (with density `scatter_pdf`)
/// that light sampling could also have found with density `light_pdf()`.
pub(super) fn emission_weight(
    settings: &PathSettings,
    first_or_specular: bool,
    scatter_pdf: f32,
    light_pdf: impl FnOnce() -> f32,
) -> f32 {
    if first_or_specular {
        return 1.0;
    }
    match settings.strategy {
        LightStrategy::BsdfOnly => 1.0,
        LightStrategy::LightOnly => 0.0,
        LightStrategy::Mis => power_heuristic(scatter_pdf, light_pdf()),
    }
}

/// Russian roulette from `settings.rr_depth` on, on the throughput with the radiance scaling
/// of refraction undone; false ends the path, and a survivor's throughput is scaled up.
pub(super) fn survives_roulette(
    beta: &mut Color,
    eta_scale: f32,
    depth: u32,
    settings: &PathSettings,
    sampler: &mut PixelSampler,
) -> bool {
    let rr = (*beta * eta_scale).max_element();
    if rr < 1.0 && depth >= settings.rr_depth {
        // Kiln ends at least one path in twenty that roulette meets; pbrt-v4 does not.
        let q = (1.0 - rr).max(if settings.pbrt_estimator { 0.0 } else { 0.05 });
        if sampler.get_1d() < q {
            return false;
        }
        *beta /= 1.0 - q;
    }
    true
}

/// Where next-event estimation starts: a point, the surface it lies on (none inside a
/// medium), and the medium the path is in there.
pub(super) struct Vertex<'a> {
    pub p: Vec3A,
    pub surface: Option<&'a SurfaceHit>,
    pub medium: Option<u32>,
    /// The path's time within the shutter.
    pub time: f32,
    /// The path's last scattering (maxdepth reached): as in pbrt-v4, the segment after it
    /// counts no medium emission, so light sampling skips emissive media here too.
    pub last: bool,
    /// The path's wavelengths in spectral mode (None: RGB).
    pub waves: Option<&'a Wavelengths>,
}

impl Vertex<'_> {
    /// The shading normal light sampling sees (zero in a medium).
    pub fn normal(&self) -> Vec3A {
        self.surface.map_or(Vec3A::ZERO, |h| h.ns)
    }

    fn medium_towards(&self, dir: Vec3A) -> Option<u32> {
        match self.surface {
            Some(h) => h.surface.medium_towards(dir, h.ng).unwrap_or(self.medium),
            None => self.medium,
        }
    }
}

/// One light sample for next-event estimation from `v`, up to its shadow ray: `f` is the
/// scattering function (times the cosine at surfaces) and `pdf` the density of sampling
/// `wi` by it. Light sampling and the shadow ray are two stages, so that a wave of paths
/// traces its shadow rays together ([`Shadow::resolve`]).
pub(super) fn light_sample(
    scene: &Scene,
    settings: &PathSettings,
    v: &Vertex,
    f: impl Fn(Vec3A) -> Color,
    pdf: impl Fn(Vec3A) -> f32,
    sampler: &mut PixelSampler,
    work: &mut Work,
) -> Direct {
    let u_light = sampler.get_1d();
    let u = sampler.get_2d();
    let Some((index, pmf)) = scene.light_sampler.sample(v.p, v.normal(), u_light) else {
        return Direct::Done(Color::ZERO);
    };
    if v.last && matches!(scene.lights[index], crate::lights::Light::Medium(_)) {
        return Direct::Done(Color::ZERO);
    }
    // pbrt-v4 leaves a uniform light at infinity to BSDF sampling: picked, it gives nothing.
    if settings.pbrt_estimator && scene.lights[index].found_by_bsdf_alone() {
        return Direct::Done(Color::ZERO);
    }
    let (sample, traced) = scene.lights[index].sample(&scene.light_context_at(v.waves), v.p, u);
    work.rays += traced;
    let Some(ls) = sample else {
        return Direct::Done(Color::ZERO);
    };
    if ls.pdf <= 0.0 || ls.radiance == Color::ZERO {
        return Direct::Done(Color::ZERO);
    }
    let f = f(ls.wi);
    if f == Color::ZERO {
        return Direct::Done(Color::ZERO);
    }
    let origin = v.surface.map_or(v.p, |h| h.origin_towards(ls.wi));
    let medium = v.medium_towards(ls.wi);
    let rng = TrackingRng::from_values(&[u_light, u.x, u.y], 2);
    let (ray, tmax) = if ls.distance.is_finite() {
        // Aim at the light's point moved off its surface towards us, and stop short of it:
        // following ls.wi for the full distance would graze the light's own surface.
        let target = if ls.n == Vec3A::ZERO {
            v.p + ls.wi * ls.distance
        } else {
            let q = v.p + ls.wi * ls.distance;
            offset_origin(q, ls.n, surface_epsilon(q), -ls.wi)
        };
        let d = target - origin;
        // (Not `len <= 0.0`: a NaN length traces nothing either.)
        let Some(len) = Some(d.length()).filter(|&len| len > 0.0) else {
            return Direct::Done(Color::ZERO);
        };
        (Ray::at_time(origin, d / len, v.time), len * (1.0 - 1e-4))
    } else {
        (Ray::at_time(origin, ls.wi, v.time), f32::INFINITY)
    };
    let light_pdf = pmf * ls.pdf;
    let w = match settings.strategy {
        LightStrategy::Mis if !ls.delta => power_heuristic(light_pdf, pdf(ls.wi) * ls.scatter_rate),
        _ => 1.0,
    };
    Direct::Shadow(Shadow {
        ray,
        tmax,
        medium,
        rng,
        light_medium: ls.medium,
        f,
        radiance: scene.light_radiance(index as u32, ls.radiance, v.waves),
        light_pdf,
        delta: ls.delta,
        w,
    })
}

/// What a light sample gives: its contribution, or a shadow ray to trace first.
pub(super) enum Direct {
    Done(Color),
    Shadow(Shadow),
}

impl Direct {
    /// The contribution, its shadow ray traced now if it waits on one.
    pub fn resolve(self, scene: &Scene, work: &mut Work, waves: Option<&Wavelengths>) -> Color {
        match self {
            Direct::Done(c) => c,
            Direct::Shadow(s) => s.resolve(scene, work, waves),
        }
    }
}

/// A light sample waiting on its shadow ray: the ray, and what its contribution is made of
/// once the ray's transmittance is known.
pub(super) struct Shadow {
    ray: Ray,
    tmax: f32,
    /// The medium the ray starts in.
    medium: Option<u32>,
    /// Ratio tracking's numbers through grid media on the way.
    rng: TrackingRng,
    /// The medium the light's point lies in (None on a surface).
    light_medium: Option<u32>,
    f: Color,
    radiance: Color,
    light_pdf: f32,
    delta: bool,
    /// The MIS weight against BSDF or phase sampling.
    w: f32,
}

impl Shadow {
    /// The light sample's contribution, its shadow ray traced.
    pub fn resolve(mut self, scene: &Scene, work: &mut Work, waves: Option<&Wavelengths>) -> Color {
        let (tr, end) = self.trace(scene, work, waves);
        self.finish(tr, end)
    }

    /// Traces the shadow ray: its transmittance, and the medium it ends in.
    fn trace(
        &mut self,
        scene: &Scene,
        work: &mut Work,
        waves: Option<&Wavelengths>,
    ) -> (Color, Option<u32>) {
        scene.transmittance(self.ray, self.tmax, self.medium, &mut self.rng, work, waves)
    }

    /// The light sample's contribution through transmittance `tr` of a shadow ray that
    /// ended in `end_medium`.
    fn finish(&self, tr: Color, end_medium: Option<u32>) -> Color {
        if tr == Color::ZERO {
            return Color::ZERO;
        }
        // A point sampled in a medium emits only if the shadow ray arrives in that medium.
        if self.light_medium.is_some() && end_medium != self.light_medium {
            return Color::ZERO;
        }
        if self.delta {
            return self.f * tr * self.radiance / self.light_pdf;
        }
        self.f * tr * self.radiance * (self.w / self.light_pdf)
    }
}
