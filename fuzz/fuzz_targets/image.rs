//! A texture image: the first byte picks the format (PNG, TGA, JPEG, BMP, HDR, QOI, PFM,
//! EXR), the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

const FORMATS: [&str; 8] = ["png", "tga", "jpg", "bmp", "hdr", "qoi", "pfm", "exr"];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let ext = FORMATS[pick as usize % FORMATS.len()];
    let _ = kiln_scene::files::images::decode_texture_image(
        bytes,
        ext,
        kiln_scene::ColorEncoding::Srgb,
    );
});
