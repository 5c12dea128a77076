//! Mitsuba `.vol` grids (density and temperature of grid media): reading, parsing, and
//! writing for tests and scene generators.

use super::read_bytes;
use crate::error::{Loc, Result, SceneError};
use crate::voxel_grid::VoxelGrid;
use std::path::Path;

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
    // i32 sizes multiply past u64: a header can claim more than any file holds.
    let expected = [ny, nz]
        .iter()
        .try_fold(nx as u64, |n, &d| n.checked_mul(d as u64))
        .and_then(|count| count.checked_mul(value_size))
        .and_then(|bytes| bytes.checked_add(HEADER as u64))
        .ok_or_else(|| format!("a {nx}x{ny}x{nz} grid is larger than any file can hold"))?;
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
mod tests {
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
        // Sizes whose product overflows 64 bits: an error, not a wrapped size check.
        let mut huge = write_vol(&grid(), ([0.0; 3], [1.0; 3]));
        for at in [8, 12, 16] {
            huge[at..at + 4].copy_from_slice(&i32::MAX.to_le_bytes());
        }
        assert!(
            parse_vol(&huge)
                .unwrap_err()
                .contains("larger than any file")
        );
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
