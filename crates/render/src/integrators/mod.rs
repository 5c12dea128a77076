//! Integrators: the estimators that turn a camera ray into radiance.
//!
//! [`Integrator`] is built from the scene description's Integrator directive. Before any
//! tile renders, [`Integrator::prepare`] runs the job's pre-passes once (the photon maps,
//! [`photons`]) into a [`Prepass`]; every camera ray then goes through the
//! [`PathTracer`] of [`Integrator::path_tracer`], whose paths advance in stages so that
//! `crate::tile` runs each stage over a wave of them. The path tracers' steps live in
//! [`path`], next-event estimation and its weights in [`direct`].
//!
//! Integrators read the scene and never change it; the scene knows nothing of them.

mod direct;
mod path;
pub mod photons;
pub mod sppm;

pub(crate) use path::{Outcome, Path, PathTracer};
pub use photons::{Gather, PhotonMaps, PhotonSettings, Roulette};
pub use sppm::SppmSettings;

use crate::math::Ray;
use crate::scene::Scene;
use kiln_scene::{IntegratorDesc, LightStrategy, PhotonDesc};

/// Where each bounce's sample dimensions start: 4 for the film and lens, then 8 per bounce.
const CAMERA_DIMENSIONS: u32 = 4;
const DIMENSIONS_PER_BOUNCE: u32 = 8;

/// The most interface surfaces a path (or photon) crosses without scattering before it is
/// given up: a ray caught between coincident interfaces would otherwise never end.
const MAX_PASS_THROUGHS: u32 = 256;

/// Crosses the surface at `hit` straight on (an interface without a BSDF, or a nested
/// shape's boundary that is hidden or joins equal indices): counts it in `crossed`, moves
/// `medium` (and `nesting`) to the other side and `ray` past it. False when the path has
/// crossed [`MAX_PASS_THROUGHS`] already, or is nested too deep, and should end.
fn pass_through(
    scene: &Scene,
    hit: &crate::shapes::SurfaceHit,
    ray: &mut Ray,
    medium: &mut Option<u32>,
    nesting: &mut crate::nesting::Nesting,
    crossed: &mut u32,
) -> bool {
    *crossed += 1;
    if *crossed > MAX_PASS_THROUGHS || !nesting.cross(&scene.nested, hit, ray.dir, ray.dir, medium)
    {
        return false;
    }
    *ray = ray.spawn(hit.origin_towards(ray.dir), ray.dir);
    true
}

/// Settings of the path tracers that change the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSettings {
    /// pbrt's maxdepth: 1 is direct lighting only.
    pub max_depth: u32,
    /// The first bounce after which Russian roulette may end a path.
    pub rr_depth: u32,
    /// The most events one subsurface walk may take (see [`kiln_scene::IntegratorDesc`]).
    pub walk_depth: u32,
    pub strategy: LightStrategy,
    /// The photon maps to build (none: pure path tracing).
    pub photons: PhotonDesc,
    /// pbrt-v4's "regularize": BSDFs met after a non-specular bounce are roughened.
    pub regularize: bool,
    /// Samples computed as pbrt-v4 computes them (see
    /// [`kiln_scene::IntegratorDesc::pbrt_estimator`]).
    pub pbrt_estimator: bool,
}

impl PathSettings {
    pub fn from_description(i: &IntegratorDesc) -> PathSettings {
        PathSettings {
            max_depth: i.max_depth,
            rr_depth: i.rr_depth,
            walk_depth: i.walk_depth,
            strategy: i.strategy,
            photons: i.photons,
            regularize: i.regularize,
            pbrt_estimator: i.pbrt_estimator,
        }
    }
}

/// The estimator used for every camera ray of a render.
#[derive(Debug, Clone, PartialEq)]
pub enum Integrator {
    /// pbrt-v4's "path": surfaces only. As in pbrt-v4, participating media are ignored:
    /// the scene is built without them.
    Path(PathSettings),
    /// pbrt-v4's "volpath": surfaces and participating media.
    VolPath(PathSettings),
    /// pbrt-v4's "sppm": stochastic progressive photon mapping, iterations from the samples
    /// per pixel; surfaces only, as pbrt-v4's. Rendered by [`crate::tile`]'s SPPM driver,
    /// not through [`Integrator::path_tracer`].
    Sppm(SppmSettings),
}

/// What an integrator computes once per job, before any tile: the same on every worker
/// whatever its thread count, so tiles stay pure functions of (scene, settings, tile).
#[derive(Debug, Clone, Default)]
pub struct Prepass {
    /// Photon maps, when the integrator asks for them and some light emits.
    pub photons: Option<PhotonMaps>,
}

