//! Goniometric lights (pbrt-v4's "goniometric"): a point light whose intensity over
//! directions is read from an equal-area square image (a measured luminaire's
//! distribution), nearest pixel, the mean of its RGB times the light's RGB intensity.

use super::LightSample;
use crate::math::{Color, luminance};
use crate::sampling::equal_area_sphere_to_square;
use glam::{Mat3A, Vec3A};
use std::f32::consts::PI;

#[derive(Debug, Clone)]
pub struct GoniometricLight {
    pub position: Vec3A,
    /// World directions into the light's space (where the image's sphere is).
    pub to_light: Mat3A,
    pub intensity: Color,
    /// The image's per-pixel mean of RGB, row by row.
    pub values: Vec<f32>,
    pub resolution: u32,
    /// The image's mean value (its power per unit intensity, over 4π).
    pub mean: f32,
}

impl GoniometricLight {
    /// The image's value towards light-space direction `w`.
    fn value(&self, w: Vec3A) -> f32 {
        let uv = equal_area_sphere_to_square(w.normalize_or_zero());
        let n = self.resolution;
        // Float to integer casts saturate: an edge coordinate stays on the image.
        let (x, y) = (
            ((uv.x * n as f32) as u32).min(n - 1),
            ((uv.y * n as f32) as u32).min(n - 1),
        );
        self.values[(y * n + x) as usize]
    }

    pub fn power(&self) -> f32 {
        4.0 * PI * luminance(self.intensity) * self.mean
    }

    pub fn sample(&self, p: Vec3A) -> Option<LightSample> {
        super::shaped_point_sample(self.position, p, |w| {
            self.intensity * self.value(self.to_light * w)
        })
    }
}
