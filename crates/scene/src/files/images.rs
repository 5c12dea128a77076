//! Images a scene refers to: EXR environment maps for the "infinite" light.

use crate::description::ImageRgb;
use crate::error::{Loc, Result, SceneError};
use std::path::Path;

/// Reads an EXR environment map as linear RGB.
pub fn read_environment(path: &Path, loc: &Loc) -> Result<ImageRgb> {
    kiln_image::read_exr_rgb(path)
        .map_err(|e| SceneError::at(loc, format!("environment map '{}': {e}", path.display())))
}
