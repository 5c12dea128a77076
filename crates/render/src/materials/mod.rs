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
mod roughness;
mod thin_dielectric;

pub use coated_diffuse::CoatedDiffuseMaterial;
pub use conductor::{ConductorMaterial, ConductorSpec};
pub use dielectric::DielectricMaterial;
pub use diffuse::DiffuseMaterial;
pub use roughness::RoughnessTexture;
pub use thin_dielectric::ThinDielectricMaterial;

use crate::bsdfs::Bsdf;
use crate::textures::{TextureEvalContext, Textures};
use kiln_scene::MaterialKind;

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
    /// The material a scene description's Material or MakeNamedMaterial gives, its
    /// textures taken from the scene's.
    pub fn from_description(kind: &MaterialKind, textures: &Textures) -> Material {
        let rough = |r| RoughnessTexture::new(r, textures);
        match kind {
            MaterialKind::Diffuse { reflectance } => Material::Diffuse(DiffuseMaterial {
                reflectance: textures.rgb_value(reflectance),
            }),
            MaterialKind::Dielectric { eta, roughness } => {
                Material::Dielectric(DielectricMaterial {
                    eta: *eta,
                    roughness: rough(roughness),
                })
            }
            MaterialKind::ThinDielectric { eta } => {
                Material::ThinDielectric(ThinDielectricMaterial { eta: *eta })
            }
            MaterialKind::Conductor { eta, k, roughness } => {
                Material::Conductor(ConductorMaterial::new(
                    ConductorSpec::EtaK {
                        eta: textures.rgb_value(eta),
                        k: textures.rgb_value(k),
                    },
                    rough(roughness),
                ))
            }
            MaterialKind::ConductorReflectance {
                reflectance,
                roughness,
            } => Material::Conductor(ConductorMaterial::new(
                ConductorSpec::Reflectance(textures.rgb_value(reflectance)),
                rough(roughness),
            )),
            MaterialKind::CoatedDiffuse {
                reflectance,
                roughness,
                eta,
                ..
            } => Material::CoatedDiffuse(CoatedDiffuseMaterial::new(
                textures.rgb_value(reflectance),
                rough(roughness),
                *eta,
            )),
            MaterialKind::Interface => Material::Interface,
        }
    }

    /// The BSDF at a hit; None for an interface, which rays cross unchanged.
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Option<Bsdf> {
        match self {
            Material::Diffuse(m) => Some(m.bsdf(ctx)),
            Material::Conductor(m) => Some(m.bsdf(ctx)),
            Material::Dielectric(m) => Some(m.bsdf(ctx)),
            Material::ThinDielectric(m) => Some(m.bsdf()),
            Material::CoatedDiffuse(m) => Some(m.bsdf(ctx)),
            Material::Interface => None,
        }
    }

    /// Whether the material varies over its surface: its BSDF then needs the hit's full
    /// texture context, footprint included; otherwise any context gives the same BSDF.
    pub fn is_textured(&self) -> bool {
        match self {
            Material::Diffuse(m) => m.reflectance.as_constant().is_none(),
            Material::Conductor(m) => m.is_textured(),
            Material::Dielectric(m) => m.roughness.is_textured(),
            Material::CoatedDiffuse(m) => {
                m.reflectance.as_constant().is_none() || m.roughness.is_textured()
            }
            Material::ThinDielectric(_) | Material::Interface => false,
        }
    }

    /// True for an interface: a boundary between media, not a surface that scatters.
    pub fn is_interface(&self) -> bool {
        matches!(self, Material::Interface)
    }
}
