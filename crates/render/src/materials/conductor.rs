//! pbrt-v4's "conductor": metals given by a complex index of refraction (eta, k) or by
//! their reflectance at normal incidence, smooth or rough.

use super::distribution;
use crate::bsdfs::{Bsdf, ConductorBxdf};
use crate::math::{Color, rgb};
use kiln_scene::{Rgb, Roughness};

#[derive(Debug, Clone)]
pub struct ConductorMaterial {
    bxdf: ConductorBxdf,
}

impl ConductorMaterial {
    pub fn new(eta: Rgb, k: Rgb, roughness: &Roughness) -> ConductorMaterial {
        ConductorMaterial {
            bxdf: ConductorBxdf {
                eta: rgb(eta),
                k: rgb(k),
                distrib: distribution(roughness),
            },
        }
    }

    /// pbrt-v4: a conductor given by reflectance r has eta = 1 and k = 2 sqrt(r) / sqrt(1 - r).
    pub fn from_reflectance(reflectance: Rgb, roughness: &Roughness) -> ConductorMaterial {
        let r = rgb(reflectance).clamp(Color::ZERO, Color::splat(0.9999));
        let k = 2.0 * r.powf(0.5) / (Color::ONE - r).powf(0.5);
        ConductorMaterial {
            bxdf: ConductorBxdf {
                eta: Color::ONE,
                k,
                distrib: distribution(roughness),
            },
        }
    }

    pub fn bsdf(&self) -> Bsdf {
        Bsdf::Conductor(self.bxdf)
    }
}
