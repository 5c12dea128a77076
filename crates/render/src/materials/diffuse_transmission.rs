//! pbrt-v4's "diffusetransmission": Lambertian reflection and transmission of (textured)
//! colours, each times `scale` and clamped to [0, 1].

use crate::bsdfs::{Bsdf, DiffuseTransmissionBxdf};
use crate::math::Color;
use crate::textures::{SpectrumTexture, TextureEvalContext};

#[derive(Debug, Clone)]
pub struct DiffuseTransmissionMaterial {
    pub reflectance: SpectrumTexture,
    pub transmittance: SpectrumTexture,
    pub scale: f32,
}

impl DiffuseTransmissionMaterial {
    pub fn is_textured(&self) -> bool {
        self.reflectance.as_constant().is_none() || self.transmittance.as_constant().is_none()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'static> {
        let clamp = |c: Color| (c * self.scale).clamp(Color::ZERO, Color::ONE);
        Bsdf::DiffuseTransmission(DiffuseTransmissionBxdf {
            r: ctx.reflectance(clamp(self.reflectance.evaluate(ctx))),
            t: ctx.reflectance(clamp(self.transmittance.evaluate(ctx))),
        })
    }
}
