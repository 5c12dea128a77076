//! Photon maps (seeds 003 and 004). Light that reaches a diffuse surface or a medium only
//! through specular surfaces (a glass lens focusing a small light) is nearly impossible for
//! a path tracer to find from the camera and easy to find from the lights; light scattered
//! many times in a medium is slow to converge either way. Photons are traced from every
//! light, chosen in proportion to its power ([`Light::emit`]), and stored in three maps:
//!
//! - the **caustic surface map**: where a photon first meets a non-specular surface after
//!   one or more specular bounces and nothing else (paths L S+ D);
//! - the **caustic volume map**: where such a photon first scatters in a medium, when no
//!   volume map is built;
//! - the **volume map**: every scattering event in a medium after the photon's first event
//!   of any kind (light scattered once or more before; direct light is left to next-event
//!   estimation so that it is not counted twice). These photons go on after scattering.
//!
//! Free flights through media use the path tracer's own sampling (delta and ratio tracking
//! for grids), so interaction points are unbiased by construction. With weight-aware
//! Russian roulette ([`Roulette::WeightAware`]) a photon survives each event with a
//! probability that is its throughput over its starting power, and carries its power
//! divided by that: stored photons carry nearly equal power, with no bright outliers.
//!
//! The maps are built once per render, before any tile, from a fixed number of photons
//! with seeds that depend only on the photon's index, in batches whose results are joined
//! in order: every worker builds the same maps whatever its thread count.
//!
//! [`Light::emit`]: crate::lights::Light::emit

mod flight;
pub mod map;

pub use map::{Gather, Photon, PhotonMap};

use crate::lights::{EmittedRay, Light, SceneSphere};
use crate::math::{Color, Frame, Ray, luminance, offset_origin, surface_epsilon};
use crate::sampling::{AliasTable, TrackingRng};
use crate::scene::Scene;
use crate::shapes::NO_MEDIUM;
use crate::spectral::Wavelengths;
use glam::{Vec2, Vec3A};
use rayon::prelude::*;
use std::f32::consts::PI;

/// How photons end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Roulette {
    /// Only at the depth limit (what Kiln did first): stored powers spread widely.
    Off,
    /// Survival in proportion to throughput over starting power (seed 004).
    WeightAware,
}

/// What to trace and how to gather it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotonSettings {
    /// Photons traced for the caustic maps (0: none).
    pub caustic_photons: u64,
    pub caustic_gather: Gather,
    /// Photons traced for the volume map (0: none).
    pub volume_photons: u64,
    pub volume_gather: Gather,
    /// Events (bounces and scatterings) a photon may have; a subsurface walk counts as
    /// one, the bounce that entered it.
    pub max_depth: u32,
    /// The most events of one subsurface walk.
    pub walk_depth: u32,
    pub roulette: Roulette,
    /// For a spectral render: each photon flies at four wavelengths of its own, and is
    /// stored with the linear sRGB the film would record of its power.
    pub spectral: bool,
}

/// The photon maps of a scene.
#[derive(Debug, Clone, Default)]
pub struct PhotonMaps {
    /// Whether caustic photons were traced: camera paths then gather them at every
    /// non-specular vertex and stop counting the light they hold.
    pub caustics: bool,
    pub caustic_surface: PhotonMap,
    pub caustic_volume: PhotonMap,
    /// Whether volume photons were traced: medium vertices then take all their indirect
    /// light from `volume` and end the path.
    pub volume_pass: bool,
    pub volume: PhotonMap,
}

/// Photons per parallel batch: the batches, not the threads, fix the order of the result.
pub(super) const BATCH: u64 = 4096;

/// Which maps a pass fills.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Caustic photons; with `volume` also their first scattering in media.
    Caustic {
        volume: bool,
    },
    Volume,
}

/// Where a pass puts photons.
#[derive(Default)]
struct Stored {
    surface: Vec<Photon>,
    volume: Vec<Photon>,
}

