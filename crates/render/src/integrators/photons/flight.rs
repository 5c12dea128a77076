//! One photon's flight: from its light through media and off surfaces until it is stored,
//! absorbed, lost to roulette or done with its events.

use super::{Launch, Pass, Photon, Roulette, Shooter, Stored, launch, scatter};
use crate::math::{Color, Ray, luminance};
use crate::media::MediumEvent;
use crate::media::subsurface::Walk;
use crate::nesting::Nesting;
use crate::sampling::TrackingRng;
use crate::shapes::SurfaceHit;
use crate::spectral::Wavelengths;
use glam::{Vec2, Vec3A};

/// A photon in flight.
struct Flight {
    ray: Ray,
    /// The power it carries, and the luminance it started with (weight-aware roulette
    /// compares them).
    beta: Color,
    start: f32,
    rng: TrackingRng,
    medium: Option<u32>,
    /// Events so far (a subsurface walk's do not count), and whether all were specular.
    events: u32,
    only_specular: bool,
    pass_throughs: u32,
    nesting: Nesting,
    /// The subsurface walk the photon is on.
    walk: Walk,
    /// A spectral photon's own four wavelengths, and whether a dispersive refraction left
    /// it the hero alone.
    waves: Option<Wavelengths>,
    hero_only: bool,
    /// A spectral photon's lanes' relative densities of being sampled so far (see
    /// [`crate::media::LANE_PDFS`]).
    lane_pdfs: Color,
}

impl Flight {
    /// What weight-aware roulette compares: the luminance of the power, or of the RGB the
    /// film would record of a spectral photon's.
    fn brightness(&self, beta: Color) -> f32 {
        match &self.waves {
            None => luminance(beta),
            Some(w) => luminance(w.to_rgb(beta)),
        }
    }

    /// The power a photon stored here carries: RGB, as the film records a spectral one's.
    fn stored_power(&self) -> Color {
        match &self.waves {
            None => self.beta,
            Some(w) => w.to_rgb(self.beta),
        }
    }
}

/// What the photon does after a step.
enum Step {
    /// Trace the next segment.
    Continue,
    /// Go on to the surface the segment reached.
    Surface,
    /// The photon is stored, absorbed or lost.
    Stop,
}

