//! The Camera directive: its place (the current transform, inverted; moving or still),
//! projection, screen window, lens and shutter; and pbrt-v4's realistic camera's
//! description: its lens file (interfaces of four numbers, `#`
//! comments), aperture stop and focus, and the aperture's shape (pbrt-v4's built-in
//! diaphragms or an image).

use super::Parser;
use crate::description::{ApertureImage, CameraDesc, Projection, RealisticLens};
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::params::ParamSet;
use std::sync::Arc;

/// The built-in diaphragms are rasterised at this resolution, as pbrt-v4 does.
const APERTURE_RES: usize = 256;

impl Parser {
    pub(super) fn camera(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_options(loc, "Camera")?;
        self.camera_medium = self.medium_id(&self.gs.media.1);
        let camera_from_world = self.gs.ctm;
        let camera_to_world = camera_from_world.inverse();
        // A moving camera (its transform differs at the end of the transform times).
        let camera_to_world_end = self.moving_end().map(|m| m.inverse());
        if !camera_to_world.is_finite() || camera_to_world_end.is_some_and(|m| !m.is_finite()) {
            return Err(SceneError::at(
                loc,
                "Camera: the current transform cannot be inverted",
            ));
        }
        self.named_coordinate_systems.insert(
            "camera".into(),
            (
                camera_to_world,
                camera_to_world_end.unwrap_or(camera_to_world),
            ),
        );
        let projection = self.projection(ty, params, loc)?;
        let screen_window = self.screen_window(params, loc)?;
        let lens_radius = params.float("lensradius", 0.0)?;
        let focal_distance = params.float("focaldistance", 1e6)?;
        if lens_radius < 0.0 || focal_distance <= 0.0 {
            return Err(SceneError::at(
                loc,
                "Camera: lensradius must be >= 0 and focaldistance > 0",
            ));
        }
        let shutter = [
            params.float("shutteropen", 0.0)?,
            params.float("shutterclose", 1.0)?,
        ];
        if !(shutter[0].is_finite() && shutter[1].is_finite() && shutter[1] > shutter[0]) {
            return Err(SceneError::at(
                loc,
                format!(
                    "Camera: the shutter opens at {} and closes at {}, so it never opens (pbrt-v4 refuses this too)",
                    shutter[0], shutter[1]
                ),
            ));
        }
        params.mark_used("frameaspectratio");
        self.check_unused(params, "Camera", &[])?;
        self.camera = Some(CameraDesc {
            projection,
            camera_to_world,
            camera_to_world_end,
            lens_radius,
            focal_distance,
            screen_window,
            shutter,
            loc: loc.clone(),
        });
        Ok(())
    }

