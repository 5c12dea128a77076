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
    /// The cone it shines in, for the light hierarchy; its power is that of a point light
    /// of the same intensity, as pbrt-v4 bounds it (the cone says where it reaches).
    pub fn bounds(&self) -> super::LightBounds {
        let mut cos_e = libm::cosf(
            libm::acosf(self.cos_end.clamp(-1.0, 1.0))
                - libm::acosf(self.cos_start.clamp(-1.0, 1.0)),
        );
        // Rounding in the importance's angles must not shut out the falloff's rim.
        if cos_e == 1.0 && self.cos_end != self.cos_start {
            cos_e = 0.999;
        }
        super::LightBounds {
            lo: self.position,
            hi: self.position,
            w: self.frame.z,
            phi: 4.0 * PI * luminance(self.intensity),
            cos_o: self.cos_start,
            cos_e,
            two_sided: false,
        }
    }

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

impl SpotLight {
    /// A photon in a uniform direction of the cone the spot lights.
    pub fn emit(&self, u: glam::Vec2) -> Option<super::EmittedRay> {
        let cos_end = self.cos_end.clamp(-1.0, 1.0);
        let dir = self
            .frame
            .to_world(crate::sampling::uniform_cone(u, cos_end));
        let falloff = smoothstep(self.cos_end, self.cos_start, dir.dot(self.frame.z));
        let pdf = 1.0 / (2.0 * PI * (1.0 - cos_end));
        (falloff > 0.0 && pdf.is_finite()).then(|| super::EmittedRay {
            origin: self.position,
            dir,
            n: Vec3A::ZERO,
            flux: self.intensity * (falloff / pdf),
        })
    }
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
