//! Parameter lists (`"float radius" [ 1 ]`) and typed access to them.
//!
//! Every lookup marks a parameter used; after a directive has been turned into
//! a scene entity, [`ParamSet::unused`] lists what nobody asked for, so that a
//! misspelt or unsupported parameter becomes a diagnostic instead of a silent
//! default (as pbrt-v4's `ReportUnused` does).

use crate::error::{Loc, Result, SceneError};
use crate::spectrum::{self, SpectrumUse};
use std::cell::Cell;

#[derive(Debug, Clone, PartialEq)]
pub enum ParamValues {
    Numbers(Vec<f64>),
    Strings(Vec<String>),
    Bools(Vec<bool>),
}

#[derive(Debug, Clone)]
pub struct Param {
    pub ty: String,
    pub name: String,
    pub values: ParamValues,
    pub loc: Loc,
    used: Cell<bool>,
}

impl Param {
    pub fn new(ty: &str, name: &str, values: ParamValues, loc: Loc) -> Param {
        Param {
            ty: ty.to_string(),
            name: name.to_string(),
            values,
            loc,
            used: Cell::new(false),
        }
    }

    fn numbers(&self) -> Result<&[f64]> {
        match &self.values {
            ParamValues::Numbers(v) => Ok(v),
            _ => Err(SceneError::at(
                &self.loc,
                format!("parameter \"{} {}\" needs numbers", self.ty, self.name),
            )),
        }
    }
}

/// The parameters of one directive.
#[derive(Debug, Clone, Default)]
pub struct ParamSet {
    params: Vec<Param>,
    /// The colour space its `rgb` values are in (pbrt-v4's ColorSpace); None is sRGB.
    color_space: Option<crate::colorspace::ColorSpace>,
}

/// The parameter types pbrt-v4 knows.
pub const PARAM_TYPES: &[&str] = &[
    "integer",
    "float",
    "point2",
    "vector2",
    "point3",
    "vector3",
    "normal3",
    "normal",
    "point",
    "vector",
    "color",
    "rgb",
    "spectrum",
    "blackbody",
    "bool",
    "string",
    "texture",
];

impl ParamSet {
    /// This set with `defaults` (pbrt-v4's `Attribute` values) added where it does not give
    /// the parameter itself. The defaults count as used: like pbrt-v4, Kiln does not
    /// complain about an attribute a shape or light has no use for.
    pub fn with_defaults(self, defaults: &[Param]) -> ParamSet {
        let mut set = self;
        for d in defaults {
            if !set.params.iter().any(|p| p.name == d.name) {
                let d = d.clone();
                d.used.set(true);
                set.params.push(d);
            }
        }
        set
    }

    /// Its parameters, consumed.
    pub fn into_params(self) -> Vec<Param> {
        self.params
    }

    pub fn push(&mut self, param: Param) -> Result<()> {
        if self.params.iter().any(|p| p.name == param.name) {
            return Err(SceneError::at(
                &param.loc,
                format!("parameter '{}' is given twice", param.name),
            ));
        }
        self.params.push(param);
        Ok(())
    }

    fn find(&self, name: &str, types: &[&str]) -> Result<Option<&Param>> {
        let Some(p) = self.params.iter().find(|p| p.name == name) else {
            return Ok(None);
        };
        if !types.contains(&p.ty.as_str()) {
            return Err(SceneError::at(
                &p.loc,
                format!(
                    "parameter '{name}' has type '{}' but Kiln expects {}",
                    p.ty,
                    types
                        .iter()
                        .map(|t| format!("'{t}'"))
                        .collect::<Vec<_>>()
                        .join(" or ")
                ),
            ));
        }
        p.used.set(true);
        Ok(Some(p))
    }

