//! Materials: `Material`, `MakeNamedMaterial` and the parameters of each material type.

use super::Parser;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::params::ParamSet;
use crate::spectrum::{self, SpectrumUse};

impl Parser {
    pub(super) fn make_named_material(
        &mut self,
        name: String,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<()> {
        let ty = params.string("type")?.ok_or_else(|| {
            SceneError::at(
                loc,
                format!("MakeNamedMaterial '{name}' has no \"string type\""),
            )
        })?;
        if self.named_materials.contains_key(&name) {
            return Err(SceneError::at(
                loc,
                format!("material '{name}' is defined twice"),
            ));
        }
        let id = self.material(&ty, params, Some(name.clone()), loc)?;
        self.named_materials.insert(name, id);
        Ok(())
    }

    fn roughness(&self, params: &ParamSet) -> Result<Roughness> {
        let r = params.float_opt("roughness")?;
        let u = params.float_opt("uroughness")?.or(r).unwrap_or(0.0);
        let v = params.float_opt("vroughness")?.or(r).unwrap_or(0.0);
        let remap = params.bool("remaproughness", true)?;
        // pbrt-v4 maps "roughness" to the microfacet alpha by a square root.
        let map = |x: f64| if remap { x.max(0.0).sqrt() } else { x.max(0.0) } as f32;
        Ok(Roughness {
            u: map(u),
            v: map(v),
        })
    }

    fn scalar_eta(&self, params: &ParamSet, default: f32) -> Result<f32> {
        // An RGB renderer cannot disperse: a spectral eta is taken at the green channel.
        Ok(match params.rgb("eta", SpectrumUse::Unbounded)? {
            Some(rgb) => rgb[1],
            None => default,
        })
    }

    pub(super) fn material(
        &mut self,
        ty: &str,
        params: &ParamSet,
        name: Option<String>,
        loc: &Loc,
    ) -> Result<MaterialId> {
        let reflectance = |default: f32| -> Result<RgbValue> {
            Ok(RgbValue::Constant(
                params
                    .rgb("reflectance", SpectrumUse::Albedo)?
                    .unwrap_or([default; 3]),
            ))
        };
        let kind = match ty {
            "diffuse" => MaterialKind::Diffuse {
                reflectance: reflectance(0.5)?,
            },
            "dielectric" => MaterialKind::Dielectric {
                eta: self.scalar_eta(params, 1.5)?,
                roughness: self.roughness(params)?,
            },
            "thindielectric" => MaterialKind::ThinDielectric {
                eta: self.scalar_eta(params, 1.5)?,
            },
            "conductor" => {
                let roughness = self.roughness(params)?;
                match params.rgb("reflectance", SpectrumUse::Albedo)? {
                    Some(reflectance) => MaterialKind::ConductorReflectance {
                        reflectance,
                        roughness,
                    },
                    None => MaterialKind::Conductor {
                        eta: params
                            .rgb("eta", SpectrumUse::Unbounded)?
                            .unwrap_or_else(|| named("metal-Cu-eta")),
                        k: params
                            .rgb("k", SpectrumUse::Unbounded)?
                            .unwrap_or_else(|| named("metal-Cu-k")),
                        roughness,
                    },
                }
            }
            "coateddiffuse" => {
                let thickness = params.float("thickness", 0.01)? as f32;
                let g = params.float("g", 0.0)? as f32;
                let albedo = params
                    .rgb("albedo", SpectrumUse::Albedo)?
                    .unwrap_or([0.0; 3]);
                if albedo != [0.0; 3] {
                    return Err(SceneError::at(
                        &params.loc_of("albedo").unwrap_or_else(|| loc.clone()),
                        "coateddiffuse: a scattering layer (\"albedo\" > 0) is not supported yet",
                    ));
                }
                params.mark_used("maxdepth");
                params.mark_used("nsamples");
                MaterialKind::CoatedDiffuse {
                    reflectance: reflectance(0.5)?,
                    roughness: self.roughness(params)?,
                    eta: self.scalar_eta(params, 1.5)?,
                    thickness,
                    albedo,
                    g,
                }
            }
            "interface" | "" | "none" => MaterialKind::Interface,
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "unknown or unsupported material type '{other}' (Kiln has diffuse, dielectric, thindielectric, conductor, coateddiffuse, interface)"
                    ),
                ));
            }
        };
        params.mark_used("type");
        for unsupported in ["normalmap", "displacement"] {
            if let Some(l) = params.loc_of(unsupported) {
                return Err(SceneError::at(
                    &l,
                    format!("material parameter '{unsupported}' is not supported yet"),
                ));
            }
        }
        self.check_unused(params, &format!("material '{ty}'"), &[])?;
        let id = MaterialId(self.materials.len() as u32);
        self.materials.push(MaterialDesc {
            kind,
            name,
            loc: loc.clone(),
        });
        Ok(id)
    }
}

fn named(name: &str) -> Rgb {
    spectrum::named_spectrum_rgb(name).unwrap_or([1.0; 3])
}
