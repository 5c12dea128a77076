//! Materials: `Material`, `MakeNamedMaterial` and the parameters of each material type.

use super::Parser;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::params::ParamSet;
use crate::spectrum::{self, SpectrumUse};
use crate::textures::{ColorEncoding, FloatValue, RgbValue};
use std::sync::Arc;

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

    /// "uroughness" and "vroughness", each falling back to "roughness" (default 0), as
    /// pbrt-v4 reads them; any of them may be a float texture.
    fn roughness(&self, params: &ParamSet) -> Result<Roughness> {
        let either = |name: &str| -> Result<FloatValue> {
            if params.loc_of(name).is_some() {
                self.float_value(params, name, 0.0)
            } else {
                self.float_value(params, "roughness", 0.0)
            }
        };
        Ok(Roughness {
            u: either("uroughness")?,
            v: either("vroughness")?,
            remap: params.bool("remaproughness", true)?,
        })
    }

    /// Roughness read from `PREFIXuroughness`, `PREFIXvroughness` and `PREFIXroughness`
    /// (coatedconductor's "interface." and "conductor."), remapped per "remaproughness".
    fn prefixed_roughness(&self, params: &ParamSet, prefix: &str) -> Result<Roughness> {
        let either = |name: &str| -> Result<FloatValue> {
            let full = format!("{prefix}{name}");
            if params.loc_of(&full).is_some() {
                self.float_value(params, &full, 0.0)
            } else {
                self.float_value(params, &format!("{prefix}roughness"), 0.0)
            }
        };
        Ok(Roughness {
            u: either("uroughness")?,
            v: either("vroughness")?,
            remap: params.bool("remaproughness", true)?,
        })
    }

    /// A layered material's medium and estimator parameters, with pbrt-v4's defaults.
    fn layer(&self, params: &ParamSet) -> Result<LayerDesc> {
        let count = |name: &str, default: i64| -> Result<u32> {
            let n = params.int(name, default)?;
            if !(1..=1000).contains(&n) {
                return Err(SceneError::at(
                    &params.loc_of(name).unwrap(),
                    format!("\"{name}\" must be between 1 and 1000, got {n}"),
                ));
            }
            Ok(n as u32)
        };
        Ok(LayerDesc {
            thickness: self.float_value(params, "thickness", 0.01)?,
            albedo: self.rgb_value_or(params, "albedo", SpectrumUse::Albedo, [0.0; 3])?,
            g: self.float_value(params, "g", 0.0)?,
            max_depth: count("maxdepth", 10)?,
            n_samples: count("nsamples", 1)?,
        })
    }

    fn scalar_eta(&self, params: &ParamSet, default: f32) -> Result<f32> {
        // An RGB renderer cannot disperse: a spectral eta is taken at the green channel.
        Ok(match params.rgb("eta", SpectrumUse::Unbounded)? {
            Some(rgb) => rgb[1],
            None => default,
        })
    }

    /// pbrt-v4's "subsurface": `eta` (1.33), `g` (0), `roughness` (or `uroughness` and
    /// `vroughness`), `scale` (1), and the interior by `name` (a measured medium), by
    /// `sigma_a` and `sigma_s`, by `reflectance` and `mfp` (1), or pbrt-v4's defaults;
    /// constants only, but for `reflectance`, which may be a texture.
    fn subsurface(&mut self, params: &ParamSet, loc: &Loc) -> Result<MaterialKind> {
        let constant = |name: &str, usage: SpectrumUse| -> Result<Option<Rgb>> {
            match self.rgb_value(params, name, usage)? {
                None => Ok(None),
                Some(RgbValue::Constant(c)) => Ok(Some(c)),
                Some(RgbValue::Texture(_)) => Err(SceneError::at(
                    &params.loc_of(name).unwrap_or_else(|| loc.clone()),
                    format!(
                        "subsurface: a textured \"{name}\" is not supported (only \"reflectance\" may be a texture); give a constant"
                    ),
                )),
            }
        };
        let scale = params.float("scale", 1.0)? as f32;
        let eta = params.float("eta", 1.33)? as f32;
        let g = params.float("g", 0.0)? as f32;
        if !(scale >= 0.0 && scale.is_finite() && eta > 0.0 && eta.is_finite()) {
            return Err(SceneError::at(
                loc,
                format!(
                    "subsurface: \"scale\" ({scale}) must be 0 or more and \"eta\" ({eta}) positive"
                ),
            ));
        }
        if !(g > -1.0 && g < 1.0) {
            return Err(SceneError::at(
                &params.loc_of("g").unwrap_or_else(|| loc.clone()),
                format!("subsurface: \"g\" is {g}; it must lie strictly between -1 and 1"),
            ));
        }
        let negative = |v: &Rgb| v.iter().any(|c| !(*c >= 0.0 && c.is_finite()));
        let mut sigma_a = constant("sigma_a", SpectrumUse::Unbounded)?;
        let mut sigma_s = constant("sigma_s", SpectrumUse::Unbounded)?;
        let mut g = g;
        if let Some(name) = params.string("name")? {
            let at = params.loc_of("name").unwrap_or_else(|| loc.clone());
            let Some((a, s)) = crate::measured_media::measured_medium(&name) else {
                return Err(SceneError::at(
                    &at,
                    format!(
                        "subsurface: no measured medium named '{name}' (Kiln knows Jensen et al. 2001's: {})",
                        crate::measured_media::measured_medium_names().join(", ")
                    ),
                ));
            };
            // The table gives reduced scattering: isotropic, as pbrt-v4 enforces.
            (sigma_a, sigma_s, g) = (Some(a), Some(s), 0.0);
        }
        let interior = match (sigma_a, sigma_s) {
            (Some(a), Some(s)) => SubsurfaceInterior::Coefficients {
                sigma_a: a.map(|v| v * scale),
                sigma_s: s.map(|v| v * scale),
            },
            (Some(_), None) | (None, Some(_)) => {
                return Err(SceneError::at(
                    loc,
                    "subsurface: give both sigma_a and sigma_s, or neither",
                ));
            }
            (None, None) => match self.rgb_value(params, "reflectance", SpectrumUse::Albedo)? {
                Some(reflectance) => {
                    let mfp = constant("mfp", SpectrumUse::Unbounded)?.unwrap_or([1.0; 3]);
                    if negative(&mfp) || mfp.contains(&0.0) {
                        return Err(SceneError::at(loc, "subsurface: \"mfp\" must be positive"));
                    }
                    SubsurfaceInterior::Reflectance {
                        reflectance: match reflectance {
                            RgbValue::Constant(c) => {
                                RgbValue::Constant(c.map(|v| v.clamp(0.0, 1.0)))
                            }
                            textured => textured,
                        },
                        mfp: mfp.map(|v| v * scale),
                    }
                }
                None => SubsurfaceInterior::Coefficients {
                    sigma_a: [0.0011, 0.0024, 0.014].map(|v| v * scale),
                    sigma_s: [2.55, 3.21, 3.77].map(|v| v * scale),
                },
            },
        };
        if let SubsurfaceInterior::Coefficients { sigma_a, sigma_s } = &interior
            && (negative(sigma_a) || negative(sigma_s))
        {
            return Err(SceneError::at(
                loc,
                "subsurface: sigma_a and sigma_s must not be negative",
            ));
        }
        if params.loc_of("name").is_some() && params.float("g", 0.0)? != 0.0 {
            let at = params.loc_of("g").unwrap_or_else(|| loc.clone());
            self.warn(&at, "subsurface: \"g\" is ignored with a named measured medium (its coefficients are reduced scattering, as in pbrt-v4)");
        }
        Ok(MaterialKind::Subsurface {
            eta,
            roughness: self.roughness(params)?,
            g,
            interior,
        })
    }

    pub(super) fn material(
        &mut self,
        ty: &str,
        params: &ParamSet,
        name: Option<String>,
        loc: &Loc,
    ) -> Result<MaterialId> {
        let copper = measured_copper(ty, params, loc)?;
        let params = &self.with_spectrum_files(copper.as_ref().unwrap_or(params))?;
        let kind = self.material_kind(ty, params, loc)?;
        params.mark_used("type");
        let normal = self.normal_perturbation(params, loc)?;
        self.check_unused(params, &format!("material '{ty}'"), &[])?;
        let id = MaterialId(self.materials.len() as u32);
        self.materials.push(MaterialDesc {
            normal,
            kind,
            name,
            loc: loc.clone(),
        });
        Ok(id)
    }

    /// The material of type `ty` from its parameters.
    fn material_kind(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<MaterialKind> {
        let reflectance = |default: f32| -> Result<RgbValue> {
            self.rgb_value_or(params, "reflectance", SpectrumUse::Albedo, [default; 3])
        };
        Ok(match ty {
            "diffuse" => MaterialKind::Diffuse {
                reflectance: reflectance(0.5)?,
            },
            "subsurface" => self.subsurface(params, loc)?,
            "dielectric" => MaterialKind::Dielectric {
                eta: self.scalar_eta(params, 1.5)?,
                roughness: self.roughness(params)?,
                dispersion: dispersion(params),
            },
            "thindielectric" => MaterialKind::ThinDielectric {
                eta: self.scalar_eta(params, 1.5)?,
            },
            "conductor" => self.conductor(params)?,
            "coateddiffuse" => MaterialKind::CoatedDiffuse {
                reflectance: reflectance(0.5)?,
                roughness: self.roughness(params)?,
                eta: self.scalar_eta(params, 1.5)?,
                layer: self.layer(params)?,
            },
            "coatedconductor" => self.coated_conductor(params)?,
            "hair" => self.hair(params)?,
            "diffusetransmission" => MaterialKind::DiffuseTransmission {
                reflectance: self.rgb_value_or(
                    params,
                    "reflectance",
                    SpectrumUse::Albedo,
                    [0.25; 3],
                )?,
                transmittance: self.rgb_value_or(
                    params,
                    "transmittance",
                    SpectrumUse::Albedo,
                    [0.25; 3],
                )?,
                scale: params.float("scale", 1.0)? as f32,
            },
            "measured" => self.measured_material(params, loc)?,
            "mix" => self.mix(params, loc)?,
            "interface" | "" | "none" => MaterialKind::Interface,
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "unknown or unsupported material type '{other}' (Kiln has diffuse, diffusetransmission, dielectric, subsurface, thindielectric, conductor, coateddiffuse, coatedconductor, measured, hair, mix, interface)"
                    ),
                ));
            }
        })
    }

    /// `"conductor"`: a reflectance (an artist's colour), or eta and k (copper's by
    /// default), spectral where both were given as spectra.
    fn conductor(&mut self, params: &ParamSet) -> Result<MaterialKind> {
        let roughness = self.roughness(params)?;
        Ok(
            match self.rgb_value(params, "reflectance", SpectrumUse::Albedo)? {
                Some(reflectance) => MaterialKind::ConductorReflectance {
                    reflectance,
                    roughness,
                },
                None => MaterialKind::Conductor {
                    eta: self.rgb_value_or(
                        params,
                        "eta",
                        SpectrumUse::Unbounded,
                        named("metal-Cu-eta"),
                    )?,
                    k: self.rgb_value_or(
                        params,
                        "k",
                        SpectrumUse::Unbounded,
                        named("metal-Cu-k"),
                    )?,
                    roughness,
                    spectra: conductor_spectra(params, "eta", "k"),
                },
            },
        )
    }

    /// `"coatedconductor"`: a dielectric interface over a conductor, each with its
    /// roughness (parameters prefixed "interface." and "conductor.").
    fn coated_conductor(&mut self, params: &ParamSet) -> Result<MaterialKind> {
        let prefixed = |p: &str| -> Result<Roughness> { self.prefixed_roughness(params, p) };
        Ok(MaterialKind::CoatedConductor {
            interface_roughness: prefixed("interface.")?,
            interface_eta: match params.rgb("interface.eta", SpectrumUse::Unbounded)? {
                Some(rgb) => rgb[1],
                None => 1.5,
            },
            conductor_eta: self.rgb_value_or(
                params,
                "conductor.eta",
                SpectrumUse::Unbounded,
                named("metal-Cu-eta"),
            )?,
            conductor_k: self.rgb_value_or(
                params,
                "conductor.k",
                SpectrumUse::Unbounded,
                named("metal-Cu-k"),
            )?,
            conductor_spectra: conductor_spectra(params, "conductor.eta", "conductor.k"),
            reflectance: self.rgb_value(params, "reflectance", SpectrumUse::Albedo)?,
            conductor_roughness: prefixed("conductor.")?,
            layer: self.layer(params)?,
        })
    }

    /// `"hair"`: absorption given (in pbrt-v4's order of preference) as sigma_a, as a
    /// reflectance, or by melanin concentrations, brown hair by default.
    fn hair(&mut self, params: &ParamSet) -> Result<MaterialKind> {
        let given = |n: &str| params.loc_of(n).is_some();
        let absorption = if given("sigma_a") {
            HairAbsorption::SigmaA(self.rgb_value_or(
                params,
                "sigma_a",
                SpectrumUse::Unbounded,
                [0.0; 3],
            )?)
        } else if given("reflectance") || given("color") {
            let name = if given("reflectance") {
                "reflectance"
            } else {
                "color"
            };
            HairAbsorption::Reflectance(self.rgb_value_or(
                params,
                name,
                SpectrumUse::Albedo,
                [0.5; 3],
            )?)
        } else if given("eumelanin") || given("pheomelanin") {
            HairAbsorption::Melanin {
                eumelanin: self.float_value(params, "eumelanin", 0.0)?,
                pheomelanin: self.float_value(params, "pheomelanin", 0.0)?,
            }
        } else {
            // pbrt-v4's default: brown hair.
            HairAbsorption::Melanin {
                eumelanin: FloatValue::Constant(1.3),
                pheomelanin: FloatValue::Constant(0.0),
            }
        };
        // pbrt-v4 ignores the ways not taken (with a warning; Kiln's unused-parameter
        // check is spared them).
        for name in [
            "sigma_a",
            "reflectance",
            "color",
            "eumelanin",
            "pheomelanin",
        ] {
            if given(name) {
                params.mark_used(name);
            }
        }
        Ok(MaterialKind::Hair {
            absorption,
            eta: self.float_value(params, "eta", 1.55)?,
            beta_m: self.float_value(params, "beta_m", 0.3)?,
            beta_n: self.float_value(params, "beta_n", 0.3)?,
            alpha: self.float_value(params, "alpha", 2.0)?,
        })
    }

    /// `"measured"`: an RGL .bsdf file, read once per scene however many materials use it.
    fn measured_material(&mut self, params: &ParamSet, loc: &Loc) -> Result<MaterialKind> {
        let Some(name) = params.string("filename")? else {
            return Err(SceneError::at(
                loc,
                "material 'measured' needs \"string filename\" (an RGL .bsdf file)",
            ));
        };
        let at = params.loc_of("filename").unwrap_or_else(|| loc.clone());
        let path = self.resolve_file(&name, &at)?;
        let brdf = match self.measured.get(&path) {
            Some(b) => b.clone(),
            None => {
                let b = Arc::new(crate::files::measured::read_measured(&path, &at)?);
                self.measured.insert(path, b.clone());
                b
            }
        };
        Ok(MaterialKind::Measured(brdf))
    }

    /// `"mix"`: two materials named before it, and the amount of the second.
    fn mix(&mut self, params: &ParamSet, loc: &Loc) -> Result<MaterialKind> {
        let names = params.strings("materials")?.unwrap_or_default();
        let at = params.loc_of("materials").unwrap_or_else(|| loc.clone());
        if names.len() != 2 {
            return Err(SceneError::at(
                &at,
                format!(
                    "material 'mix' needs two named materials in \"string materials\", got {}",
                    names.len()
                ),
            ));
        }
        let id = |n: &String| {
            self.named_materials.get(n).copied().ok_or_else(|| {
                SceneError::at(
                    &at,
                    format!("material 'mix': no material named '{n}' is defined before it"),
                )
            })
        };
        Ok(MaterialKind::Mix {
            materials: [id(&names[0])?, id(&names[1])?],
            amount: self.float_value(params, "amount", 0.5)?,
        })
    }

    /// A normal map or a bump map by "displacement". pbrt-v4 reads a normal map's values as
    /// they are (linear), and prefers it to a displacement when a material has both.
    fn normal_perturbation(
        &mut self,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<NormalPerturbationDesc> {
        let normal = match params.string("normalmap")? {
            Some(file) if !file.is_empty() => NormalPerturbationDesc::NormalMap(
                self.texture_image(&file, ColorEncoding::Linear, loc)?,
            ),
            _ => match self.float_value(params, "displacement", 0.0)? {
                FloatValue::Constant(_) if params.loc_of("displacement").is_none() => {
                    NormalPerturbationDesc::None
                }
                d => NormalPerturbationDesc::Bump(d),
            },
        };
        params.mark_used("displacement");
        Ok(normal)
    }
}

