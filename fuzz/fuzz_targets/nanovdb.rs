//! A NanoVDB file: its grids found, read and looked up densely over their active boxes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    use kiln_scene::files::nanovdb;
    let Ok(names) = nanovdb::grid_names(data) else {
        return;
    };
    for name in names.iter().take(4) {
        if let Ok(Some(g)) = nanovdb::read_grid(data, name) {
            let (lo, hi) = g.index_bbox;
            let dims = [0, 1, 2].map(|a| (hi[a] as i64 - lo[a] as i64 + 1).clamp(1, 64) as usize);
            let _ = g.dense(lo, dims);
        }
    }
});
