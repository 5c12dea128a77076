//! Files a scene refers to: PLY and OBJ meshes, EXR environment maps.

use crate::description::{ImageRgb, TriangleMeshData};
use crate::error::{Loc, Result, SceneError};
use crate::ply;
use std::path::Path;

fn read_bytes(path: &Path, loc: &Loc) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| SceneError::Io {
        loc: loc.clone(),
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a PLY mesh; errors name the directive's location and the file.
pub fn read_ply(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let bytes = read_bytes(path, loc)?;
    let mesh = ply::parse_ply(&bytes)
        .map_err(|e| SceneError::at(loc, format!("PLY file '{}': {e}", path.display())))?;
    Ok(TriangleMeshData {
        positions: mesh.positions,
        normals: mesh.normals,
        uvs: mesh.uvs,
        indices: mesh.indices,
    })
}

/// Reads every object of an OBJ file into one triangle mesh (materials in the file are ignored:
/// the scene's current material applies, as for every other shape).
pub fn read_obj(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let bytes = read_bytes(path, loc)?;
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj_buf(&mut bytes.as_slice(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| SceneError::at(loc, format!("OBJ file '{}': {e}", path.display())))?;
    let mut out = TriangleMeshData::default();
    let all_normals = models.iter().all(|m| !m.mesh.normals.is_empty());
    let all_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = out.positions.len() as u32;
        out.positions
            .extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        if all_normals {
            normals.extend(m.normals.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        }
        if all_uvs {
            uvs.extend(m.texcoords.chunks_exact(2).map(|c| [c[0], c[1]]));
        }
        out.indices.extend(m.indices.iter().map(|i| i + base));
    }
    if out.indices.is_empty() {
        return Err(SceneError::at(
            loc,
            format!("OBJ file '{}' has no faces", path.display()),
        ));
    }
    let n = out.positions.len();
    if out.indices.iter().any(|&i| i as usize >= n) {
        return Err(SceneError::at(
            loc,
            format!(
                "OBJ file '{}' refers to a vertex that does not exist",
                path.display()
            ),
        ));
    }
    if all_normals && normals.len() == n {
        out.normals = Some(normals);
    }
    if all_uvs && uvs.len() == n {
        out.uvs = Some(uvs);
    }
    Ok(out)
}

/// Reads an EXR environment map as linear RGB.
pub fn read_environment(path: &Path, loc: &Loc) -> Result<ImageRgb> {
    kiln_image::read_exr_rgb(path)
        .map_err(|e| SceneError::at(loc, format!("environment map '{}': {e}", path.display())))
}