/// pbrt-v4's conductors are copper unless told otherwise. Where the user has copper's
/// measured tables (`KILN_SPECTRUM_DATA`), a conductor given no eta or k names them, as if
/// the scene had: `params` with those parameters added, or None when nothing is added.
fn measured_copper(ty: &str, params: &ParamSet, loc: &Loc) -> Result<Option<ParamSet>> {
    use crate::files::spectrum_data::named_spectrum_file;
    use crate::params::{Param, ParamValues};
    let (eta, k) = match ty {
        "conductor" => ("eta", "k"),
        "coatedconductor" => ("conductor.eta", "conductor.k"),
        _ => return Ok(None),
    };
    if params.loc_of("reflectance").is_some() {
        return Ok(None);
    }
    let mut out: Option<ParamSet> = None;
    for (param, spectrum) in [(eta, "metal-Cu-eta"), (k, "metal-Cu-k")] {
        if params.loc_of(param).is_none() && named_spectrum_file(spectrum).is_some() {
            let values = ParamValues::Strings(vec![spectrum.to_string()]);
            out.get_or_insert_with(|| params.clone()).push(Param::new(
                "spectrum",
                param,
                values,
                loc.clone(),
            ))?;
        }
    }
    Ok(out)
}

fn named(name: &str) -> Rgb {
    spectrum::named_spectrum_rgb(name).unwrap_or([1.0; 3])
}

/// A dielectric's index as a spectrum, when it was given as one: sampled (inline or from a
/// file) or a named glass Kiln knows the dispersion of.
fn dispersion(params: &ParamSet) -> Option<Arc<Vec<(f32, f32)>>> {
    params
        .sampled_spectrum("eta")
        .or_else(|| spectrum::glass_index(&params.named_spectrum("eta")?))
        .filter(|s| s.len() >= 2 && s.iter().any(|p| p.1 != s[0].1))
        .map(Arc::new)
}

/// A conductor's eta and k as spectra, when both were given as sampled spectra.
fn conductor_spectra(params: &ParamSet, eta: &str, k: &str) -> Option<Arc<ConductorSpectra>> {
    Some(Arc::new(ConductorSpectra {
        eta: params.sampled_spectrum(eta)?,
        k: params.sampled_spectrum(k)?,
    }))
}
