//! Stochastic progressive photon mapping, as pbrt-v4's "sppm" integrator defines it
//! (Hachisuka and Jensen 2009): each iteration traces one camera path per pixel to its
//! first non-specular surface (a *visible point*), adding emission met through specular
//! bounces and light-sampled direct light on the way; then traces a pass of photons and
//! adds, to each visible point, the photons that land within the pixel's radius after their
//! first bounce. Each pixel's radius shrinks as it gathers (alpha 2/3), so the estimate is
//! consistent: its bias goes to zero as iterations grow.
//!
//! Iterations run outermost over every pixel being rendered, so each pass of photons is
//! traced once for all of them. A pixel's value depends only on its own camera samples and
//! on the photon passes, which are seeded by (seed, iteration, photon index) and traced in
//! fixed batches: the image is the same for any tile split and thread count.
//!
//! As in pbrt-v4, SPPM renders surfaces only (participating media are ignored).
//!
//! Spectrally, as in pbrt-v4, an iteration's camera paths and photons share the iteration's
//! four wavelengths ([`pass_wavelengths`]), so a photon's power and a visible point's
//! throughput multiply wavelength by wavelength; each product goes through the film to RGB
//! where it is added to a pixel.

use super::direct::{Vertex, light_sample};
use super::photons::map::{decode, encode};
use super::photons::{BATCH, Emitters, Gather, Launch, Photon, PhotonMap, launch, scatter};
use super::{CAMERA_DIMENSIONS, DIMENSIONS_PER_BOUNCE, PathSettings, pass_through};
use crate::bsdfs::Bsdf;
use crate::lights::SceneSphere;
use crate::math::{Color, Frame, Ray};
use crate::nesting::Nesting;
use crate::sampling::{AliasTable, PixelSampler, TrackingRng};
use crate::scene::Scene;
use crate::sensor::Sensor;
use crate::shared::{Shared, SharedPrepass, shared_or_built};
use crate::spectral::Wavelengths;
use crate::work::Work;
use glam::Vec3A;
use kiln_scene::{LightStrategy, PhotonDesc};
use rayon::prelude::*;
use std::collections::HashMap;
use std::f32::consts::PI;
use std::sync::{Arc, Mutex};

/// pbrt-v4's SPPM parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SppmSettings {
    /// The longest camera path and photon path, in bounces.
    pub max_depth: u32,
    /// Photons per iteration (pbrt-v4's default: the pixels of the image).
    pub photons_per_iteration: u64,
    /// Every pixel's initial search radius.
    pub radius: f32,
}

impl SppmSettings {
    /// The path-tracer settings the camera pass shares: light sampling alone for direct
    /// light, as pbrt-v4's SPPM does (emission reached by scattering counts only through
    /// specular bounces).
    fn camera_path(&self) -> PathSettings {
        PathSettings {
            max_depth: self.max_depth,
            rr_depth: u32::MAX,
            walk_depth: kiln_scene::DEFAULT_WALK_DEPTH,
            strategy: LightStrategy::LightOnly,
            photons: PhotonDesc::NONE,
            regularize: false,
            pbrt_estimator: false,
        }
    }
}

/// What a pixel carries from one iteration to the next.
#[derive(Debug, Clone, Copy)]
pub struct PixelState {
    /// Direct light and emission found by the camera paths (summed over iterations).
    ld: Color,
    /// Accumulated photon flux times BSDF (pbrt's tau), for the current radius.
    tau: Color,
    /// Photons counted so far (pbrt's N) and the current radius.
    n: f32,
    radius: f32,
}

impl PixelState {
    pub fn new(radius: f32) -> PixelState {
        PixelState {
            ld: Color::ZERO,
            tau: Color::ZERO,
            n: 0.0,
            radius,
        }
    }

    /// The pixel's radiance after `iterations` iterations of `photons` photons each.
    pub fn radiance(&self, iterations: u32, photons: u64) -> Color {
        let it = iterations.max(1) as f32;
        let np = (iterations as f64 * photons as f64).max(1.0) as f32;
        self.ld / it + self.tau / (np * PI * self.radius * self.radius)
    }
}

