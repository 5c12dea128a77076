//! Conductors: complex Fresnel reflection, perfectly smooth or Trowbridge-Reitz rough.

use super::fresnel::{FresnelTable, fresnel_complex};
use super::{BsdfSample, TrowbridgeReitz, reflect, same_hemisphere};
use crate::math::Color;
use glam::{Vec2, Vec3A};

/// A conductor: complex Fresnel reflection, smooth or Trowbridge-Reitz rough.
#[derive(Debug, Clone, Copy)]
pub struct ConductorBxdf<'a> {
    pub eta: Color,
    pub k: Color,
    pub distrib: TrowbridgeReitz,
    /// The spectral Fresnel reflectance in RGB, which replaces that of `eta` and `k` when
    /// the material was given spectra.
    pub table: Option<&'a FresnelTable>,
}

impl ConductorBxdf<'_> {
    /// The Fresnel reflectance at `cos`.
    fn fresnel(&self, cos: f32) -> Color {
        match self.table {
            Some(t) => t.eval(cos),
            None => fresnel_complex(cos, self.eta, self.k),
        }
    }

    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        let distrib = self.distrib;
        if !same_hemisphere(wo, wi) || distrib.effectively_smooth() {
            return Color::ZERO;
        }
        let (cos_o, cos_i) = (wo.z.abs(), wi.z.abs());
        let wm = wi + wo;
        if cos_i == 0.0 || cos_o == 0.0 || wm.length_squared() == 0.0 {
            return Color::ZERO;
        }
        let wm = wm.normalize();
        let f = self.fresnel(wo.dot(wm).abs());
        distrib.d(wm) * f * distrib.g(wo, wi) / (4.0 * cos_i * cos_o)
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let distrib = self.distrib;
        if !same_hemisphere(wo, wi) || distrib.effectively_smooth() {
            return 0.0;
        }
        let wm = wo + wi;
        if wm.length_squared() == 0.0 {
            return 0.0;
        }
        let mut wm = wm.normalize();
        if wm.z < 0.0 {
            wm = -wm;
        }
        distrib.pdf(wo, wm) / (4.0 * wo.dot(wm).abs())
    }

    pub fn sample(&self, wo: Vec3A, _uc: f32, u: Vec2) -> Option<BsdfSample> {
        let distrib = self.distrib;
        if distrib.effectively_smooth() {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            let cos = wi.z.abs();
            return Some(BsdfSample {
                f: self.fresnel(cos) / cos,
                wi,
                pdf: 1.0,
                specular: true,
                eta: 1.0,
            });
        }
        let flip = wo.z < 0.0;
        let wo_up = if flip { -wo } else { wo };
        let wm = distrib.sample_wm(wo_up, u);
        let mut wi = reflect(wo_up, wm);
        if wi.z <= 0.0 {
            return None;
        }
        if flip {
            wi = -wi;
        }
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample {
            f: self.f(wo, wi),
            wi,
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}
