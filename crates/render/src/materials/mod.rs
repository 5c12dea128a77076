//! Materials: what a surface is made of, turned into a BSDF where a ray hits it.
//!
//! [`Material`] is the closed set of pbrt-v4 materials Kiln has and its dispatch; each lives
//! in its own file, holds its parameters (as [textures](crate::textures) where the scene
//! may vary them over the surface) and makes its [`Bsdf`] at a hit from a
//! [`TextureEvalContext`]. Materials know nothing of lights, media or integrators.

mod bump;
mod coated_conductor;
mod coated_diffuse;
mod conductor;
mod dielectric;
mod diffuse;
mod diffuse_transmission;
mod hair;
mod layer;
mod measured;
mod mix;
mod roughness;
mod thin_dielectric;

pub use bump::Perturbation;
pub use coated_conductor::CoatedConductorMaterial;
pub use coated_diffuse::CoatedDiffuseMaterial;
pub use conductor::{ConductorMaterial, ConductorSpec};
pub use dielectric::DielectricMaterial;
pub use diffuse::DiffuseMaterial;
pub use diffuse_transmission::DiffuseTransmissionMaterial;
pub use hair::{HairAbsorptionTexture, HairMaterial};
pub use layer::Layer;
pub use measured::MeasuredMaterial;
pub use mix::MixMaterial;
pub use roughness::RoughnessTexture;
pub use thin_dielectric::ThinDielectricMaterial;

use crate::bsdfs::{Bsdf, MeasuredTables};
use crate::textures::{TextureEvalContext, Textures};
use kiln_scene::{MaterialDesc, MaterialKind, NormalPerturbationDesc};
use std::sync::Arc;

/// A material: the model that makes its BSDF, and how it perturbs the shading normal.
#[derive(Debug, Clone)]
pub struct Material {
    pub model: Model,
    pub normal: Perturbation,
}

/// The reflection models, one per pbrt-v4 material.
#[derive(Debug, Clone)]
pub enum Model {
    Diffuse(DiffuseMaterial),
    DiffuseTransmission(DiffuseTransmissionMaterial),
    /// Resolved to one of its two materials before shading (see `Scene::bsdf`).
    Mix(MixMaterial),
    Conductor(ConductorMaterial),
    Dielectric(DielectricMaterial),
    ThinDielectric(ThinDielectricMaterial),
    CoatedDiffuse(CoatedDiffuseMaterial),
    CoatedConductor(CoatedConductorMaterial),
    Measured(MeasuredMaterial),
    Hair(HairMaterial),
    /// Marks a boundary between media: rays pass through unchanged.
    Interface,
}

impl Material {
    /// The material a scene description's Material or MakeNamedMaterial gives, its
    /// textures taken from the scene's.
    pub fn from_description(desc: &MaterialDesc, textures: &Textures) -> Result<Material, String> {
        Ok(Material {
            model: Model::from_description(&desc.kind, textures)?,
            normal: match &desc.normal {
                NormalPerturbationDesc::None => Perturbation::None,
                NormalPerturbationDesc::Bump(d) => Perturbation::Bump(textures.float_value(d)),
                NormalPerturbationDesc::NormalMap(image) => Perturbation::NormalMap(image.clone()),
            },
        })
    }

    /// A material with no perturbation.
    pub fn plain(model: Model) -> Material {
        Material {
            model,
            normal: Perturbation::None,
        }
    }

    /// The BSDF at a hit; None for an interface, which rays cross unchanged.
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Option<Bsdf<'_>> {
        self.model.bsdf(ctx)
    }

    /// Whether the material varies over its surface: its BSDF then needs the hit's full
    /// texture context, footprint included; otherwise any context gives the same BSDF.
    pub fn is_textured(&self) -> bool {
        self.model.is_textured() || !self.normal.is_none()
    }

    /// True for an interface: a boundary between media, not a surface that scatters.
    pub fn is_interface(&self) -> bool {
        self.model.is_interface()
    }
}

