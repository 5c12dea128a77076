//! pbrt-v4's "coateddiffuse" (albedo 0): a dielectric coat over a diffuse base of a
//! (textured) reflectance.

use super::distribution;
use crate::bsdfs::{Bsdf, CoatedDiffuseBxdf, TrowbridgeReitz, internal_diffuse_reflectance};
use crate::math::Color;
use crate::textures::{SpectrumTexture, TextureEvalContext};
use kiln_scene::{RgbValue, Roughness};

#[derive(Debug, Clone)]
pub struct CoatedDiffuseMaterial {
    pub reflectance: SpectrumTexture,
    pub eta: f32,
    pub distrib: TrowbridgeReitz,
    /// The coat's internal diffuse reflectance, a numerical integral over angles computed
    /// once from `eta`.
    fdr_internal: f32,
}

impl CoatedDiffuseMaterial {
    pub fn new(reflectance: &RgbValue, roughness: &Roughness, eta: f32) -> CoatedDiffuseMaterial {
        CoatedDiffuseMaterial {
            reflectance: reflectance.into(),
            eta,
            distrib: distribution(roughness),
            fdr_internal: internal_diffuse_reflectance(eta),
        }
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf {
        Bsdf::CoatedDiffuse(CoatedDiffuseBxdf {
            r: self
                .reflectance
                .evaluate(ctx)
                .clamp(Color::ZERO, Color::ONE),
            eta: self.eta,
            distrib: self.distrib,
            fdr_internal: self.fdr_internal,
        })
    }
}
