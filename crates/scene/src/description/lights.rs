//! Lights: emission attached to shapes (diffuse area lights and VolumeLights) and lights
//! of their own (point, spot, distant, infinite and the rest).

use super::media::{MediumId, VoxelGrid};
use crate::error::Loc;
use crate::spectrum::Rgb;
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// Emission attached to a shape by AreaLightSource.
#[derive(Debug, Clone, PartialEq)]
pub enum AreaLightDesc {
    Diffuse {
        /// Radiance, with `scale` already applied; with an image, the scale alone, which
        /// multiplies the image's linear RGB.
        radiance: Rgb,
        /// pbrt-v4's `"string filename"`: radiance from an image at the surface's (u, 1 − v),
        /// bilinearly interpolated, clamped at the edges.
        image: Option<Arc<crate::textures::TextureImage>>,
        two_sided: bool,
        /// The shape of the radiance's spectrum, where "L" was one (not with an image).
        spectrum: Option<crate::spectrum::EmissionSpectrum>,
        /// pbrt-v4's "power": the lumens each shape (each triangle of a mesh, as in
        /// pbrt-v4) emits; the radiance is then `radiance` · power / (π · area · sides ·
        /// the image's mean luminance, if any).
        power: Option<f32>,
        loc: Loc,
    },
    /// Seed 000's VolumeLight: the shape's interior emits, and the radiance leaving a
    /// surface point integrates that emission along the refracted interior segment.
    Volume(VolumeLightDesc),
}

/// `AreaLightSource "volume"`: emission inside a shape, seen through its surface.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeLightDesc {
    /// Emitted radiance per unit length inside the shape, `scale` applied.
    pub le: Rgb,
    /// Multipliers of `le` over the shape's object-space bounding box, trilinearly interpolated.
    pub grid: Option<Arc<VoxelGrid>>,
    /// Midpoint-rule steps along each interior segment (a uniform field needs only 1).
    pub steps: u32,
    /// Random interior segments per face for estimating each face's power.
    pub power_samples: u32,
    /// Absorption inside the shape, per unit length (emission-absorption); 0 by default.
    pub sigma_a: Rgb,
    pub loc: Loc,
}

/// A linear-RGB image (an environment map): row-major, top row first.
pub use kiln_image::ImageRgb;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvironmentLayout {
    /// pbrt-v4's equal-area octahedral square.
    EqualArea,
    /// Latitude-longitude (equirectangular), +z up in light space.
    LatLong,
}

#[derive(Debug, Clone)]
pub enum LightKind {
    Point {
        position: DVec3,
        intensity: Rgb,
    },
    Spot {
        position: DVec3,
        direction: DVec3,
        intensity: Rgb,
        cos_falloff_start: f64,
        cos_falloff_end: f64,
    },
    /// Light arriving from one direction; `direction` points from the scene towards the light.
    Distant {
        direction: DVec3,
        radiance: Rgb,
    },
    /// Constant radiance from every direction.
    UniformInfinite {
        radiance: Rgb,
    },
    /// Radiance from an environment map; `light_to_world` orients it.
    ImageInfinite {
        image: Arc<ImageRgb>,
        layout: EnvironmentLayout,
        scale: f32,
        light_to_world: DMat4,
        /// pbrt-v4's "portal": a world-space rectangle (a window); light arrives only from
        /// the side its normal (p3 − p0) × (p1 − p0) faces.
        portal: Option<[[f64; 3]; 4]>,
    },
    /// pbrt-v4's "goniometric": a point light whose intensity over directions is an
    /// equal-area square image's (the mean of its RGB), times `intensity`. The light looks
    /// along its space's y axis (pbrt-v4 swaps y and z).
    Goniometric {
        light_to_world: DMat4,
        intensity: Rgb,
        image: Arc<ImageRgb>,
    },
    /// pbrt-v4's "projection": a point light casting an image through a frustum of `fov`
    /// degrees along its space's +z, `scale` times the image's RGB as intensity.
    Projection {
        light_to_world: DMat4,
        scale: f32,
        fov: f64,
        image: Arc<ImageRgb>,
    },
    /// Constant radiance from the hemisphere around `up` only (seed 003's dome light).
    Dome {
        radiance: Rgb,
        up: DVec3,
    },
}

#[derive(Debug, Clone)]
pub struct LightDesc {
    pub kind: LightKind,
    /// The outside medium current at the LightSource directive: where photons from the light
    /// start (pbrt-v4 records it the same way).
    pub medium: Option<MediumId>,
    /// The shape of the light's spectrum, where its colour ("I" or "L") was given as one
    /// (not for lights whose colour is an image's).
    pub spectrum: Option<crate::spectrum::EmissionSpectrum>,
    pub loc: Loc,
}
