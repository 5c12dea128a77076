//! Images a scene refers to: EXR environment maps for the "infinite" light.

use crate::description::ImageRgb;
use crate::error::{Loc, Result, SceneError};
use std::path::Path;

/// The most pixels an environment map may hold: 16384 x 8192, 1.5 GiB of float RGB. The
/// EXR's header is checked against it before its pixels are read.
pub const MAX_ENVIRONMENT_PIXELS: u64 = 1 << 27;

/// Reads an EXR environment map as linear RGB.
pub fn read_environment(path: &Path, loc: &Loc) -> Result<ImageRgb> {
    let fail =
        |e: String| SceneError::at(loc, format!("environment map '{}': {e}", path.display()));
    let bytes = std::fs::read(path).map_err(|e| fail(e.to_string()))?;
    let image = kiln_image::decode_exr_limited(&bytes, MAX_ENVIRONMENT_PIXELS)
        .map_err(|e| fail(e.to_string()))?;
    Ok(ImageRgb {
        width: image.width,
        height: image.height,
        pixels: image.pixels,
    })
}
