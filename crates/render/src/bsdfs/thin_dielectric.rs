//! Thin dielectric slabs (window panes): reflection and straight-through transmission.

use super::BsdfSample;
use super::fresnel::fresnel_dielectric;
use crate::math::Color;
use glam::{Vec2, Vec3A};

/// A thin dielectric slab: reflection and straight-through transmission, inter-reflections summed.
#[derive(Debug, Clone, Copy)]
pub struct ThinDielectricBxdf {
    pub eta: f32,
}

impl ThinDielectricBxdf {
    /// Zero: both lobes are deltas, found only by sampling.
    pub fn f(&self, _wo: Vec3A, _wi: Vec3A) -> Color {
        Color::ZERO
    }

    pub fn pdf(&self, _wo: Vec3A, _wi: Vec3A) -> f32 {
        0.0
    }

    pub fn sample(&self, wo: Vec3A, uc: f32, _u: Vec2) -> Option<BsdfSample> {
        let ThinDielectricBxdf { eta } = *self;
        let mut r = fresnel_dielectric(wo.z.abs(), eta);
        let mut t = 1.0 - r;
        // Sum the inter-reflections inside the thin slab.
        if r < 1.0 {
            r += t * t * r / (1.0 - r * r);
            t = 1.0 - r;
        }
        if uc < r / (r + t) {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            Some(BsdfSample {
                f: Color::splat(r / wi.z.abs()),
                wi,
                pdf: r / (r + t),
                specular: true,
                eta: 1.0,
            })
        } else {
            let wi = -wo;
            Some(BsdfSample {
                f: Color::splat(t / wi.z.abs()),
                wi,
                pdf: t / (r + t),
                specular: true,
                eta: 1.0,
            })
        }
    }
}