/// After a dispersive refraction a spectral path (or photon) keeps its hero wavelength alone,
/// its weight four times over, as pbrt-v4's do (once).
fn keep_hero_only(bsdf: &Bsdf, beta: &mut Color, hero_only: &mut bool) {
    if let Bsdf::Dielectric(d) = bsdf
        && d.dispersive
        && !*hero_only
    {
        *hero_only = true;
        *beta = Color::new(4.0 * beta.x, 0.0, 0.0, 0.0);
    }
}

/// The four wavelengths iteration `iteration` of a spectral render carries, for its camera
/// paths and its photons alike: the hero at the iteration's place in the base-2 radical
/// inverse, turned by an offset the seed gives (so that seeds differ).
pub fn pass_wavelengths(seed: u32, iteration: u32) -> Wavelengths {
    let turn = (seed.wrapping_mul(0x9E37_79B9) >> 8) as f32 / (1u32 << 24) as f32;
    let u = iteration.reverse_bits() as f32 / 4_294_967_296.0 + turn;
    Wavelengths::sample(if u >= 1.0 { u - 1.0 } else { u })
}

/// What the film records of `l`: itself in RGB, through the sensor (the observer, or a named
/// camera's curves) at `waves`.
fn film(sensor: &Sensor, l: Color, waves: Option<&Wavelengths>) -> Color {
    waves.map_or(l, |w| sensor.sample(l, w))
}

/// A camera path's first non-specular surface: where it gathers photons.
struct VisiblePoint<'a> {
    p: Vec3A,
    wo: Vec3A,
    frame: Frame,
    bsdf: Bsdf<'a>,
    beta: Color,
    /// The iteration's wavelengths, for a spectral render.
    waves: Option<Wavelengths>,
    /// A dispersive refraction left the camera path the hero wavelength alone.
    hero_only: bool,
}

/// The camera pass of one iteration for one pixel: its direct light (added to `state`) and
/// its visible point. `ray` is the camera ray (None if the lens stopped it), `weight` the
/// camera's and the filter's weight; `waves` the iteration's wavelengths in a spectral
/// render.
#[allow(clippy::too_many_arguments)]
pub fn camera_pass<'a>(
    scene: &'a Scene,
    settings: &SppmSettings,
    ray: Option<Ray>,
    weight: f32,
    sampler: &mut PixelSampler,
    work: &mut Work,
    state: &mut PixelState,
    waves: Option<&Wavelengths>,
) -> Option<VisiblePointHandle<'a>> {
    let mut ray = ray?;
    let path = settings.camera_path();
    let mut beta = Color::splat(weight);
    let mut specular = true;
    let mut medium = None;
    let mut nesting = Nesting::default();
    let mut depth = 0u32;
    let mut pass_throughs = 0u32;
    let mut hero_only = false;
    while depth < settings.max_depth {
        work.rays += 1;
        let Some(hit) = scene.geometry.intersect(&ray, f32::INFINITY) else {
            if specular {
                for &i in &scene.infinite_lights {
                    let le = scene.lights[i as usize].infinite_le(ray.origin, ray.dir);
                    state.ld += film(
                        &scene.sensor,
                        beta * scene.light_radiance(i, le, waves),
                        waves,
                    );
                }
            }
            return None;
        };
        if specular && let Some(light) = hit.light {
            let (le, traced) = scene.lights[light as usize].le(
                &scene.light_context_at(waves),
                hit.p,
                hit.ng,
                hit.ns,
                -ray.dir,
            );
            work.rays += traced;
            state.ld += film(
                &scene.sensor,
                beta * scene.light_radiance(light, le, waves),
                waves,
            );
        }
        let mut shaded = hit;
        let Some(bsdf) = scene.bsdf_nested(&mut shaded, 1.0, waves, &nesting, ray.dir) else {
            // An interface: straight on, without counting a bounce.
            if !pass_through(
                scene,
                &hit,
                &mut ray,
                &mut medium,
                &mut nesting,
                &mut pass_throughs,
            ) {
                return None;
            }
            continue;
        };
        let hit = &shaded;
        let frame = Frame::new(hit.ns, hit.dpdu);
        let wo_world = -ray.dir;
        let wo = frame.to_local(wo_world);
        sampler.set_dimension(CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * depth);
        if !bsdf.is_specular() {
            if !scene.light_sampler.is_empty() {
                let v = Vertex {
                    p: hit.p,
                    surface: Some(hit),
                    medium,
                    time: ray.time,
                    last: false,
                    waves,
                };
                let f = |wi: Vec3A| bsdf.f(wo, frame.to_local(wi)) * wi.dot(hit.ns).abs();
                let pdf = |wi: Vec3A| bsdf.pdf(wo, frame.to_local(wi));
                let ld = light_sample(scene, &path, &v, f, pdf, sampler, work)
                    .resolve(scene, work, waves);
                state.ld += film(&scene.sensor, beta * ld, waves);
            }
            return Some(VisiblePointHandle(VisiblePoint {
                p: hit.p,
                wo,
                frame,
                bsdf,
                beta,
                waves: waves.copied(),
                hero_only,
            }));
        }
        if bsdf.is_black() || depth + 1 >= settings.max_depth {
            return None;
        }
        keep_hero_only(&bsdf, &mut beta, &mut hero_only);
        sampler.set_dimension(CAMERA_DIMENSIONS + DIMENSIONS_PER_BOUNCE * depth + 3);
        let uc = sampler.get_1d();
        let u = sampler.get_2d();
        let bs = bsdf.sample(wo, uc, u)?;
        if bs.pdf <= 0.0 {
            return None;
        }
        let wi = frame.to_world(bs.wi);
        beta *= bs.f * wi.dot(hit.ns).abs() / bs.pdf;
        if !beta.is_finite() || beta == Color::ZERO {
            return None;
        }
        specular = bs.specular;
        if !nesting.cross(&scene.nested, hit, ray.dir, wi, &mut medium) {
            return None;
        }
        ray = ray.spawn(hit.origin_towards(wi), wi);
        depth += 1;
    }
    None
}

