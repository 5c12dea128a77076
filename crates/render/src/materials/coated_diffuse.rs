//! pbrt-v4's "coateddiffuse" (albedo 0): a dielectric coat over a diffuse base of a
//! (textured) reflectance.

use super::RoughnessTexture;
use crate::bsdfs::{Bsdf, CoatedDiffuseBxdf, internal_diffuse_reflectance};
use crate::math::Color;
use crate::textures::{SpectrumTexture, TextureEvalContext};

#[derive(Debug, Clone)]
pub struct CoatedDiffuseMaterial {
    pub reflectance: SpectrumTexture,
    pub eta: f32,
    pub roughness: RoughnessTexture,
    /// The coat's internal diffuse reflectance, a numerical integral over angles computed
    /// once from `eta`.
    fdr_internal: f32,
}

impl CoatedDiffuseMaterial {
    pub fn new(
        reflectance: SpectrumTexture,
        roughness: RoughnessTexture,
        eta: f32,
    ) -> CoatedDiffuseMaterial {
        CoatedDiffuseMaterial {
            reflectance,
            eta,
            roughness,
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
            distrib: self.roughness.distribution(ctx),
            fdr_internal: self.fdr_internal,
        })
    }
}
