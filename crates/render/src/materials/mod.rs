//! Materials: what a surface is made of, turned into a BSDF where a ray hits it.
//!
//! [`Material`] is the closed set of pbrt-v4 materials Kiln has and its dispatch; each lives
//! in its own file, holds its parameters (as [textures](crate::textures) where the scene
//! may vary them over the surface) and makes its [`Bsdf`] at a hit from a
//! [`TextureEvalContext`]. Materials know nothing of lights, media or integrators.

mod coated_diffuse;
mod conductor;
mod dielectric;
mod diffuse;
mod thin_dielectric;

pub use coated_diffuse::CoatedDiffuseMaterial;
pub use conductor::ConductorMaterial;
pub use dielectric::DielectricMaterial;
pub use diffuse::DiffuseMaterial;
pub use thin_dielectric::ThinDielectricMaterial;

use crate::bsdfs::{Bsdf, TrowbridgeReitz};
use crate::shapes::SurfaceHit;
use crate::textures::TextureEvalContext;
use kiln_scene::{MaterialKind, Roughness};

#[derive(Debug, Clone)]
pub enum Material {
    Diffuse(DiffuseMaterial),
    Conductor(ConductorMaterial),
    Dielectric(DielectricMaterial),
    ThinDielectric(ThinDielectricMaterial),
    CoatedDiffuse(CoatedDiffuseMaterial),
    /// Marks a boundary between media: rays pass through unchanged.
    Interface,
}

impl Material {
    /// The material a scene description's Material or MakeNamedMaterial gives.
    pub fn from_description(kind: &MaterialKind) -> Material {
        match kind {
            MaterialKind::Diffuse { reflectance } => {
                Material::Diffuse(DiffuseMaterial::new(reflectance))
            }
            MaterialKind::Dielectric { eta, roughness } => {
                Material::Dielectric(DielectricMaterial::new(*eta, roughness))
            }
            MaterialKind::ThinDielectric { eta } => {
                Material::ThinDielectric(ThinDielectricMaterial { eta: *eta })
            }
            MaterialKind::Conductor { eta, k, roughness } => {
                Material::Conductor(ConductorMaterial::new(*eta, *k, roughness))
            }
            MaterialKind::ConductorReflectance {
                reflectance,
                roughness,
            } => Material::Conductor(ConductorMaterial::from_reflectance(*reflectance, roughness)),
            MaterialKind::CoatedDiffuse {
                reflectance,
                roughness,
                eta,
                ..
            } => Material::CoatedDiffuse(CoatedDiffuseMaterial::new(reflectance, roughness, *eta)),
            MaterialKind::Interface => Material::Interface,
        }
    }

    /// The BSDF at a hit; None for an interface, which rays cross unchanged.
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Option<Bsdf> {
        match self {
            Material::Diffuse(m) => Some(m.bsdf(ctx)),
            Material::Conductor(m) => Some(m.bsdf()),
            Material::Dielectric(m) => Some(m.bsdf()),
            Material::ThinDielectric(m) => Some(m.bsdf()),
            Material::CoatedDiffuse(m) => Some(m.bsdf(ctx)),
            Material::Interface => None,
        }
    }

    /// True for an interface: a boundary between media, not a surface that scatters.
    pub fn is_interface(&self) -> bool {
        matches!(self, Material::Interface)
    }
}

impl TextureEvalContext {
    /// The context at a surface hit.
    pub fn at(hit: &SurfaceHit) -> TextureEvalContext {
        TextureEvalContext {
            p: hit.p,
            uv: hit.uv,
        }
    }
}

fn distribution(r: &Roughness) -> TrowbridgeReitz {
    TrowbridgeReitz::new(r.u, r.v)
}