/// A visible point, opaque outside this module.
pub struct VisiblePointHandle<'a>(VisiblePoint<'a>);

/// An iteration's photons: those that kept all four wavelengths, and (in a spectral render)
/// those a dispersive refraction left with the hero alone, its power four times over. A
/// visible point that kept its hero alone too weighs the second kind once, not twice (pbrt-v4
/// terminates a wavelength once, whichever path did it).
#[derive(Default)]
pub struct Pass {
    full: PhotonMap,
    hero: PhotonMap,
}

impl Pass {
    fn bytes(&self) -> usize {
        self.full.bytes() + self.hero.bytes()
    }

    fn encode(&self) -> Vec<u8> {
        encode(&[self.full.photons(), self.hero.photons()])
    }

    fn decode(bytes: &[u8], gather: Gather) -> Result<Pass, String> {
        let [full, hero]: [Vec<Photon>; 2] = decode(bytes)?
            .try_into()
            .map_err(|_| "not two photon lists".to_string())?;
        Ok(Pass {
            full: PhotonMap::new(full, gather),
            hero: PhotonMap::new(hero, gather),
        })
    }
}

/// Adds the photons of `map` within the pixel's radius of its visible point and shrinks the
/// radius as pbrt-v4 does: N' = N + 2/3 M, R' = R sqrt(N' / (N + M)), tau' = (tau + Phi)
/// R'^2 / R^2.
pub fn gather(
    sensor: &Sensor,
    pass: &Pass,
    vp: Option<&VisiblePointHandle>,
    state: &mut PixelState,
) {
    let Some(VisiblePointHandle(vp)) = vp else {
        return;
    };
    let mut phi = Color::ZERO;
    let mut m = 0u32;
    pass.full.gather_within(vp.p, state.radius, |ph| {
        phi += ph.power * vp.bsdf.f(vp.wo, vp.frame.to_local(ph.wi));
        m += 1;
    });
    let mut hero = Color::ZERO;
    pass.hero.gather_within(vp.p, state.radius, |ph| {
        hero += ph.power * vp.bsdf.f(vp.wo, vp.frame.to_local(ph.wi));
        m += 1;
    });
    if hero != Color::ZERO {
        phi += if vp.hero_only { hero * 0.25 } else { hero };
    }
    if m == 0 {
        return;
    }
    const GAMMA: f32 = 2.0 / 3.0;
    let n_new = state.n + GAMMA * m as f32;
    let r_new = state.radius * (n_new / (state.n + m as f32)).sqrt();
    let shrink = (r_new * r_new) / (state.radius * state.radius);
    state.tau = (state.tau + film(sensor, vp.beta * phi, vp.waves.as_ref())) * shrink;
    state.n = n_new;
    state.radius = r_new;
}

