//! Point lights: all their intensity from one point, in every direction.

use super::LightSample;
use crate::math::{Color, luminance};
use glam::Vec3A;
use std::f32::consts::PI;

#[derive(Debug, Clone)]
pub struct PointLight {
    pub position: Vec3A,
    pub intensity: Color,
}

impl PointLight {
    pub fn power(&self) -> f32 {
        4.0 * PI * luminance(self.intensity)
    }

    pub fn sample(&self, p: Vec3A) -> Option<LightSample> {
        let d = self.position - p;
        let dist2 = d.length_squared();
        let dist = dist2.sqrt();
        Some(LightSample::delta(self.intensity / dist2, d / dist, dist))
    }
}
