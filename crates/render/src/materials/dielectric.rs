//! pbrt-v4's "dielectric": glass, water, any interface that reflects and refracts.

use super::distribution;
use crate::bsdfs::{Bsdf, DielectricBxdf, TrowbridgeReitz};
use kiln_scene::Roughness;

#[derive(Debug, Clone)]
pub struct DielectricMaterial {
    pub eta: f32,
    pub distrib: TrowbridgeReitz,
}

impl DielectricMaterial {
    pub fn new(eta: f32, roughness: &Roughness) -> DielectricMaterial {
        DielectricMaterial {
            eta,
            distrib: distribution(roughness),
        }
    }

    /// A perfectly smooth interface (what a VolumeLight's surface must be).
    pub fn is_smooth(&self) -> bool {
        self.distrib.effectively_smooth()
    }

    pub fn bsdf(&self) -> Bsdf {
        Bsdf::Dielectric(DielectricBxdf {
            eta: self.eta,
            distrib: self.distrib,
        })
    }
}