/// Traces iteration `iteration`'s photons from `emitters` (None: no light emits) and returns
/// them as a map for gathers within every pixel's radius (which only shrinks from the
/// initial one). A spectral render's photons carry the iteration's wavelengths
/// ([`pass_wavelengths`]).
pub fn photon_pass(
    scene: &Scene,
    settings: &SppmSettings,
    emitters: Option<&Emitters>,
    seed: u32,
    iteration: u32,
    spectral: bool,
) -> Pass {
    let waves = spectral.then(|| pass_wavelengths(seed, iteration));
    let Some(emitters) = emitters else {
        return Pass::default();
    };
    let (table, sphere) = (&emitters.table, emitters.sphere);
    let n = settings.photons_per_iteration;
    let batches: Vec<Stored> = (0..n.div_ceil(BATCH))
        .into_par_iter()
        .map(|b| {
            let mut stored = Stored::default();
            for i in b * BATCH..((b + 1) * BATCH).min(n) {
                let key = ((seed as u64) << 32 | iteration as u64)
                    .wrapping_mul(0xd605_bbb5_8c8a_bbb7)
                    ^ i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
                trace_photon(
                    scene,
                    settings,
                    table,
                    sphere,
                    key,
                    waves.as_ref(),
                    &mut stored,
                );
            }
            stored
        })
        .collect();
    let (mut full, mut hero) = (Vec::new(), Vec::new());
    for b in batches {
        full.extend(b.full);
        hero.extend(b.hero);
    }
    let gather = Gather::Radius(settings.radius);
    Pass {
        full: PhotonMap::new(full, gather),
        hero: PhotonMap::new(hero, gather),
    }
}

/// A batch's stored photons, by whether they kept all four wavelengths (see [`Pass`]).
#[derive(Default)]
struct Stored {
    full: Vec<Photon>,
    hero: Vec<Photon>,
}

/// One SPPM photon: stored at every non-specular surface after its first bounce, ended by
/// pbrt-v4's roulette (survival in proportion to what a bounce keeps of its throughput).
fn trace_photon(
    scene: &Scene,
    settings: &SppmSettings,
    table: &AliasTable,
    sphere: SceneSphere,
    key: u64,
    waves: Option<&Wavelengths>,
    stored: &mut Stored,
) {
    let mut rng = TrackingRng::new(key);
    let mut hero_only = false;
    let Some(Launch {
        beta,
        mut ray,
        light,
        ..
    }) = launch(scene, table, sphere, 1, &mut rng, waves)
    else {
        return;
    };
    let mut beta = scene.light_radiance(light as u32, beta, waves);
    let mut depth = 0u32;
    let mut pass_throughs = 0u32;
    let mut nesting = Nesting::default();
    while depth < settings.max_depth {
        let Some(mut hit) = scene.geometry.intersect(&ray, f32::INFINITY) else {
            return;
        };
        let Some(bsdf) = scene.bsdf_nested(&mut hit, 1.0, waves, &nesting, ray.dir) else {
            // SPPM renders no media: the medium an interface leads to is not followed.
            if !pass_through(
                scene,
                &hit,
                &mut ray,
                &mut None,
                &mut nesting,
                &mut pass_throughs,
            ) {
                return;
            }
            continue;
        };
        if depth > 0 && !bsdf.is_specular() {
            let photon = Photon {
                p: hit.p,
                wi: -ray.dir,
                n: hit.ns,
                power: beta,
            };
            match hero_only {
                false => stored.full.push(photon),
                true => stored.hero.push(photon),
            }
        }
        keep_hero_only(&bsdf, &mut beta, &mut hero_only);
        let Some(bounce) = scatter(&bsdf, &hit, ray.dir, &mut rng) else {
            return;
        };
        let wi = bounce.wi;
        let bnew = beta * bounce.weight;
        let q = (1.0 - bnew.max_element() / beta.max_element()).max(0.0);
        if rng.next_f32() < q {
            return;
        }
        beta = bnew / (1.0 - q);
        if !beta.is_finite() || beta == Color::ZERO {
            return;
        }
        if !nesting.cross(&scene.nested, &hit, ray.dir, wi, &mut None) {
            return;
        }
        ray = ray.spawn(hit.origin_towards(wi), wi);
        depth += 1;
    }
}

