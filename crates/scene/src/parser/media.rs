//! Participating media: `MakeNamedMedium` with homogeneous and grid ("uniformgrid", "rgbgrid",
//! "cloud", "nanovdb") media, their grids (inline, Mitsuba `.vol` or NanoVDB files) and phase
//! functions.

use super::Parser;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::params::ParamSet;
use crate::spectrum::SpectrumUse;
use std::sync::Arc;

/// The integral of the CIE 1931 y-bar matching function over 360..830 nm: what pbrt-v4's
/// `SpectrumToPhotometric` gives for an illuminant normalised to luminance 1.
const CIE_Y_INTEGRAL: f32 = 106.856_895;

/// A grid's bounding box as a .vol file gives it: (min corner, max corner).
type GridBox = ([f32; 3], [f32; 3]);

/// A medium's coefficients per unit density (`scale` applied) and its phase function.
pub(super) struct Coefficients {
    pub sigma_a: [f32; 3],
    pub sigma_s: [f32; 3],
    pub phase: PhaseDesc,
}

/// `"homogeneous"`: constant coefficients, and emission Le (times "Lescale").
fn homogeneous_medium(
    params: &ParamSet,
    name: &str,
    loc: &Loc,
    c: Coefficients,
) -> Result<MediumKind> {
    let le_scale = params.float("Lescale", 1.0)? as f32;
    let le = params
        .rgb("Le", SpectrumUse::Illuminant)?
        .unwrap_or([0.0; 3])
        .map(|v| v * le_scale);
    if le.iter().any(|v| *v < 0.0) {
        return Err(SceneError::at(
            loc,
            format!("medium '{name}': Le must not be negative"),
        ));
    }
    Ok(MediumKind::Homogeneous {
        sigma_a: c.sigma_a,
        sigma_s: c.sigma_s,
        le,
        le_spectrum: params.emission_spectrum("Le"),
        phase: c.phase,
    })
}

