//! Textures: the `Texture` directive, texture mappings, and the material parameters that
//! may name a texture (`"texture reflectance" "wood"`).

use super::Parser;
use crate::error::{Loc, Result, SceneError};
use crate::files::images;
use crate::params::ParamSet;
use crate::spectrum::Rgb;
use crate::spectrum::SpectrumUse;
use crate::textures::*;
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// Whether a `Texture` directive defines a float or a spectrum texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Type {
    Float,
    Spectrum,
}

impl Parser {
    /// `Texture "name" "float"|"spectrum" "class" params...`
    pub(super) fn texture(
        &mut self,
        name: String,
        ty: &str,
        class: &str,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<()> {
        let ty = match ty {
            "float" => Type::Float,
            // pbrt-v3 called spectrum textures "color"; pbrt-v4's upgrader renames them.
            "spectrum" | "color" => Type::Spectrum,
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Texture '{name}': type '{other}' is neither \"float\" nor \"spectrum\""
                    ),
                ));
            }
        };
        let defined = match ty {
            Type::Float => self.float_texture_names.contains_key(&name),
            Type::Spectrum => self.spectrum_texture_names.contains_key(&name),
        };
        if defined {
            return Err(SceneError::at(
                loc,
                format!("Texture '{name}' is defined twice"),
            ));
        }
        let what = format!("Texture '{name}' ({class})");
        match ty {
            Type::Float => {
                let kind = self.texture_kind(class, params, loc, &what, |s, p, n, d| {
                    s.float_value(p, n, d)
                })?;
                if matches!(kind, TextureKind::Marble { .. }) {
                    return Err(SceneError::at(
                        loc,
                        format!("{what}: marble is a spectrum texture in pbrt-v4, not a float one"),
                    ));
                }
                self.check_unused(params, &what, &[])?;
                let id = FloatTextureId(self.float_textures.len() as u32);
                self.float_textures.push(TextureDesc {
                    name: name.clone(),
                    kind,
                    loc: loc.clone(),
                });
                self.float_texture_names.insert(name, id);
            }
            Type::Spectrum => {
                let kind = self.texture_kind(class, params, loc, &what, |s, p, n, d| {
                    s.rgb_value_or(p, n, SpectrumUse::Unbounded, [d; 3])
                })?;
                if matches!(
                    kind,
                    TextureKind::Fbm { .. }
                        | TextureKind::Wrinkled { .. }
                        | TextureKind::Windy { .. }
                ) {
                    return Err(SceneError::at(
                        loc,
                        format!(
                            "{what}: {class} is a float texture in pbrt-v4, not a spectrum one"
                        ),
                    ));
                }
                self.check_unused(params, &what, &[])?;
                let id = SpectrumTextureId(self.spectrum_textures.len() as u32);
                self.spectrum_textures.push(TextureDesc {
                    name: name.clone(),
                    kind,
                    loc: loc.clone(),
                });
                self.spectrum_texture_names.insert(name, id);
            }
        }
        Ok(())
    }

    /// The kind of texture `class` names, its values read by `value(self, params, name, default)`.
    fn texture_kind<V>(
        &mut self,
        class: &str,
        params: &ParamSet,
        loc: &Loc,
        what: &str,
        value: fn(&Parser, &ParamSet, &str, f32) -> Result<V>,
    ) -> Result<TextureKind<V>> {
        let texture_from_world = self.texture_from_world(loc, what)?;
        let count = |name: &str, default: i64| -> Result<u32> {
            let n = params.int(name, default)?;
            if !(1..=64).contains(&n) {
                return Err(SceneError::at(
                    &params.loc_of(name).unwrap_or_else(|| loc.clone()),
                    format!("{what}: \"{name}\" must be between 1 and 64, got {n}"),
                ));
            }
            Ok(n as u32)
        };
        Ok(match class {
            "constant" => TextureKind::Constant(value(self, params, "value", 1.0)?),
            "scale" => TextureKind::Scale {
                tex: value(self, params, "tex", 1.0)?,
                scale: self.float_value(params, "scale", 1.0)?,
            },
            "mix" => TextureKind::Mix {
                tex1: value(self, params, "tex1", 0.0)?,
                tex2: value(self, params, "tex2", 1.0)?,
                amount: self.float_value(params, "amount", 0.5)?,
            },
            "directionmix" => {
                let dir = DVec3::from(params.point3("dir", [0.0, 1.0, 0.0])?);
                let world = self.gs.ctm.transform_vector3(dir);
                if world.length_squared() <= 0.0 || !world.is_finite() {
                    return Err(SceneError::at(
                        &params.loc_of("dir").unwrap_or_else(|| loc.clone()),
                        format!("{what}: \"dir\" must be a non-zero vector"),
                    ));
                }
                TextureKind::DirectionMix {
                    tex1: value(self, params, "tex1", 0.0)?,
                    tex2: value(self, params, "tex2", 1.0)?,
                    dir: world.normalize(),
                }
            }
            "checkerboard" => {
                let mapping = match params.int("dimension", 2)? {
                    2 => CheckerMapping::Planar(self.mapping(params, loc, what)?),
                    3 => CheckerMapping::Solid { texture_from_world },
                    d => {
                        return Err(SceneError::at(
                            &params.loc_of("dimension").unwrap_or_else(|| loc.clone()),
                            format!("{what}: \"dimension\" must be 2 or 3, got {d}"),
                        ));
                    }
                };
                TextureKind::Checkerboard {
                    mapping,
                    tex1: value(self, params, "tex1", 1.0)?,
                    tex2: value(self, params, "tex2", 0.0)?,
                }
            }
            "bilerp" => TextureKind::Bilerp {
                mapping: self.mapping(params, loc, what)?,
                v00: value(self, params, "v00", 0.0)?,
                v01: value(self, params, "v01", 1.0)?,
                v10: value(self, params, "v10", 0.0)?,
                v11: value(self, params, "v11", 1.0)?,
            },
            "dots" => TextureKind::Dots {
                mapping: self.mapping(params, loc, what)?,
                inside: value(self, params, "inside", 1.0)?,
                outside: value(self, params, "outside", 0.0)?,
            },
            "fbm" => TextureKind::Fbm {
                texture_from_world,
                octaves: count("octaves", 8)?,
                roughness: params.float("roughness", 0.5)? as f32,
            },
            "wrinkled" => TextureKind::Wrinkled {
                texture_from_world,
                octaves: count("octaves", 8)?,
                roughness: params.float("roughness", 0.5)? as f32,
            },
            "windy" => TextureKind::Windy { texture_from_world },
            "marble" => TextureKind::Marble {
                texture_from_world,
                octaves: count("octaves", 8)?,
                roughness: params.float("roughness", 0.5)? as f32,
                scale: params.float("scale", 1.0)? as f32,
                variation: params.float("variation", 0.2)? as f32,
            },
            "imagemap" => TextureKind::Image(self.image_texture(params, loc, what)?),
            "ptex" => {
                let file = params.string("filename")?.unwrap_or_default();
                return Err(SceneError::at(
                    loc,
                    format!(
                        "{what}: Kiln does not read Ptex files ('{file}'); convert it to an image with uvs (an EXR or PNG) and use \"imagemap\""
                    ),
                ));
            }
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "{what}: unknown texture class '{other}' (pbrt-v4 has constant, scale, mix, directionmix, checkerboard, bilerp, dots, fbm, wrinkled, windy, marble, imagemap, ptex)"
                    ),
                ));
            }
        })
    }

    /// pbrt-v4's textureFromRender: the inverse of the CTM at the Texture directive.
    fn texture_from_world(&self, loc: &Loc, what: &str) -> Result<DMat4> {
        let m = self.gs.ctm;
        if m.determinant().abs() < 1e-300 || !m.is_finite() {
            return Err(SceneError::at(
                loc,
                format!("{what}: the current transform cannot be inverted"),
            ));
        }
        Ok(m.inverse())
    }

    /// A 2D texture mapping from "string mapping" and its parameters.
    fn mapping(&self, params: &ParamSet, loc: &Loc, what: &str) -> Result<Mapping2D> {
        let ty = params.string("mapping")?.unwrap_or_else(|| "uv".into());
        let f =
            |name: &str, default: f64| -> Result<f32> { Ok(params.float(name, default)? as f32) };
        Ok(match ty.as_str() {
            "uv" => Mapping2D::Uv {
                su: f("uscale", 1.0)?,
                sv: f("vscale", 1.0)?,
                du: f("udelta", 0.0)?,
                dv: f("vdelta", 0.0)?,
            },
            "spherical" => Mapping2D::Spherical {
                texture_from_world: self.texture_from_world(loc, what)?,
            },
            "cylindrical" => Mapping2D::Cylindrical {
                texture_from_world: self.texture_from_world(loc, what)?,
            },
            "planar" => Mapping2D::Planar {
                texture_from_world: self.texture_from_world(loc, what)?,
                vs: DVec3::from(params.point3("v1", [1.0, 0.0, 0.0])?),
                vt: DVec3::from(params.point3("v2", [0.0, 1.0, 0.0])?),
                ds: f("udelta", 0.0)?,
                dt: f("vdelta", 0.0)?,
            },
            other => {
                return Err(SceneError::at(
                    &params.loc_of("mapping").unwrap_or_else(|| loc.clone()),
                    format!(
                        "{what}: unknown texture mapping '{other}' (pbrt-v4 has uv, spherical, cylindrical, planar)"
                    ),
                ));
            }
        })
    }

    fn image_texture(
        &mut self,
        params: &ParamSet,
        loc: &Loc,
        what: &str,
    ) -> Result<ImageTextureDesc> {
        let at = |name: &str| params.loc_of(name).unwrap_or_else(|| loc.clone());
        let Some(filename) = params.string("filename")? else {
            return Err(SceneError::at(
                loc,
                format!("{what}: an imagemap needs \"string filename\""),
            ));
        };
        let filter = match params
            .string("filter")?
            .unwrap_or_else(|| "bilinear".into())
            .as_str()
        {
            "point" => ImageFilter::Point,
            "bilinear" => ImageFilter::Bilinear,
            "trilinear" => ImageFilter::Trilinear,
            "ewa" | "EWA" => ImageFilter::Ewa,
            other => {
                return Err(SceneError::at(
                    &at("filter"),
                    format!(
                        "{what}: unknown filter '{other}' (pbrt-v4 has point, bilinear, trilinear, ewa)"
                    ),
                ));
            }
        };
        let wrap = match params
            .string("wrap")?
            .unwrap_or_else(|| "repeat".into())
            .as_str()
        {
            "repeat" => ImageWrap::Repeat,
            "clamp" => ImageWrap::Clamp,
            "black" => ImageWrap::Black,
            "octahedralsphere" => ImageWrap::OctahedralSphere,
            other => {
                return Err(SceneError::at(
                    &at("wrap"),
                    format!(
                        "{what}: unknown wrap mode '{other}' (pbrt-v4 has repeat, clamp, black, octahedralsphere)"
                    ),
                ));
            }
        };
        let encoding = match params.string("encoding")? {
            // pbrt-v4's default; only PNGs consult it.
            None => ColorEncoding::Srgb,
            Some(e) => parse_encoding(&e).ok_or_else(|| {
                SceneError::at(
                    &at("encoding"),
                    format!(
                        "{what}: unknown encoding '{e}' (pbrt-v4 has \"sRGB\", \"linear\" and \"gamma G\")"
                    ),
                )
            })?,
        };
        let max_anisotropy = params.float("maxanisotropy", 8.0)? as f32;
        let scale = params.float("scale", 1.0)? as f32;
        let invert = params.bool("invert", false)?;
        let mapping = self.mapping(params, loc, what)?;
        let image = self.texture_image(&filename, encoding, loc)?;
        Ok(ImageTextureDesc {
            image,
            mapping,
            filter,
            max_anisotropy,
            wrap,
            scale,
            invert,
        })
    }

    /// An image file, read once per scene however many textures use it.
    pub(super) fn texture_image(
        &mut self,
        filename: &str,
        encoding: ColorEncoding,
        loc: &Loc,
    ) -> Result<Arc<TextureImage>> {
        let path = self.resolve_file(filename, loc)?;
        let key = (path.clone(), format!("{encoding:?}"));
        if let Some(image) = self.images.get(&key) {
            return Ok(image.clone());
        }
        let image = Arc::new(images::read_texture_image(&path, encoding, loc)?);
        self.images.insert(key, image.clone());
        Ok(image)
    }

    /// A float material or texture parameter: a constant, or `"texture name" "tex"` naming
    /// a float texture defined earlier.
    pub(super) fn float_value(
        &self,
        params: &ParamSet,
        name: &str,
        default: f32,
    ) -> Result<FloatValue> {
        if let Some((tex, loc)) = params.texture_name(name)? {
            return match self.float_texture_names.get(&tex) {
                Some(id) => Ok(FloatValue::Texture(*id)),
                None => Err(SceneError::at(
                    &loc,
                    undefined_texture(
                        &tex,
                        name,
                        "float",
                        self.spectrum_texture_names.contains_key(&tex),
                    ),
                )),
            };
        }
        Ok(FloatValue::Constant(
            params.float(name, default as f64)? as f32
        ))
    }

    /// A colour material or texture parameter: a constant (any of the forms
    /// [`ParamSet::rgb`] reads), or a spectrum texture defined earlier.
    pub(super) fn rgb_value(
        &self,
        params: &ParamSet,
        name: &str,
        usage: SpectrumUse,
    ) -> Result<Option<RgbValue>> {
        if let Some((tex, loc)) = params.texture_name(name)? {
            return match self.spectrum_texture_names.get(&tex) {
                Some(id) => Ok(Some(RgbValue::Texture(*id))),
                None => Err(SceneError::at(
                    &loc,
                    undefined_texture(
                        &tex,
                        name,
                        "spectrum",
                        self.float_texture_names.contains_key(&tex),
                    ),
                )),
            };
        }
        Ok(params.rgb(name, usage)?.map(RgbValue::Constant))
    }

    /// [`Self::rgb_value`] with a grey default.
    pub(super) fn rgb_value_or(
        &self,
        params: &ParamSet,
        name: &str,
        usage: SpectrumUse,
        default: Rgb,
    ) -> Result<RgbValue> {
        Ok(self
            .rgb_value(params, name, usage)?
            .unwrap_or(RgbValue::Constant(default)))
    }
}

fn undefined_texture(tex: &str, param: &str, kind: &str, other_kind: bool) -> String {
    if other_kind {
        let other = if kind == "float" { "spectrum" } else { "float" };
        format!(
            "parameter '{param}' needs a {kind} texture, but texture '{tex}' is a {other} texture"
        )
    } else {
        format!("parameter '{param}' names texture '{tex}', which is not defined before it")
    }
}

/// "sRGB", "linear" or "gamma G", as pbrt-v4 spells them.
fn parse_encoding(s: &str) -> Option<ColorEncoding> {
    match s {
        "sRGB" | "srgb" => Some(ColorEncoding::Srgb),
        "linear" => Some(ColorEncoding::Linear),
        _ => {
            let g: f32 = s.strip_prefix("gamma ")?.trim().parse().ok()?;
            (g.is_finite() && g > 0.0).then_some(ColorEncoding::Gamma(g))
        }
    }
}
