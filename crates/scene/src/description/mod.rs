//! The plain scene description that the parser produces and the renderer consumes.
//!
//! Everything here is data: typed, validated, in world space where that is
//! meaningful, with the file location it came from. Nothing here knows how it
//! will be rendered.
//!
//! One file per concept: `camera.rs` (camera, film, sampler, filter), `integrator.rs`,
//! `materials.rs`, `shapes.rs` (with instancing), `lights.rs` and `media.rs`; this file
//! holds the whole scene and the overrides a command line or a job applies to it.

mod camera;
mod integrator;
mod lights;
mod materials;
mod media;
mod memory;
mod shapes;

pub use camera::*;
pub use integrator::*;
pub use lights::*;
pub use materials::*;
pub use media::*;
pub use shapes::*;

use crate::error::Diagnostic;
use crate::textures::{FloatTextureDesc, SpectrumTextureDesc};

pub use crate::spectrum::Rgb;

/// A whole scene: camera and film settings, materials, shapes and lights.
#[derive(Debug, Clone)]
pub struct SceneDescription {
    /// Render spectrally (four wavelengths per camera sample), as pbrt-v4 does and Kiln does
    /// by default, rather than in RGB (Kiln's `Option "kiln.spectral" false`, or `--rgb`).
    pub spectral: bool,
    pub camera: CameraDesc,
    pub film: FilmDesc,
    pub sampler: SamplerDesc,
    pub filter: FilterDesc,
    pub integrator: IntegratorDesc,
    pub materials: Vec<MaterialDesc>,
    /// Textures in definition order; a texture refers only to textures before it.
    pub float_textures: Vec<FloatTextureDesc>,
    pub spectrum_textures: Vec<SpectrumTextureDesc>,
    pub media: Vec<MediumDesc>,
    /// The medium the camera sits in (the outside medium current at the Camera directive).
    pub camera_medium: Option<MediumId>,
    pub shapes: Vec<ShapeDesc>,
    pub lights: Vec<LightDesc>,
    /// Named objects (ObjectBegin/End), referred to by [`InstanceDesc::object`].
    pub objects: Vec<ObjectDesc>,
    pub instances: Vec<InstanceDesc>,
    /// pbrt-v4's TransformTimes: the times of the start and end transforms (0 and 1 by
    /// default); between them a moving transform is interpolated, outside them held.
    pub transform_times: [f64; 2],
    /// Every file the scene read besides its main file (includes, meshes, maps, grids), in order.
    pub files: Vec<std::path::PathBuf>,
    /// Warnings found while loading (errors abort loading instead).
    pub warnings: Vec<Diagnostic>,
}

/// Command-line and job overrides of a scene's own settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    pub resolution: Option<(u32, u32)>,
    pub spp: Option<u32>,
    pub seed: Option<u32>,
    /// Adaptive sampling's threshold; 0 turns it off.
    pub noise_threshold: Option<f32>,
    /// Spectral (true) or RGB (false) rendering.
    pub spectral: Option<bool>,
}

impl SceneDescription {
    /// The pixels a render of this scene holds: the film's crop window (the whole frame
    /// without one).
    pub fn rendered_pixels(&self) -> u64 {
        let [x0, x1, y0, y1] = self.film.pixel_bounds;
        u64::from(x1 - x0) * u64::from(y1 - y0)
    }

    /// Refuses a render of more than `max_pixels` pixels before anything is allocated for
    /// it, saying how large it would be.
    pub fn check_frame_size(&self, max_pixels: u64) -> Result<(), String> {
        let n = self.rendered_pixels();
        if n <= max_pixels {
            return Ok(());
        }
        let [x0, x1, y0, y1] = self.film.pixel_bounds;
        Err(format!(
            "a {}x{} render is {n} pixels, {:.1} GB of float RGB: more than the {max_pixels} pixels allowed (raise --max-frame-pixels on a machine with the memory)",
            x1 - x0,
            y1 - y0,
            n as f64 * 12.0 / 1e9
        ))
    }

    /// Applies overrides; a crop window keeps its fractions of the frame.
    pub fn apply_overrides(&mut self, o: &Overrides) -> Result<(), String> {
        if let Some((w, h)) = o.resolution {
            if w == 0 || h == 0 || w > 65536 || h > 65536 {
                return Err(format!("resolution {w}x{h} is out of range"));
            }
            let f = &mut self.film;
            let [x0, x1, y0, y1] = f.pixel_bounds;
            let sx = |v: u32| (v as u64 * w as u64).div_ceil(f.xresolution as u64) as u32;
            let sy = |v: u32| (v as u64 * h as u64).div_ceil(f.yresolution as u64) as u32;
            let bounds = [sx(x0), sx(x1).min(w), sy(y0), sy(y1).min(h)];
            if bounds[0] >= bounds[1] || bounds[2] >= bounds[3] {
                return Err(format!("the crop window covers no pixel at {w}x{h}"));
            }
            f.pixel_bounds = bounds;
            f.xresolution = w;
            f.yresolution = h;
        }
        if let Some(spp) = o.spp {
            if spp == 0 || spp > 65536 {
                return Err(format!(
                    "{spp} samples per pixel is out of range (1 to 65536)"
                ));
            }
            self.sampler.pixel_samples = spp;
        }
        if let Some(seed) = o.seed {
            self.sampler.seed = seed;
        }
        if let Some(t) = o.noise_threshold {
            if !(t.is_finite() && t >= 0.0) {
                return Err(format!(
                    "a noise threshold is a number from 0 (off) up, not {t}"
                ));
            }
            self.sampler.noise_threshold = (t > 0.0).then_some(t);
        }
        if let Some(spectral) = o.spectral {
            self.spectral = spectral;
        }
        Ok(())
    }
}
