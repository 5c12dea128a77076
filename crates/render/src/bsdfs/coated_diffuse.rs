//! A dielectric coat over a diffuse base (pbrt-v4's "coateddiffuse" with albedo 0), with the
//! inter-reflections between base and coat summed in closed form.

use super::fresnel::fresnel_dielectric;
use super::{BsdfSample, TrowbridgeReitz, reflect, same_hemisphere, upper};
use crate::math::{Color, luminance};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::{Vec2, Vec3A};
use std::f32::consts::FRAC_1_PI;

/// A dielectric coat over a diffuse base.
#[derive(Debug, Clone, Copy)]
pub struct CoatedDiffuseBxdf {
    pub r: Color,
    pub eta: f32,
    pub distrib: TrowbridgeReitz,
    pub fdr_internal: f32,
}

impl CoatedDiffuseBxdf {
    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        let CoatedDiffuseBxdf {
            r,
            eta,
            distrib,
            fdr_internal,
        } = *self;
        let (wo, wi) = upper(wo, wi);
        if !same_hemisphere(wo, wi) {
            return Color::ZERO;
        }
        let fo = fresnel_dielectric(wo.z, eta);
        let fi = fresnel_dielectric(wi.z, eta);
        // Light enters the coat, bounces between base and coat (a geometric
        // series), and leaves; radiance is scaled by 1/eta^2 across the interface.
        let diffuse =
            (1.0 - fo) * (1.0 - fi) / (eta * eta) * r * FRAC_1_PI / (Color::ONE - r * fdr_internal);
        let spec = if distrib.effectively_smooth() {
            0.0
        } else {
            let wm = (wi + wo).normalize();
            distrib.d(wm) * fresnel_dielectric(wo.dot(wm), eta) * distrib.g(wo, wi)
                / (4.0 * wi.z * wo.z)
        };
        diffuse + Color::splat(spec)
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let CoatedDiffuseBxdf {
            r, eta, distrib, ..
        } = *self;
        let (wo, wi) = upper(wo, wi);
        if !same_hemisphere(wo, wi) {
            return 0.0;
        }
        let p_spec = coat_specular_probability(wo, eta, r);
        let diffuse = (1.0 - p_spec) * cosine_hemisphere_pdf(wi.z);
        if distrib.effectively_smooth() {
            return diffuse;
        }
        let wm = (wo + wi).normalize();
        diffuse + p_spec * distrib.pdf(wo, wm) / (4.0 * wo.dot(wm).abs())
    }

    pub fn sample(&self, wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let CoatedDiffuseBxdf {
            r, eta, distrib, ..
        } = *self;
        let flip = wo.z < 0.0;
        let wo_up = if flip { -wo } else { wo };
        let p_spec = coat_specular_probability(wo_up, eta, r);
        let unflip = |w: Vec3A| if flip { -w } else { w };
        if uc < p_spec {
            if distrib.effectively_smooth() {
                let wi = Vec3A::new(-wo_up.x, -wo_up.y, wo_up.z);
                let f = fresnel_dielectric(wo_up.z, eta) / wi.z;
                return Some(BsdfSample {
                    f: Color::splat(f),
                    wi: unflip(wi),
                    pdf: p_spec,
                    specular: true,
                    eta: 1.0,
                });
            }
            let wm = distrib.sample_wm(wo_up, u);
            let wi = reflect(wo_up, wm);
            if wi.z <= 0.0 {
                return None;
            }
            let wi = unflip(wi);
            let pdf = self.pdf(wo, wi);
            return (pdf > 0.0).then(|| BsdfSample {
                f: self.f(wo, wi),
                wi,
                pdf,
                specular: false,
                eta: 1.0,
            });
        }
        let wi = unflip(cosine_hemisphere(u));
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

fn coat_specular_probability(wo: Vec3A, eta: f32, r: Color) -> f32 {
    let f = fresnel_dielectric(wo.z.abs(), eta);
    let d = (1.0 - f) * luminance(r).max(0.0);
    if f + d <= 0.0 {
        1.0
    } else {
        (f / (f + d)).clamp(0.05, 0.95)
    }
}