    /// The camera's projection by its type: perspective (with its field of view),
    /// orthographic, spherical or realistic (a lens system).
    fn projection(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<Projection> {
        let projection = match ty {
            "perspective" => Projection::Perspective {
                fov_degrees: params.float("fov", 90.0)?,
            },
            "orthographic" => Projection::Orthographic,
            "spherical" => Projection::Spherical {
                equal_area: match params.string("mapping")?.as_deref().unwrap_or("equalarea") {
                    "equalarea" => true,
                    "equirectangular" => false,
                    other => {
                        return Err(SceneError::at(
                            &params.loc_of("mapping").unwrap_or_else(|| loc.clone()),
                            format!(
                                "Camera 'spherical': \"mapping\" must be \"equalarea\" or \"equirectangular\", got \"{other}\""
                            ),
                        ));
                    }
                },
            },
            "realistic" => Projection::Realistic(Arc::new(self.realistic_lens(params, loc)?)),
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Camera '{other}' is not supported (Kiln has perspective, orthographic, spherical and realistic)"
                    ),
                ));
            }
        };
        if let Projection::Perspective { fov_degrees } = projection
            && !(fov_degrees > 0.0 && fov_degrees < 180.0)
        {
            return Err(SceneError::at(
                loc,
                format!("Camera: fov {fov_degrees} is not between 0 and 180 degrees"),
            ));
        }
        Ok(projection)
    }

    /// The screen window: "screenwindow" as given, or derived from "frameaspectratio" as
    /// pbrt-v4 derives it where the window is not given (None: from the film's aspect).
    fn screen_window(&mut self, params: &ParamSet, loc: &Loc) -> Result<Option<[f64; 4]>> {
        Ok(match params.floats("screenwindow")? {
            None => match params.loc_of("frameaspectratio") {
                Some(at) => {
                    let f = params.float("frameaspectratio", 1.0)?;
                    if !(f.is_finite() && f > 0.0) {
                        return Err(SceneError::at(
                            &at,
                            format!("Camera: \"frameaspectratio\" must be positive, got {f}"),
                        ));
                    }
                    Some(if f > 1.0 {
                        [-f, f, -1.0, 1.0]
                    } else {
                        [-1.0, 1.0, -1.0 / f, 1.0 / f]
                    })
                }
                None => None,
            },
            Some(v) if v.len() == 4 => Some([v[0], v[1], v[2], v[3]]),
            // pbrt-v4 reports this and renders with the default window (its Error is not
            // fatal): the image is pbrt-v4's with the default, so Kiln warns and does so too.
            Some(v) => {
                self.warn(
                    &params.loc_of("screenwindow").unwrap_or_else(|| loc.clone()),
                    format!(
                        "Camera: \"float screenwindow\" has {} values, not 4; ignored, as pbrt-v4 ignores it (the default window is used)",
                        v.len()
                    ),
                );
                None
            }
        })
    }

    pub(super) fn realistic_lens(&mut self, params: &ParamSet, loc: &Loc) -> Result<RealisticLens> {
        let name = params.string("lensfile")?.ok_or_else(|| {
            SceneError::at(
                loc,
                "Camera 'realistic' needs a \"string lensfile\" (a lens description)",
            )
        })?;
        let at = params.loc_of("lensfile").unwrap_or_else(|| loc.clone());
        let path = self.resolve_file(&name, &at)?;
        let text = files::read_text(&path, &at)?;
        let mut numbers = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("");
            for word in line.split_whitespace() {
                let v: f64 = word.parse().map_err(|_| {
                    SceneError::at(
                        &at,
                        format!(
                            "lens file '{}', line {}: '{word}' is not a number",
                            path.display(),
                            i + 1
                        ),
                    )
                })?;
                if !v.is_finite() {
                    return Err(SceneError::at(
                        &at,
                        format!(
                            "lens file '{}', line {}: {v} is not finite",
                            path.display(),
                            i + 1
                        ),
                    ));
                }
                numbers.push(v);
            }
        }
        if numbers.is_empty() || numbers.len() % 4 != 0 || numbers.len() > 4 * 1024 {
            return Err(SceneError::at(
                &at,
                format!(
                    "lens file '{}': {} numbers; it needs four per interface (radius, thickness, index of refraction, aperture diameter)",
                    path.display(),
                    numbers.len()
                ),
            ));
        }
        let elements: Vec<[f64; 4]> = numbers
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        if let Some(e) = elements.iter().find(|e| e[3] <= 0.0 || e[2] < 0.0) {
            return Err(SceneError::at(
                &at,
                format!(
                    "lens file '{}': an interface {e:?} has no aperture or a negative index of refraction",
                    path.display()
                ),
            ));
        }
        let aperture_diameter = params.float("aperturediameter", 1.0)?;
        let focus_distance = params.float("focusdistance", 10.0)?;
        if !(aperture_diameter > 0.0 && focus_distance > 0.0 && focus_distance.is_finite()) {
            return Err(SceneError::at(
                loc,
                "Camera 'realistic': \"aperturediameter\" and \"focusdistance\" must be positive",
            ));
        }
        if let Some(stop) = elements.iter().find(|e| e[0] == 0.0)
            && aperture_diameter > stop[3]
        {
            self.warn(
                loc,
                format!(
                    "Camera 'realistic': aperture diameter {aperture_diameter} mm is greater than the stop's {} mm; clamped, as pbrt-v4 does",
                    stop[3]
                ),
            );
        }
        let aperture = match params.string("aperture")?.as_deref() {
            None | Some("") => None,
            Some(shape) => Some(self.aperture_image(shape, params, loc)?),
        };
        Ok(RealisticLens {
            elements,
            aperture_diameter,
            focus_distance,
            aperture,
        })
    }

    /// An aperture shape, normalised so that it passes as much light as a round stop of the
    /// same size, as pbrt-v4 scales it; its rows as pbrt-v4 holds them after flipping the
    /// image (an image file's bottom row first).
    fn aperture_image(
        &mut self,
        shape: &str,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<ApertureImage> {
        let n = APERTURE_RES;
        let centre = |i: usize| -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
        let mut image = match shape {
            "gaussian" => ApertureImage {
                width: n,
                height: n,
                values: (0..n * n)
                    .map(|k| {
                        let (x, y) = (centre(k % n), centre(k / n));
                        (libm::exp(-(x * x + y * y)) - libm::exp(-1.0f64)).max(0.0) as f32
                    })
                    .collect(),
            },
            "square" => ApertureImage {
                width: n,
                height: n,
                values: (0..n * n)
                    .map(|k| {
                        let inside = |i: usize| (n / 4..3 * n / 4).contains(&i);
                        if inside(k % n) && inside(k / n) {
                            4.0
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            },
            "pentagon" => {
                let (c1, c2) = ((5f64.sqrt() - 1.0) / 4.0, (5f64.sqrt() + 1.0) / 4.0);
                let s1 = (10.0 + 2.0 * 5f64.sqrt()).sqrt() / 4.0;
                let s2 = (10.0 - 2.0 * 5f64.sqrt()).sqrt() / 4.0;
                let vert = [(0.0, 1.0), (s1, c1), (s2, -c2), (-s2, -c2), (-s1, c1)]
                    .map(|(x, y)| (0.8 * x, 0.8 * y));
                rasterize(&vert)
            }
            "star" => {
                let mut vert: Vec<(f64, f64)> = (0..10)
                    .map(|i| {
                        let r = if i % 2 == 1 {
                            1.0
                        } else {
                            libm::cos(72f64.to_radians()) / libm::cos(36f64.to_radians())
                        };
                        let a = std::f64::consts::PI * i as f64 / 5.0;
                        (r * libm::cos(a), r * libm::sin(a))
                    })
                    .collect();
                vert.reverse();
                rasterize(&vert)
            }
            file => {
                let at = params.loc_of("aperture").unwrap_or_else(|| loc.clone());
                let path = self.resolve_file(file, &at)?;
                let rgb = files::images::read_environment(&path, &at)?;
                // Flipped so that row 0 is the bottom, the average of R, G and B.
                let (w, h) = (rgb.width as usize, rgb.height as usize);
                let mut values = vec![0.0f32; w * h];
                for y in 0..h {
                    for x in 0..w {
                        let p = rgb.pixels[(h - 1 - y) * w + x];
                        values[y * w + x] = (p[0] + p[1] + p[2]) / 3.0;
                    }
                }
                ApertureImage {
                    width: w,
                    height: h,
                    values,
                }
            }
        };
        let mean = image.values.iter().map(|&v| f64::from(v)).sum::<f64>()
            / image.values.len().max(1) as f64;
        if !(mean > 0.0 && mean.is_finite()) {
            return Err(SceneError::at(
                loc,
                format!("Camera 'realistic': the aperture '{shape}' lets no light through"),
            ));
        }
        let scale = (std::f64::consts::PI / 4.0 / mean) as f32;
        image.values.iter_mut().for_each(|v| *v *= scale);
        Ok(image)
    }
}

/// A polygon (vertices in [-1, 1]^2) as 1 inside, 0 outside, by its winding number at each
/// pixel centre, as pbrt-v4 rasterises its diaphragms (then flips them).
fn rasterize(vert: &[(f64, f64)]) -> ApertureImage {
    let n = APERTURE_RES;
    let mut values = vec![0.0f32; n * n];
    for y in 0..n {
        for x in 0..n {
            let p = (
                -1.0 + 2.0 * (x as f64 + 0.5) / n as f64,
                -1.0 + 2.0 * (y as f64 + 0.5) / n as f64,
            );
            let mut winding = 0;
            for i in 0..vert.len() {
                let (a, b) = (vert[i], vert[(i + 1) % vert.len()]);
                let e = (p.0 - a.0) * (b.1 - a.1) - (p.1 - a.1) * (b.0 - a.0);
                if a.1 <= p.1 {
                    if b.1 > p.1 && e > 0.0 {
                        winding += 1;
                    }
                } else if b.1 <= p.1 && e < 0.0 {
                    winding -= 1;
                }
            }
            // Stored flipped, as pbrt-v4 flips every aperture image after making it.
            values[(n - 1 - y) * n + x] = if winding == 0 { 0.0 } else { 1.0 };
        }
    }
    ApertureImage {
        width: n,
        height: n,
        values,
    }
}
