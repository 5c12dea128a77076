//! pbrt-v4's diffuse transmission: Lambertian reflection `r` on the side light arrives
//! from and Lambertian transmission `t` to the other (thin leaves, paper, lamp shades).

use super::{BsdfSample, same_hemisphere};
use crate::math::Color;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3A};
use std::f32::consts::FRAC_1_PI;

#[derive(Debug, Clone, Copy)]
pub struct DiffuseTransmissionBxdf {
    pub r: Color,
    pub t: Color,
}

impl DiffuseTransmissionBxdf {
    /// The probability of sampling reflection: by the larger components, as pbrt-v4 does.
    fn reflect_probability(&self) -> f32 {
        let (pr, pt) = (self.r.max_element(), self.t.max_element());
        if pr + pt == 0.0 { 0.0 } else { pr / (pr + pt) }
    }

    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        if same_hemisphere(wo, wi) {
            self.r * FRAC_1_PI
        } else {
            self.t * FRAC_1_PI
        }
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let pr = self.reflect_probability();
        let lobe = if same_hemisphere(wo, wi) {
            pr
        } else {
            1.0 - pr
        };
        lobe * cosine_hemisphere_pdf(wi.z.abs())
    }

    pub fn sample(&self, wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let pr = self.reflect_probability();
        if self.r == Color::ZERO && self.t == Color::ZERO {
            return None;
        }
        let mut wi = cosine_hemisphere(u);
        let reflect = uc < pr;
        // Reflection stays on wo's side, transmission crosses to the other.
        if (wo.z < 0.0) == reflect {
            wi.z = -wi.z;
        }
        let (f, lobe) = if reflect {
            (self.r, pr)
        } else {
            (self.t, 1.0 - pr)
        };
        let pdf = lobe * cosine_hemisphere_pdf(wi.z.abs());
        (pdf > 0.0).then_some(BsdfSample {
            f: f * FRAC_1_PI,
            wi,
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}