impl PhotonMaps {
    /// Traces the photons `settings` asks for.
    pub fn build(scene: &Scene, settings: &PhotonSettings) -> PhotonMaps {
        let mut maps = PhotonMaps::default();
        let Some(shooter) = Shooter::new(scene, settings) else {
            return maps;
        };
        if settings.caustic_photons > 0 {
            let pass = Pass::Caustic {
                volume: settings.volume_photons == 0,
            };
            let s = shooter.shoot(pass, settings.caustic_photons);
            maps.caustics = true;
            maps.caustic_surface = PhotonMap::new(s.surface, settings.caustic_gather);
            maps.caustic_volume = PhotonMap::new(s.volume, settings.caustic_gather);
        }
        if settings.volume_photons > 0 {
            let s = shooter.shoot(Pass::Volume, settings.volume_photons);
            maps.volume_pass = true;
            maps.volume = PhotonMap::new(s.volume, settings.volume_gather);
        }
        maps
    }

    /// The maps as bytes (see [`map::encode`]): which passes ran, then the three maps'
    /// photons.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = vec![u8::from(self.caustics) | (u8::from(self.volume_pass) << 1)];
        out.extend(map::encode(&[
            self.caustic_surface.photons(),
            self.caustic_volume.photons(),
            self.volume.photons(),
        ]));
        out
    }

    /// Maps from [`PhotonMaps::to_bytes`], gathered as `settings` says.
    pub fn from_bytes(bytes: &[u8], settings: &PhotonSettings) -> Result<PhotonMaps, String> {
        let (&flags, rest) = bytes.split_first().ok_or("no photon maps")?;
        let lists: [Vec<Photon>; 3] = map::decode(rest)?
            .try_into()
            .map_err(|l: Vec<_>| format!("{} photon lists, not 3", l.len()))?;
        let [surface, caustic_volume, volume] = lists;
        Ok(PhotonMaps {
            caustics: flags & 1 != 0,
            caustic_surface: PhotonMap::new(surface, settings.caustic_gather),
            caustic_volume: PhotonMap::new(caustic_volume, settings.caustic_gather),
            volume_pass: flags & 2 != 0,
            volume: PhotonMap::new(volume, settings.volume_gather),
        })
    }

    /// Whether no pass ran (no light emits).
    pub fn is_empty(&self) -> bool {
        !self.caustics && !self.volume_pass
    }

    /// Caustic radiance leaving surface point `p` (normal `n` on the side looked at) towards
    /// the viewer, given the BSDF for each photon's direction (`f(wi)`; the photon's flux
    /// already holds its cosine); at a spectral path's `waves`, each photon's recorded RGB
    /// taken as light of that colour.
    pub fn surface_radiance(
        &self,
        p: Vec3A,
        n: Vec3A,
        f: impl Fn(Vec3A) -> Color,
        waves: Option<&Wavelengths>,
    ) -> Color {
        let (sum, r) = self.caustic_surface.sum(p, |ph| {
            if ph.n.dot(n) > 0.9 {
                power_at(ph, waves) * f(ph.wi)
            } else {
                Color::ZERO
            }
        });
        if r > 0.0 { sum / (PI * r * r) } else { sum }
    }

    /// Radiance scattered at medium point `p` towards `wo`, times sigma_s there, from the
    /// volume map if there is one (all light but the direct), else from the caustic volume
    /// map: the sum of phase * flux over the gathered photons over the ball's volume.
    /// `phase(wo, wi)`.
    pub fn medium_radiance(
        &self,
        p: Vec3A,
        wo: Vec3A,
        phase: impl Fn(Vec3A, Vec3A) -> f32,
        waves: Option<&Wavelengths>,
    ) -> Color {
        let map = if self.volume_pass {
            &self.volume
        } else {
            &self.caustic_volume
        };
        let (sum, r) = map.sum(p, |ph| power_at(ph, waves) * phase(wo, ph.wi));
        if r > 0.0 {
            sum / (4.0 / 3.0 * PI * r * r * r)
        } else {
            sum
        }
    }

    /// Whether medium vertices take all their indirect light from the volume map (and end
    /// the path there).
    pub fn has_volume_map(&self) -> bool {
        self.volume_pass
    }
}

