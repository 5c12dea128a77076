//! What pbrt-v4's two coated materials share: the medium between coat and base (thickness,
//! albedo, asymmetry g, any of them textured) and the layered BSDF's estimator settings.

use crate::bsdfs::{Base, DielectricBxdf, LayeredBxdf};
use crate::math::Color;
use crate::textures::{FloatTexture, SpectrumTexture, TextureEvalContext, Textures};
use kiln_scene::LayerDesc;

#[derive(Debug, Clone)]
pub struct Layer {
    pub thickness: FloatTexture,
    pub albedo: SpectrumTexture,
    pub g: FloatTexture,
    pub max_depth: u32,
    pub n_samples: u32,
}

impl Layer {
    pub fn new(desc: &LayerDesc, textures: &Textures) -> Layer {
        Layer {
            thickness: textures.float_value(&desc.thickness),
            albedo: textures.rgb_value(&desc.albedo),
            g: textures.float_value(&desc.g),
            max_depth: desc.max_depth,
            n_samples: desc.n_samples,
        }
    }

    pub fn is_textured(&self) -> bool {
        self.thickness.as_constant().is_none()
            || self.albedo.as_constant().is_none()
            || self.g.as_constant().is_none()
    }

    /// The layered BSDF of `top` over `bottom` at the point of `ctx`.
    pub fn bxdf<'a>(
        &self,
        top: DielectricBxdf,
        bottom: Base<'a>,
        ctx: &TextureEvalContext,
    ) -> LayeredBxdf<'a> {
        LayeredBxdf {
            top,
            bottom,
            thickness: self.thickness.evaluate(ctx).max(f32::MIN_POSITIVE),
            albedo: ctx.reflectance(self.albedo.evaluate(ctx).clamp(Color::ZERO, Color::ONE)),
            g: self.g.evaluate(ctx).clamp(-0.99, 0.99),
            max_depth: self.max_depth,
            n_samples: self.n_samples,
        }
    }
}