impl Parser {
    pub(super) fn medium(&mut self, name: String, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.still_at_start(loc, &format!("MakeNamedMedium '{name}'"));
        let params = &self.with_spectrum_files(params)?;
        let ty = params.string("type")?.ok_or_else(|| {
            SceneError::at(
                loc,
                format!("MakeNamedMedium '{name}' has no \"string type\""),
            )
        })?;
        if self.named_media.contains_key(&name) {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}' is defined twice"),
            ));
        }
        let phase = medium_phase(params, &name, loc)?;
        let scale = params.float("scale", 1.0)? as f32;
        // An rgbgrid's coefficients are arrays, read with its grid.
        let constant = |p: &str| -> Result<[f32; 3]> {
            if ty == "rgbgrid" {
                return Ok([1.0; 3]);
            }
            Ok(params
                .rgb(p, SpectrumUse::Unbounded)?
                .unwrap_or([1.0; 3])
                .map(|v| v * scale))
        };
        let sigma_a = constant("sigma_a")?;
        let sigma_s = constant("sigma_s")?;
        if sigma_a.iter().chain(&sigma_s).any(|v| *v < 0.0) {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': sigma_a and sigma_s must not be negative"),
            ));
        }
        if params.loc_of("preset").is_some() {
            return Err(SceneError::at(
                loc,
                "medium \"preset\" (measured scattering data) is not supported yet; give sigma_a and sigma_s",
            ));
        }
        let kind = match ty.as_str() {
            "homogeneous" => homogeneous_medium(
                params,
                &name,
                loc,
                Coefficients {
                    sigma_a,
                    sigma_s,
                    phase,
                },
            )?,
            "uniformgrid" => MediumKind::Grid(Arc::new(self.grid_medium(
                params,
                &name,
                loc,
                Coefficients {
                    sigma_a,
                    sigma_s,
                    phase,
                },
            )?)),
            "rgbgrid" => MediumKind::Grid(Arc::new(
                self.rgb_grid_medium(params, &name, loc, scale, phase)?,
            )),
            "nanovdb" => self.nanovdb_medium(
                params,
                &name,
                loc,
                Coefficients {
                    sigma_a,
                    sigma_s,
                    phase,
                },
            )?,
            "cloud" => self.cloud_medium(
                params,
                &name,
                loc,
                Coefficients {
                    sigma_a,
                    sigma_s,
                    phase,
                },
            )?,
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "medium type '{other}' is not supported yet (Kiln has 'homogeneous', 'uniformgrid', 'rgbgrid', 'cloud' and 'nanovdb'); the image would be wrong without it"
                    ),
                ));
            }
        };
        params.mark_used("type");
        self.check_unused(params, &format!("medium '{name}'"), &[])?;
        let id = MediumId(self.media.len() as u32);
        self.media.push(MediumDesc {
            name: name.clone(),
            kind,
            loc: loc.clone(),
        });
        self.named_media.insert(name, id);
        Ok(())
    }

    /// `"cloud"`: pbrt-v4's procedural cloud (noise-shaped density) over a box.
    fn cloud_medium(
        &mut self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
        c: Coefficients,
    ) -> Result<MediumKind> {
        let box_ = self.medium_box(params, name, loc, ([0.0; 3], [1.0; 3]))?;
        let wispiness = params.float("wispiness", 1.0)? as f32;
        let frequency = params.float("frequency", 5.0)? as f32;
        let density = params.float("density", 1.0)? as f32;
        if ![wispiness, frequency, density]
            .iter()
            .all(|v| v.is_finite())
            || density < 0.0
        {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': density, wispiness and frequency must be finite, density not negative"
                ),
            ));
        }
        Ok(MediumKind::Grid(Arc::new(GridMediumDesc {
            sigma_a: c.sigma_a,
            sigma_s: c.sigma_s,
            phase: c.phase,
            density: GridDensity::Cloud {
                density,
                wispiness,
                frequency,
            },
            emission: GridEmission::None,
            p0: box_.0,
            p1: box_.1,
            medium_to_world: self.gs.ctm,
            lattice: Lattice::Centred,
        })))
    }

    /// A grid given inline ("float <name>", nx*ny*nz values) or from a Mitsuba .vol file
    /// ("string <name>file"); returns it with the .vol file's bounding box.
    fn medium_grid(
        &mut self,
        params: &ParamSet,
        medium: &str,
        name: &str,
        loc: &Loc,
    ) -> Result<Option<(VoxelGrid, Option<GridBox>)>> {
        let file_param = format!("{name}file");
        let inline = params.floats(name)?;
        let file = params.string(&file_param)?;
        match (inline, file) {
            (Some(_), Some(_)) => Err(SceneError::at(
                loc,
                format!("medium '{medium}': give \"{name}\" or \"{file_param}\", not both"),
            )),
            (None, None) => Ok(None),
            (None, Some(f)) => {
                let path = self.resolve_file(&f, loc)?;
                let at = params.loc_of(&file_param).unwrap_or_else(|| loc.clone());
                let vol = files::vol::read_vol(&path, &at)?;
                Ok(Some((vol.grid, Some(vol.bbox))))
            }
            (Some(values), None) => {
                let (nx, ny, nz) = (
                    params.int("nx", 1)?,
                    params.int("ny", 1)?,
                    params.int("nz", 1)?,
                );
                if nx < 1 || ny < 1 || nz < 1 {
                    return Err(SceneError::at(
                        loc,
                        format!("medium '{medium}': nx, ny and nz must be at least 1"),
                    ));
                }
                let want = nx
                    .checked_mul(ny)
                    .and_then(|v| v.checked_mul(nz))
                    .filter(|v| *v <= 1 << 31)
                    .ok_or_else(|| {
                        SceneError::at(
                            loc,
                            format!("medium '{medium}': a {nx}x{ny}x{nz} grid is too large"),
                        )
                    })? as usize;
                if values.len() != want {
                    return Err(SceneError::at(
                        params.loc_of(name).as_ref().unwrap_or(loc),
                        format!(
                            "medium '{medium}': \"{name}\" has {} values; nx*ny*nz = {nx}*{ny}*{nz} = {want}",
                            values.len()
                        ),
                    ));
                }
                if let Some(v) = values.iter().find(|v| !v.is_finite() || **v < 0.0) {
                    return Err(SceneError::at(
                        params.loc_of(name).as_ref().unwrap_or(loc),
                        format!(
                            "medium '{medium}': \"{name}\" value {v} is negative or not finite"
                        ),
                    ));
                }
                Ok(Some((
                    VoxelGrid {
                        nx: nx as usize,
                        ny: ny as usize,
                        nz: nz as usize,
                        values: values.iter().map(|&v| v as f32).collect(),
                    },
                    None,
                )))
            }
        }
    }

    fn grid_medium(
        &mut self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
        c: Coefficients,
    ) -> Result<GridMediumDesc> {
        let Coefficients {
            sigma_a,
            sigma_s,
            phase,
        } = c;
        let Some((density, bbox)) = self.medium_grid(params, name, "density", loc)? else {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': a uniformgrid needs \"float density\" (with nx, ny, nz) or \"string densityfile\" (a Mitsuba .vol file)"
                ),
            ));
        };
        let same_shape = |g: &VoxelGrid| (g.nx, g.ny, g.nz) == (density.nx, density.ny, density.nz);
        let temperature = self.medium_grid(params, name, "temperature", loc)?;
        if let Some((t, _)) = &temperature
            && !same_shape(t)
        {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': the temperature grid is {}x{}x{}, the density grid {}x{}x{}",
                    t.nx, t.ny, t.nz, density.nx, density.ny, density.nz
                ),
            ));
        }
        let le = params.rgb("Le", SpectrumUse::Illuminant)?;
        if le.is_some() && temperature.is_some() {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': give \"Le\" or a temperature grid, not both"),
            ));
        }
        let scale = match params.floats("Lescale")? {
            None => VoxelGrid {
                nx: 1,
                ny: 1,
                nz: 1,
                values: vec![1.0],
            },
            Some(v) if v.len() == 1 => VoxelGrid {
                nx: 1,
                ny: 1,
                nz: 1,
                values: vec![v[0] as f32],
            },
            Some(v) if v.len() == density.values.len() => VoxelGrid {
                values: v.iter().map(|&x| x as f32).collect(),
                ..density.clone()
            },
            Some(v) => {
                return Err(SceneError::at(
                    params.loc_of("Lescale").as_ref().unwrap_or(loc),
                    format!(
                        "medium '{name}': \"Lescale\" has {} values; give 1 or one per density voxel ({})",
                        v.len(),
                        density.values.len()
                    ),
                ));
            }
        };
        if scale.values.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': \"Lescale\" must be finite and not negative"),
            ));
        }
        let emission = match (le, temperature) {
            (Some(le), None) if le.iter().any(|&v| v > 0.0) => {
                if le.iter().any(|v| *v < 0.0) {
                    return Err(SceneError::at(
                        loc,
                        format!("medium '{name}': Le must not be negative"),
                    ));
                }
                GridEmission::Constant {
                    le,
                    le_spectrum: params.emission_spectrum("Le"),
                    scale,
                }
            }
            (_, Some((temperature, _))) => {
                let (offset, t_scale) = temperature_mapping(params)?;
                GridEmission::Temperature {
                    temperature,
                    offset,
                    t_scale,
                    scale: Some(scale),
                    le_scale: 1.0,
                }
            }
            _ => GridEmission::None,
        };
        let (p0, p1) = self.medium_box(params, name, loc, bbox.unwrap_or(([0.0; 3], [1.0; 3])))?;
        for d in ["nx", "ny", "nz"] {
            params.mark_used(d);
        }
        Ok(GridMediumDesc {
            sigma_a,
            sigma_s,
            phase,
            density: GridDensity::Scalar(density),
            emission,
            p0,
            p1,
            medium_to_world: self.gs.ctm,
            lattice: Lattice::Centred,
        })
    }

    /// A grid medium's box `p0`..`p1` (`default` where not given), refused when empty or
    /// when the transform in effect is singular.
    fn medium_box(
        &self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
        default: GridBox,
    ) -> Result<GridBox> {
        let p0 = params
            .point3("p0", default.0.map(f64::from))?
            .map(|v| v as f32);
        let p1 = params
            .point3("p1", default.1.map(f64::from))?
            .map(|v| v as f32);
        if (0..3).any(|a| p1[a].partial_cmp(&p0[a]) != Some(std::cmp::Ordering::Greater)) {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': the box p0 {p0:?} .. p1 {p1:?} is empty"),
            ));
        }
        self.check_medium_transform(name, loc)?;
        Ok((p0, p1))
    }

    pub(super) fn check_medium_transform(&self, name: &str, loc: &Loc) -> Result<()> {
        let det = self.gs.ctm.determinant();
        if !det.is_finite() || det.abs() < 1e-12 {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': the transform in effect where it is defined is singular"),
            ));
        }
        Ok(())
    }

    /// pbrt-v4's "rgbgrid": RGB `sigma_a`, `sigma_s` and `Le` per voxel (nx·ny·nz triples
    /// each), `scale` on the coefficients and `Lescale` on the emission.
    fn rgb_grid_medium(
        &mut self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
        scale: f32,
        phase: PhaseDesc,
    ) -> Result<GridMediumDesc> {
        let (nx, ny, nz) = (
            params.int("nx", 1)?,
            params.int("ny", 1)?,
            params.int("nz", 1)?,
        );
        let n = nx
            .checked_mul(ny)
            .and_then(|v| v.checked_mul(nz))
            .filter(|v| (1..=1 << 28).contains(v) && nx > 0 && ny > 0 && nz > 0)
            .ok_or_else(|| {
                SceneError::at(
                    loc,
                    format!("medium '{name}': a {nx}x{ny}x{nz} grid is empty or too large"),
                )
            })? as usize;
        let grid = |param: &str, usage: SpectrumUse| -> Result<Option<[VoxelGrid; 3]>> {
            let Some(values) = params.rgbs(param, usage)? else {
                return Ok(None);
            };
            if values.len() != n {
                return Err(SceneError::at(
                    params.loc_of(param).as_ref().unwrap_or(loc),
                    format!(
                        "medium '{name}': \"{param}\" has {} RGB values; nx*ny*nz = {nx}*{ny}*{nz} = {n}",
                        values.len()
                    ),
                ));
            }
            let channel = |c: usize| VoxelGrid {
                nx: nx as usize,
                ny: ny as usize,
                nz: nz as usize,
                values: values.iter().map(|v| v[c]).collect(),
            };
            Ok(Some([channel(0), channel(1), channel(2)]))
        };
        let sigma_a = grid("sigma_a", SpectrumUse::Unbounded)?;
        let sigma_s = grid("sigma_s", SpectrumUse::Unbounded)?;
        let le = grid("Le", SpectrumUse::Illuminant)?;
        if sigma_a.is_none() && sigma_s.is_none() {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': an rgbgrid needs \"rgb sigma_a\" and/or \"rgb sigma_s\" (nx*ny*nz values each)"
                ),
            ));
        }
        if le.is_some() && sigma_a.is_none() {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': an rgbgrid with \"Le\" needs \"sigma_a\" (emission is sigma_a times Le)"
                ),
            ));
        }
        if le
            .iter()
            .flatten()
            .any(|g| g.values.iter().any(|v| *v < 0.0))
        {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': Le must not be negative"),
            ));
        }
        let le_scale = params.float("Lescale", 1.0)? as f32;
        if !le_scale.is_finite() || le_scale < 0.0 || !scale.is_finite() || scale < 0.0 {
            return Err(SceneError::at(
                loc,
                format!("medium '{name}': scale and Lescale must be finite and not negative"),
            ));
        }
        let (p0, p1) = self.medium_box(params, name, loc, ([0.0; 3], [1.0; 3]))?;
        Ok(GridMediumDesc {
            sigma_a: [scale; 3],
            sigma_s: [scale; 3],
            phase,
            density: GridDensity::Rgb {
                sigma_a: sigma_a.map(Box::new),
                sigma_s: sigma_s.map(Box::new),
            },
            // pbrt-v4 divides every other emission by its illuminant's photometric
            // integral (so that RGB 1 is luminance 1) but not an rgbgrid's `Le`: there RGB 1
            // is luminance CIE_Y_INTEGRAL. Scenes are written against that, so Kiln keeps it.
            emission: match le {
                Some(le) if le_scale > 0.0 => GridEmission::Rgb {
                    le,
                    scale: le_scale * CIE_Y_INTEGRAL,
                },
                _ => GridEmission::None,
            },
            p0,
            p1,
            medium_to_world: self.gs.ctm,
            lattice: Lattice::Centred,
        })
    }
}

