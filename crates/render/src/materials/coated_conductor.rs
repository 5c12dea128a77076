//! pbrt-v4's "coatedconductor": a dielectric coat over a conductor (given by eta and k or
//! by its reflectance), each with its own roughness, with an optional scattering layer
//! between, as pbrt-v4's stochastic layered BSDF.

use super::layer::Layer;
use super::{ConductorSpec, RoughnessTexture};
use crate::bsdfs::{Base, Bsdf, ConductorBxdf, DielectricBxdf};
use crate::math::Color;
use crate::textures::TextureEvalContext;

#[derive(Debug, Clone)]
pub struct CoatedConductorMaterial {
    pub interface_eta: f32,
    pub interface_roughness: RoughnessTexture,
    pub conductor: ConductorSpec,
    pub conductor_roughness: RoughnessTexture,
    pub layer: Layer,
}

impl CoatedConductorMaterial {
    pub fn is_textured(&self) -> bool {
        let spec = match &self.conductor {
            ConductorSpec::EtaK { eta, k, .. } => {
                eta.as_constant().is_none() || k.as_constant().is_none()
            }
            ConductorSpec::Reflectance(r) => r.as_constant().is_none(),
        };
        spec || self.interface_roughness.is_textured()
            || self.conductor_roughness.is_textured()
            || self.layer.is_textured()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'_> {
        let top = DielectricBxdf {
            eta: self.interface_eta,
            distrib: self.interface_roughness.distribution(ctx),
            dispersive: false,
        };
        let distrib = self.conductor_roughness.distribution(ctx);
        // Inside the coat the conductor meets a medium of index interface_eta: pbrt-v4
        // divides its eta and k by it (and the spectral table was made so).
        let (eta, k, table) = match &self.conductor {
            // The table is RGB: a spectral path takes eta and k at its wavelengths.
            ConductorSpec::EtaK {
                eta,
                k,
                table,
                spectra,
            } => {
                let (eta, k) = super::conductor::eta_k(eta, k, spectra.as_deref(), ctx);
                (eta, k, table.as_deref().filter(|_| ctx.waves.is_none()))
            }
            ConductorSpec::Reflectance(r) => {
                let r = ctx
                    .reflectance(r.evaluate(ctx))
                    .clamp(Color::ZERO, Color::splat(0.9999));
                (
                    Color::ONE,
                    2.0 * r.powf(0.5) / (Color::ONE - r).powf(0.5),
                    None,
                )
            }
        };
        let bottom = Base::Conductor(ConductorBxdf {
            eta: eta / self.interface_eta,
            k: k / self.interface_eta,
            distrib,
            table,
        });
        Bsdf::Layered(self.layer.bxdf(top, bottom, ctx))
    }
}
