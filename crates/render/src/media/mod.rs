//! Participating media: what fills the space between surfaces.
//!
//! [`Medium`] is the closed set of kinds and its dispatch; each kind lives in its own file
//! ([`homogeneous`], [`grid`]; [`subsurface`] builds a subsurface material's interior), beside the one
//! voxel-grid type ([`voxel_grid`]) that grid media and VolumeLight interiors share.
//! Free-flight sampling, transmittance and the scattering coefficient are asked of a
//! `Medium`, never of a kind: a new kind is added here and the compiler lists the rest.
//!
//! Media know nothing of the scene, its lights or the integrators.

pub mod cloud;
pub mod grid;
pub mod homogeneous;
pub mod subsurface;

pub mod voxel_grid;

pub use crate::phase::Phase;
pub use grid::{GridMedium, Walk};
pub use homogeneous::HomogeneousMedium;
pub use voxel_grid::SampledGrid;

use crate::math::{Color, Ray};
use crate::sampling::TrackingRng;
use crate::spectral::Wavelengths;
use glam::Vec3A;

/// A medium: what fills the space between surfaces.
#[derive(Debug, Clone)]
pub enum Medium {
    Homogeneous(HomogeneousMedium),
    /// Coefficients scaled by a density grid, with optional emission (a heterogeneous medium).
    Grid(Box<GridMedium>),
}

/// What free-flight sampling through a medium segment found.
pub enum MediumEvent {
    /// The segment was crossed: the ray reaches its surface (or escapes).
    Crossed,
    /// Absorbed: the path ends.
    Absorbed,
    /// Scattered at this distance along the ray.
    Scattered(f32),
    /// The walk through a grid was cut off at [`MAX_TRACKING_STEPS`](crate::work::MAX_TRACKING_STEPS)
    /// collisions: the path ends, and the sample is reported.
    CutOff,
}

/// Emission met by free-flight sampling, handed to the caller to weight and add.
pub enum Emitted {
    /// A whole segment's emission in closed form, already times the throughput. No other
    /// strategy finds it (a homogeneous medium is not sampled as a light).
    Segment(Color),
    /// Emission at a tentative collision at distance `t`, where the majorant is
    /// `sigma_maj`: `radiance` is beta * sigma_a * Le, to be divided by `sigma_maj`. Sampling
    /// the medium as a light could also have found it.
    Collision {
        t: f32,
        sigma_maj: f32,
        radiance: Color,
    },
}

/// The sum of a colour's first `lanes` lanes: its three channels in RGB ((r + g) + b, as
/// RGB always summed them), a spectral path's four wavelengths.
fn lane_sum(c: Color, lanes: usize) -> f32 {
    if lanes == 4 {
        c.element_sum()
    } else {
        crate::math::rgb_sum(c)
    }
}

/// A spectral path's relative densities of having been sampled with each of its four lanes
/// as the hero (normalised to a mean of 1; pbrt-v4's r_u), before any medium event
/// changed them: equal. See `homogeneous::track_hero`.
pub const LANE_PDFS: Color = Color::ONE;

/// The same after a dispersive refraction kept only the hero (lane 0): from there on the path
/// is sampled by the hero alone, so only its density counts.
pub const HERO_ONLY_LANE_PDFS: Color = Color::new(4.0, 0.0, 0.0, 0.0);

/// The throughput a spectral path keeps when a dispersive refraction leaves it its hero
/// wavelength alone: the hero's, four times over (the film averages the four lanes), and
/// over the hero's own density of the path so far rather than the four lanes' mean, which
/// the throughput was divided by ([`LANE_PDFS`]): that mean weighs the lanes only while
/// all four go on. (With no medium met, `lane_pdfs` is 1 and this is 4 times the hero's.)
pub fn hero_only(beta: Color, lane_pdfs: Color) -> Color {
    Color::new(4.0 * beta.x / lane_pdfs.x, 0.0, 0.0, 0.0)
}

/// The mean of a colour's first `lanes` lanes (see [`lane_sum`]).
fn lane_mean(c: Color, lanes: usize) -> f32 {
    lane_sum(c, lanes) / lanes as f32
}

impl Medium {
    /// The box in world space outside which the medium has no density (None: unbounded).
    pub fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        match self {
            Medium::Homogeneous(_) => None,
            Medium::Grid(g) => Some(g.world_bounds()),
        }
    }

    pub fn phase(&self) -> Phase {
        match self {
            Medium::Homogeneous(h) => h.phase,
            Medium::Grid(g) => g.phase,
        }
    }

    /// The scattering coefficient at world point `p`: in RGB, or at a spectral path's
    /// `waves`.
    pub fn sigma_s_at(&self, p: Vec3A, waves: Option<&Wavelengths>) -> Color {
        match (self, waves) {
            (Medium::Homogeneous(h), None) => h.sigma_s,
            (Medium::Homogeneous(h), Some(w)) => w.unbounded(h.sigma_s),
            (Medium::Grid(g), w) => g.coefficients_at(g.to_box(p), w).1,
        }
    }

    /// Transmittance along the segment from `o` in unit direction `d` over (0, `t`); grid
    /// media estimate it by ratio tracking with numbers from `rng` (None if that walk was
    /// cut off). With `waves`, at a spectral path's wavelengths.
    pub fn transmittance(
        &self,
        o: Vec3A,
        d: Vec3A,
        t: f32,
        rng: &mut TrackingRng,
        waves: Option<&Wavelengths>,
    ) -> Option<Color> {
        match (self, waves) {
            (Medium::Homogeneous(h), None) => Some(h.transmittance(t)),
            (Medium::Homogeneous(h), Some(w)) => Some(h.at_wavelengths(w).transmittance(t)),
            (Medium::Grid(g), w) => g.transmittance(o, d, t, rng, w),
        }
    }

    /// Free-flight sampling along `ray` over (0, `t_max`), updating the throughput `beta`.
    /// Emission met on the way goes to `emitted` (see [`Emitted`]) before the event it
    /// precedes is chosen. The path tracer and the photon tracer share this; with `waves`,
    /// a spectral path at those wavelengths, whose lanes' relative densities of being
    /// sampled so far are `lane_pdfs` (see [`LANE_PDFS`]).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_interaction(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut TrackingRng,
        beta: &mut Color,
        lane_pdfs: &mut Color,
        waves: Option<&Wavelengths>,
        mut emitted: impl FnMut(Emitted),
    ) -> MediumEvent {
        match self {
            Medium::Homogeneous(h) => {
                let spectral;
                let (h, lane_pdfs) = match waves {
                    None => (h, None),
                    Some(w) => {
                        spectral = h.at_wavelengths(w);
                        (&spectral, Some(lane_pdfs))
                    }
                };
                emitted(Emitted::Segment(*beta * h.segment_emission(t_max)));
                h.sample_interaction(t_max, rng, beta, lane_pdfs)
            }
            Medium::Grid(g) => g.track(ray, t_max, rng, beta, waves, |t, sigma_maj, radiance| {
                emitted(Emitted::Collision {
                    t,
                    sigma_maj,
                    radiance,
                })
            }),
        }
    }

    /// The medium as a light: its emitted power (luminance times 4 pi), when it is an
    /// emissive grid with a distribution to sample its emission by.
    pub fn light_power(&self) -> Option<f32> {
        match self {
            Medium::Homogeneous(_) => None,
            Medium::Grid(g) => g.emission_distribution.is_some().then(|| g.emitted_power()),
        }
    }
}
