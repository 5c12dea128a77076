//! Lambertian diffuse reflection.

use super::{BsdfSample, same_hemisphere};
use crate::math::Color;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3A};
use std::f32::consts::FRAC_1_PI;

/// Lambertian reflection.
#[derive(Debug, Clone, Copy)]
pub struct DiffuseBxdf {
    pub r: Color,
}

impl DiffuseBxdf {
    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        let DiffuseBxdf { r } = *self;
        if same_hemisphere(wo, wi) {
            r * FRAC_1_PI
        } else {
            Color::ZERO
        }
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if same_hemisphere(wo, wi) {
            cosine_hemisphere_pdf(wi.z.abs())
        } else {
            0.0
        }
    }

    pub fn sample(&self, wo: Vec3A, _uc: f32, u: Vec2) -> Option<BsdfSample> {
        let DiffuseBxdf { r } = *self;
        let mut wi = cosine_hemisphere(u);
        if wo.z < 0.0 {
            wi.z = -wi.z;
        }
        let pdf = cosine_hemisphere_pdf(wi.z.abs());
        (pdf > 0.0).then_some(BsdfSample {
            f: r * FRAC_1_PI,
            wi,
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}
