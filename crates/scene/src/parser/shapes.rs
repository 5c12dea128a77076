//! Shapes: spheres, disks, cylinders and triangle meshes (inline `trianglemesh` and `bilinearmesh`, or read
//! from PLY and OBJ files), with the graphics state they are made in.

use super::Parser;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::params::ParamSet;
use crate::textures::FloatValue;
use std::sync::Arc;

impl Parser {
    pub(super) fn shape(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_world(loc, "Shape")?;
        self.require_still(loc, &format!("Shape '{ty}'"))?;
        let mut displacement = None;
        let kind = match ty {
            "sphere" => {
                let radius = params.float("radius", 1.0)?;
                if !(radius > 0.0 && radius.is_finite()) {
                    return Err(SceneError::at(loc, "sphere: radius must be positive"));
                }
                let (z0, z1) = (
                    params.float("zmin", -radius)?,
                    params.float("zmax", radius)?,
                );
                // pbrt-v4 orders the two and clamps them to the sphere.
                ShapeKind::Sphere {
                    radius,
                    z_min: z0.min(z1).clamp(-radius, radius),
                    z_max: z0.max(z1).clamp(-radius, radius),
                    phi_max: phi_max(params, loc)?,
                }
            }
            "disk" => {
                let radius = params.float("radius", 1.0)?;
                let inner_radius = params.float("innerradius", 0.0)?;
                if !(radius >= 0.0 && inner_radius >= 0.0 && radius.is_finite()) {
                    return Err(SceneError::at(
                        loc,
                        "disk: radius and innerradius must be non-negative",
                    ));
                }
                ShapeKind::Disk {
                    height: params.float("height", 0.0)?,
                    radius,
                    inner_radius,
                    phi_max: phi_max(params, loc)?,
                }
            }
            "cylinder" => {
                let radius = params.float("radius", 1.0)?;
                if !(radius >= 0.0 && radius.is_finite()) {
                    return Err(SceneError::at(loc, "cylinder: radius must be non-negative"));
                }
                let (z0, z1) = (params.float("zmin", -1.0)?, params.float("zmax", 1.0)?);
                ShapeKind::Cylinder {
                    radius,
                    z_min: z0.min(z1),
                    z_max: z0.max(z1),
                    phi_max: phi_max(params, loc)?,
                }
            }
            "trianglemesh" => ShapeKind::Mesh(Arc::new(mesh_from_params(params, loc)?)),
            "loopsubdiv" => ShapeKind::Mesh(Arc::new(loop_subdiv_from_params(params, loc)?)),
            "bilinearmesh" => ShapeKind::Mesh(Arc::new(bilinear_from_params(params, loc)?)),
            "plymesh" | "objmesh" => {
                let name = params.string("filename")?.ok_or_else(|| {
                    SceneError::at(loc, format!("{ty}: \"string filename\" is required"))
                })?;
                let path = self.resolve_file(&name, loc)?;
                let mesh = if ty == "plymesh" {
                    displacement = self.mesh_displacement(params, loc)?;
                    let mesh = files::ply::read_ply(&path, loc)?;
                    if displacement.is_some() && mesh.uvs.is_none() {
                        return Err(SceneError::at(
                            loc,
                            format!(
                                "plymesh: displacement needs per-vertex uv coordinates, and '{name}' has none (pbrt-v4 requires them too)"
                            ),
                        ));
                    }
                    mesh
                } else {
                    files::obj::read_obj(&path, loc)?
                };
                ShapeKind::Mesh(Arc::new(mesh))
            }
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Shape '{other}' is not supported (Kiln has trianglemesh, bilinearmesh, loopsubdiv, plymesh, objmesh, sphere, disk, cylinder)"
                    ),
                ));
            }
        };
        let alpha = match self.float_value(params, "alpha", 1.0)? {
            FloatValue::Constant(a) if a >= 1.0 => None,
            a => Some(a),
        };
        self.check_unused(params, &format!("Shape '{ty}'"), &["emissionfilename"])?;
        let (inside, outside) = (
            self.medium_id(&self.gs.media.0),
            self.medium_id(&self.gs.media.1),
        );
        let shape = ShapeDesc {
            kind,
            object_to_world: self.gs.ctm,
            reverse_orientation: self.gs.reverse_orientation,
            material: self.gs.material,
            area_light: self.gs.area_light.clone(),
            media: (inside != outside).then_some(MediumInterfaceDesc { inside, outside }),
            alpha,
            displacement,
            loc: loc.clone(),
        };
        match &mut self.current_object {
            Some(object) => {
                if shape.area_light.is_some() {
                    return Err(SceneError::at(
                        loc,
                        "area lights inside ObjectBegin/ObjectEnd are not supported (as in pbrt-v4)",
                    ));
                }
                object.shapes.push(shape);
            }
            None => self.shapes.push(shape),
        }
        Ok(())
    }
}

