//! The rendering options that come before WorldBegin: camera, film, sampler, pixel
//! filter and integrator; also Option, ColorSpace and Accelerator, which Kiln checks or
//! ignores with a warning, and WorldBegin/WorldEnd themselves.

use super::Parser;
use super::cursor::Cursor;
use crate::camera_sensor::{CameraResponse, camera_response};
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files::sensor_curves::{SENSOR_DATA_ENV, find_sensor, read_sensor_curves};
use crate::files::training_chart::{TRAINING_CHART_FILE, read_training_chart};
use crate::lexer::TokenKind;
use crate::params::ParamSet;
use glam::DMat4;

impl Parser {
    /// pbrt-v4's `Option "name" value`: an untyped name and one value.
    pub(super) fn option(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("Option", "option name")?;
        let value = match c.peek() {
            Some(t) => {
                c.pos += 1;
                match &t.kind {
                    TokenKind::Word(w) | TokenKind::Str(w) | TokenKind::Number(w) => w.clone(),
                    TokenKind::OpenBracket | TokenKind::CloseBracket => {
                        return Err(SceneError::at(
                            loc,
                            format!("Option \"{name}\" takes one value, not a list"),
                        ));
                    }
                }
            }
            None => {
                return Err(SceneError::at(
                    loc,
                    format!("Option \"{name}\" needs a value"),
                ));
            }
        };
        let truthy = match value.as_str() {
            "true" => Some(true),
            "false" => Some(false),
            _ => None,
        };
        match name.to_ascii_lowercase().as_str() {
            "seed" => {
                let seed = value.parse::<i64>().map_err(|_| {
                    SceneError::at(
                        loc,
                        format!("Option \"seed\" needs an integer, got '{value}'"),
                    )
                })?;
                self.option_seed = Some(seed as u32);
            }
            // Options that only change how pbrt-v4 runs or reports, never the image.
            "rendercoordsys"
            | "pixelstats"
            | "wavefront"
            | "msereferenceimage"
            | "msereferenceout"
            | "disablewavelengthjitter" => self.warn(
                loc,
                format!("Option \"{name}\" does not change Kiln's image; ignored"),
            ),
            "kiln.spectral" => match truthy {
                Some(spectral) => self.option_spectral = spectral,
                None => {
                    return Err(SceneError::at(
                        loc,
                        format!("Option \"kiln.spectral\" needs true or false, got '{value}'"),
                    ));
                }
            },
            "disablepixeljitter" | "disabletexturefiltering" | "forcediffuse" => match truthy {
                Some(false) => {}
                Some(true) => {
                    return Err(SceneError::at(
                        loc,
                        format!(
                            "Option \"{name}\" true changes the image in pbrt-v4 and is not supported by Kiln"
                        ),
                    ));
                }
                None => {
                    return Err(SceneError::at(
                        loc,
                        format!("Option \"{name}\" needs true or false, got '{value}'"),
                    ));
                }
            },
            "displacementedgescale" => {
                if value.parse::<f64>().ok() != Some(1.0) {
                    return Err(SceneError::at(
                        loc,
                        format!(
                            "Option \"displacementedgescale\" {value}: scales pbrt-v4's displacement refinement; Kiln supports only 1"
                        ),
                    ));
                }
            }
            _ => {
                return Err(SceneError::at(
                    loc,
                    format!("Option \"{name}\": pbrt-v4 knows no such option"),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn color_space(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let name = c.string("ColorSpace", "colour space name")?;
        match crate::colorspace::ColorSpace::by_name(&name) {
            Some(cs) => {
                self.gs.color_space = cs;
                Ok(())
            }
            None => Err(SceneError::at(
                loc,
                format!(
                    "ColorSpace '{name}' is unknown (pbrt-v4 knows {})",
                    crate::colorspace::ColorSpace::names().join(", ")
                ),
            )),
        }
    }

    pub(super) fn accelerator(&mut self, c: &mut Cursor, loc: &Loc) -> Result<()> {
        let _ty = c.string("Accelerator", "type")?;
        let _params = c.params()?;
        self.warn(
            loc,
            "Accelerator: Kiln always builds its own BVH; ignored with its parameters",
        );
        Ok(())
    }

    pub(super) fn world_begin(&mut self, loc: &Loc) -> Result<()> {
        if self.in_world {
            return Err(SceneError::at(loc, "WorldBegin appears twice"));
        }
        self.in_world = true;
        self.named_coordinate_systems
            .insert("world".into(), (DMat4::IDENTITY, DMat4::IDENTITY));
        self.gs.ctm = DMat4::IDENTITY;
        self.gs.ctm_end = DMat4::IDENTITY;
        Ok(())
    }

    pub(super) fn world_end(&mut self, loc: &Loc) {
        self.warn(
            loc,
            "WorldEnd is pbrt-v3 syntax; pbrt-v4 ends the world at the end of the file",
        );
    }

    pub(super) fn film(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_options(loc, "Film")?;
        let gbuffer = match ty {
            "rgb" => None,
            "gbuffer" => match params.string("coordinatesystem")?.as_deref() {
                None | Some("camera") => Some(GBufferSpace::Camera),
                Some("world") => Some(GBufferSpace::World),
                Some(other) => {
                    return Err(SceneError::at(
                        &params
                            .loc_of("coordinatesystem")
                            .unwrap_or_else(|| loc.clone()),
                        format!(
                            "Film 'gbuffer': unknown coordinate system '{other}' (pbrt-v4 has \"camera\" and \"world\")"
                        ),
                    ));
                }
            },
            // pbrt-v4's spectral film writes radiance in wavelength buckets beside RGB. Kiln
            // renders spectra but its films hold RGB sums only, and an RGB film in their place
            // would be a different file.
            "spectral" => {
                return Err(SceneError::at(
                    loc,
                    "Film 'spectral' (radiance in wavelength buckets) is not written by Kiln, whose films hold RGB (rendered from spectra by default); use Film \"rgb\"",
                ));
            }
            other => {
                return Err(SceneError::at(
                    loc,
                    format!("Film '{other}' is unknown (pbrt-v4 has rgb, gbuffer and spectral)"),
                ));
            }
        };
        // The output's colour space: Kiln writes linear sRGB only.
        if let Some(space) = params.string("colorspace")?
            && space != "srgb"
        {
            return Err(SceneError::at(
                &params.loc_of("colorspace").unwrap_or_else(|| loc.clone()),
                format!(
                    "Film: \"colorspace\" \"{space}\": Kiln writes linear sRGB only (a ColorSpace directive converts scene values; the output stays sRGB)"
                ),
            ));
        }
        let x = params.int("xresolution", 1280)?;
        let y = params.int("yresolution", 720)?;
        if !(1..=65536).contains(&x) || !(1..=65536).contains(&y) {
            return Err(SceneError::at(
                loc,
                format!("Film: resolution {x}x{y} is out of range"),
            ));
        }
        let (x, y) = (x as u32, y as u32);
        let filename = params
            .string("filename")?
            .unwrap_or_else(|| "kiln.exr".into());
        let mut bounds = [0, x, 0, y];
        if let Some(c) = params.floats("cropwindow")? {
            if c.len() != 4
                || c.iter().any(|v| !(0.0..=1.0).contains(v))
                || c[0] >= c[1]
                || c[2] >= c[3]
            {
                return Err(SceneError::at(
                    loc,
                    "Film: \"float cropwindow\" needs [x0 x1 y0 y1] in [0,1] with x0 < x1, y0 < y1",
                ));
            }
            bounds = [
                (x as f64 * c[0]).ceil() as u32,
                (x as f64 * c[1]).ceil() as u32,
                (y as f64 * c[2]).ceil() as u32,
                (y as f64 * c[3]).ceil() as u32,
            ];
        }
        if let Some(b) = params.ints("pixelbounds")? {
            if b.len() != 4
                || b[0] < 0
                || b[2] < 0
                || b[0] >= b[1]
                || b[2] >= b[3]
                || b[1] > x as i64
                || b[3] > y as i64
            {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Film: \"integer pixelbounds\" must be [x0 x1 y0 y1] inside the {x}x{y} frame"
                    ),
                ));
            }
            bounds = [b[0] as u32, b[1] as u32, b[2] as u32, b[3] as u32];
        }
        if bounds[0] >= bounds[1] || bounds[2] >= bounds[3] {
            return Err(SceneError::at(loc, "Film: the crop window covers no pixel"));
        }
        let sensor = self.film_sensor(params, loc)?;
        let diagonal = params.float("diagonal", 35.0)?;
        if !(diagonal.is_finite() && diagonal > 0.0) {
            return Err(SceneError::at(
                &params.loc_of("diagonal").unwrap_or_else(|| loc.clone()),
                format!("Film: \"diagonal\" must be positive (millimetres), got {diagonal}"),
            ));
        }
        self.check_unused(params, "Film", &["savefp16"])?;
        self.film = Some(FilmDesc {
            xresolution: x,
            yresolution: y,
            filename,
            pixel_bounds: bounds,
            sensor,
            diagonal: diagonal / 1000.0,
            gbuffer,
            loc: loc.clone(),
        });
        Ok(())
    }

    /// The film's pixel sensor: pbrt-v4's "sensor" (the CIE 1931 observer, or a camera whose
    /// response [`SENSOR_DATA_ENV`] holds), "iso", "whitebalance" and "maxcomponentvalue".
    fn film_sensor(&self, params: &ParamSet, loc: &Loc) -> Result<SensorDesc> {
        let at = |name: &str| params.loc_of(name).unwrap_or_else(|| loc.clone());
        if params.loc_of("exposuretime").is_some() {
            return Err(SceneError::at(
                &at("exposuretime"),
                "Film: \"exposuretime\" is not a pbrt-v4 Film parameter: the exposure is the camera's shutter interval (\"shutteropen\", \"shutterclose\")",
            ));
        }
        let sensor = params.string("sensor")?.unwrap_or_else(|| "cie1931".into());
        let iso = params.float("iso", 100.0)?;
        let mut white_balance = params.float("whitebalance", 0.0)?;
        let max_component = params.float("maxcomponentvalue", f64::INFINITY)?;
        if !(iso.is_finite() && iso > 0.0) {
            return Err(SceneError::at(
                &at("iso"),
                format!("Film: \"iso\" must be positive, got {iso}"),
            ));
        }
        if white_balance != 0.0 && !(1000.0..=100_000.0).contains(&white_balance) {
            return Err(SceneError::at(
                &at("whitebalance"),
                format!(
                    "Film: \"whitebalance\" is a daylight temperature in kelvin (1000 to 100000), or 0 for none; got {white_balance}"
                ),
            ));
        }
        if max_component.is_nan() || max_component <= 0.0 {
            return Err(SceneError::at(
                &at("maxcomponentvalue"),
                format!("Film: \"maxcomponentvalue\" must be positive, got {max_component}"),
            ));
        }
        let camera = if sensor == "cie1931" {
            None
        } else {
            // pbrt-v4 balances a camera for 6500 K daylight unless told otherwise.
            if white_balance == 0.0 {
                white_balance = 6500.0;
            }
            Some(
                camera_of(&sensor, white_balance)
                    .map_err(|e| SceneError::at(&at("sensor"), format!("Film: {e}")))?,
            )
        };
        Ok(SensorDesc {
            iso,
            white_balance,
            max_component,
            camera,
        })
    }

    pub(super) fn sampler(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_options(loc, "Sampler")?;
        let known = [
            "halton",
            "independent",
            "paddedsobol",
            "pmj02bn",
            "sobol",
            "stratified",
            "zsobol",
        ];
        if !known.contains(&ty) {
            return Err(SceneError::at(
                loc,
                format!(
                    "Sampler '{ty}' is unknown (pbrt-v4 has {})",
                    known.join(", ")
                ),
            ));
        }
        let spp = if ty == "stratified" {
            params.int("xsamples", 4)? * params.int("ysamples", 4)?
        } else {
            params.int("pixelsamples", 16)?
        };
        if !(1..=65536).contains(&spp) {
            return Err(SceneError::at(
                loc,
                format!("Sampler: {spp} samples per pixel is out of range (1 to 65536)"),
            ));
        }
        let seed = params.int("seed", 0)?;
        self.sampler_seed_given = params.loc_of("seed").is_some();
        let noise_threshold = match params.float_opt("noisethreshold")? {
            None => None,
            Some(t) if t.is_finite() && t > 0.0 => Some(t as f32),
            Some(t) => {
                return Err(SceneError::at(
                    &params
                        .loc_of("noisethreshold")
                        .unwrap_or_else(|| loc.clone()),
                    format!("Sampler: \"float noisethreshold\" must be above 0, not {t}"),
                ));
            }
        };
        let min_samples = params.int("minsamples", 256)?;
        if !(1..=65536).contains(&min_samples) {
            return Err(SceneError::at(
                &params.loc_of("minsamples").unwrap_or_else(|| loc.clone()),
                format!(
                    "Sampler: \"integer minsamples\" is out of range (1 to 65536): {min_samples}"
                ),
            ));
        }
        self.check_unused(params, "Sampler", &["jitter", "randomization"])?;
        self.sampler = Some(SamplerDesc {
            name: ty.to_string(),
            pixel_samples: spp as u32,
            seed: seed as u32,
            noise_threshold,
            min_samples: min_samples as u32,
            loc: loc.clone(),
        });
        Ok(())
    }

    pub(super) fn filter(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_options(loc, "PixelFilter")?;
        let (kind, default_radius) = match ty {
            "box" => (FilterKind::Box, 0.5),
            "triangle" => (FilterKind::Triangle, 2.0),
            "gaussian" => (
                FilterKind::Gaussian {
                    sigma: params.float("sigma", 0.5)?,
                },
                1.5,
            ),
            "mitchell" => (
                FilterKind::Mitchell {
                    b: params.float("B", 1.0 / 3.0)?,
                    c: params.float("C", 1.0 / 3.0)?,
                },
                2.0,
            ),
            "sinc" => (
                FilterKind::Sinc {
                    tau: params.float("tau", 3.0)?,
                },
                4.0,
            ),
            other => {
                return Err(SceneError::at(
                    loc,
                    format!("PixelFilter '{other}' is unknown"),
                ));
            }
        };
        let radius = [
            params.float("xradius", default_radius)?,
            params.float("yradius", default_radius)?,
        ];
        if radius.iter().any(|&r| !(r > 0.0 && r.is_finite())) {
            return Err(SceneError::at(loc, "PixelFilter: radii must be positive"));
        }
        match kind {
            FilterKind::Sinc { tau } if !(tau > 0.0 && tau.is_finite()) => {
                return Err(SceneError::at(
                    loc,
                    format!("PixelFilter 'sinc': \"tau\" must be positive, got {tau}"),
                ));
            }
            FilterKind::Gaussian { sigma } if !(sigma > 0.0 && sigma.is_finite()) => {
                return Err(SceneError::at(
                    loc,
                    format!("PixelFilter 'gaussian': \"sigma\" must be positive, got {sigma}"),
                ));
            }
            _ => {}
        }
        self.check_unused(params, "PixelFilter", &[])?;
        self.filter = Some(FilterDesc {
            kind,
            radius,
            loc: loc.clone(),
        });
        Ok(())
    }

    pub(super) fn integrator(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_options(loc, "Integrator")?;
        match ty {
            "path" | "volpath" | "photonmap" | "sppm" => {}
            "bdpt" | "mlt" | "lightpath" | "simplepath" | "simplevolpath" | "randomwalk"
            | "ambientocclusion" | "aov" => {
                self.warn(loc, format!("Integrator '{ty}' is not in Kiln; using its path tracer ('path'), which converges to the same image for the features Kiln supports"));
                for p in [
                    "radius",
                    "photonsperiteration",
                    "seed",
                    "bootstrapsamples",
                    "chains",
                    "mutationsperpixel",
                    "largestepprobability",
                    "sigma",
                    "visualizestrategies",
                    "visualizeweights",
                    "maxdistance",
                    "cossample",
                    "iterations",
                ] {
                    params.mark_used(p);
                }
            }
            other => {
                return Err(SceneError::at(
                    loc,
                    format!("Integrator '{other}' is unknown"),
                ));
            }
        }
        let max_depth = params.int("maxdepth", 5)?;
        if !(0..=10_000).contains(&max_depth) {
            return Err(SceneError::at(
                loc,
                format!("Integrator: maxdepth {max_depth} is out of range"),
            ));
        }
        let strategy = match params.string("strategy")?.as_deref() {
            None | Some("mis") => LightStrategy::Mis,
            Some("light") => LightStrategy::LightOnly,
            Some("bsdf") => LightStrategy::BsdfOnly,
            Some(other) => {
                return Err(SceneError::at(
                    loc,
                    format!("Integrator: strategy '{other}' is unknown (mis, light or bsdf)"),
                ));
            }
        };
        let max_radiance = params.float("maxradiance", 0.0)? as f32;
        // pbrt-v4 starts Russian roulette after the first bounce; Kiln waits for five
        // (as Mitsuba does), which measured 15% more efficient on the Cornell box.
        let rr_depth = params.int("rrdepth", 5)?;
        if !(1..=10_000).contains(&rr_depth) {
            return Err(SceneError::at(
                loc,
                format!("Integrator: rrdepth {rr_depth} is out of range"),
            ));
        }
        let walk_depth = params.int("walkdepth", i64::from(DEFAULT_WALK_DEPTH))?;
        if !(1..=1_000_000).contains(&walk_depth) {
            return Err(SceneError::at(
                &params.loc_of("walkdepth").unwrap_or_else(|| loc.clone()),
                format!("Integrator: walkdepth {walk_depth} is out of range (1 to 1000000)"),
            ));
        }
        let light_sampler = match params.string("lightsampler")?.as_deref() {
            None | Some("bvh") => LightSamplerKind::Bvh,
            Some("power") => LightSamplerKind::Power,
            Some("uniform") => LightSamplerKind::Uniform,
            Some("exhaustive") => LightSamplerKind::Exhaustive,
            Some(other) => {
                return Err(SceneError::at(
                    &params.loc_of("lightsampler").unwrap_or_else(|| loc.clone()),
                    format!(
                        "Integrator: lightsampler '{other}' is unknown (bvh, exhaustive, power or uniform)"
                    ),
                ));
            }
        };
        let photons = self.photon_params(ty, params, loc)?;
        let (sppm_photons, sppm_radius) = if ty == "sppm" {
            self.sppm_params(params, loc)?
        } else {
            (None, 1.0)
        };
        let regularize = params.bool("regularize", false)?;
        self.check_unused(params, "Integrator", &[])?;
        self.integrator = Some(IntegratorDesc {
            name: ty.to_string(),
            kind: match ty {
                "path" => IntegratorKind::Path,
                "sppm" => IntegratorKind::Sppm,
                _ => IntegratorKind::VolPath,
            },
            max_depth: max_depth as u32,
            rr_depth: rr_depth as u32,
            rr_depth_given: params.loc_of("rrdepth").is_some(),
            pbrt_estimator: false,
            walk_depth: walk_depth as u32,
            strategy,
            light_sampler,
            regularize,
            max_radiance,
            photons,
            sppm_photons,
            sppm_radius,
            loc: loc.clone(),
        });
        Ok(())
    }

    /// pbrt-v4's SPPM parameters: photons per iteration (-1, the default: one per pixel
    /// rendered) and the initial radius. Its "seed" is read and not used: Kiln's photons
    /// are seeded by the sampler's seed.
    fn sppm_params(&mut self, params: &ParamSet, loc: &Loc) -> Result<(Option<u64>, f32)> {
        let photons = params.int("photonsperiteration", -1)?;
        if !(photons == -1 || (1..=50_000_000).contains(&photons)) {
            return Err(SceneError::at(
                &params
                    .loc_of("photonsperiteration")
                    .unwrap_or_else(|| loc.clone()),
                format!(
                    "Integrator 'sppm': photonsperiteration must be -1 (one per pixel) or 1 to 5*10^7, not {photons}"
                ),
            ));
        }
        let radius = params.float("radius", 1.0)?;
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(SceneError::at(
                &params.loc_of("radius").unwrap_or_else(|| loc.clone()),
                format!("Integrator 'sppm': radius must be a positive distance, not {radius}"),
            ));
        }
        if params.int("seed", 0).is_ok() && params.loc_of("seed").is_some() {
            self.warn(
                loc,
                "Integrator 'sppm': \"seed\" is not used; Kiln seeds photons from the Sampler's seed (or --seed)",
            );
        }
        params.mark_used("seed");
        Ok(((photons > 0).then_some(photons as u64), radius as f32))
    }

    /// Kiln's photon-map parameters; "photonmap" turns both maps on by default (seed 003:
    /// 100,000 volume photons, the 100 nearest gathered).
    fn photon_params(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<PhotonDesc> {
        let on = ty == "photonmap";
        let count = |name: &str, default: i64| -> Result<u64> {
            let n = params.int(name, default)?;
            // Each stored photon takes 64 bytes: 5 * 10^7 of them is at most 3.2 GB.
            if !(0..=50_000_000).contains(&n) {
                return Err(SceneError::at(
                    &params.loc_of(name).unwrap_or_else(|| loc.clone()),
                    format!(
                        "Integrator: {name} must be 0 to 5*10^7 (each stored photon takes 64 bytes), not {n}"
                    ),
                ));
            }
            Ok(n as u64)
        };
        let radius = |name: &str| -> Result<f32> {
            let r = params.float(name, 0.0)?;
            if !(r >= 0.0 && r.is_finite()) {
                return Err(SceneError::at(
                    &params.loc_of(name).unwrap_or_else(|| loc.clone()),
                    format!(
                        "Integrator: {name} must be 0 (automatic) or a positive distance, not {r}"
                    ),
                ));
            }
            Ok(r as f32)
        };
        let nearest = |name: &str, default: i64| -> Result<u32> {
            let k = params.int(name, default)?;
            if !(0..=10_000).contains(&k) {
                return Err(SceneError::at(
                    &params.loc_of(name).unwrap_or_else(|| loc.clone()),
                    format!("Integrator: {name} must be 0 (a fixed radius) to 10000, not {k}"),
                ));
            }
            Ok(k as u32)
        };
        let roulette = match params.string("photonroulette")?.as_deref() {
            None | Some("weight") => true,
            Some("none") => false,
            Some(other) => {
                return Err(SceneError::at(
                    &params
                        .loc_of("photonroulette")
                        .unwrap_or_else(|| loc.clone()),
                    format!("Integrator: photonroulette '{other}' is unknown (weight or none)"),
                ));
            }
        };
        Ok(PhotonDesc {
            caustic_photons: count("causticphotons", if on { 200_000 } else { 0 })?,
            caustic_radius: radius("causticradius")?,
            caustic_nearest: nearest("causticnearest", 0)?,
            volume_photons: count("volumephotons", if on { 100_000 } else { 0 })?,
            volume_radius: radius("volumeradius")?,
            volume_nearest: nearest("volumenearest", if on { 100 } else { 0 })?,
            roulette,
        })
    }
}

/// The response of the camera a film's "sensor" names, read from the folder
/// [`SENSOR_DATA_ENV`] names, white balanced for daylight at `kelvin`, and fitted on the
/// folder's [`TRAINING_CHART_FILE`] where it has one.
fn camera_of(name: &str, kelvin: f64) -> std::result::Result<CameraResponse, String> {
    let Some(dir) = std::env::var_os(SENSOR_DATA_ENV).filter(|d| !d.is_empty()) else {
        return Err(format!(
            "sensor '{name}' is a camera's measured spectral response, which Kiln does not ship: \
             set {SENSOR_DATA_ENV} to a folder of camera response files (PhysLight's data/camera, \
             github.com/wetadigital/physlight, Apache-2.0, has every camera pbrt-v4 names), or \
             use \"cie1931\""
        ));
    };
    let dir = std::path::PathBuf::from(dir);
    let path = find_sensor(&dir, name)?;
    let curves = read_sensor_curves(&path)?;
    let chart_path = dir.join(TRAINING_CHART_FILE);
    let chart = if chart_path.is_file() {
        Some(read_training_chart(&chart_path)?)
    } else {
        None
    };
    camera_response(name, &curves, kelvin, chart.as_ref())
}

#[cfg(test)]
mod tests {
    use crate::description::*;
    use crate::parser::tests::{load, load_err};

    /// ColorSpace converts later rgb values into sRGB until its attribute scope ends; an
    /// unknown space is an error that lists the known ones.
    #[test]
    fn color_space_scopes_rgb_values() {
        let s = load(
            "WorldBegin
             AttributeBegin
               ColorSpace \"rec2020\"
               Material \"diffuse\" \"rgb reflectance\" [ 0 1 0 ]
             AttributeEnd
             Material \"diffuse\" \"rgb reflectance\" [ 0 1 0 ]",
        );
        let green = |i: usize| match &s.materials[i].kind {
            MaterialKind::Diffuse {
                reflectance: crate::textures::RgbValue::Constant(c),
            } => *c,
            other => panic!("{other:?}"),
        };
        let n = s.materials.len();
        assert_eq!(green(n - 1), [0.0, 1.0, 0.0]);
        assert!(
            green(n - 2)[1] > 1.0,
            "Rec. 2020 green is beyond sRGB's: {:?}",
            green(n - 2)
        );
        let err = load_err("ColorSpace \"prophoto\"\nWorldBegin");
        assert!(
            err.contains("prophoto") && err.contains("aces2065-1"),
            "{err}"
        );
    }

    /// A screen window of other than four values is reported and ignored, as pbrt-v4 does.
    #[test]
    fn a_screen_window_of_two_values_is_ignored_with_a_warning() {
        let s =
            load("Camera \"orthographic\" \"float screenwindow\" [ -0.0001 0.0001 ]\nWorldBegin");
        assert_eq!(s.camera.screen_window, None);
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    }

    /// pbrt-v4 takes the screen window from "frameaspectratio" when none is given.
    #[test]
    fn frame_aspect_ratio_sets_the_screen_window() {
        let s = load("Camera \"perspective\" \"float frameaspectratio\" [ 2 ]\nWorldBegin");
        assert_eq!(s.camera.screen_window, Some([-2.0, 2.0, -1.0, 1.0]));
        let s = load("Camera \"orthographic\" \"float frameaspectratio\" [ 0.5 ]\nWorldBegin");
        assert_eq!(s.camera.screen_window, Some([-1.0, 1.0, -2.0, 2.0]));
        let s = load(
            "Camera \"orthographic\" \"float frameaspectratio\" [ 0.5 ] \"float screenwindow\" [ -1 1 -1 1 ]\nWorldBegin",
        );
        assert_eq!(s.camera.screen_window, Some([-1.0, 1.0, -1.0, 1.0]));
    }

    /// pbrt-v4's `Option "name" value`: the seed stands in for a Sampler's missing one;
    /// options that cannot change the image are ignored; those that would are errors.
    #[test]
    fn options_take_pbrt_v4_syntax() {
        let s = load(
            "Option \"seed\" 7\nOption \"disablepixeljitter\" false\nOption \"rendercoordsys\" \"world\"\nWorldBegin",
        );
        assert_eq!(s.sampler.seed, 7);
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        let s = load("Option \"seed\" 7\nSampler \"halton\" \"integer seed\" [ 2 ]\nWorldBegin");
        assert_eq!(s.sampler.seed, 2, "the Sampler's own seed wins");
        let err = load_err("\nOption \"forcediffuse\" true\nWorldBegin");
        assert!(
            err.contains("t.pbrt:2") && err.contains("forcediffuse"),
            "{err}"
        );
        let err = load_err("Option \"nosuchthing\" 1\nWorldBegin");
        assert!(err.contains("no such option"), "{err}");
    }

    #[test]
    fn film_sampler_filter_and_integrator_settings() {
        let s = load(
            "Film \"rgb\" \"integer xresolution\" [ 200 ] \"integer yresolution\" [ 100 ] \"float cropwindow\" [ 0.5 1 0 0.5 ]
             Sampler \"halton\" \"integer pixelsamples\" [ 7 ] \"integer seed\" [ 3 ]
             PixelFilter \"gaussian\" \"float sigma\" [ 0.3 ]
             Integrator \"volpath\" \"integer maxdepth\" [ 9 ]
             WorldBegin",
        );
        assert_eq!(s.film.pixel_bounds, [100, 200, 0, 50]);
        assert_eq!((s.sampler.pixel_samples, s.sampler.seed), (7, 3));
        assert_eq!(s.filter.kind, FilterKind::Gaussian { sigma: 0.3 });
        assert_eq!(s.filter.radius, [1.5, 1.5]);
        assert_eq!(s.integrator.max_depth, 9);
    }

    /// A scene renders spectrally, as in pbrt-v4, unless Kiln's option asks for RGB; the
    /// option takes only true or false.
    #[test]
    fn scenes_are_spectral_unless_the_option_says_rgb() {
        assert!(load("WorldBegin").spectral);
        assert!(!load("Option \"kiln.spectral\" false\nWorldBegin").spectral);
        assert!(load("Option \"kiln.spectral\" true\nWorldBegin").spectral);
        let err = load_err("Option \"kiln.spectral\" \"rgb\"\nWorldBegin");
        assert!(
            err.contains("t.pbrt:1") && err.contains("true or false"),
            "{err}"
        );
    }

    /// A spectral film (wavelength buckets) is not one Kiln writes: an error, as is an unknown film;
    /// a gbuffer film asks for its channels in camera space unless told otherwise.
    #[test]
    fn spectral_and_unknown_films_are_errors() {
        let err = load_err("\nFilm \"spectral\"\nWorldBegin");
        assert!(
            err.contains("t.pbrt:2")
                && err.contains("wavelength buckets")
                && err.contains("Film \"rgb\""),
            "{err}"
        );
        let err = load_err("Film \"hdr\"\nWorldBegin");
        assert!(err.contains("'hdr' is unknown"), "{err}");
        let s = load("Film \"gbuffer\"\nWorldBegin");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.film.gbuffer, Some(GBufferSpace::Camera));
        let s = load("Film \"gbuffer\" \"string coordinatesystem\" \"world\"\nWorldBegin");
        assert_eq!(s.film.gbuffer, Some(GBufferSpace::World));
        let err = load_err("Film \"gbuffer\" \"string coordinatesystem\" \"screen\"\nWorldBegin");
        assert!(err.contains("unknown coordinate system 'screen'"), "{err}");
    }

    /// pbrt-v4's light samplers: "bvh" by default, "power" and "uniform" when named.
    #[test]
    fn light_samplers_by_name() {
        assert_eq!(
            load("WorldBegin").integrator.light_sampler,
            LightSamplerKind::Bvh
        );
        for (name, kind) in [
            ("bvh", LightSamplerKind::Bvh),
            ("power", LightSamplerKind::Power),
            ("uniform", LightSamplerKind::Uniform),
            ("exhaustive", LightSamplerKind::Exhaustive),
        ] {
            let s = load(&format!(
                "Integrator \"path\" \"string lightsampler\" \"{name}\"\nWorldBegin"
            ));
            assert_eq!(s.integrator.light_sampler, kind);
            assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        }
        let err = load_err("\nIntegrator \"path\" \"string lightsampler\" \"nearest\"\nWorldBegin");
        assert!(err.contains("t.pbrt:2") && err.contains("nearest"), "{err}");
    }
}
