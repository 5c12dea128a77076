//! Readers for the files a scene refers to, one format a file: PLY and OBJ meshes, voxel
//! grids (CSV, Mitsuba `.vol` and NanoVDB), EXR environment maps, cameras' spectral
//! responses and colour charts' reflectances. Errors name the directive's location and the file.

use crate::error::{Loc, Result, SceneError};
use std::path::Path;

pub mod images;
pub mod measured;
pub mod mesh_cache;
pub mod nanovdb;
pub mod obj;
pub mod ply;
pub mod sensor_curves;
pub mod spectrum_data;
pub mod tensor;
pub mod training_chart;
pub mod vol;
pub mod voxel_csv;

/// The most a gzipped file may decompress to: 1 GiB (a PLY of some 35 million triangles).
/// A few kilobytes of gzip can claim gigabytes; the limit stops reading there.
pub const MAX_DECOMPRESSED_BYTES: u64 = 1 << 30;

/// Reads a whole data file of at most `max` bytes (`what` names its kind in the error, "a
/// camera response file"); errors name the file.
pub fn read_small(path: &Path, max: u64, what: &str) -> std::result::Result<Vec<u8>, String> {
    let size = std::fs::metadata(path)
        .map_err(|e| format!("cannot read '{}': {e}", path.display()))?
        .len();
    if size > max {
        return Err(format!(
            "'{}' is {size} bytes; {what} is at most {max}",
            path.display()
        ));
    }
    std::fs::read(path).map_err(|e| format!("cannot read '{}': {e}", path.display()))
}

/// Reads a whole file, decompressed if its name ends in `.gz` (as pbrt-v4 reads meshes and
/// includes); an error names the directive's location and the file.
pub fn read_bytes(path: &Path, loc: &Loc) -> Result<Vec<u8>> {
    let raw = std::fs::read(path).map_err(|cause| SceneError::Io {
        loc: loc.clone(),
        path: path.to_path_buf(),
        cause,
    })?;
    if path.extension().and_then(|e| e.to_str()) != Some("gz") {
        return Ok(raw);
    }
    use std::io::Read;
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(&raw[..])
        .take(MAX_DECOMPRESSED_BYTES + 1)
        .read_to_end(&mut out)
        .map_err(|e| {
            let why = if e.kind() == std::io::ErrorKind::OutOfMemory {
                format!(
                    "'{}' does not fit in this process's memory once decompressed ({} bytes were)",
                    path.display(),
                    out.len()
                )
            } else {
                format!("'{}' is not a valid gzip file: {e}", path.display())
            };
            SceneError::at(loc, why)
        })?;
    if out.len() as u64 > MAX_DECOMPRESSED_BYTES {
        return Err(SceneError::at(
            loc,
            format!(
                "'{}' decompresses to more than {MAX_DECOMPRESSED_BYTES} bytes",
                path.display()
            ),
        ));
    }
    Ok(out)
}

/// Reads a text file (a scene or an include), gzipped or not.
pub fn read_text(path: &Path, loc: &Loc) -> Result<String> {
    String::from_utf8(read_bytes(path, loc)?).map_err(|e| {
        SceneError::at(
            loc,
            format!(
                "'{}' is not UTF-8 text (byte {} is not)",
                path.display(),
                e.utf8_error().valid_up_to()
            ),
        )
    })
}
