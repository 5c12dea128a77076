//! Integrators: the estimators that turn a camera ray into radiance.
//!
//! [`Integrator`] is built from the scene description's Integrator directive. Before any
//! tile renders, [`Integrator::prepare`] runs the job's pre-passes once (the caustic photon
//! maps, [`photons`]) into a [`Prepass`]; every camera ray then goes through
//! [`Integrator::li`]. The path tracers' steps live in [`path`], next-event estimation and
//! its weights in [`direct`].
//!
//! Integrators read the scene and never change it; the scene knows nothing of them.

mod direct;
mod path;
pub mod photons;

pub use photons::{CausticMaps, CausticSettings};

use crate::math::{Color, Ray};
use crate::sampling::PixelSampler;
use crate::scene::Scene;
use crate::work::Work;
use kiln_scene::{IntegratorDesc, LightStrategy};

/// Where each bounce's sample dimensions start: 4 for the film and lens, then 8 per bounce.
const CAMERA_DIMENSIONS: u32 = 4;
const DIMENSIONS_PER_BOUNCE: u32 = 8;

/// Settings of the path tracers that change the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSettings {
    /// pbrt's maxdepth: 1 is direct lighting only.
    pub max_depth: u32,
    /// The first bounce after which Russian roulette may end a path.
    pub rr_depth: u32,
    pub strategy: LightStrategy,
    /// Photons traced for the caustic photon maps (0: none, pure path tracing).
    pub caustic_photons: u64,
    /// Their search radius (0: 1/200 of the scene's radius).
    pub caustic_radius: f32,
    /// pbrt-v4's "regularize": BSDFs met after a non-specular bounce are roughened.
    pub regularize: bool,
}

impl PathSettings {
    pub fn from_description(i: &IntegratorDesc) -> PathSettings {
        PathSettings {
            max_depth: i.max_depth,
            rr_depth: i.rr_depth,
            strategy: i.strategy,
            caustic_photons: i.caustic_photons,
            caustic_radius: i.caustic_radius,
            regularize: i.regularize,
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
}

/// What an integrator computes once per job, before any tile: the same on every worker
/// whatever its thread count, so tiles stay pure functions of (scene, settings, tile).
#[derive(Debug, Clone, Default)]
pub struct Prepass {
    /// Caustic photon maps, when the integrator asks for them and the scene has lights
    /// that shoot photons.
    pub caustics: Option<CausticMaps>,
}

impl Integrator {
    /// The integrator a scene description asks for.
    pub fn from_description(desc: &IntegratorDesc) -> Integrator {
        let settings = PathSettings::from_description(desc);
        match desc.kind {
            kiln_scene::IntegratorKind::Path => Integrator::Path(settings),
            kiln_scene::IntegratorKind::VolPath => Integrator::VolPath(settings),
        }
    }

    /// Whether the scene must be built with its participating media.
    pub fn renders_media(&self) -> bool {
        match self {
            Integrator::Path(_) => false,
            Integrator::VolPath(_) => true,
        }
    }

    pub fn path_settings(&self) -> &PathSettings {
        match self {
            Integrator::Path(s) | Integrator::VolPath(s) => s,
        }
    }

    /// Runs the pre-passes this integrator needs on `scene`.
    pub fn prepare(&self, scene: &Scene) -> Prepass {
        let settings = self.path_settings();
        if settings.caustic_photons == 0 {
            return Prepass::default();
        }
        let radius = if settings.caustic_radius > 0.0 {
            settings.caustic_radius
        } else {
            scene.radius / 200.0
        };
        let maps = CausticMaps::build(
            scene,
            CausticSettings {
                photons: settings.caustic_photons,
                radius,
            },
        );
        Prepass {
            caustics: (!maps.is_empty()).then_some(maps),
        }
    }

    /// Radiance arriving along `ray`; `work` counts what it cost. Textures filter over the
    /// camera's pixel footprint times `footprint`. With `visible`, the first surface the
    /// ray reached (for a G-buffer) is written there.
    #[allow(clippy::too_many_arguments)]
    pub fn li(
        &self,
        prepass: &Prepass,
        scene: &Scene,
        footprint: f32,
        ray: Ray,
        sampler: &mut PixelSampler,
        work: &mut Work,
        visible: Option<&mut Option<crate::gbuffer::VisibleSurface>>,
    ) -> Color {
        match self {
            // The path tracer is the volumetric one; without media in the scene its medium
            // steps never run.
            Integrator::Path(settings) | Integrator::VolPath(settings) => {
                let ctx = path::PathContext {
                    scene,
                    settings,
                    prepass,
                    footprint,
                };
                path::path_li(&ctx, ray, sampler, work, visible)
            }
        }
    }
}
