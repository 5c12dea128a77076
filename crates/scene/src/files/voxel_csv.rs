//! Voxel grids of emission multipliers in Kiln's CSV layout (for `AreaLightSource "volume"`).

use super::read_bytes;
use crate::error::{Loc, Result, SceneError};
use crate::voxel_grid::VoxelGrid;
use std::path::Path;

/// Reads a voxel grid of emission multipliers from CSV.
///
/// The layout: `#` starts a comment; blank lines are ignored. The first data line holds
/// the dimensions `nx, ny, nz`. Then come `ny * nz` rows of `nx` numbers each: row
/// `z * ny + y` holds the values at x = 0..nx for that y and z (x fastest, then y, then
/// z, each from the low end of the shape's bounding box). Values must be finite and
/// non-negative. Errors name the CSV line.
pub fn read_voxel_grid(path: &Path, loc: &Loc) -> Result<VoxelGrid> {
    let bytes = read_bytes(path, loc)?;
    let text = String::from_utf8(bytes).map_err(|_| {
        SceneError::at(
            loc,
            format!("voxel grid '{}' is not UTF-8 text", path.display()),
        )
    })?;
    parse_voxel_grid(&text).map_err(|(line, message)| {
        SceneError::at(
            loc,
            format!("voxel grid '{}', line {line}: {message}", path.display()),
        )
    })
}

/// Parses the CSV layout of [`read_voxel_grid`]; errors are (line, message).
pub fn parse_voxel_grid(text: &str) -> std::result::Result<VoxelGrid, (usize, String)> {
    let mut rows = text.lines().enumerate().filter_map(|(i, l)| {
        let l = l.split('#').next().unwrap_or("").trim();
        (!l.is_empty()).then_some((i + 1, l))
    });
    let parse_row = |line: usize, row: &str| -> std::result::Result<Vec<f64>, (usize, String)> {
        row.split(',')
            .map(|c| {
                let c = c.trim();
                c.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| (line, format!("'{c}' is not a number")))
            })
            .collect()
    };
    let (line, header) = rows.next().ok_or((
        1,
        "the file is empty; it needs a first line 'nx, ny, nz'".to_string(),
    ))?;
    let dims = parse_row(line, header)?;
    if dims.len() != 3
        || dims
            .iter()
            .any(|d| *d < 1.0 || d.fract() != 0.0 || *d > 4096.0)
    {
        return Err((
            line,
            format!(
                "the first line must be three whole numbers 'nx, ny, nz' from 1 to 4096, found '{header}'"
            ),
        ));
    }
    let (nx, ny, nz) = (dims[0] as usize, dims[1] as usize, dims[2] as usize);
    // Reserve what the header asks for only as far as the text could hold it (a value takes
    // at least two characters): a short file claiming 4096^3 voxels must not allocate them.
    let mut values = Vec::with_capacity((nx * ny * nz).min(text.len() / 2));
    let mut count = 0;
    for (line, row) in rows.by_ref() {
        if count == ny * nz {
            return Err((
                line,
                format!(
                    "more than the {} rows of values that {nx}x{ny}x{nz} needs",
                    ny * nz
                ),
            ));
        }
        let v = parse_row(line, row)?;
        if v.len() != nx {
            return Err((
                line,
                format!("{} values where nx = {nx} are needed", v.len()),
            ));
        }
        if let Some(bad) = v.iter().find(|x| **x < 0.0) {
            return Err((line, format!("negative value {bad}")));
        }
        values.extend(v.into_iter().map(|x| x as f32));
        count += 1;
    }
    if count != ny * nz {
        let last = text.lines().count();
        return Err((
            last,
            format!(
                "{count} rows of values, but {nx}x{ny}x{nz} needs ny*nz = {}",
                ny * nz
            ),
        ));
    }
    Ok(VoxelGrid { nx, ny, nz, values })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A few bytes that claim 4096^3 voxels are an error, not a 275 GB allocation.
    #[test]
    fn a_header_claiming_a_huge_grid_allocates_nothing_for_it() {
        let err = parse_voxel_grid("4096, 4096, 4096\n1, 2\n").unwrap_err();
        assert_eq!(err.0, 2, "{err:?}");
    }

    #[test]
    fn voxel_grid_layout_and_errors() {
        let g = parse_voxel_grid("# 2x1x2\n2, 1, 2\n1, 2\n\n3,4 # z = 1\n").unwrap();
        assert_eq!((g.nx, g.ny, g.nz), (2, 1, 2));
        assert_eq!(g.values, vec![1.0, 2.0, 3.0, 4.0]);
        assert_eq!(
            parse_voxel_grid("2,1,2\n1,2\n3\n").unwrap_err().0,
            3,
            "ragged row"
        );
        assert_eq!(
            parse_voxel_grid("2,1,2\n1,2\n3,x\n").unwrap_err().0,
            3,
            "not a number"
        );
        assert_eq!(
            parse_voxel_grid("2,1,2\n1,2\n").unwrap_err().0,
            2,
            "too few rows"
        );
        assert_eq!(
            parse_voxel_grid("2,1,1\n1,2\n3,4\n").unwrap_err().0,
            3,
            "too many rows"
        );
        assert_eq!(parse_voxel_grid("2,1\n").unwrap_err().0, 1, "bad header");
        assert!(
            parse_voxel_grid("1,1,1\n-1\n")
                .unwrap_err()
                .1
                .contains("negative")
        );
    }
}
