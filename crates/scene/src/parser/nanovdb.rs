//! pbrt-v4's "nanovdb" medium: a float density grid and an optional temperature grid read
//! from a NanoVDB file, looked up trilinearly in the grid's index space over the union of
//! the grids' world boxes, as pbrt-v4's `NanoVDBMedium` does. The grids are copied into
//! dense arrays over that box (with a sample of margin), so lookups cost what a uniform
//! grid's do.

use super::Parser;
use super::media::{Coefficients, temperature_mapping};
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::files::nanovdb::{self, IndexMap, NanoVdbGrid};
use crate::params::ParamSet;
use glam::{DMat3, DMat4, DVec3};
use std::path::PathBuf;
use std::sync::Arc;

/// The file the grids come from, and where the scene names it: what errors about it say.
struct GridFile {
    at: Loc,
    path: PathBuf,
}

impl GridFile {
    fn fail(&self, e: String) -> SceneError {
        SceneError::at(
            &self.at,
            format!("NanoVDB file '{}': {e}", self.path.display()),
        )
    }
}

/// The samples a medium's box needs: the first, and how many along each axis.
struct Window {
    first: [i32; 3],
    dims: [usize; 3],
}

impl Parser {
    pub(super) fn nanovdb_medium(
        &mut self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
        c: Coefficients,
    ) -> Result<MediumKind> {
        let (file, density, temperature) = self.nanovdb_grids(params, name, loc)?;
        let le_scale = params.float("Lescale", 1.0)? as f32;
        let (offset, t_scale) = temperature_mapping(params)?;
        if ![le_scale, offset, t_scale].iter().all(|v| v.is_finite()) || le_scale < 0.0 {
            return Err(SceneError::at(
                loc,
                format!(
                    "medium '{name}': Lescale, temperatureoffset and temperaturescale must be finite, Lescale not negative"
                ),
            ));
        }
        self.check_medium_transform(name, loc)?;
        let Some((p0, p1)) = world_box(&density, temperature.as_ref()) else {
            // No active voxels: pbrt-v4's medium is empty there, and so is this one.
            self.warn(
                loc,
                format!(
                    "medium '{name}': grid '{}' has no active voxels; the medium is empty",
                    density.name
                ),
            );
            return Ok(MediumKind::Homogeneous {
                sigma_a: [0.0; 3],
                sigma_s: [0.0; 3],
                le: [0.0; 3],
                le_spectrum: None,
                phase: c.phase,
            });
        };
        let window = sample_window(&density, p0, p1).map_err(|e| file.fail(e))?;
        let density_grid = self.dense_density(&file, &density, &window, name, loc)?;
        let emission = match &temperature {
            Some(t) if le_scale > 0.0 => {
                let grid = dense(&file, t, &window)?;
                if let Some(v) = grid.values.iter().find(|v| !v.is_finite()) {
                    return Err(file.fail(format!(
                        "grid '{}' holds a value {v} that is not finite",
                        t.name
                    )));
                }
                GridEmission::Temperature {
                    temperature: grid,
                    offset,
                    t_scale,
                    scale: None,
                    le_scale,
                }
            }
            _ => GridEmission::None,
        };
        Ok(MediumKind::Grid(Arc::new(GridMediumDesc {
            sigma_a: c.sigma_a,
            sigma_s: c.sigma_s,
            phase: c.phase,
            density: GridDensity::Scalar(density_grid),
            emission,
            p0,
            p1,
            medium_to_world: self.gs.ctm,
            lattice: Lattice::Affine {
                to_samples: box_to_samples(&density.map, p0, p1, window.first),
            },
        })))
    }

