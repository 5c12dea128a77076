//! A voxel grid in CSV (seed 000's VolumeLight grids).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = kiln_scene::files::voxel_csv::parse_voxel_grid(text);
    }
});