impl Model {
    /// The model a description gives; Err only for tables that cannot be sampled.
    pub fn from_description(kind: &MaterialKind, textures: &Textures) -> Result<Model, String> {
        let rough = |r| RoughnessTexture::new(r, textures);
        Ok(match kind {
            MaterialKind::Diffuse { reflectance } => Model::Diffuse(DiffuseMaterial {
                reflectance: textures.rgb_value(reflectance),
            }),
            // The surface of a subsurface material is a dielectric; its interior becomes a
            // medium inside the shapes that use it (scene/build.rs).
            MaterialKind::Subsurface { eta, roughness, .. } => {
                Model::Dielectric(DielectricMaterial::new(*eta, rough(roughness), None))
            }
            MaterialKind::Dielectric {
                eta,
                roughness,
                dispersion,
            } => Model::Dielectric(DielectricMaterial::new(
                *eta,
                rough(roughness),
                dispersion.as_deref().map(Vec::as_slice),
            )),
            MaterialKind::ThinDielectric { eta } => {
                Model::ThinDielectric(ThinDielectricMaterial { eta: *eta })
            }
            MaterialKind::Conductor {
                eta,
                k,
                roughness,
                spectra,
            } => Model::Conductor(ConductorMaterial::new(
                ConductorSpec::EtaK {
                    eta: textures.rgb_value(eta),
                    k: textures.rgb_value(k),
                    table: fresnel_table(spectra.as_deref(), 1.0)?,
                    spectra: dense_spectra(spectra.as_deref()),
                },
                rough(roughness),
            )),
            MaterialKind::ConductorReflectance {
                reflectance,
                roughness,
            } => Model::Conductor(ConductorMaterial::new(
                ConductorSpec::Reflectance(textures.rgb_value(reflectance)),
                rough(roughness),
            )),
            MaterialKind::CoatedDiffuse {
                reflectance,
                roughness,
                eta,
                layer,
            } => Model::CoatedDiffuse(CoatedDiffuseMaterial::new(
                textures.rgb_value(reflectance),
                rough(roughness),
                *eta,
                Layer::new(layer, textures),
            )),
            MaterialKind::CoatedConductor { .. } => coated_conductor(kind, textures)?,
            MaterialKind::DiffuseTransmission {
                reflectance,
                transmittance,
                scale,
            } => Model::DiffuseTransmission(DiffuseTransmissionMaterial {
                reflectance: textures.rgb_value(reflectance),
                transmittance: textures.rgb_value(transmittance),
                scale: *scale,
            }),
            MaterialKind::Hair {
                absorption,
                eta,
                beta_m,
                beta_n,
                alpha,
            } => Model::Hair(HairMaterial {
                absorption: match absorption {
                    kiln_scene::HairAbsorption::SigmaA(s) => {
                        HairAbsorptionTexture::SigmaA(textures.rgb_value(s))
                    }
                    kiln_scene::HairAbsorption::Reflectance(c) => {
                        HairAbsorptionTexture::Reflectance(textures.rgb_value(c))
                    }
                    kiln_scene::HairAbsorption::Melanin {
                        eumelanin,
                        pheomelanin,
                    } => HairAbsorptionTexture::Melanin {
                        eumelanin: textures.float_value(eumelanin),
                        pheomelanin: textures.float_value(pheomelanin),
                    },
                },
                eta: textures.float_value(eta),
                beta_m: textures.float_value(beta_m),
                beta_n: textures.float_value(beta_n),
                alpha: textures.float_value(alpha),
            }),
            MaterialKind::Mix { materials, amount } => Model::Mix(MixMaterial {
                materials: materials.map(|m| m.0),
                amount: textures.float_value(amount),
            }),
            MaterialKind::Measured(brdf) => Model::Measured(MeasuredMaterial {
                tables: Arc::new(MeasuredTables::new(brdf)?),
            }),
            MaterialKind::Interface => Model::Interface,
        })
    }