impl Parser {
    /// A plymesh's "texture displacement" and "edgelength" (pbrt-v4 displaces by a named
    /// float texture only, and reads "edgelength" whether or not it displaces).
    fn mesh_displacement(&self, params: &ParamSet, loc: &Loc) -> Result<Option<MeshDisplacement>> {
        let edge_length = params.float("edgelength", 1.0)?;
        let at = params.loc_of("displacement");
        let texture = match self.float_value(params, "displacement", 0.0)? {
            t @ FloatValue::Texture(_) => t,
            FloatValue::Constant(_) if at.is_none() => return Ok(None),
            FloatValue::Constant(_) => {
                return Err(SceneError::at(
                    &at.unwrap_or_else(|| loc.clone()),
                    "plymesh: \"displacement\" must name a float texture (\"texture displacement\"), as in pbrt-v4",
                ));
            }
        };
        if !(edge_length.is_finite() && edge_length > 0.0) {
            return Err(SceneError::at(
                &params.loc_of("edgelength").unwrap_or_else(|| loc.clone()),
                format!("plymesh: \"edgelength\" must be a positive length, got {edge_length}"),
            ));
        }
        Ok(Some(MeshDisplacement {
            texture,
            edge_length: edge_length as f32,
        }))
    }
}

/// A quadric's "phimax", in degrees, clamped to [0, 360] as pbrt-v4 does, in radians.
fn phi_max(params: &ParamSet, loc: &Loc) -> Result<f64> {
    let degrees = params.float("phimax", 360.0)?;
    if degrees.is_nan() {
        return Err(SceneError::at(
            &params.loc_of("phimax").unwrap_or_else(|| loc.clone()),
            "\"phimax\" must be a number of degrees",
        ));
    }
    Ok(degrees.clamp(0.0, 360.0).to_radians())
}

/// pbrt-v4's "loopsubdiv": the control mesh ("point3 P", "integer indices") subdivided
/// "levels" times (3 by default) to a triangle mesh with the limit surface's normals.
fn loop_subdiv_from_params(params: &ParamSet, loc: &Loc) -> Result<TriangleMeshData> {
    let levels = params.int("levels", 3)?;
    if !(0..=12).contains(&levels) {
        return Err(SceneError::at(
            &params.loc_of("levels").unwrap_or_else(|| loc.clone()),
            format!("loopsubdiv: \"levels\" must be 0 to 12, got {levels}"),
        ));
    }
    let control = mesh_from_params(params, loc)?;
    crate::loop_subdiv::loop_subdivide(&control.positions, &control.indices, levels as u32)
        .map_err(|e| SceneError::at(loc, format!("loopsubdiv: {e}")))
}

fn mesh_from_params(params: &ParamSet, loc: &Loc) -> Result<TriangleMeshData> {
    let positions = params
        .point3s("P")?
        .ok_or_else(|| SceneError::at(loc, "trianglemesh: \"point3 P\" is required"))?;
    let indices = match params.ints("indices")? {
        Some(i) => i,
        None if positions.len() == 3 => vec![0, 1, 2],
        None => {
            return Err(SceneError::at(
                loc,
                "trianglemesh: \"integer indices\" is required unless P has exactly 3 points",
            ));
        }
    };
    let normals = params.point3s("N")?;
    let uvs = match params.point2s("uv")? {
        Some(uv) => Some(uv),
        None => params.point2s("st")?,
    };
    params.mark_used("faceIndices");
    if params.loc_of("S").is_some() {
        params.mark_used("S");
    }
    validate_mesh(positions, normals, uvs, indices, 3, "trianglemesh", loc)
}

fn bilinear_from_params(params: &ParamSet, loc: &Loc) -> Result<TriangleMeshData> {
    let positions = params
        .point3s("P")?
        .ok_or_else(|| SceneError::at(loc, "bilinearmesh: \"point3 P\" is required"))?;
    let quads = match params.ints("indices")? {
        Some(i) => i,
        None if positions.len() == 4 => vec![0, 1, 2, 3],
        None => {
            return Err(SceneError::at(
                loc,
                "bilinearmesh: \"integer indices\" is required",
            ));
        }
    };
    if quads.len() % 4 != 0 {
        return Err(SceneError::at(
            loc,
            "bilinearmesh: indices must come in fours",
        ));
    }
    // pbrt's bilinear patch has corners p00 p10 p01 p11: split along p00-p11.
    let mut tris = Vec::with_capacity(quads.len() / 4 * 6);
    for q in quads.chunks_exact(4) {
        tris.extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
    }
    let normals = params.point3s("N")?;
    let uvs = params.point2s("uv")?;
    validate_mesh(positions, normals, uvs, tris, 3, "bilinearmesh", loc)
}

fn validate_mesh(
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    indices: Vec<i64>,
    stride: usize,
    what: &str,
    loc: &Loc,
) -> Result<TriangleMeshData> {
    if indices.len() % stride != 0 {
        return Err(SceneError::at(
            loc,
            format!(
                "{what}: {} indices is not a multiple of {stride}",
                indices.len()
            ),
        ));
    }
    let n = positions.len() as i64;
    if let Some(bad) = indices.iter().find(|&&i| i < 0 || i >= n) {
        return Err(SceneError::at(
            loc,
            format!("{what}: index {bad} is out of range (there are {n} points)"),
        ));
    }
    if normals.as_ref().is_some_and(|v| v.len() != positions.len()) {
        return Err(SceneError::at(
            loc,
            format!("{what}: N has a different count than P"),
        ));
    }
    if uvs.as_ref().is_some_and(|v| v.len() != positions.len()) {
        return Err(SceneError::at(
            loc,
            format!("{what}: uv has a different count than P"),
        ));
    }
    Ok(TriangleMeshData {
        positions,
        normals,
        uvs,
        indices: indices.into_iter().map(|i| i as u32).collect(),
    })
}