/// SPPM photon passes by iteration, kept up to [`PassCache::BUDGET`] bytes (the first
/// passes a job needs; later ones are traced again for every tile). A pass is a pure
/// function of (scene, settings, iteration), so keeping one changes no pixel.
#[derive(Default)]
pub struct PassCache {
    /// The bytes kept, and the passes by iteration.
    kept: Mutex<(usize, HashMap<u32, Arc<Pass>>)>,
    /// Passes this renderer has claimed in the shared store and is tracing. Another thread
    /// of the same renderer must not wait for one: rayon may have run that thread's tile
    /// inside the very trace it would wait for (a thread waiting for its own stack).
    tracing: Mutex<std::collections::HashSet<u32>>,
}

impl PassCache {
    const BUDGET: usize = 1 << 30;

    /// How many passes ahead a worker waiting for another's pass claims and traces.
    const AHEAD: u32 = 8;

    /// Pass `iteration` of `iterations`: from the cache, from `shared` (where another
    /// worker published it), or traced by `trace` (published when shared, and kept if it
    /// fits). While another worker traces it, this one traces passes ahead that nobody has
    /// claimed. None if `stop` says so while waiting.
    pub(crate) fn get(
        &self,
        iteration: u32,
        iterations: u32,
        shared: Option<&dyn SharedPrepass>,
        trace: &(dyn Fn(u32) -> Pass + Sync),
        gather: Gather,
        stop: &dyn Fn() -> bool,
    ) -> Option<Arc<Pass>> {
        if let Some(map) = self.lock().1.get(&iteration) {
            return Some(map.clone());
        }
        let Some(shared) = shared else {
            return Some(self.keep(iteration, trace(iteration)));
        };
        let name = |it: u32| format!("sppm-pass-{it}");
        let decode_pass = |b: &[u8]| Pass::decode(b, gather);
        // Traces a pass this renderer holds the claim to (its other threads trace it again
        // rather than wait for it: rayon may have run their tile inside this very trace).
        let trace_claimed = |it: u32| {
            self.claims().insert(it);
            let map = trace(it);
            self.claims().remove(&it);
            map
        };
        // While another worker traces this pass: a pass ahead that is published (keep it)
        // or that nobody has claimed (trace and publish it). One answer per pass: a claim
        // is asked for once.
        let mut ahead = || {
            for it in iteration + 1..(iteration + 1 + Self::AHEAD).min(iterations) {
                if self.lock().1.contains_key(&it) || self.lock().0 >= Self::BUDGET {
                    continue;
                }
                match shared.fetch(&name(it)) {
                    Shared::Theirs => continue,
                    Shared::Ready(bytes) => {
                        if let Ok(map) = decode_pass(&bytes) {
                            self.keep(it, map);
                            return true;
                        }
                    }
                    Shared::Yours => {
                        let map = trace_claimed(it);
                        shared.publish(&name(it), &map.encode());
                        self.keep(it, map);
                        return true;
                    }
                }
            }
            false
        };
        if self.claims().contains(&iteration) {
            return Some(self.keep(iteration, trace(iteration)));
        }
        let map = shared_or_built(
            shared,
            &name(iteration),
            || trace_claimed(iteration),
            |m: &Pass| m.encode(),
            decode_pass,
            &mut ahead,
            stop,
        )?;
        Some(self.keep(iteration, map))
    }

    fn claims(&self) -> std::sync::MutexGuard<'_, std::collections::HashSet<u32>> {
        self.tracing.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Keeps pass `iteration` if it fits in the budget.
    fn keep(&self, iteration: u32, map: Pass) -> Arc<Pass> {
        let map = Arc::new(map);
        let mut kept = self.lock();
        if kept.0 + map.bytes() <= Self::BUDGET {
            kept.0 += map.bytes();
            kept.1.insert(iteration, map.clone());
        }
        map
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, (usize, HashMap<u32, Arc<Pass>>)> {
        // A panic elsewhere cannot leave the cache half-written: entries go in whole.
        self.kept.lock().unwrap_or_else(|e| e.into_inner())
    }
}