    /// The location of a parameter, if present (for later diagnostics).
    pub fn loc_of(&self, name: &str) -> Option<Loc> {
        self.params
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.loc.clone())
    }

    fn one_number(&self, name: &str, types: &[&str]) -> Result<Option<f64>> {
        match self.find(name, types)? {
            None => Ok(None),
            Some(p) => {
                let v = p.numbers()?;
                if v.len() != 1 {
                    return Err(SceneError::at(
                        &p.loc,
                        format!("parameter '{name}' needs one value, got {}", v.len()),
                    ));
                }
                Ok(Some(v[0]))
            }
        }
    }

    pub fn float(&self, name: &str, default: f64) -> Result<f64> {
        Ok(self.one_number(name, &["float"])?.unwrap_or(default))
    }

    pub fn float_opt(&self, name: &str) -> Result<Option<f64>> {
        self.one_number(name, &["float"])
    }

    pub fn int(&self, name: &str, default: i64) -> Result<i64> {
        Ok(self
            .one_number(name, &["integer"])?
            .map(|v| v as i64)
            .unwrap_or(default))
    }

    pub fn string(&self, name: &str) -> Result<Option<String>> {
        match self.find(name, &["string"])? {
            None => Ok(None),
            Some(p) => match &p.values {
                ParamValues::Strings(v) if v.len() == 1 => Ok(Some(v[0].clone())),
                _ => Err(SceneError::at(
                    &p.loc,
                    format!("parameter '{name}' needs one string"),
                )),
            },
        }
    }

    /// Every string of a string parameter.
    pub fn strings(&self, name: &str) -> Result<Option<Vec<String>>> {
        match self.find(name, &["string"])? {
            None => Ok(None),
            Some(p) => match &p.values {
                ParamValues::Strings(v) => Ok(Some(v.clone())),
                _ => Err(SceneError::at(
                    &p.loc,
                    format!("parameter '{name}' needs strings"),
                )),
            },
        }
    }

    pub fn bool(&self, name: &str, default: bool) -> Result<bool> {
        match self.find(name, &["bool"])? {
            None => Ok(default),
            Some(p) => match &p.values {
                ParamValues::Bools(v) if v.len() == 1 => Ok(v[0]),
                _ => Err(SceneError::at(
                    &p.loc,
                    format!("parameter '{name}' needs one bool (true or false)"),
                )),
            },
        }
    }

    /// All numbers of a parameter, checking that their count is a multiple of `stride`.
    pub fn numbers(&self, name: &str, types: &[&str], stride: usize) -> Result<Option<Vec<f64>>> {
        match self.find(name, types)? {
            None => Ok(None),
            Some(p) => {
                let v = p.numbers()?;
                if v.len() % stride != 0 {
                    return Err(SceneError::at(
                        &p.loc,
                        format!(
                            "parameter '{name}' has {} values, not a multiple of {stride}",
                            v.len()
                        ),
                    ));
                }
                Ok(Some(v.to_vec()))
            }
        }
    }

    pub fn floats(&self, name: &str) -> Result<Option<Vec<f64>>> {
        self.numbers(name, &["float"], 1)
    }

    pub fn ints(&self, name: &str) -> Result<Option<Vec<i64>>> {
        Ok(self
            .numbers(name, &["integer"], 1)?
            .map(|v| v.into_iter().map(|x| x as i64).collect()))
    }

    pub fn point3s(&self, name: &str) -> Result<Option<Vec<[f32; 3]>>> {
        Ok(self
            .numbers(
                name,
                &["point3", "point", "vector3", "vector", "normal3", "normal"],
                3,
            )?
            .map(|v| {
                v.chunks_exact(3)
                    .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
                    .collect()
            }))
    }

    pub fn point2s(&self, name: &str) -> Result<Option<Vec<[f32; 2]>>> {
        Ok(self
            .numbers(name, &["point2", "vector2", "float"], 2)?
            .map(|v| {
                v.chunks_exact(2)
                    .map(|c| [c[0] as f32, c[1] as f32])
                    .collect()
            }))
    }

    /// One point or vector (`"point3 from" [0 0 0]`).
    pub fn point3(&self, name: &str, default: [f64; 3]) -> Result<[f64; 3]> {
        match self.numbers(
            name,
            &["point3", "point", "vector3", "vector", "normal3", "normal"],
            3,
        )? {
            None => Ok(default),
            Some(v) if v.len() == 3 => Ok([v[0], v[1], v[2]]),
            Some(_) => Err(SceneError::at(
                &self
                    .loc_of(name)
                    .unwrap_or_else(|| Loc::synthetic("params")),
                format!("parameter '{name}' needs exactly one 3-component value"),
            )),
        }
    }

    /// A colour, from `rgb`, `spectrum` (named or sampled) or `blackbody`, converted to linear sRGB.
    pub fn rgb(&self, name: &str, usage: SpectrumUse) -> Result<Option<[f32; 3]>> {
        let Some(p) = self.find(
            name,
            &["rgb", "color", "spectrum", "blackbody", "float", "texture"],
        )?
        else {
            return Ok(None);
        };
        let at = |msg: String| SceneError::at(&p.loc, msg);
        match p.ty.as_str() {
            "rgb" | "color" => {
                let v = p.numbers()?;
                if v.len() != 3 {
                    return Err(at(format!("'rgb {name}' needs 3 values, got {}", v.len())));
                }
                if usage == SpectrumUse::Albedo && v.iter().any(|&x| x < 0.0) {
                    return Err(at(format!("'rgb {name}' has a negative value")));
                }
                let rgb = [v[0] as f32, v[1] as f32, v[2] as f32];
                Ok(Some(match &self.color_space {
                    Some(cs) => cs.to_srgb(rgb, usage),
                    None => rgb,
                }))
            }
            // A single float where a spectrum is expected is a constant spectrum.
            "float" => {
                let v = p.numbers()?;
                if v.len() != 1 {
                    return Err(at(format!("'float {name}' needs one value")));
                }
                let x = v[0] as f32;
                Ok(Some([x, x, x]))
            }
            "blackbody" => {
                let v = p.numbers()?;
                if v.len() != 1 {
                    return Err(at(format!(
                        "'blackbody {name}' needs one temperature in kelvin"
                    )));
                }
                spectrum::blackbody_rgb(v[0] as f32)
                    .map(Some)
                    .map_err(|e| at(format!("'blackbody {name}': {e}")))
            }
            "spectrum" => match &p.values {
                ParamValues::Strings(s) if s.len() == 1 => {
                    match spectrum::named_spectrum_rgb(&s[0]) {
                        Some(rgb) => Ok(Some(rgb)),
                        None => Err(at(format!(
                            "unknown named spectrum '{}' (Kiln knows: {}; spectrum files are read for materials, lights and media)",
                            s[0],
                            spectrum::named_spectrum_names().join(", ")
                        ))),
                    }
                }
                ParamValues::Numbers(v) => {
                    if v.len() < 2 || v.len() % 2 != 0 {
                        return Err(at(format!(
                            "'spectrum {name}' needs (wavelength, value) pairs"
                        )));
                    }
                    let pairs: Vec<(f32, f32)> = v
                        .chunks_exact(2)
                        .map(|c| (c[0] as f32, c[1] as f32))
                        .collect();
                    // Zero beyond its ends, as pbrt-v4 reads a scene's spectra (inline or
                    // from a file), where its named spectra carry their end values on.
                    spectrum::sampled_to_rgb_with(&pairs, usage, spectrum::Ends::Zero)
                        .map(Some)
                        .map_err(|e| at(format!("'spectrum {name}': {e}")))
                }
                _ => Err(at(format!(
                    "'spectrum {name}' needs a name or wavelength-value pairs"
                ))),
            },
            _ => Err(at(format!(
                "'texture {name}': a texture is not accepted here; give a value"
            ))),
        }
    }

    /// The luminance pbrt-v4 gives emission parameter `name` where it makes an image of
    /// the spectrum's own XYZ (an infinite light's "L" seen through a portal) rather than
    /// normalising it to 1 nit as its lights otherwise do: a blackbody's (1 at its peak
    /// wavelength) or an inline or file spectrum's own, as a factor on the 1-nit colour
    /// [`ParamSet::rgb`] gives. 1 for RGB, a float, or a named spectrum (pbrt-v4's named
    /// illuminants are 1 nit already). Call it after [`ParamSet::rgb`] has checked the value.
    pub fn own_luminance(&self, name: &str) -> f32 {
        let Some(p) = self
            .params
            .iter()
            .find(|p| p.name == name && matches!(p.ty.as_str(), "blackbody" | "spectrum"))
        else {
            return 1.0;
        };
        match &p.values {
            ParamValues::Numbers(_) => self
                .emission_spectrum(name)
                .map_or(1.0, |s| spectrum::own_luminance(&s) as f32),
            _ => 1.0,
        }
    }

    /// The shape of an emission parameter given as a spectrum (see
    /// [`spectrum::EmissionSpectrum`]): a blackbody, or inline (wavelength, value) pairs (a
    /// spectrum file's, once read, or one of pbrt-v4's named illuminants, from the CIE's
    /// tables). None when it is absent, given as RGB or a float, or another named spectrum.
    /// Call it after [`ParamSet::rgb`] has checked the value.
    pub fn emission_spectrum(&self, name: &str) -> Option<spectrum::EmissionSpectrum> {
        let p = self
            .params
            .iter()
            .find(|p| p.name == name && matches!(p.ty.as_str(), "blackbody" | "spectrum"))?;
        match (p.ty.as_str(), &p.values) {
            ("blackbody", ParamValues::Numbers(v)) if v.len() == 1 && v[0] > 0.0 => {
                Some(spectrum::blackbody_spectrum(v[0] as f32))
            }
            ("spectrum", ParamValues::Numbers(v)) if v.len() >= 2 && v.len() % 2 == 0 => {
                let pairs: Vec<(f32, f32)> = v
                    .chunks_exact(2)
                    .map(|c| (c[0] as f32, c[1] as f32))
                    .collect();
                // Zero beyond its ends (as pbrt-v4 reads a scene's spectra): a nanometre out.
                let (first, last) = (pairs[0].0, pairs[pairs.len() - 1].0);
                let ordered = pairs.windows(2).all(|w| w[0].0 < w[1].0);
                ordered.then(|| {
                    std::iter::once((first - 1.0, 0.0))
                        .chain(pairs)
                        .chain(std::iter::once((last + 1.0, 0.0)))
                        .collect()
                })
            }
            ("spectrum", ParamValues::Strings(v)) if v.len() == 1 => {
                spectrum::named_illuminant_spectrum(&v[0])
            }
            _ => None,
        }
    }

    /// Every RGB triple of an `rgb` parameter (pbrt-v4's RGB arrays, such as an "rgbgrid"
    /// medium's), converted from the colour space in effect; None when it is absent.
    pub fn rgbs(&self, name: &str, usage: SpectrumUse) -> Result<Option<Vec<[f32; 3]>>> {
        let Some(v) = self.numbers(name, &["rgb", "color"], 3)? else {
            return Ok(None);
        };
        let loc = self
            .loc_of(name)
            .unwrap_or_else(|| Loc::synthetic("rgb array"));
        let mut out = Vec::with_capacity(v.len() / 3);
        for c in v.chunks_exact(3) {
            let rgb = [c[0] as f32, c[1] as f32, c[2] as f32];
            if rgb
                .iter()
                .any(|x| !x.is_finite() || (usage != SpectrumUse::Illuminant && *x < 0.0))
            {
                return Err(SceneError::at(
                    &loc,
                    format!("'rgb {name}' has a negative or non-finite value {rgb:?}"),
                ));
            }
            out.push(match &self.color_space {
                Some(cs) => cs.to_srgb(rgb, usage),
                None => rgb,
            });
        }
        Ok(Some(out))
    }

    /// The texture a parameter names, with its location, if it is given as
    /// `"texture NAME" "texture-name"`; None if it is absent or given as a value.
    pub fn texture_name(&self, name: &str) -> Result<Option<(String, Loc)>> {
        let Some(p) = self
            .params
            .iter()
            .find(|p| p.name == name && p.ty == "texture")
        else {
            return Ok(None);
        };
        p.used.set(true);
        match &p.values {
            ParamValues::Strings(s) if s.len() == 1 => Ok(Some((s[0].clone(), p.loc.clone()))),
            _ => Err(SceneError::at(
                &p.loc,
                format!("'texture {name}' needs one texture name"),
            )),
        }
    }

    /// These parameters, with their `rgb` values in colour space `cs`.
    pub fn in_color_space(mut self, cs: crate::colorspace::ColorSpace) -> ParamSet {
        self.color_space = (!cs.is_srgb()).then_some(cs);
        self
    }

    /// A `spectrum` parameter given as (wavelength, value) pairs (inline, or read from a
    /// file), as given; None when it is absent or given any other way. (It is not marked
    /// used: the parameter's RGB is read too.)
    pub fn sampled_spectrum(&self, name: &str) -> Option<Vec<(f32, f32)>> {
        let p = self
            .params
            .iter()
            .find(|p| p.name == name && p.ty == "spectrum")?;
        match &p.values {
            ParamValues::Numbers(v) if v.len() >= 2 && v.len() % 2 == 0 => Some(
                v.chunks_exact(2)
                    .map(|c| (c[0] as f32, c[1] as f32))
                    .collect(),
            ),
            _ => None,
        }
    }

    /// A `spectrum` parameter given as one string (a name or a file), if it is.
    pub fn named_spectrum(&self, name: &str) -> Option<String> {
        let p = self
            .params
            .iter()
            .find(|p| p.name == name && p.ty == "spectrum")?;
        match &p.values {
            ParamValues::Strings(v) if v.len() == 1 => Some(v[0].clone()),
            _ => None,
        }
    }

    /// The `spectrum` parameters given as one string that names no built-in spectrum: files
    /// of (wavelength, value) pairs, as (parameter name, file name, location).
    pub fn spectrum_files(&self) -> Vec<(String, String, Loc)> {
        self.spectrum_strings(false)
    }

    /// The `spectrum` parameters given as one of the built-in names, as (parameter name,
    /// spectrum name, location).
    pub fn named_spectra(&self) -> Vec<(String, String, Loc)> {
        self.spectrum_strings(true)
    }

    /// The `spectrum` parameters given as one string that is (`named`) or is not one of the
    /// built-in names.
    fn spectrum_strings(&self, named: bool) -> Vec<(String, String, Loc)> {
        self.params
            .iter()
            .filter(|p| p.ty == "spectrum")
            .filter_map(|p| match &p.values {
                ParamValues::Strings(v)
                    if v.len() == 1 && spectrum::named_spectrum_rgb(&v[0]).is_some() == named =>
                {
                    Some((p.name.clone(), v[0].clone(), p.loc.clone()))
                }
                _ => None,
            })
            .collect()
    }

    /// Replaces the values of parameter `name`.
    pub fn set_values(&mut self, name: &str, values: ParamValues) {
        if let Some(p) = self.params.iter_mut().find(|p| p.name == name) {
            p.values = values;
        }
    }

    /// Parameters that no lookup asked for.
    pub fn unused(&self) -> impl Iterator<Item = &Param> {
        self.params.iter().filter(|p| !p.used.get())
    }

    /// Marks a parameter as used without reading it (one Kiln deliberately ignores).
    pub fn mark_used(&self, name: &str) {
        if let Some(p) = self.params.iter().find(|p| p.name == name) {
            p.used.set(true);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(params: Vec<Param>) -> ParamSet {
        let mut s = ParamSet::default();
        for p in params {
            s.push(p).unwrap();
        }
        s
    }

    #[test]
    fn lookups_mark_parameters_used() {
        let loc = Loc::synthetic("t");
        let s = set(vec![
            Param::new(
                "float",
                "radius",
                ParamValues::Numbers(vec![2.0]),
                loc.clone(),
            ),
            Param::new("float", "raduis", ParamValues::Numbers(vec![3.0]), loc),
        ]);
        assert_eq!(s.float("radius", 1.0).unwrap(), 2.0);
        let unused: Vec<_> = s.unused().map(|p| p.name.clone()).collect();
        assert_eq!(unused, vec!["raduis"]);
    }

    #[test]
    fn wrong_type_is_an_error() {
        let s = set(vec![Param::new(
            "integer",
            "radius",
            ParamValues::Numbers(vec![2.0]),
            Loc::synthetic("t"),
        )]);
        assert!(s.float("radius", 1.0).is_err());
    }

    #[test]
    fn rgb_and_blackbody_become_rgb() {
        let loc = Loc::synthetic("t");
        let s = set(vec![
            Param::new(
                "rgb",
                "a",
                ParamValues::Numbers(vec![0.1, 0.2, 0.3]),
                loc.clone(),
            ),
            Param::new("blackbody", "b", ParamValues::Numbers(vec![2000.0]), loc),
        ]);
        assert_eq!(
            s.rgb("a", SpectrumUse::Albedo).unwrap(),
            Some([0.1, 0.2, 0.3])
        );
        let b = s.rgb("b", SpectrumUse::Illuminant).unwrap().unwrap();
        assert!(b[0] > b[1] && b[1] > b[2], "{b:?}");
    }
}
