//! A Mitsuba .vol grid.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = kiln_scene::files::vol::parse_vol(data);
});
