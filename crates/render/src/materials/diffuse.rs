//! pbrt-v4's "diffuse": Lambertian reflection of a (textured) reflectance.

use crate::bsdfs::{Bsdf, DiffuseBxdf};
use crate::math::Color;
use crate::textures::{SpectrumTexture, TextureEvalContext};

#[derive(Debug, Clone)]
pub struct DiffuseMaterial {
    pub reflectance: SpectrumTexture,
}

impl DiffuseMaterial {
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'static> {
        Bsdf::Diffuse(DiffuseBxdf {
            r: ctx.reflectance(
                self.reflectance
                    .evaluate(ctx)
                    .clamp(Color::ZERO, Color::ONE),
            ),
        })
    }
}
