//! Lights: `LightSource` (point, spot, goniometric, projection, distant, infinite, dome)
//! and `AreaLightSource`
//! (pbrt's "diffuse" and Kiln's "volume", the VolumeLight).

use super::Parser;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::params::ParamSet;
use crate::spectrum::SpectrumUse;
use crate::textures::ColorEncoding;
use glam::{DMat4, DVec3};
use std::sync::Arc;

/// What every LightSource reads before its type's own parameters: its type, "scale", the
/// current transform, and pbrt-v4's photometric targets ("power" in lumens, "illuminance"
/// in lux), each refused on a light that does not take it.
struct Common<'a> {
    ty: &'a str,
    scale: f32,
    ctm: DMat4,
    power: Option<f32>,
    illuminance: Option<f32>,
}

impl<'a> Common<'a> {
    fn read(ty: &'a str, params: &ParamSet, ctm: DMat4) -> Result<Common<'a>> {
        // pbrt-v4's photometric targets: the spectrum is normalised to luminance 1 (RGB keeps
        // its values), then "power" (lumens) or "illuminance" (lux) sets the brightness.
        let target = |name: &str, allowed: bool| -> Result<Option<f32>> {
            let Some(at) = params.loc_of(name) else {
                return Ok(None);
            };
            let v = params.float(name, -1.0)?;
            if !allowed {
                return Err(SceneError::at(
                    &at,
                    format!("LightSource '{ty}': \"{name}\" is not supported for this light yet"),
                ));
            }
            // As pbrt-v4: a value that is not positive leaves the light as given.
            Ok((v > 0.0 && v.is_finite()).then_some(v as f32))
        };
        let scale = params.float("scale", 1.0)? as f32;
        let power = target(
            "power",
            matches!(ty, "point" | "spot" | "goniometric" | "projection"),
        )?;
        let illuminance = target("illuminance", ty == "distant" || ty == "infinite")?;
        Ok(Common {
            ty,
            scale,
            ctm,
            power,
            illuminance,
        })
    }

    fn point(&self, p: [f64; 3]) -> DVec3 {
        self.ctm.transform_point3(DVec3::from(p))
    }

    /// The colour parameter `name` (white by default) times "scale" and `k`.
    fn colour(&self, params: &ParamSet, name: &str, k: f32) -> Result<Rgb> {
        let rgb = params
            .rgb(name, SpectrumUse::Illuminant)?
            .unwrap_or([1.0; 3]);
        Ok(rgb.map(|c| c * self.scale).map(|c| c * k))
    }
}

impl Parser {
    pub(super) fn light(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        let params = &self.with_spectrum_files(params)?;
        self.require_world(loc, "LightSource")?;
        self.still_at_start(loc, &format!("LightSource '{ty}'"));
        let c = Common::read(ty, params, self.gs.ctm)?;
        let kind = match ty {
            "point" => point_light(&c, params)?,
            "spot" => spot_light(&c, params, loc)?,
            "distant" => distant_light(&c, params, loc)?,
            "infinite" => self.infinite_light(&c, params, loc)?,
            "goniometric" => self.goniometric_light(&c, params, loc)?,
            "projection" => self.projection_light(&c, params, loc)?,
            "dome" => {
                let up = DVec3::from(params.point3("up", [0.0, 0.0, 1.0])?);
                let at = params.loc_of("up").unwrap_or_else(|| loc.clone());
                LightKind::Dome {
                    radiance: c.colour(params, "L", 1.0)?,
                    up: direction(
                        c.ctm.transform_vector3(up),
                        "LightSource 'dome': \"up\"",
                        &at,
                    )?,
                }
            }
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "LightSource '{other}' is not supported (Kiln has point, spot, goniometric, projection, distant, infinite, dome)"
                    ),
                ));
            }
        };
        self.check_unused(params, &format!("LightSource '{ty}'"), &[])?;
        let medium = self.medium_id(&self.gs.media.1);
        // The colour's spectrum, where the light's colour is that parameter alone.
        let spectrum = match &kind {
            LightKind::Point { .. } | LightKind::Spot { .. } | LightKind::Goniometric { .. } => {
                params.emission_spectrum("I")
            }
            LightKind::Distant { .. }
            | LightKind::UniformInfinite { .. }
            | LightKind::Dome { .. } => params.emission_spectrum("L"),
            LightKind::ImageInfinite { .. } | LightKind::Projection { .. } => None,
        };
        self.lights.push(LightDesc {
            kind,
            medium,
            spectrum,
            loc: loc.clone(),
        });
        Ok(())
    }

    /// `LightSource "infinite"`: a constant sky, or an environment map (equal-area square
    /// or lat-long), either seen through a portal if it has one.
    fn infinite_light(&mut self, c: &Common, params: &ParamSet, loc: &Loc) -> Result<LightKind> {
        if c.illuminance.is_some() && params.loc_of("filename").is_some() {
            return Err(SceneError::at(
                loc,
                "LightSource 'infinite': \"illuminance\" with an image is not supported yet",
            ));
        }
        let portal = match params.point3s("portal")? {
            None => None,
            Some(p) if p.len() == 4 => {
                let p: [[f64; 3]; 4] = std::array::from_fn(|i| p[i].map(f64::from));
                Some(self.check_portal(p, params, loc))
            }
            Some(p) => {
                return Err(SceneError::at(
                    &params.loc_of("portal").unwrap_or_else(|| loc.clone()),
                    format!(
                        "LightSource 'infinite': a \"portal\" has 4 corners, got {}",
                        p.len()
                    ),
                ));
            }
        };
        let Some(name) = params.string("filename")? else {
            // E = π L on an upward-facing patch.
            let k = c.illuminance.map_or(1.0, |e| e / std::f32::consts::PI);
            let radiance = c.colour(params, "L", k)?;
            return Ok(match portal {
                None => LightKind::UniformInfinite { radiance },
                // As pbrt-v4: a constant image behind the portal, of the spectrum's own
                // XYZ, not normalised to 1 nit as its other lights' spectra are (a
                // blackbody of 6500 K is 0.886 of the uniform sky's brightness).
                Some(_) => LightKind::ImageInfinite {
                    image: Arc::new(kiln_image::ImageRgb {
                        width: 1,
                        height: 1,
                        pixels: vec![radiance.map(|c| c * params.own_luminance("L"))],
                    }),
                    layout: EnvironmentLayout::EqualArea,
                    scale: 1.0,
                    light_to_world: c.ctm,
                    portal,
                },
            });
        };
        if params.loc_of("L").is_some() {
            return Err(SceneError::at(
                loc,
                "LightSource 'infinite': give either \"L\" or \"filename\", not both",
            ));
        }
        let path = self.resolve_file(&name, loc)?;
        let image = files::images::read_environment(&path, loc)?;
        let layout = if image.width == image.height {
            EnvironmentLayout::EqualArea
        } else if image.width == 2 * image.height {
            EnvironmentLayout::LatLong
        } else {
            return Err(SceneError::at(
                loc,
                format!(
                    "LightSource 'infinite': '{name}' is {}x{}; Kiln reads square equal-area maps (pbrt-v4) or 2:1 lat-long maps",
                    image.width, image.height
                ),
            ));
        };
        Ok(LightKind::ImageInfinite {
            image: Arc::new(image),
            layout,
            scale: c.scale,
            light_to_world: c.ctm,
            portal,
        })
    }

    /// The image a goniometric or projection light requires ("string filename"), with its
    /// name; every pixel finite.
    fn light_image(
        &mut self,
        c: &Common,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<(String, kiln_image::ImageRgb)> {
        let ty = c.ty;
        let Some(name) = params.string("filename")? else {
            return Err(SceneError::at(
                loc,
                format!("LightSource '{ty}': \"string filename\" (an image) is required"),
            ));
        };
        let path = self.resolve_file(&name, loc)?;
        let image = files::images::read_environment(&path, loc)?;
        if image.pixels.iter().flatten().any(|c| !c.is_finite()) {
            return Err(SceneError::at(
                loc,
                format!("LightSource '{ty}': '{name}' has pixels that are not finite numbers"),
            ));
        }
        Ok((name, image))
    }

    /// `LightSource "goniometric"`: a point light whose intensity over directions is a
    /// square equal-area image.
    fn goniometric_light(&mut self, c: &Common, params: &ParamSet, loc: &Loc) -> Result<LightKind> {
        let (name, image) = self.light_image(c, params, loc)?;
        if image.width != image.height {
            return Err(SceneError::at(
                loc,
                format!(
                    "LightSource 'goniometric': '{name}' is {}x{}; pbrt-v4 takes a square equal-area image",
                    image.width, image.height
                ),
            ));
        }
        // Φ = 4π · the image's mean (of the mean of RGB), as pbrt-v4's k_e.
        let k_e = 4.0 * std::f64::consts::PI * crate::photometry::goniometric_mean(&image);
        let k = c.power.map_or(1.0, |phi| per_unit(phi, k_e));
        // pbrt-v4 turns the light's y axis into z.
        let swap_yz = DMat4::from_cols(
            glam::DVec4::X,
            glam::DVec4::Z,
            glam::DVec4::Y,
            glam::DVec4::W,
        );
        Ok(LightKind::Goniometric {
            light_to_world: c.ctm * swap_yz,
            intensity: c.colour(params, "I", k)?,
            image: Arc::new(image),
        })
    }

    /// `LightSource "projection"`: an image projected from a point through a field of view.
    fn projection_light(&mut self, c: &Common, params: &ParamSet, loc: &Loc) -> Result<LightKind> {
        let (_, image) = self.light_image(c, params, loc)?;
        let fov = params.float("fov", 90.0)?;
        if !(fov > 0.0 && fov < 180.0) {
            return Err(SceneError::at(
                loc,
                format!("LightSource 'projection': fov {fov} is not between 0 and 180 degrees"),
            ));
        }
        let k = c.power.map_or(1.0, |phi| {
            per_unit(phi, crate::photometry::projection_power(&image, fov))
        });
        // pbrt-v4 flips the light's y, so the image's top row is its +y.
        let flip_y = DMat4::from_scale(DVec3::new(1.0, -1.0, 1.0));
        Ok(LightKind::Projection {
            light_to_world: c.ctm * flip_y,
            scale: c.scale * k,
            fov,
            image: Arc::new(image),
        })
    }

    /// A portal's corners, warned about as pbrt-v4 does if they are not a rectangle (the
    /// side they face is still defined, and is all Kiln uses).
    fn check_portal(&mut self, p: [[f64; 3]; 4], params: &ParamSet, loc: &Loc) -> [[f64; 3]; 4] {
        let v = p.map(DVec3::from);
        let n = |a: DVec3| a.normalize_or_zero();
        let (p01, p12, p32, p03) = (
            n(v[1] - v[0]),
            n(v[2] - v[1]),
            n(v[2] - v[3]),
            n(v[3] - v[0]),
        );
        let rectangle = (p01.dot(p32) - 1.0).abs() <= 1e-3
            && (p12.dot(p03) - 1.0).abs() <= 1e-3
            && p01.dot(p12).abs() <= 1e-3
            && p12.dot(p32).abs() <= 1e-3
            && p32.dot(p03).abs() <= 1e-3
            && p03.dot(p01).abs() <= 1e-3;
        if !rectangle {
            self.warn(
                &params.loc_of("portal").unwrap_or_else(|| loc.clone()),
                "LightSource 'infinite': the \"portal\" is not a planar rectangle (pbrt-v4 says so too); light comes through the side it faces",
            );
        }
        p
    }

    pub(super) fn area_light(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        let params = &self.with_spectrum_files(params)?;
        self.require_world(loc, "AreaLightSource")?;
        if ty == "volume" {
            return self.volume_light(params, loc);
        }
        if ty != "diffuse" {
            return Err(SceneError::at(
                loc,
                format!(
                    "AreaLightSource '{ty}' is not supported (Kiln has 'diffuse' and 'volume')"
                ),
            ));
        }
        // pbrt-v4's "power": each shape (each triangle of a mesh) emits that many lumens;
        // the renderer divides by the shape's area. Not positive: the light as given.
        let power = params.float("power", -1.0)?;
        let power = (power > 0.0 && power.is_finite()).then_some(power as f32);
        let scale = params.float("scale", 1.0)? as f32;
        // pbrt-v4: an image gives the radiance (linear RGB, looked up at the surface's uv)
        // in place of L, and only "scale" multiplies it.
        let image = match params.string("filename")? {
            Some(name) => {
                if params.loc_of("L").is_some() {
                    return Err(SceneError::at(
                        loc,
                        "AreaLightSource 'diffuse': give either \"L\" or \"filename\", not both",
                    ));
                }
                let at = params.loc_of("filename").unwrap_or_else(|| loc.clone());
                let image = self.texture_image(&name, ColorEncoding::Srgb, &at)?;
                if image.channels < 3 {
                    return Err(SceneError::at(
                        &at,
                        format!(
                            "AreaLightSource 'diffuse': '{name}' has {} channel(s); an emission image needs R, G and B",
                            image.channels
                        ),
                    ));
                }
                Some(image)
            }
            None => None,
        };
        let radiance = match image {
            Some(_) => [scale; 3],
            None => params
                .rgb("L", SpectrumUse::Illuminant)?
                .unwrap_or([1.0; 3])
                .map(|c| c * scale),
        };
        let spectrum = match image {
            Some(_) => None,
            None => params.emission_spectrum("L"),
        };
        let two_sided = params.bool("twosided", false)?;
        self.check_unused(params, "AreaLightSource 'diffuse'", &[])?;
        self.gs.area_light = Some(AreaLightDesc::Diffuse {
            radiance,
            image,
            two_sided,
            spectrum,
            power,
            loc: loc.clone(),
        });
        Ok(())
    }

    /// Kiln's `AreaLightSource "volume"` (seed 000's VolumeLight).
    fn volume_light(&mut self, params: &ParamSet, loc: &Loc) -> Result<()> {
        let scale = params.float("scale", 1.0)? as f32;
        let le = params
            .rgb("Le", SpectrumUse::Illuminant)?
            .unwrap_or([1.0; 3])
            .map(|c| c * scale);
        let steps = params.int("steps", 32)?;
        if !(1..=100_000).contains(&steps) {
            return Err(SceneError::at(
                loc,
                format!("AreaLightSource 'volume': steps {steps} must be between 1 and 100000"),
            ));
        }
        let power_samples = params.int("powersamples", 50)?;
        if !(1..=1_000_000).contains(&power_samples) {
            return Err(SceneError::at(
                loc,
                format!(
                    "AreaLightSource 'volume': powersamples {power_samples} must be between 1 and 1000000"
                ),
            ));
        }
        let sigma_a = params
            .rgb("sigma_a", SpectrumUse::Unbounded)?
            .unwrap_or([0.0; 3]);
        if le.iter().chain(&sigma_a).any(|v| *v < 0.0) {
            return Err(SceneError::at(
                loc,
                "AreaLightSource 'volume': Le and sigma_a must not be negative",
            ));
        }
        let grid = match params.string("grid")? {
            Some(name) => {
                let path = self.resolve_file(&name, loc)?;
                let at = params.loc_of("grid").unwrap_or_else(|| loc.clone());
                Some(Arc::new(files::voxel_csv::read_voxel_grid(&path, &at)?))
            }
            None => None,
        };
        self.check_unused(params, "AreaLightSource 'volume'", &[])?;
        self.gs.area_light = Some(AreaLightDesc::Volume(VolumeLightDesc {
            le,
            grid,
            steps: steps as u32,
            power_samples: power_samples as u32,
            sigma_a,
            loc: loc.clone(),
        }));
        Ok(())
    }
}

