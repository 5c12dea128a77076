//! Materials: the scene's description turned into a BSDF at a hit point.

use crate::bsdfs::{
    Bsdf, CoatedDiffuseBxdf, ConductorBxdf, DielectricBxdf, DiffuseBxdf, ThinDielectricBxdf,
    TrowbridgeReitz, internal_diffuse_reflectance,
};
use crate::math::{Color, rgb};
use kiln_scene::{MaterialKind, RgbValue, Roughness};

#[derive(Debug, Clone)]
pub enum Material {
    /// A surface with one BSDF everywhere (all of Kiln's materials while textures are absent).
    Uniform(Bsdf),
    /// Marks a boundary between media: rays pass through unchanged.
    Interface,
}

fn constant(v: &RgbValue) -> Color {
    match v {
        RgbValue::Constant(c) => rgb(*c),
    }
}

fn distrib(r: &Roughness) -> TrowbridgeReitz {
    TrowbridgeReitz::new(r.u, r.v)
}

impl Material {
    pub fn from_desc(kind: &MaterialKind) -> Material {
        Material::Uniform(match kind {
            MaterialKind::Diffuse { reflectance } => Bsdf::Diffuse(DiffuseBxdf {
                r: constant(reflectance).clamp(Color::ZERO, Color::ONE),
            }),
            MaterialKind::Dielectric { eta, roughness } => Bsdf::Dielectric(DielectricBxdf {
                eta: *eta,
                distrib: distrib(roughness),
            }),
            MaterialKind::ThinDielectric { eta } => {
                Bsdf::ThinDielectric(ThinDielectricBxdf { eta: *eta })
            }
            MaterialKind::Conductor { eta, k, roughness } => Bsdf::Conductor(ConductorBxdf {
                eta: rgb(*eta),
                k: rgb(*k),
                distrib: distrib(roughness),
            }),
            MaterialKind::ConductorReflectance {
                reflectance,
                roughness,
            } => {
                // pbrt-v4: a conductor given by reflectance has eta = 1 and k = 2 sqrt(r) / sqrt(1 - r).
                let r = rgb(*reflectance).clamp(Color::ZERO, Color::splat(0.9999));
                let k = 2.0 * r.powf(0.5) / (Color::ONE - r).powf(0.5);
                Bsdf::Conductor(ConductorBxdf {
                    eta: Color::ONE,
                    k,
                    distrib: distrib(roughness),
                })
            }
            MaterialKind::CoatedDiffuse {
                reflectance,
                roughness,
                eta,
                ..
            } => Bsdf::CoatedDiffuse(CoatedDiffuseBxdf {
                r: constant(reflectance).clamp(Color::ZERO, Color::ONE),
                eta: *eta,
                distrib: distrib(roughness),
                fdr_internal: internal_diffuse_reflectance(*eta),
            }),
            MaterialKind::Interface => return Material::Interface,
        })
    }

    pub fn bsdf(&self) -> Option<&Bsdf> {
        match self {
            Material::Uniform(b) => Some(b),
            Material::Interface => None,
        }
    }
}