    /// The file's density grid ("gridname", "density" by default) and its temperature grid
    /// ("temperaturename") if it has one: fog volumes sharing one index-to-world map.
    fn nanovdb_grids(
        &mut self,
        params: &ParamSet,
        name: &str,
        loc: &Loc,
    ) -> Result<(GridFile, NanoVdbGrid, Option<NanoVdbGrid>)> {
        let given = params.string("filename")?.ok_or_else(|| {
            SceneError::at(
                loc,
                format!("medium '{name}': a nanovdb medium needs \"string filename\""),
            )
        })?;
        let at = params.loc_of("filename").unwrap_or_else(|| loc.clone());
        let path = self.resolve_file(&given, &at)?;
        let bytes = files::read_bytes(&path, &at)?;
        let file = GridFile { at, path };
        let fail = |e: String| file.fail(e);
        let density_name = params
            .string("gridname")?
            .unwrap_or_else(|| "density".into());
        let temperature_name = params
            .string("temperaturename")?
            .unwrap_or_else(|| "temperature".into());
        let density = match nanovdb::read_grid(&bytes, &density_name).map_err(fail)? {
            Some(g) => g,
            None => {
                let names = nanovdb::grid_names(&bytes).map_err(fail)?;
                return Err(fail(format!(
                    "it has no grid named '{density_name}' (it has {}); name the density grid with \"string gridname\"",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
        };
        let temperature = nanovdb::read_grid(&bytes, &temperature_name).map_err(fail)?;
        drop(bytes);
        for g in std::iter::once(&density).chain(&temperature) {
            if g.class != nanovdb::CLASS_FOG_VOLUME && g.class != nanovdb::CLASS_UNKNOWN {
                return Err(fail(format!(
                    "grid '{}' is not a fog volume (NanoVDB class {}); a medium's grids hold densities, as pbrt-v4 requires",
                    g.name, g.class
                )));
            }
        }
        if let Some(t) = &temperature
            && t.map != density.map
        {
            return Err(fail(format!(
                "grids '{}' and '{}' have different index-to-world maps; Kiln needs them to share one",
                density.name, t.name
            )));
        }
        Ok((file, density, temperature))
    }

    /// The density grid over the window; a value that is not finite is an error, a
    /// negative one is taken as 0 (with a warning).
    fn dense_density(
        &mut self,
        file: &GridFile,
        density: &NanoVdbGrid,
        window: &Window,
        name: &str,
        loc: &Loc,
    ) -> Result<VoxelGrid> {
        let mut grid = dense(file, density, window)?;
        let mut negative = 0usize;
        for v in grid.values.iter_mut() {
            if !v.is_finite() {
                return Err(file.fail(format!(
                    "grid '{}' holds a value {v} that is not finite",
                    density.name
                )));
            }
            if *v < 0.0 {
                negative += 1;
                *v = 0.0;
            }
        }
        if negative > 0 {
            self.warn(
                loc,
                format!(
                    "medium '{name}': grid '{}' has {negative} negative densities; they are taken as 0",
                    density.name
                ),
            );
        }
        Ok(grid)
    }
}

/// pbrt-v4's bounds: the union of the grids' world boxes, in single precision; None when
/// it is empty (no active voxels).
fn world_box(
    density: &NanoVdbGrid,
    temperature: Option<&NanoVdbGrid>,
) -> Option<([f32; 3], [f32; 3])> {
    let (mut p0, mut p1) = (
        density.world_bbox.0.map(|v| v as f32),
        density.world_bbox.1.map(|v| v as f32),
    );
    if let Some(t) = temperature {
        for a in 0..3 {
            p0[a] = p0[a].min(t.world_bbox.0[a] as f32);
            p1[a] = p1[a].max(t.world_bbox.1[a] as f32);
        }
    }
    let empty = (0..3).any(|a| p1[a].partial_cmp(&p0[a]) != Some(std::cmp::Ordering::Greater));
    (!empty).then_some((p0, p1))
}

/// The samples whose trilinear footprint reaches into the box, with one of margin.
fn sample_window(
    density: &NanoVdbGrid,
    p0: [f32; 3],
    p1: [f32; 3],
) -> std::result::Result<Window, String> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for c in 0..8 {
        let corner = [0, 1, 2].map(|a| if c >> a & 1 == 1 { p1[a] } else { p0[a] });
        let i = density.map.world_to_index(corner);
        for a in 0..3 {
            lo[a] = lo[a].min(i[a]);
            hi[a] = hi[a].max(i[a]);
        }
    }
    let first = lo.map(|v| v.floor() as i64 - 1);
    let last = hi.map(|v| v.floor() as i64 + 2);
    if first
        .iter()
        .chain(&last)
        .any(|v| *v < i32::MIN as i64 || *v > i32::MAX as i64)
    {
        return Err(format!(
            "grid '{}': its box is out of the index range",
            density.name
        ));
    }
    let first = first.map(|v| v as i32);
    let dims = [0, 1, 2].map(|a| (last[a] - first[a] as i64 + 1) as usize);
    Ok(Window { first, dims })
}

/// A grid's values over the window, as a dense voxel grid.
fn dense(file: &GridFile, g: &NanoVdbGrid, window: &Window) -> Result<VoxelGrid> {
    let values = g
        .dense(window.first, window.dims)
        .map_err(|e| file.fail(e))?;
    Ok(VoxelGrid {
        nx: window.dims[0],
        ny: window.dims[1],
        nz: window.dims[2],
        values,
    })
}

/// Unit box -> medium space -> index space (single-precision inverse map, as pbrt-v4
/// looks up) -> samples.
fn box_to_samples(map: &IndexMap, p0: [f32; 3], p1: [f32; 3], first: [i32; 3]) -> DMat4 {
    let size = [0, 1, 2].map(|a| p1[a] as f64 - p0[a] as f64);
    let inv = DMat3::from_cols_array(&map.inv.map(f64::from)).transpose();
    let box_to_medium = DMat4::from_translation(DVec3::from(p0.map(f64::from)))
        * DMat4::from_scale(DVec3::from(size));
    let medium_to_index =
        DMat4::from_mat3(inv) * DMat4::from_translation(-DVec3::from(map.vec.map(f64::from)));
    let index_to_samples = DMat4::from_translation(-DVec3::from(first.map(f64::from)));
    index_to_samples * medium_to_index * box_to_medium
}
