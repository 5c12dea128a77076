//! Readers for the files a scene refers to, one format a file: PLY and OBJ meshes, voxel
//! grids (CSV and Mitsuba `.vol`) and EXR environment maps. Errors name the directive's
//! location and the file.

use crate::error::{Loc, Result, SceneError};
use std::path::Path;

pub mod images;
pub mod obj;
pub mod ply;
pub mod vol;
pub mod voxel_csv;

/// Reads a whole file; an error names the directive's location and the file.
fn read_bytes(path: &Path, loc: &Loc) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| SceneError::Io {
        loc: loc.clone(),
        path: path.to_path_buf(),
        source,
    })
}
