//! An uploaded tile's EXR, decoded as the coordinator decodes it (at most a 64x64 tile's
//! pixels), and its header read alone, as for an upload under an unknown lease.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = kiln_image::read_exr_windows(data);
    let _ = kiln_image::decode_exr_limited(data, 64 * 64);
});