impl Integrator {
    /// The integrator a scene description asks for.
    pub fn from_description(desc: &IntegratorDesc) -> Integrator {
        let settings = PathSettings::from_description(desc);
        match desc.kind {
            kiln_scene::IntegratorKind::Path => Integrator::Path(settings),
            kiln_scene::IntegratorKind::VolPath => Integrator::VolPath(settings),
            kiln_scene::IntegratorKind::Sppm => Integrator::Sppm(SppmSettings {
                max_depth: desc.max_depth,
                // Resolved from the pixels rendered by RenderSettings::from_description.
                photons_per_iteration: desc.sppm_photons.unwrap_or(0),
                radius: desc.sppm_radius,
            }),
        }
    }

    /// Whether the scene must be built with its participating media.
    pub fn renders_media(&self) -> bool {
        match self {
            Integrator::Path(_) | Integrator::Sppm(_) => false,
            Integrator::VolPath(_) => true,
        }
    }

    /// The path tracer's settings; None for SPPM.
    pub fn path_settings(&self) -> Option<&PathSettings> {
        match self {
            Integrator::Path(s) | Integrator::VolPath(s) => Some(s),
            Integrator::Sppm(_) => None,
        }
    }

    /// Runs the pre-passes this integrator needs on `scene` (for an RGB render).
    pub fn prepare(&self, scene: &Scene) -> Prepass {
        self.prepare_sharing(scene, None, false)
    }

    /// [`Integrator::prepare`], taking the photon maps from `shared` when another worker
    /// of the job has built them (and publishing them when this one builds them).
    /// `spectral`: photons fly at wavelengths of their own (see [`PhotonSettings::spectral`]).
    pub fn prepare_sharing(
        &self,
        scene: &Scene,
        shared: Option<&dyn crate::shared::SharedPrepass>,
        spectral: bool,
    ) -> Prepass {
        let Some(mut settings) = self.photon_settings(scene) else {
            return Prepass::default();
        };
        settings.spectral = spectral;
        let build = || PhotonMaps::build(scene, &settings);
        let maps = match shared {
            None => build(),
            Some(shared) => crate::shared::shared_or_built(
                shared,
                "photon-maps",
                build,
                PhotonMaps::to_bytes,
                |b| PhotonMaps::from_bytes(b, &settings),
                || false,
                &|| false,
            )
            .expect("never stopped"),
        };
        Prepass {
            photons: (!maps.is_empty()).then_some(maps),
        }
    }

    /// The photon pass this integrator asks for on `scene`, with its automatic radii
    /// resolved; None for none.
    pub fn photon_settings(&self, scene: &Scene) -> Option<PhotonSettings> {
        let settings = self.path_settings()?;
        let p = &settings.photons;
        // Without media there is nothing for a volume map to hold.
        let volume_photons = if scene.media.is_empty() {
            0
        } else {
            p.volume_photons
        };
        if p.caustic_photons == 0 && volume_photons == 0 {
            return None;
        }
        let gather = |radius: f32, automatic: f32, k: u32| {
            let r = if radius > 0.0 { radius } else { automatic };
            if k == 0 {
                Gather::Radius(r)
            } else {
                Gather::Nearest { k, max_radius: r }
            }
        };
        Some(PhotonSettings {
            caustic_photons: p.caustic_photons,
            caustic_gather: gather(p.caustic_radius, scene.radius / 200.0, p.caustic_nearest),
            volume_photons,
            volume_gather: gather(p.volume_radius, scene.radius / 50.0, p.volume_nearest),
            max_depth: settings.max_depth,
            walk_depth: settings.walk_depth,
            roulette: if p.roulette {
                Roulette::WeightAware
            } else {
                Roulette::Off
            },
            spectral: false,
        })
    }

    /// The path tracer every camera ray of a render goes through, textures filtered over
    /// the camera's pixel footprint times `footprint`; None for SPPM, whose pixels come from
    /// its own driver ([`crate::tile`]).
    pub(crate) fn path_tracer<'a>(
        &'a self,
        prepass: &'a Prepass,
        scene: &'a Scene,
        footprint: f32,
    ) -> Option<PathTracer<'a>> {
        match self {
            // The path tracer is the volumetric one; without media in the scene its medium
            // steps never run.
            Integrator::Path(settings) | Integrator::VolPath(settings) => Some(PathTracer {
                scene,
                settings,
                prepass,
                footprint,
            }),
            Integrator::Sppm(_) => None,
        }
    }
}