/// A stored photon's power as a path sees it: its RGB, or at a spectral path's `waves` the
/// spectrum of light of that colour. (A spectral photon flew at wavelengths of its own,
/// which a path gathering it does not share: what it brings is the colour the film would
/// record of it, met by the gathering surface's spectrum.) That colour, four wavelengths'
/// estimate, is often out of gamut: its negative components count as negative light.
fn power_at(ph: &Photon, waves: Option<&Wavelengths>) -> Color {
    match waves {
        None => ph.power,
        Some(w) => w.signed_illuminant(ph.power),
    }
}

/// The coefficient of variation (standard deviation over mean) of the stored photons'
/// luminance: how unequal their powers are.
pub fn power_spread(photons: &[Photon]) -> f64 {
    let n = photons.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let y: Vec<f64> = photons.iter().map(|p| luminance(p.power) as f64).collect();
    let mean = y.iter().sum::<f64>() / n;
    let var = y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    if mean > 0.0 { var.sqrt() / mean } else { 0.0 }
}

/// What photons leave from: the lights' powers to choose them by, and the scene's bounding
/// sphere that lights at infinity shine onto. Made once per render.
pub struct Emitters {
    pub(super) table: AliasTable,
    pub(super) sphere: SceneSphere,
}

impl Emitters {
    /// None where no light emits.
    pub fn of(scene: &Scene) -> Option<Emitters> {
        let powers: Vec<f64> = scene
            .lights
            .iter()
            .map(|l| l.power(scene.radius).max(0.0) as f64)
            .collect();
        if powers.iter().all(|p| *p <= 0.0) {
            return None;
        }
        let (lo, hi) = scene.geometry.bounds();
        let sphere = SceneSphere {
            center: (lo + hi) * 0.5,
            radius: scene.radius,
        };
        Some(Emitters {
            table: AliasTable::new(&powers),
            sphere,
        })
    }
}

/// A photon leaving a light.
pub(super) struct Launch {
    /// The light's index.
    pub light: usize,
    pub emitted: EmittedRay,
    /// Its flux over the light's probability and the photon count: RGB, as
    /// [`Scene::light_radiance`] takes it.
    pub beta: Color,
    /// Its first ray, at an instant of the shutter, off the light's surface.
    pub ray: Ray,
}

/// Chooses a light by `table` (its powers) and a ray leaving it, from `rng`'s next numbers;
/// None where it emits nothing that way.
pub(super) fn launch(
    scene: &Scene,
    table: &AliasTable,
    sphere: SceneSphere,
    count: u64,
    rng: &mut TrackingRng,
    waves: Option<&Wavelengths>,
) -> Option<Launch> {
    let (light, pmf) = table.sample(rng.next_f32())?;
    let u = [
        Vec2::new(rng.next_f32(), rng.next_f32()),
        Vec2::new(rng.next_f32(), rng.next_f32()),
    ];
    let uc = rng.next_f32();
    let (emitted, _) = scene.lights[light].emit(&scene.light_context_at(waves), sphere, u, uc);
    let emitted = emitted?;
    let beta = emitted.flux / (pmf * count as f32);
    if !(luminance(beta) > 0.0 && beta.is_finite()) {
        return None;
    }
    // A photon flies at one instant of the shutter, as a camera path does.
    let time = if scene.has_motion {
        scene.shutter[0] + (scene.shutter[1] - scene.shutter[0]) * rng.next_f32()
    } else {
        0.0
    };
    let origin = if emitted.n == Vec3A::ZERO {
        emitted.origin
    } else {
        offset_origin(
            emitted.origin,
            emitted.n,
            surface_epsilon(emitted.origin),
            emitted.dir,
        )
    };
    Some(Launch {
        light,
        emitted,
        beta,
        ray: Ray::at_time(origin, emitted.dir, time),
    })
}

