//! OBJ meshes, read with `tobj` for the "objmesh" shape.

use super::read_bytes;
use crate::error::{Loc, Result, SceneError};
use crate::mesh::TriangleMeshData;
use std::path::Path;

/// Reads every object of an OBJ file into one triangle mesh (materials in the file are ignored:
/// the scene's current material applies, as for every other shape).
pub fn read_obj(path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    parse_obj(&read_bytes(path, loc)?, path, loc)
}

/// [`read_obj`] on the file's bytes; `path` names it in errors.
pub fn parse_obj(bytes: &[u8], path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj_buf(&mut &bytes[..], &options, |_| {
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