/// `LightSource "point"`: Φ = 4π I.
fn point_light(c: &Common, params: &ParamSet) -> Result<LightKind> {
    let k = c
        .power
        .map_or(1.0, |phi| phi / (4.0 * std::f32::consts::PI));
    Ok(LightKind::Point {
        position: c.point(params.point3("from", [0.0; 3])?),
        intensity: c.colour(params, "I", k)?,
    })
}

/// `LightSource "spot"`: Φ = 2π I ((1 − cos start) + (cos start − cos end) / 2), pbrt-v4's
/// k_e.
fn spot_light(c: &Common, params: &ParamSet, loc: &Loc) -> Result<LightKind> {
    let from = params.point3("from", [0.0; 3])?;
    let to = params.point3("to", [0.0, 0.0, 1.0])?;
    let at = params.loc_of("to").unwrap_or_else(|| loc.clone());
    let direction = direction(
        c.point(to) - c.point(from),
        "LightSource 'spot': \"from\" to \"to\"",
        &at,
    )?;
    let cone = params.float("coneangle", 30.0)?;
    let delta = params.float("conedeltaangle", 5.0)?;
    let (cos_end, cos_start) = (
        libm::cos(cone.to_radians()),
        libm::cos((cone - delta).to_radians()),
    );
    let k = c.power.map_or(1.0, |phi| {
        let k_e = 2.0 * std::f64::consts::PI * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0);
        (f64::from(phi) / k_e) as f32
    });
    Ok(LightKind::Spot {
        position: c.point(from),
        direction,
        intensity: c.colour(params, "I", k)?,
        cos_falloff_end: cos_end,
        cos_falloff_start: cos_start,
    })
}

