//! Files a scene refers to: PLY and OBJ meshes, EXR environment maps.

use crate::description::{ImageRgb, TriangleMeshData, VoxelGrid};
use crate::error::{Loc, Result, SceneError};
use crate::ply;
use std::path::Path;

fn read_bytes(path: &Path, loc: &Loc) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| SceneError::Io {
        loc: loc.clone(),
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a PLY mesh; errors name the directive's location and the file.
pub fn read_ply(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let bytes = read_bytes(path, loc)?;
    let mesh = ply::parse_ply(&bytes)
        .map_err(|e| SceneError::at(loc, format!("PLY file '{}': {e}", path.display())))?;
    Ok(TriangleMeshData {
        positions: mesh.positions,
        normals: mesh.normals,
        uvs: mesh.uvs,
        indices: mesh.indices,
    })
}

/// Reads every object of an OBJ file into one triangle mesh (materials in the file are ignored:
/// the scene's current material applies, as for every other shape).
pub fn read_obj(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let bytes = read_bytes(path, loc)?;
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj_buf(&mut bytes.as_slice(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| SceneError::at(loc, format!("OBJ file '{}': {e}", path.display())))?;
    let mut out = TriangleMeshData::default();
    let all_normals = models.iter().all(|m| !m.mesh.normals.is_empty());
    let all_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = out.positions.len() as u32;
        out.positions
            .extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        if all_normals {
            normals.extend(m.normals.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        }
        if all_uvs {
            uvs.extend(m.texcoords.chunks_exact(2).map(|c| [c[0], c[1]]));
        }
        out.indices.extend(m.indices.iter().map(|i| i + base));
    }
    if out.indices.is_empty() {
        return Err(SceneError::at(
            loc,
            format!("OBJ file '{}' has no faces", path.display()),
        ));
    }
    let n = out.positions.len();
    if out.indices.iter().any(|&i| i as usize >= n) {
        return Err(SceneError::at(
            loc,
            format!(
                "OBJ file '{}' refers to a vertex that does not exist",
                path.display()
            ),
        ));
    }
    if all_normals && normals.len() == n {
        out.normals = Some(normals);
    }
    if all_uvs && uvs.len() == n {
        out.uvs = Some(uvs);
    }
    Ok(out)
}

/// Reads an EXR environment map as linear RGB.
pub fn read_environment(path: &Path, loc: &Loc) -> Result<ImageRgb> {
    kiln_image::read_exr_rgb(path)
        .map_err(|e| SceneError::at(loc, format!("environment map '{}': {e}", path.display())))
}

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
    let mut values = Vec::with_capacity(nx * ny * nz);
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

/// A grid read from a Mitsuba `.vol` file: its values and the bounding box the file gives
/// (min corner, max corner).
#[derive(Debug, Clone, PartialEq)]
pub struct VolFile {
    pub grid: VoxelGrid,
    pub bbox: ([f32; 3], [f32; 3]),
}

/// Reads a single-channel Mitsuba `.vol` grid (as seed 001 does for density and temperature);
/// errors name the directive's location and the file, and say what is wrong with it.
pub fn read_vol(path: &Path, loc: &Loc) -> Result<VolFile> {
    let bytes = read_bytes(path, loc)?;
    parse_vol(&bytes)
        .map_err(|e| SceneError::at(loc, format!("volume file '{}': {e}", path.display())))
}

/// Parses Mitsuba's binary grid format: "VOL", version 3, then little-endian i32 encoding
/// (1: float32, 3: uint8 scaled to [0, 1]), i32 resolution x, y, z, i32 channels, six f32 for
/// the bounding box, and the values with x fastest, then y, then z.
pub fn parse_vol(bytes: &[u8]) -> std::result::Result<VolFile, String> {
    const HEADER: usize = 48;
    if bytes.len() < 4 || &bytes[..3] != b"VOL" {
        return Err("not a Mitsuba .vol file (it does not start with \"VOL\")".into());
    }
    if bytes[3] != 3 {
        return Err(format!(
            "version {} is not supported (Kiln reads version 3)",
            bytes[3]
        ));
    }
    if bytes.len() < HEADER {
        return Err(format!(
            "truncated: {} bytes, shorter than the {HEADER}-byte header",
            bytes.len()
        ));
    }
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let encoding = i32_at(4);
    let value_size = match encoding {
        1 => 4,
        3 => 1,
        2 => {
            return Err("float16 data (encoding 2) is not supported; convert it to float32".into());
        }
        other => {
            return Err(format!(
                "unknown data encoding {other} (1 is float32, 3 is uint8)"
            ));
        }
    };
    let (nx, ny, nz, channels) = (i32_at(8), i32_at(12), i32_at(16), i32_at(20));
    if nx <= 0 || ny <= 0 || nz <= 0 {
        return Err(format!("resolution {nx}x{ny}x{nz} is not positive"));
    }
    if channels != 1 {
        return Err(format!(
            "{channels} channels per voxel; a density or temperature grid has 1"
        ));
    }
    let bbox_min = [f32_at(24), f32_at(28), f32_at(32)];
    let bbox_max = [f32_at(36), f32_at(40), f32_at(44)];
    if bbox_min.iter().chain(&bbox_max).any(|v| !v.is_finite())
        || (0..3).any(|a| bbox_max[a] <= bbox_min[a])
    {
        return Err(format!(
            "bounding box {bbox_min:?}..{bbox_max:?} is empty or not finite"
        ));
    }
    let count = (nx as u64) * (ny as u64) * (nz as u64);
    let expected = HEADER as u64 + count * value_size;
    if (bytes.len() as u64) < expected {
        return Err(format!(
            "truncated: a {nx}x{ny}x{nz} grid needs {expected} bytes, the file has {}",
            bytes.len()
        ));
    }
    if (bytes.len() as u64) > expected {
        return Err(format!(
            "{} bytes after the {nx}x{ny}x{nz} grid's data (the header does not match the file)",
            bytes.len() as u64 - expected
        ));
    }
    let data = &bytes[HEADER..];
    let values: Vec<f32> = match encoding {
        1 => data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect(),
        _ => data.iter().map(|&b| f32::from(b) / 255.0).collect(),
    };
    if let Some(i) = values.iter().position(|v| !v.is_finite() || *v < 0.0) {
        let (x, y, z) = (
            i % nx as usize,
            (i / nx as usize) % ny as usize,
            i / (nx as usize * ny as usize),
        );
        return Err(format!(
            "value {} at voxel ({x}, {y}, {z}) is negative or not finite",
            values[i]
        ));
    }
    Ok(VolFile {
        grid: VoxelGrid {
            nx: nx as usize,
            ny: ny as usize,
            nz: nz as usize,
            values,
        },
        bbox: (bbox_min, bbox_max),
    })
}

/// Encodes a single-channel float32 `.vol` file (for tests and scene generators).
pub fn write_vol(grid: &VoxelGrid, bbox: ([f32; 3], [f32; 3])) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + 4 * grid.values.len());
    out.extend_from_slice(b"VOL\x03");
    for v in [1, grid.nx as i32, grid.ny as i32, grid.nz as i32, 1] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in bbox.0.iter().chain(&bbox.1) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in &grid.values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod vol_tests {
    use super::*;

    fn grid() -> VoxelGrid {
        VoxelGrid {
            nx: 3,
            ny: 2,
            nz: 2,
            values: (0..12).map(|v| v as f32 * 0.5).collect(),
        }
    }

    #[test]
    fn vol_round_trips() {
        let bytes = write_vol(&grid(), ([0.0, -1.0, 0.0], [3.0, 1.0, 2.0]));
        let vol = parse_vol(&bytes).unwrap();
        assert_eq!(vol.grid, grid());
        assert_eq!(vol.bbox, ([0.0, -1.0, 0.0], [3.0, 1.0, 2.0]));
    }

    #[test]
    fn malformed_vol_files_say_why() {
        let good = write_vol(&grid(), ([0.0; 3], [1.0; 3]));
        let check = |bytes: &[u8], want: &str| {
            let e = parse_vol(bytes).unwrap_err();
            assert!(e.contains(want), "{e:?} should mention {want:?}");
        };
        check(
            &good[..good.len() - 3],
            "truncated: a 3x2x2 grid needs 96 bytes, the file has 93",
        );
        check(&good[..20], "truncated");
        check(b"VOX\x03", "does not start with");
        let mut v = good.clone();
        v[3] = 2;
        check(&v, "version 2");
        let mut v = good.clone();
        v[4] = 7;
        check(&v, "unknown data encoding 7");
        let mut v = good.clone();
        v[20] = 3;
        check(&v, "3 channels");
        let mut v = good.clone();
        v.push(0);
        check(&v, "1 bytes after");
        let mut v = good.clone();
        v[48..52].copy_from_slice(&(-1.0f32).to_le_bytes());
        check(&v, "voxel (0, 0, 0) is negative");
    }
}
