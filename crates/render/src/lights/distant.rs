//! Distant lights: parallel light from one direction, as from the sun.

use super::LightSample;
use crate::math::{Color, luminance};
use glam::Vec3A;
use std::f32::consts::PI;

#[derive(Debug, Clone)]
pub struct DistantLight {
    /// Points from the scene towards the light.
    pub direction: Vec3A,
    pub radiance: Color,
}

impl DistantLight {
    /// The power falling on a disk as wide as the scene.
    pub fn power(&self, scene_radius: f32) -> f32 {
        PI * scene_radius * scene_radius * luminance(self.radiance)
    }

    pub fn sample(&self) -> Option<LightSample> {
        Some(LightSample::delta(
            self.radiance,
            self.direction,
            f32::INFINITY,
        ))
    }
}
