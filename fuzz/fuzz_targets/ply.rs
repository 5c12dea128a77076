//! A PLY mesh, ASCII or binary.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = kiln_scene::files::ply::parse_ply(data);
});
