use super::writer::name_hash;
use super::*;

fn sample_grid() -> (Vec<f32>, [i32; 3], [usize; 3]) {
    let (lo, dims) = ([-13, 5, -40], [29usize, 21, 17]);
    let mut v = Vec::new();
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                // A smooth blob, and a constant 8³ block (written as a tile).
                let (gx, gy, gz) = (x as i32 + lo[0], y as i32 + lo[1], z as i32 + lo[2]);
                let in_block =
                    (0..8).contains(&gx) && (8..16).contains(&gy) && (-32..-24).contains(&gz);
                let r2 = ((x as f32 - 10.0).powi(2)
                    + (y as f32 - 9.0).powi(2)
                    + (z as f32 - 8.0).powi(2))
                    / 40.0;
                v.push(if in_block {
                    0.75
                } else if r2 < 1.0 {
                    1.0 - r2
                } else {
                    0.0
                });
            }
        }
    }
    (v, lo, dims)
}

#[test]
fn written_grids_read_back_voxel_for_voxel() {
    let (values, lo, dims) = sample_grid();
    let temperature: Vec<f32> = values.iter().map(|v| v * 2000.0).collect();
    for zip in [false, true] {
        let file = write_nanovdb(
            &[
                GridToWrite {
                    name: "density",
                    class: CLASS_FOG_VOLUME,
                    voxel_size: [0.5, 0.25, 0.125],
                    origin: [1.0, -2.0, 3.0],
                    lo,
                    dims,
                    values: &values,
                },
                GridToWrite {
                    name: "temperature",
                    class: CLASS_FOG_VOLUME,
                    voxel_size: [0.5, 0.25, 0.125],
                    origin: [1.0, -2.0, 3.0],
                    lo,
                    dims,
                    values: &temperature,
                },
            ],
            zip,
        );
        assert_eq!(grid_names(&file).unwrap(), ["density", "temperature"]);
        let d = read_grid(&file, "density").unwrap().unwrap();
        let t = read_grid(&file, "temperature").unwrap().unwrap();
        assert!(read_grid(&file, "velocity").unwrap().is_none());
        assert_eq!(d.class, CLASS_FOG_VOLUME);
        // One sample of margin on every side: zero (background) there.
        let wide_lo = lo.map(|v| v - 1);
        let wide = dims.map(|v| v + 2);
        let dense = d.dense(wide_lo, wide).unwrap();
        let tdense = t.dense(wide_lo, wide).unwrap();
        for z in 0..wide[2] {
            for y in 0..wide[1] {
                for x in 0..wide[0] {
                    let inside = (1..=dims[0]).contains(&x)
                        && (1..=dims[1]).contains(&y)
                        && (1..=dims[2]).contains(&z);
                    let want = if inside {
                        values[((z - 1) * dims[1] + y - 1) * dims[0] + x - 1]
                    } else {
                        0.0
                    };
                    let i = (z * wide[1] + y) * wide[0] + x;
                    assert_eq!(dense[i], want, "voxel {x} {y} {z}");
                    assert_eq!(tdense[i], want * 2000.0);
                    let ijk = [
                        x as i32 + wide_lo[0],
                        y as i32 + wide_lo[1],
                        z as i32 + wide_lo[2],
                    ];
                    assert_eq!(d.value(ijk).unwrap(), want);
                }
            }
        }
        // The active box, and the map: index (0, 0, 0) sits at the origin.
        let active: Vec<usize> = (0..values.len()).filter(|i| values[*i] != 0.0).collect();
        assert!(!active.is_empty());
        assert_eq!(d.map.world_to_index([1.0, -2.0, 3.0]), [0.0, 0.0, 0.0]);
        assert_eq!(d.map.world_to_index([1.5, -1.5, 3.375]), [1.0, 2.0, 3.0]);
        let (bl, bh) = d.index_bbox;
        assert!(bl.iter().zip(&bh).all(|(l, h)| l <= h));
        assert_eq!(d.world_bbox.0[0], 1.0 + 0.5 * bl[0] as f64);
        assert_eq!(d.world_bbox.1[2], 3.0 + 0.125 * (bh[2] as f64 + 1.0));
    }
}

#[test]
fn the_name_hash_is_nanovdbs() {
    // NanoVDB's io::stringHash: h = h * 67 + c + (h >> 56) per byte.
    assert_eq!(name_hash(""), 0);
    assert_eq!(name_hash("a"), 97);
    assert_eq!(name_hash("ab"), 97 * 67 + 98);
}

#[test]
fn corrupt_files_are_errors_not_panics() {
    let (values, lo, dims) = sample_grid();
    let file = write_nanovdb(
        &[GridToWrite {
            name: "density",
            class: CLASS_FOG_VOLUME,
            voxel_size: [1.0; 3],
            origin: [0.0; 3],
            lo,
            dims,
            values: &values,
        }],
        false,
    );
    assert!(read_grid(&[], "density").unwrap_err().contains("empty"));
    assert!(read_grid(b"VOL\x03", "density").is_err());
    // Every truncation, and a byte flipped at a spread of offsets: an error or a grid
    // whose lookups are errors or values, never a panic.
    for cut in (0..file.len()).step_by(97) {
        let _ = read_grid(&file[..cut], "density");
    }
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..400 {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let mut f = file.clone();
        let at = (rng % f.len() as u64) as usize;
        f[at] ^= (rng >> 32) as u8 | 1;
        if let Ok(Some(g)) = read_grid(&f, "density") {
            let _ = g.dense(lo, dims);
        }
    }
    // Another version's layout is refused with the version named.
    let mut f = file.clone();
    f[8..12].copy_from_slice(&((32u32 << 21) | (6 << 10)).to_le_bytes());
    assert!(read_grid(&f, "density").unwrap_err().contains("32.6.0"));
    let mut f = file;
    f[0..8].copy_from_slice(&MAGIC_NEW_FILE.to_le_bytes());
    assert!(read_grid(&f, "density").unwrap_err().contains("NanoVDB2"));
}
