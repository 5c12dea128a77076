//! pbrt-v4's "hair": the fibre BSDF of [`crate::bsdfs::HairBxdf`] with its absorption given
//! directly, by a colour, or by melanin concentrations, any of them textured. Where across
//! the fibre a ray struck comes from the curve's v, so the material always needs the hit's
//! (u, v).

use crate::bsdfs::{Bsdf, HairBxdf};
use crate::math::Color;
use crate::textures::{FloatTexture, SpectrumTexture, TextureEvalContext};

#[derive(Debug, Clone)]
pub enum HairAbsorptionTexture {
    SigmaA(SpectrumTexture),
    Reflectance(SpectrumTexture),
    Melanin {
        eumelanin: FloatTexture,
        pheomelanin: FloatTexture,
    },
}

#[derive(Debug, Clone)]
pub struct HairMaterial {
    pub absorption: HairAbsorptionTexture,
    pub eta: FloatTexture,
    pub beta_m: FloatTexture,
    pub beta_n: FloatTexture,
    pub alpha: FloatTexture,
}

impl HairMaterial {
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'static> {
        // pbrt-v4 keeps both roughnesses in [0.01, 1].
        let beta_m = self.beta_m.evaluate(ctx).clamp(1e-2, 1.0);
        let beta_n = self.beta_n.evaluate(ctx).clamp(1e-2, 1.0);
        // Spectrally, as pbrt-v4: the absorption and the melanins' absorption are unbounded
        // spectra, the colour a reflectance spectrum turned into absorption per wavelength.
        let sigma_a = match &self.absorption {
            HairAbsorptionTexture::SigmaA(s) => ctx.unbounded(s.evaluate(ctx).max(Color::ZERO)),
            HairAbsorptionTexture::Reflectance(c) => HairBxdf::sigma_a_from_reflectance(
                ctx.reflectance(c.evaluate(ctx).clamp(Color::ZERO, Color::ONE)),
                beta_n,
            ),
            HairAbsorptionTexture::Melanin {
                eumelanin,
                pheomelanin,
            } => ctx.unbounded(HairBxdf::sigma_a_from_melanin(
                eumelanin.evaluate(ctx),
                pheomelanin.evaluate(ctx),
            )),
        };
        let hair = HairBxdf::new(
            -1.0 + 2.0 * ctx.uv.y,
            self.eta.evaluate(ctx),
            sigma_a,
            beta_m,
            beta_n,
            self.alpha.evaluate(ctx),
        );
        Bsdf::Hair(match ctx.waves {
            Some(_) => hair.spectral(),
            None => hair,
        })
    }
}
