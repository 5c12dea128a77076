//! pbrt-v4's "dielectric": glass, water, any interface that reflects and refracts.

use super::RoughnessTexture;
use crate::bsdfs::{Bsdf, DielectricBxdf};
use crate::textures::TextureEvalContext;

#[derive(Debug, Clone)]
pub struct DielectricMaterial {
    pub eta: f32,
    pub roughness: RoughnessTexture,
}

impl DielectricMaterial {
    /// A perfectly smooth interface (what a VolumeLight's surface must be).
    pub fn is_smooth(&self) -> bool {
        self.roughness.is_smooth()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'static> {
        Bsdf::Dielectric(DielectricBxdf {
            eta: self.eta,
            distrib: self.roughness.distribution(ctx),
        })
    }
}
