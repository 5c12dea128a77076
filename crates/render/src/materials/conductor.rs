//! pbrt-v4's "conductor": metals given by a complex index of refraction (eta, k) or by
//! their reflectance at normal incidence, smooth or rough, any of them textured.

use super::RoughnessTexture;
use crate::bsdfs::{Bsdf, ConductorBxdf, FresnelTable};
use crate::math::Color;
use crate::spectral::DenseSpectrum;
use crate::textures::{SpectrumTexture, TextureEvalContext};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub enum ConductorSpec {
    EtaK {
        eta: SpectrumTexture,
        k: SpectrumTexture,
        /// The spectral Fresnel reflectance, when eta and k were given as spectra (and
        /// so are constant).
        table: Option<Arc<FresnelTable>>,
        /// Those spectra (eta, k), which a spectral path reads at its wavelengths.
        spectra: Option<Arc<[DenseSpectrum; 2]>>,
    },
    Reflectance(SpectrumTexture),
}

/// A conductor's eta and k, given as such, as the path sees them: RGB, or spectra at its
/// wavelengths (the scene's own spectra where it gave them, else the RGB upsampled).
pub fn eta_k(
    eta: &SpectrumTexture,
    k: &SpectrumTexture,
    spectra: Option<&[DenseSpectrum; 2]>,
    ctx: &TextureEvalContext,
) -> (Color, Color) {
    match (&ctx.waves, spectra) {
        (Some(w), Some(s)) => (s[0].at(w), s[1].at(w)),
        _ => (
            ctx.unbounded(eta.evaluate(ctx)),
            ctx.unbounded(k.evaluate(ctx)),
        ),
    }
}

#[derive(Debug, Clone)]
pub struct ConductorMaterial {
    spec: ConductorSpec,
    roughness: RoughnessTexture,
    /// The BxDF, when nothing about it varies over the surface (its `table` is attached
    /// when it is handed out).
    fixed: Option<ConductorBxdf<'static>>,
}

impl ConductorMaterial {
    pub fn new(spec: ConductorSpec, roughness: RoughnessTexture) -> ConductorMaterial {
        let constant = match &spec {
            ConductorSpec::EtaK { eta, k, .. } => {
                eta.as_constant().is_some() && k.as_constant().is_some()
            }
            ConductorSpec::Reflectance(r) => r.as_constant().is_some(),
        };
        let mut m = ConductorMaterial {
            spec,
            roughness,
            fixed: None,
        };
        if constant && !m.roughness.is_textured() {
            m.fixed = Some(m.bxdf(&TextureEvalContext::default()));
        }
        m
    }

    /// The BxDF at `ctx`, without its spectral Fresnel table.
    fn bxdf(&self, ctx: &TextureEvalContext) -> ConductorBxdf<'static> {
        let distrib = self.roughness.distribution(ctx);
        match &self.spec {
            ConductorSpec::EtaK {
                eta, k, spectra, ..
            } => {
                let (eta, k) = eta_k(eta, k, spectra.as_deref(), ctx);
                ConductorBxdf {
                    eta,
                    k,
                    distrib,
                    table: None,
                }
            }
            // pbrt-v4: a conductor of reflectance r has eta = 1 and k = 2 sqrt(r) / sqrt(1 - r).
            ConductorSpec::Reflectance(r) => {
                let r = ctx
                    .reflectance(r.evaluate(ctx))
                    .clamp(Color::ZERO, Color::splat(0.9999));
                ConductorBxdf {
                    eta: Color::ONE,
                    k: 2.0 * r.powf(0.5) / (Color::ONE - r).powf(0.5),
                    distrib,
                    table: None,
                }
            }
        }
    }

    pub fn is_textured(&self) -> bool {
        self.fixed.is_none()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'_> {
        // The fixed BxDF and the table are RGB: a spectral path makes its own, at its
        // wavelengths.
        if ctx.waves.is_some() {
            return Bsdf::Conductor(self.bxdf(ctx));
        }
        let mut b: ConductorBxdf<'_> = self.fixed.unwrap_or_else(|| self.bxdf(ctx));
        if let ConductorSpec::EtaK { table, .. } = &self.spec {
            b.table = table.as_deref();
        }
        Bsdf::Conductor(b)
    }
}