impl Shooter<'_> {
    /// Traces photon `index` of `count` for `pass`.
    pub(super) fn trace(&self, pass: Pass, index: u64, count: u64, stored: &mut Stored) {
        let scene = self.scene;
        let salt = match pass {
            Pass::Caustic { .. } => 0xc0ff_ee00,
            Pass::Volume => 0x5ca7_7e12,
        };
        let mut rng = TrackingRng::new(index.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ salt);
        let waves = self.spectral.then(|| Wavelengths::sample(rng.next_f32()));
        let Some(Launch {
            light,
            emitted,
            beta,
            ray,
        }) = launch(
            scene,
            &self.table,
            self.sphere,
            count,
            &mut rng,
            waves.as_ref(),
        )
        else {
            return;
        };
        let beta = scene.light_radiance(light as u32, beta, waves.as_ref());
        let mut f = Flight {
            ray,
            beta,
            start: 0.0,
            rng,
            medium: self.start_medium(light, &emitted),
            events: 0,
            only_specular: true,
            pass_throughs: 0,
            nesting: Nesting::default(),
            walk: Walk::default(),
            waves,
            hero_only: false,
            lane_pdfs: crate::media::LANE_PDFS,
        };
        f.start = f.brightness(f.beta);
        loop {
            let found = scene.geometry.intersect(&f.ray, f32::INFINITY);
            if let Some(m) = f.medium {
                match self.in_medium(pass, &mut f, m, found.as_ref(), stored) {
                    Step::Continue => continue,
                    Step::Stop => return,
                    Step::Surface => {}
                }
            }
            let Some(mut hit) = found else { return };
            if let Step::Stop = self.at_surface(pass, &mut f, &mut hit, stored) {
                return;
            }
        }
    }

    /// The photon's segment through medium `m` up to `found`: crossed, or a scattering
    /// event (stored as the pass asks, then a new direction by the phase function).
    fn in_medium(
        &self,
        pass: Pass,
        f: &mut Flight,
        m: u32,
        found: Option<&SurfaceHit>,
        stored: &mut Stored,
    ) -> Step {
        let scene = self.scene;
        let t_max = found.map_or(f32::INFINITY, |h| h.t);
        // Photons carry no medium emission: the lights that are media shoot their own.
        let med = f.walk.medium(&scene.media, m);
        let waves = f.waves;
        let t = match med.sample_interaction(
            &f.ray,
            t_max,
            &mut f.rng,
            &mut f.beta,
            &mut f.lane_pdfs,
            waves.as_ref(),
            |_| {},
        ) {
            MediumEvent::Crossed => return Step::Surface,
            // A photon whose walk is cut off is lost (the camera paths report theirs).
            MediumEvent::Absorbed | MediumEvent::CutOff => return Step::Stop,
            MediumEvent::Scattered(t) => t,
        };
        let p = f.ray.at(t);
        let photon = Photon {
            p,
            wi: -f.ray.dir,
            n: Vec3A::ZERO,
            power: f.stored_power(),
        };
        // Inside a subsurface material the photon walks on, stored nowhere: camera paths
        // walk there themselves (and a walk ends a caustic).
        let in_walk = scene.is_walk_medium(m);
        match pass {
            Pass::Caustic { .. } if in_walk => {}
            Pass::Caustic { volume } => {
                if volume && f.events > 0 && f.only_specular {
                    stored.volume.push(photon);
                }
                return Step::Stop;
            }
            Pass::Volume if f.events > 0 && !in_walk => stored.volume.push(photon),
            Pass::Volume => {}
        }
        if in_walk {
            if !f.walk.take_event(self.walk_depth) {
                return Step::Stop;
            }
        } else {
            f.events += 1;
            if f.events >= self.max_depth {
                return Step::Stop;
            }
        }
        let phase = f.walk.medium(&scene.media, m).phase();
        // Phase functions are sampled exactly: the throughput is unchanged.
        let (wi, _) = phase.sample(-f.ray.dir, Vec2::new(f.rng.next_f32(), f.rng.next_f32()));
        f.only_specular = false;
        if !self.survives(f) {
            return Step::Stop;
        }
        f.ray = f.ray.spawn(p, wi);
        Step::Continue
    }

    /// The photon at the surface it reached: straight through an interface, stored where
    /// a caustic ends, or scattered by the BSDF.
    fn at_surface(
        &self,
        pass: Pass,
        f: &mut Flight,
        hit: &mut SurfaceHit,
        stored: &mut Stored,
    ) -> Step {
        let scene = self.scene;
        let waves = f.waves;
        let Some(bsdf) = scene.bsdf_nested(hit, 1.0, waves.as_ref(), &f.nesting, f.ray.dir) else {
            // An interface: straight on, into the medium on the other side.
            let before = f.medium;
            if !super::super::pass_through(
                scene,
                hit,
                &mut f.ray,
                &mut f.medium,
                &mut f.nesting,
                &mut f.pass_throughs,
            ) {
                return Step::Stop;
            }
            scene.enter_walk(hit, f.ray.dir, before, f.medium, &mut f.walk);
            return Step::Continue;
        };
        let specular = bsdf.is_specular();
        if let Pass::Caustic { .. } = pass
            && !specular
        {
            if f.events > 0 && f.only_specular {
                // The side the photon arrived on.
                let n = if f.ray.dir.dot(hit.ns) < 0.0 {
                    hit.ns
                } else {
                    -hit.ns
                };
                stored.surface.push(Photon {
                    p: hit.p,
                    wi: -f.ray.dir,
                    n,
                    power: f.stored_power(),
                });
            }
            return Step::Stop;
        }
        // Met from inside a subsurface walk, the surface is one of the walk's events.
        let in_walk = f.medium.is_some_and(|m| scene.is_walk_medium(m));
        if in_walk {
            if !f.walk.take_event(self.walk_depth) {
                return Step::Stop;
            }
        } else if f.events >= self.max_depth {
            return Step::Stop;
        }
        // A dispersive refraction keeps a spectral photon's hero wavelength alone (its
        // weight four times over), as camera paths keep theirs.
        if let crate::bsdfs::Bsdf::Dielectric(d) = &bsdf
            && d.dispersive
            && !f.hero_only
        {
            f.hero_only = true;
            f.beta = crate::media::hero_only(f.beta, f.lane_pdfs);
            f.lane_pdfs = crate::media::HERO_ONLY_LANE_PDFS;
        }
        let Some(bounce) = scatter(&bsdf, hit, f.ray.dir, &mut f.rng) else {
            return Step::Stop;
        };
        let wi = bounce.wi;
        f.beta *= bounce.weight;
        if !f.beta.is_finite() || f.beta == Color::ZERO {
            return Step::Stop;
        }
        if !in_walk {
            f.events += 1;
        }
        f.only_specular &= bounce.specular;
        if !self.survives(f) {
            return Step::Stop;
        }
        let before = f.medium;
        if !f
            .nesting
            .cross(&scene.nested, hit, f.ray.dir, wi, &mut f.medium)
        {
            return Step::Stop;
        }
        scene.enter_walk(hit, wi, before, f.medium, &mut f.walk);
        f.ray = f.ray.spawn(hit.origin_towards(wi), wi);
        Step::Continue
    }

    /// Russian roulette after an event: with weight-aware roulette a photon survives with
    /// probability min(1, throughput / starting power) and carries its power divided by it.
    fn survives(&self, f: &mut Flight) -> bool {
        if self.roulette == Roulette::Off {
            return true;
        }
        let q = (f.brightness(f.beta) / f.start).min(1.0);
        if q <= 0.0 || f.rng.next_f32() >= q {
            return false;
        }
        f.beta /= q;
        true
    }
}