/// How a grid's temperature becomes a blackbody's, as pbrt-v4 reads it for "uniformgrid" and
/// "nanovdb": (T - offset) * scale, the offset given as "temperatureoffset" or, under its
/// older name, "temperaturecutoff".
pub(super) fn temperature_mapping(params: &ParamSet) -> Result<(f32, f32)> {
    let offset = match params.float_opt("temperatureoffset")? {
        Some(v) => v,
        None => params.float("temperaturecutoff", 0.0)?,
    };
    Ok((offset as f32, params.float("temperaturescale", 1.0)? as f32))
}

/// The phase function of a medium: "float g" and Kiln's "string phase" ("hg", the default,
/// or "schlick").
fn medium_phase(params: &ParamSet, name: &str, loc: &Loc) -> Result<PhaseDesc> {
    let g = params.float("g", 0.0)? as f32;
    if g.abs().partial_cmp(&1.0) != Some(std::cmp::Ordering::Less) {
        return Err(SceneError::at(
            loc,
            format!("medium '{name}': g = {g} must be strictly between -1 and 1"),
        ));
    }
    match params.string("phase")?.as_deref() {
        None | Some("hg") | Some("henyeygreenstein") => Ok(PhaseDesc::HenyeyGreenstein { g }),
        Some("schlick") => Ok(PhaseDesc::Schlick { g }),
        Some(other) => Err(SceneError::at(
            params.loc_of("phase").as_ref().unwrap_or(loc),
            format!(
                "medium '{name}': phase function '{other}' is unknown (Kiln has 'hg' and 'schlick')"
            ),
        )),
    }
}
