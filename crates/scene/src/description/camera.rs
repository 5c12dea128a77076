//! The camera and what makes its image: projection (lens systems and apertures), film
//! (with the G-buffer's channels and the pixel sensor), sampler and pixel filter.

use crate::error::Loc;
use glam::DMat4;
use std::sync::Arc;

#[derive(Debug, Clone, PartialEq)]
pub enum Projection {
    /// `fov` is the full angle, in degrees, of the shorter image axis.
    Perspective {
        fov_degrees: f64,
    },
    Orthographic,
    /// pbrt-v4's spherical camera: the whole sphere of directions on the film, in the
    /// equal-area square layout or as an equirectangular (latitude-longitude) map.
    Spherical {
        equal_area: bool,
    },
    /// pbrt-v4's realistic camera: rays traced from the film through a lens system.
    Realistic(Arc<RealisticLens>),
}

/// A lens system as pbrt-v4's lens files give it, front (scene side) to back, and how it
/// is set.
#[derive(Debug, Clone, PartialEq)]
pub struct RealisticLens {
    /// Per interface, in millimetres as in the file: curvature radius (0: the aperture
    /// stop), thickness (the distance to the next interface, or to the film for the last),
    /// the index of refraction behind it (0: air), and its aperture diameter.
    pub elements: Vec<[f64; 4]>,
    /// The aperture stop's diameter, in millimetres ("aperturediameter").
    pub aperture_diameter: f64,
    /// The distance in focus, in metres ("focusdistance").
    pub focus_distance: f64,
    /// The aperture's shape as a grey image over the stop's square, looked up at
    /// ((x / r + 1) / 2, (y / r + 1) / 2) for a point (x, y) on a stop of radius r, row 0
    /// first (pbrt-v4's image after its flip), normalised to pass as much light as the round
    /// stop; None: round.
    pub aperture: Option<ApertureImage>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ApertureImage {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

#[derive(Debug, Clone)]
pub struct CameraDesc {
    pub projection: Projection,
    /// Camera space to world space (pbrt's convention: the camera looks down +z, +y up), at
    /// the start of the transform times.
    pub camera_to_world: DMat4,
    /// At their end, where it differs: the camera moves over the shutter.
    pub camera_to_world_end: Option<DMat4>,
    pub lens_radius: f64,
    pub focal_distance: f64,
    /// [xmin, xmax, ymin, ymax] of the screen window; `None` means pbrt's default for the aspect ratio.
    pub screen_window: Option<[f64; 4]>,
    /// The shutter's interval (pbrt-v4's shutteropen, shutterclose); its length is the
    /// exposure time the film's ISO multiplies.
    pub shutter: [f64; 2],
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct FilmDesc {
    pub xresolution: u32,
    pub yresolution: u32,
    pub filename: String,
    /// [x0, x1, y0, y1] in pixels, half-open: the region to render. The whole frame when not cropped.
    pub pixel_bounds: [u32; 4],
    pub sensor: SensorDesc,
    /// The film's diagonal in metres (pbrt-v4's "diagonal", given in millimetres; only the
    /// realistic camera uses it).
    pub diagonal: f64,
    /// pbrt-v4's "gbuffer" film: [`GBUFFER_CHANNELS`] beside R, G and B, in this space.
    pub gbuffer: Option<GBufferSpace>,
    pub loc: Loc,
}

/// The space a G-buffer's positions and normals are given in (pbrt-v4's "coordinatesystem").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GBufferSpace {
    /// The camera's space (pbrt-v4's default): the camera at the origin, looking down +z.
    Camera,
    World,
}

/// The channels a G-buffer film writes beside R, G and B, named as pbrt-v4 names them: the
/// first visible surface's reflectance, position, screen-space depth derivatives, geometric
/// and shading normals and uv, and the per-pixel variance of the samples that saw a surface.
pub const GBUFFER_CHANNELS: [&str; 22] = [
    "Albedo.R",
    "Albedo.G",
    "Albedo.B",
    "P.X",
    "P.Y",
    "P.Z",
    "dzdx",
    "dzdy",
    "N.X",
    "N.Y",
    "N.Z",
    "Ns.X",
    "Ns.Y",
    "Ns.Z",
    "u",
    "v",
    "Variance.R",
    "Variance.G",
    "Variance.B",
    "RelativeVariance.R",
    "RelativeVariance.G",
    "RelativeVariance.B",
];

/// pbrt-v4's pixel sensor: each sample's response (XYZ on the CIE 1931 observer, or a named
/// camera's raw RGB) times the imaging ratio (exposure time · ISO / 100), its largest
/// component clamped to `max_component`, then white balanced from daylight at
/// `white_balance` kelvin (0: none) to the output's white.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorDesc {
    pub iso: f64,
    /// Kelvin; 0 for none (a camera's is never 0: it defaults to 6500).
    pub white_balance: f64,
    pub max_component: f64,
    /// A named camera's response; None for the CIE 1931 observer ("cie1931").
    pub camera: Option<crate::camera_sensor::CameraResponse>,
}

impl Default for SensorDesc {
    fn default() -> SensorDesc {
        SensorDesc {
            iso: 100.0,
            white_balance: 0.0,
            max_component: f64::INFINITY,
            camera: None,
        }
    }
}

#[derive(Debug, Clone)]
pub struct SamplerDesc {
    /// The sampler name in the file; Kiln always uses its own deterministic sampler.
    pub name: String,
    pub pixel_samples: u32,
    pub seed: u32,
    /// Kiln's adaptive sampling (`"float noisethreshold"`): a pixel stops taking samples
    /// once its own estimate's error is below this. None: every pixel takes them all.
    pub noise_threshold: Option<f32>,
    /// The fewest samples a pixel takes before it may stop (`"integer minsamples"`).
    pub min_samples: u32,
    pub loc: Loc,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FilterKind {
    Box,
    Triangle,
    Gaussian {
        sigma: f64,
    },
    /// pbrt-v4's Mitchell-Netravali filter (negative lobes).
    Mitchell {
        b: f64,
        c: f64,
    },
    /// pbrt-v4's "sinc": a Lanczos-windowed sinc (negative lobes).
    Sinc {
        tau: f64,
    },
}

#[derive(Debug, Clone)]
pub struct FilterDesc {
    pub kind: FilterKind,
    pub radius: [f64; 2],
    pub loc: Loc,
}
