//! pbrt-v4's "coateddiffuse": a dielectric coat over a diffuse base of a (textured)
//! reflectance, with a layer between them of optical `thickness` that may scatter
//! (`albedo`, `g`), all through pbrt-v4's stochastic layered BSDF with its `maxdepth` and
//! `nsamples`. Even a clear layer (`albedo` 0) absorbs by its thickness, as in pbrt-v4, and
//! the walk's depth limit darkens it further: a closed form of the clear coat (Fresnel
//! transmission and the base's inter-reflections summed to infinity) renders 6 to 8% brighter
//! than pbrt-v4 on the same file, so it is not used.

use super::RoughnessTexture;
use super::layer::Layer;
use crate::bsdfs::{Base, Bsdf, DielectricBxdf, DiffuseBxdf};
use crate::math::Color;
use crate::textures::{SpectrumTexture, TextureEvalContext};

#[derive(Debug, Clone)]
pub struct CoatedDiffuseMaterial {
    pub reflectance: SpectrumTexture,
    pub eta: f32,
    pub roughness: RoughnessTexture,
    pub layer: Layer,
}

impl CoatedDiffuseMaterial {
    pub fn new(
        reflectance: SpectrumTexture,
        roughness: RoughnessTexture,
        eta: f32,
        layer: Layer,
    ) -> CoatedDiffuseMaterial {
        CoatedDiffuseMaterial {
            reflectance,
            eta,
            roughness,
            layer,
        }
    }

    pub fn is_textured(&self) -> bool {
        self.reflectance.as_constant().is_none()
            || self.roughness.is_textured()
            || self.layer.is_textured()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'_> {
        let top = DielectricBxdf {
            eta: self.eta,
            distrib: self.roughness.distribution(ctx),
            dispersive: false,
        };
        let r = ctx.reflectance(
            self.reflectance
                .evaluate(ctx)
                .clamp(Color::ZERO, Color::ONE),
        );
        Bsdf::Layered(self.layer.bxdf(top, Base::Diffuse(DiffuseBxdf { r }), ctx))
    }
}
