//! Spot lights: a point light whose intensity falls off smoothly between two cone angles.

use super::LightSample;
use crate::math::{Color, Frame, luminance};
use glam::Vec3A;
use std::f32::consts::PI;

#[derive(Debug, Clone)]
pub struct SpotLight {
    pub position: Vec3A,
    /// `frame.z` is the cone's axis.
    pub frame: Frame,
    pub intensity: Color,
    pub cos_start: f32,
    pub cos_end: f32,
}

impl SpotLight {
    pub fn power(&self) -> f32 {
        2.0 * PI * luminance(self.intensity) * (1.0 - 0.5 * (self.cos_start + self.cos_end))
    }

    pub fn sample(&self, p: Vec3A) -> Option<LightSample> {
        let d = self.position - p;
        let dist2 = d.length_squared();
        let dist = dist2.sqrt();
        let wi = d / dist;
        let cos = (-wi).dot(self.frame.z);
        let falloff = smoothstep(self.cos_end, self.cos_start, cos);
        (falloff > 0.0).then(|| LightSample::delta(self.intensity * falloff / dist2, wi, dist))
    }
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