    /// The BSDF at a hit; None for an interface, which rays cross unchanged.
    pub fn bsdf(&self, ctx: &TextureEvalContext) -> Option<Bsdf<'_>> {
        match self {
            Model::Diffuse(m) => Some(m.bsdf(ctx)),
            Model::DiffuseTransmission(m) => Some(m.bsdf(ctx)),
            // A mix is resolved to a material before shading; it has no BSDF of its own.
            Model::Mix(_) => None,
            Model::Conductor(m) => Some(m.bsdf(ctx)),
            Model::Dielectric(m) => Some(m.bsdf(ctx)),
            Model::ThinDielectric(m) => Some(m.bsdf()),
            Model::CoatedDiffuse(m) => Some(m.bsdf(ctx)),
            Model::CoatedConductor(m) => Some(m.bsdf(ctx)),
            Model::Measured(m) => Some(m.bsdf(ctx.waves.as_ref())),
            Model::Hair(m) => Some(m.bsdf(ctx)),
            Model::Interface => None,
        }
    }

    /// Whether the material varies over its surface: its BSDF then needs the hit's full
    /// texture context, footprint included; otherwise any context gives the same BSDF.
    pub fn is_textured(&self) -> bool {
        match self {
            Model::Diffuse(m) => m.reflectance.as_constant().is_none(),
            Model::DiffuseTransmission(m) => m.is_textured(),
            Model::Mix(_) => true,
            Model::Conductor(m) => m.is_textured(),
            Model::Dielectric(m) => m.roughness.is_textured(),
            Model::CoatedDiffuse(m) => m.is_textured(),
            Model::CoatedConductor(m) => m.is_textured(),
            Model::ThinDielectric(_) | Model::Measured(_) | Model::Interface => false,
            // Where across the fibre a ray struck (the hit's v) shapes the BSDF.
            Model::Hair(_) => true,
        }
    }

    /// True for an interface: a boundary between media, not a surface that scatters.
    pub fn is_interface(&self) -> bool {
        matches!(self, Model::Interface)
    }
}

/// The spectral Fresnel table of a conductor given spectra, seen from a medium of index
/// `outside_eta`.
/// pbrt-v4's "coatedconductor" as a description gives it.
fn coated_conductor(kind: &MaterialKind, textures: &Textures) -> Result<Model, String> {
    let MaterialKind::CoatedConductor {
        interface_roughness,
        interface_eta,
        conductor_eta,
        conductor_k,
        conductor_spectra,
        reflectance,
        conductor_roughness,
        layer,
    } = kind
    else {
        return Err("not a coated conductor".into());
    };
    let rough = |r| RoughnessTexture::new(r, textures);
    Ok(Model::CoatedConductor(CoatedConductorMaterial {
        interface_eta: *interface_eta,
        interface_roughness: rough(interface_roughness),
        conductor: match reflectance {
            Some(r) => ConductorSpec::Reflectance(textures.rgb_value(r)),
            None => ConductorSpec::EtaK {
                eta: textures.rgb_value(conductor_eta),
                k: textures.rgb_value(conductor_k),
                table: fresnel_table(conductor_spectra.as_deref(), *interface_eta)?,
                spectra: dense_spectra(conductor_spectra.as_deref()),
            },
        },
        conductor_roughness: rough(conductor_roughness),
        layer: Layer::new(layer, textures),
    }))
}

/// A conductor's eta and k spectra tabulated for spectral paths.
fn dense_spectra(
    spectra: Option<&kiln_scene::ConductorSpectra>,
) -> Option<std::sync::Arc<[crate::spectral::DenseSpectrum; 2]>> {
    let s = spectra?;
    (!s.eta.is_empty() && !s.k.is_empty()).then(|| {
        std::sync::Arc::new([
            crate::spectral::DenseSpectrum::new(&s.eta),
            crate::spectral::DenseSpectrum::new(&s.k),
        ])
    })
}

fn fresnel_table(
    spectra: Option<&kiln_scene::ConductorSpectra>,
    outside_eta: f32,
) -> Result<Option<std::sync::Arc<crate::bsdfs::FresnelTable>>, String> {
    let Some(s) = spectra else {
        return Ok(None);
    };
    let rgb = kiln_scene::spectrum::conductor_fresnel_rgb(&s.eta, &s.k, outside_eta)
        .map_err(|e| format!("conductor spectra: {e}"))?;
    Ok(Some(std::sync::Arc::new(crate::bsdfs::FresnelTable::new(
        &rgb,
    ))))
}
