//! How light transport is estimated: the integrator, its light sampler and strategy, and
//! Kiln's photon maps.

use crate::error::Loc;

/// Which estimator of direct lighting the path tracer uses. Only `Mis` is a
/// production setting; the others exist to check that the estimators agree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightStrategy {
    Mis,
    LightOnly,
    BsdfOnly,
}

/// How the path tracer chooses the light to sample at each vertex (pbrt-v4's
/// "lightsampler").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightSamplerKind {
    /// A bounding volume hierarchy over the lights, chosen by an importance that accounts
    /// for each cluster's power, distance and orientation from the shading point (pbrt-v4's
    /// default).
    #[default]
    Bvh,
    /// In proportion to each light's power, wherever the shading point is.
    Power,
    /// Every light equally.
    Uniform,
    /// In proportion to every light's importance from the shading point (the hierarchy's
    /// measure, without the hierarchy: exact, and linear in the number of lights).
    Exhaustive,
}

/// The integrators Kiln has: pbrt-v4's "path" ignores participating media, "volpath"
/// renders them. Integrators Kiln lacks are rendered with "volpath".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IntegratorKind {
    Path,
    VolPath,
    /// pbrt-v4's stochastic progressive photon mapping (surfaces only, as pbrt-v4's).
    Sppm,
}

/// How many events a subsurface walk may take unless the Integrator's "walkdepth" says
/// otherwise: enough that a walk in skin-like stuff (single-scattering albedo 0.99) is almost
/// never cut off before Russian roulette or its surface ends it.
pub const DEFAULT_WALK_DEPTH: u32 = 1024;

#[derive(Debug, Clone)]
pub struct IntegratorDesc {
    /// The name in the file ("path", "volpath", or one Kiln mapped onto those).
    pub name: String,
    /// What Kiln renders it with.
    pub kind: IntegratorKind,
    pub max_depth: u32,
    /// Russian roulette may end paths from this bounce on (Kiln's "integer rrdepth").
    pub rr_depth: u32,
    /// Whether the file set `rr_depth` itself.
    pub rr_depth_given: bool,
    /// Each sample is computed as pbrt-v4 computes it, where that changes the image: when
    /// the film clamps each sample ("maxcomponentvalue"), two estimators of the same mean
    /// give different images, so a clamped pbrt-v4 scene that leaves "rrdepth" alone gets
    /// pbrt-v4's own: Russian roulette from the second bounce with q = 1 − max β, and a
    /// uniform light at infinity found by BSDF sampling alone (its `allowIncompletePDF`).
    pub pbrt_estimator: bool,
    /// The most events one subsurface random walk may take, its scatterings inside and its
    /// reflections off the inside of its surface (Kiln's "integer walkdepth"). A walk counts
    /// as one bounce towards `max_depth`, as pbrt-v4's BSSRDF does.
    pub walk_depth: u32,
    pub strategy: LightStrategy,
    pub light_sampler: LightSamplerKind,
    /// pbrt-v4's "regularize": after the first non-specular bounce, microfacet BSDFs are
    /// roughened (alpha under 0.3 doubled, within [0.1, 0.3]).
    pub regularize: bool,
    /// Clamp the radiance of each path sample to this value (0 disables it).
    pub max_radiance: f32,
    /// Kiln's photon maps (none unless asked for, or Integrator "photonmap").
    pub photons: PhotonDesc,
    /// SPPM's photons per iteration ("integer photonsperiteration"; None: pbrt-v4's default,
    /// the number of pixels rendered).
    pub sppm_photons: Option<u64>,
    /// SPPM's initial search radius ("float radius", default 1).
    pub sppm_radius: f32,
    pub loc: Loc,
}

/// Kiln's photon maps (seeds 003 and 004): on "path" and "volpath" with
/// "integer causticphotons" or "integer volumephotons", or Integrator "photonmap", which
/// turns both on by default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotonDesc {
    /// Photons traced for the caustic maps ("integer causticphotons"; 0: none).
    pub caustic_photons: u64,
    /// Their search radius, or the k-nearest gather's largest ("float causticradius"; 0:
    /// 1/200 of the scene's radius).
    pub caustic_radius: f32,
    /// Gather the k nearest caustic photons ("integer causticnearest"; 0: all within the
    /// radius).
    pub caustic_nearest: u32,
    /// Photons traced for the volume map of multiply scattered light in media
    /// ("integer volumephotons"; 0: none).
    pub volume_photons: u64,
    /// As `caustic_radius`, for the volume map ("float volumeradius"; 0: 1/50 of the
    /// scene's radius).
    pub volume_radius: f32,
    /// As `caustic_nearest` ("integer volumenearest").
    pub volume_nearest: u32,
    /// Weight-aware Russian roulette while tracing photons ("string photonroulette":
    /// "weight", the default, or "none").
    pub roulette: bool,
}

impl PhotonDesc {
    /// No photon maps.
    pub const NONE: PhotonDesc = PhotonDesc {
        caustic_photons: 0,
        caustic_radius: 0.0,
        caustic_nearest: 0,
        volume_photons: 0,
        volume_radius: 0.0,
        volume_nearest: 0,
        roulette: true,
    };
}