/// `LightSource "distant"`: E = L on a patch facing the light.
fn distant_light(c: &Common, params: &ParamSet, loc: &Loc) -> Result<LightKind> {
    let from = DVec3::from(params.point3("from", [0.0; 3])?);
    let to = DVec3::from(params.point3("to", [0.0, 0.0, 1.0])?);
    let k = c.illuminance.unwrap_or(1.0);
    let at = params.loc_of("to").unwrap_or_else(|| loc.clone());
    Ok(LightKind::Distant {
        direction: direction(
            c.ctm.transform_vector3(from - to),
            "LightSource 'distant': \"to\" to \"from\"",
            &at,
        )?,
        radiance: c.colour(params, "L", k)?,
    })
}

/// `v` as a unit vector, or an error at `at` saying that `what` has no direction (zero, or
/// not finite once transformed): a light aimed nowhere would render black, or NaN.
fn direction(v: DVec3, what: &str, at: &Loc) -> Result<DVec3> {
    let unit = v.normalize_or_zero();
    if unit == DVec3::ZERO || !unit.is_finite() {
        return Err(SceneError::at(
            at,
            format!(
                "{what} has no direction: it is ({}, {}, {}) in world space",
                v.x, v.y, v.z
            ),
        ));
    }
    Ok(unit)
}

