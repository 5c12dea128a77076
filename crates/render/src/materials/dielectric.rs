//! pbrt-v4's "dielectric": glass, water, any interface that reflects and refracts.

use super::RoughnessTexture;
use crate::bsdfs::{Bsdf, DielectricBxdf};
use crate::spectral::DenseSpectrum;
use crate::textures::TextureEvalContext;
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct DielectricMaterial {
    /// The index RGB rendering refracts by.
    pub eta: f32,
    pub roughness: RoughnessTexture,
    /// The index as a spectrum, for a dispersive glass: a spectral path refracts by its hero
    /// wavelength's index (and keeps only that wavelength), as pbrt-v4 does.
    pub dispersion: Option<Arc<DenseSpectrum>>,
}

impl DielectricMaterial {
    /// A dielectric of index `eta`, dispersive where `dispersion` gives its index as a
    /// spectrum ((wavelength nm, index) pairs).
    pub fn new(
        eta: f32,
        roughness: RoughnessTexture,
        dispersion: Option<&[(f32, f32)]>,
    ) -> DielectricMaterial {
        DielectricMaterial {
            eta,
            roughness,
            dispersion: dispersion.map(|s| Arc::new(DenseSpectrum::new(s))),
        }
    }

    /// A perfectly smooth interface (what a VolumeLight's surface must be).
    pub fn is_smooth(&self) -> bool {
        self.roughness.is_smooth()
    }

    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Bsdf<'static> {
        let (eta, dispersive) = match (&ctx.waves, &self.dispersion) {
            (Some(w), Some(d)) => (d.at(w).x, true),
            _ => (self.eta, false),
        };
        Bsdf::Dielectric(DielectricBxdf {
            eta,
            distrib: self.roughness.distribution(ctx),
            dispersive,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectral::Wavelengths;
    use glam::{Vec2, Vec3A};

    /// A prism's law per wavelength: a dispersive glass (BK7's Sellmeier index) refracts a
    /// spectral path by its hero wavelength's index, as Snell's law says for that
    /// wavelength, and marks the BSDF so the path keeps that wavelength alone; in RGB it
    /// refracts by its one index.
    #[test]
    fn a_dispersive_glass_refracts_each_wavelength_by_its_own_index() {
        let bk7 = kiln_scene::spectrum::glass_index("glass-BK7").unwrap();
        let glass = DielectricMaterial {
            eta: 1.5185,
            roughness: RoughnessTexture::smooth(),
            dispersion: Some(Arc::new(DenseSpectrum::new(&bk7))),
        };
        let sin_i = 0.6f32;
        let wo = Vec3A::new(-sin_i, 0.0, (1.0 - sin_i * sin_i).sqrt());
        let mut seen = Vec::new();
        for u in [0.05, 0.3, 0.55, 0.8] {
            let waves = Wavelengths::sample(u);
            let ctx = TextureEvalContext {
                waves: Some(waves),
                ..Default::default()
            };
            let Bsdf::Dielectric(d) = glass.bsdf(&ctx) else {
                panic!("a dielectric")
            };
            assert!(d.dispersive);
            let lambda = waves.lambda.x;
            // Snell's law with the Sellmeier index at the hero wavelength.
            let l2 = (f64::from(lambda) / 1000.0).powi(2);
            let n = (1.0
                + 1.039_612_12 * l2 / (l2 - 0.006_000_698_67)
                + 0.231_792_344 * l2 / (l2 - 0.020_017_914_4)
                + 1.010_469_45 * l2 / (l2 - 103.560_653))
                .sqrt() as f32;
            assert!(
                (d.eta - n).abs() < 2e-4,
                "{lambda} nm: eta {} vs {n}",
                d.eta
            );
            // The refracted direction (uc near 1 picks transmission past the Fresnel term).
            let bs = Bsdf::Dielectric(d)
                .sample(wo, 0.999, Vec2::new(0.5, 0.5))
                .expect("a refraction");
            assert!(bs.wi.z < 0.0, "transmitted");
            let sin_t = (bs.wi.x * bs.wi.x + bs.wi.y * bs.wi.y).sqrt();
            assert!(
                (sin_t * n - sin_i).abs() < 1e-4,
                "{lambda} nm: {sin_t} x {n}"
            );
            seen.push((lambda, sin_t));
        }
        // Shorter wavelengths bend more.
        seen.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(seen.windows(2).all(|w| w[0].1 < w[1].1), "{seen:?}");
        let Bsdf::Dielectric(rgb) = glass.bsdf(&TextureEvalContext::default()) else {
            panic!("a dielectric")
        };
        assert!(rgb.eta == 1.5185 && !rgb.dispersive);
    }
}