/// A photon's bounce off a surface.
pub(super) struct Bounce {
    pub wi: Vec3A,
    /// What the photon's flux is multiplied by.
    pub weight: Color,
    pub specular: bool,
}

/// Samples the direction a photon arriving along `dir` leaves `hit` in, by its BSDF.
pub(super) fn scatter(
    bsdf: &crate::bsdfs::Bsdf,
    hit: &crate::shapes::SurfaceHit,
    dir: Vec3A,
    rng: &mut TrackingRng,
) -> Option<Bounce> {
    let frame = Frame::new(hit.ns, hit.dpdu);
    let wo = -dir;
    let uc = rng.next_f32();
    let u = Vec2::new(rng.next_f32(), rng.next_f32());
    let bs = bsdf.sample(frame.to_local(wo), uc, u)?;
    if bs.pdf <= 0.0 {
        return None;
    }
    let wi = frame.to_world(bs.wi);
    // Flux, not radiance, crosses a refraction: undo the BSDF's 1/eta^2. Shading normals
    // make light transport asymmetric: pbrt's correction for importance, bounded.
    let shading =
        (wo.dot(hit.ns) * wi.dot(hit.ng)).abs() / (wo.dot(hit.ng) * wi.dot(hit.ns)).abs().max(1e-8);
    Some(Bounce {
        wi,
        weight: bs.f * (wi.dot(hit.ns).abs() / bs.pdf * (bs.eta * bs.eta) * shading.min(10.0)),
        specular: bs.specular,
    })
}

/// Chooses lights by power and traces photons from them.
struct Shooter<'a> {
    scene: &'a Scene,
    table: AliasTable,
    sphere: SceneSphere,
    max_depth: u32,
    walk_depth: u32,
    roulette: Roulette,
    spectral: bool,
}

impl<'a> Shooter<'a> {
    fn new(scene: &'a Scene, settings: &PhotonSettings) -> Option<Shooter<'a>> {
        let Emitters { table, sphere } = Emitters::of(scene)?;
        Some(Shooter {
            scene,
            table,
            sphere,
            max_depth: settings.max_depth,
            walk_depth: settings.walk_depth,
            roulette: settings.roulette,
            spectral: settings.spectral,
        })
    }

    /// Traces `count` photons of `pass`.
    fn shoot(&self, pass: Pass, count: u64) -> Stored {
        let batches: Vec<Stored> = (0..count.div_ceil(BATCH))
            .into_par_iter()
            .map(|b| {
                let mut stored = Stored::default();
                for i in b * BATCH..((b + 1) * BATCH).min(count) {
                    self.trace(pass, i, count, &mut stored);
                }
                stored
            })
            .collect();
        let mut all = Stored::default();
        for s in batches {
            all.surface.extend(s.surface);
            all.volume.extend(s.volume);
        }
        all
    }

    /// The medium a photon leaving light `light` along `ray` starts in: for area lights the
    /// one on the side it leaves by, for lights in space the medium they were declared in,
    /// for lights at infinity the camera's (the medium outside everything).
    fn start_medium(&self, light: usize, ray: &EmittedRay) -> Option<u32> {
        let scene = self.scene;
        match scene.light_media.get(light).copied().flatten() {
            Some([inside, outside]) => {
                let m = if ray.n == Vec3A::ZERO || ray.dir.dot(ray.n) > 0.0 {
                    outside
                } else {
                    inside
                };
                (m != NO_MEDIUM).then_some(m)
            }
            None => match &scene.lights[light] {
                Light::Distant(_)
                | Light::UniformInfinite(_)
                | Light::ImageInfinite(_)
                | Light::Dome(_) => scene.camera_medium,
                Light::Medium(l) => Some(l.medium),
                _ => None,
            },
        }
    }
}