/// The scale that makes a light of power `k_e` per unit scale emit `phi` (none where it
/// emits nothing).
fn per_unit(phi: f32, k_e: f64) -> f32 {
    if k_e > 0.0 {
        (f64::from(phi) / k_e) as f32
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use crate::description::*;
    use crate::parser::tests::load;

    #[test]
    fn area_lights_and_reverse_orientation_follow_attributes() {
        let s = load(
            "WorldBegin
             AttributeBegin
               AreaLightSource \"diffuse\" \"blackbody L\" [ 6500 ] \"float scale\" [ 2 ] \"bool twosided\" true
               ReverseOrientation
               Shape \"sphere\"
             AttributeEnd
             Shape \"sphere\"",
        );
        let Some(AreaLightDesc::Diffuse {
            radiance,
            two_sided,
            ..
        }) = &s.shapes[0].area_light
        else {
            panic!()
        };
        assert!(*two_sided && s.shapes[0].reverse_orientation);
        // A 6500 K blackbody is close to white at luminance 1, times the scale.
        let y = 0.2126 * radiance[0] + 0.7152 * radiance[1] + 0.0722 * radiance[2];
        assert!((y - 2.0).abs() < 0.01, "{radiance:?}");
        assert!(s.shapes[1].area_light.is_none() && !s.shapes[1].reverse_orientation);
    }
    /// A light aimed nowhere (a zero or overflowing direction, once transformed) is an error
    /// naming its line, not a black or NaN frame; so is a rotation about no axis.
    #[test]
    fn lights_aimed_nowhere_are_errors_naming_the_line() {
        for (text, what) in [
            (
                "LightSource \"dome\" \"vector3 up\" [ 0 0 0 ]",
                "'dome': \"up\"",
            ),
            (
                "LightSource \"distant\" \"point3 from\" [ 1 2 3 ] \"point3 to\" [ 1 2 3 ]",
                "'distant'",
            ),
            (
                "LightSource \"spot\" \"point3 from\" [ 0 1 0 ] \"point3 to\" [ 0 1 0 ]",
                "'spot'",
            ),
            (
                "Scale 1e300 1e300 1e300 LightSource \"dome\" \"vector3 up\" [ 1e300 0 0 ]",
                "'dome': \"up\"",
            ),
            ("Scale 0 0 0 LightSource \"distant\"", "'distant'"),
            ("Rotate 30 1e300 1e300 0", "Rotate about a zero-length axis"),
        ] {
            let scene = format!("WorldBegin\n\n{text}\n");
            let err = crate::load_str(&scene, "lights.pbrt".as_ref(), ".".as_ref())
                .err()
                .unwrap_or_else(|| panic!("accepted: {text}"))
                .to_string();
            assert!(
                err.starts_with("lights.pbrt:3:") && err.contains(what),
                "{text}: {err}"
            );
        }
        // A direction that is fine stays fine.
        load("WorldBegin\nLightSource \"dome\" \"vector3 up\" [ 0 1 0 ]");
    }
}
