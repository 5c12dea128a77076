//! Shapes: spheres, disks, cylinders and triangle meshes (inline `trianglemesh` and `bilinearmesh`, or read
//! from PLY and OBJ files), with the graphics state they are made in.

use super::Parser;
use super::curves::curve_from_params;
use crate::description::*;
use crate::error::{Loc, Result, SceneError};
use crate::files;
use crate::files::mesh_cache::MeshFormat;
use crate::params::ParamSet;
use crate::textures::FloatValue;
use std::sync::Arc;

impl Parser {
    pub(super) fn shape(&mut self, ty: &str, params: &ParamSet, loc: &Loc) -> Result<()> {
        self.require_world(loc, "Shape")?;
        let (kind, displacement) = self.shape_kind(ty, params, loc)?;
        let alpha = match self.float_value(params, "alpha", 1.0)? {
            FloatValue::Constant(a) if a >= 1.0 => None,
            a => Some(a),
        };
        let priority = priority(params, loc)?;
        self.check_unused(params, &format!("Shape '{ty}'"), &["emissionfilename"])?;
        if let ShapeKind::Mesh(mesh) = &kind
            && matches!(
                self.materials[self.gs.material.0 as usize].kind,
                MaterialKind::Subsurface { .. }
            )
            && mesh.faces_inward() != self.gs.reverse_orientation
        {
            self.warn(
                loc,
                format!(
                    "{ty}: this mesh faces inward (its faces enclose a negative volume), so its subsurface interior lies outside it and fills the space around it; reverse its winding (or add ReverseOrientation)"
                ),
            );
        }
        let (inside, outside) = (
            self.medium_id(&self.gs.media.0),
            self.medium_id(&self.gs.media.1),
        );
        let shape = ShapeDesc {
            kind,
            object_to_world: self.gs.ctm,
            object_to_world_end: self.moving_end(),
            reverse_orientation: self.gs.reverse_orientation,
            material: self.gs.material,
            area_light: self.gs.area_light.clone(),
            media: (inside != outside).then_some(MediumInterfaceDesc { inside, outside }),
            alpha,
            displacement,
            priority,
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

    /// The shape of type `ty` from its parameters (a plymesh with its displacement).
    fn shape_kind(
        &mut self,
        ty: &str,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<(ShapeKind, Option<MeshDisplacement>)> {
        let kind = match ty {
            "sphere" => sphere_from_params(params, loc)?,
            "disk" => disk_from_params(params, loc)?,
            "cylinder" => cylinder_from_params(params, loc)?,
            "revolution" => ShapeKind::Revolution(Arc::new(revolution_from_params(params, loc)?)),
            "curve" => ShapeKind::Curve(Arc::new(curve_from_params(params, loc)?)),
            "trianglemesh" => ShapeKind::Mesh(Arc::new(mesh_from_params(params, loc)?)),
            "loopsubdiv" => ShapeKind::Mesh(Arc::new(loop_subdiv_from_params(params, loc)?)),
            "bilinearmesh" => ShapeKind::Mesh(Arc::new(bilinear_from_params(params, loc)?)),
            "plymesh" | "objmesh" => return self.mesh_file(ty, params, loc),
            other => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Shape '{other}' is not supported (Kiln has trianglemesh, bilinearmesh, loopsubdiv, plymesh, objmesh, sphere, disk, cylinder, curve, and its own revolution)"
                    ),
                ));
            }
        };
        Ok((kind, None))
    }

    /// `"plymesh"` or `"objmesh"`: a mesh read from "filename"; a plymesh may be displaced.
    fn mesh_file(
        &mut self,
        ty: &str,
        params: &ParamSet,
        loc: &Loc,
    ) -> Result<(ShapeKind, Option<MeshDisplacement>)> {
        let name = params
            .string("filename")?
            .ok_or_else(|| SceneError::at(loc, format!("{ty}: \"string filename\" is required")))?;
        let path = self.resolve_file(&name, loc)?;
        if ty != "plymesh" {
            let mesh = self.read_mesh(MeshFormat::Obj, &path, loc)?;
            return Ok((ShapeKind::Mesh(mesh), None));
        }
        let displacement = self.mesh_displacement(params, loc)?;
        let mesh = self.read_mesh(MeshFormat::Ply, &path, loc)?;
        if displacement.is_some() && mesh.uvs.is_none() {
            return Err(SceneError::at(
                loc,
                format!(
                    "plymesh: displacement needs per-vertex uv coordinates, and '{name}' has none (pbrt-v4 requires them too)"
                ),
            ));
        }
        Ok((ShapeKind::Mesh(mesh), displacement))
    }

    /// The mesh in `path`: from the shared cache if the scene is loaded with one.
    fn read_mesh(
        &self,
        format: MeshFormat,
        path: &std::path::Path,
        loc: &Loc,
    ) -> Result<Arc<crate::mesh::TriangleMeshData>> {
        match &self.meshes {
            Some(cache) => cache.get(format, path, loc),
            None => Ok(Arc::new(match format {
                MeshFormat::Ply => files::ply::read_ply(path, loc)?,
                MeshFormat::Obj => files::obj::read_obj(path, loc)?,
            })),
        }
    }
}

/// `"sphere"`: pbrt-v4 orders "zmin" and "zmax" and clamps them to the sphere.
fn sphere_from_params(params: &ParamSet, loc: &Loc) -> Result<ShapeKind> {
    let radius = params.float("radius", 1.0)?;
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(SceneError::at(loc, "sphere: radius must be positive"));
    }
    let (z0, z1) = (
        params.float("zmin", -radius)?,
        params.float("zmax", radius)?,
    );
    Ok(ShapeKind::Sphere {
        radius,
        z_min: z0.min(z1).clamp(-radius, radius),
        z_max: z0.max(z1).clamp(-radius, radius),
        phi_max: phi_max(params, loc)?,
    })
}

/// `"disk"`: at "height" on z, from "innerradius" to "radius".
fn disk_from_params(params: &ParamSet, loc: &Loc) -> Result<ShapeKind> {
    let radius = params.float("radius", 1.0)?;
    let inner_radius = params.float("innerradius", 0.0)?;
    if !(radius >= 0.0 && inner_radius >= 0.0 && radius.is_finite()) {
        return Err(SceneError::at(
            loc,
            "disk: radius and innerradius must be non-negative",
        ));
    }
    Ok(ShapeKind::Disk {
        height: params.float("height", 0.0)?,
        radius,
        inner_radius,
        phi_max: phi_max(params, loc)?,
    })
}

/// `"cylinder"`: about z from "zmin" to "zmax" (ordered).
fn cylinder_from_params(params: &ParamSet, loc: &Loc) -> Result<ShapeKind> {
    let radius = params.float("radius", 1.0)?;
    if !(radius >= 0.0 && radius.is_finite()) {
        return Err(SceneError::at(loc, "cylinder: radius must be non-negative"));
    }
    let (z0, z1) = (params.float("zmin", -1.0)?, params.float("zmax", 1.0)?);
    Ok(ShapeKind::Cylinder {
        radius,
        z_min: z0.min(z1),
        z_max: z0.max(z1),
        phi_max: phi_max(params, loc)?,
    })
}

/// A nested dielectric's "priority": 0 (not nested) to 1000000.
fn priority(params: &ParamSet, loc: &Loc) -> Result<u32> {
    let priority = params.int("priority", 0)?;
    u32::try_from(priority)
        .ok()
        .filter(|&p| p <= 1_000_000)
        .ok_or_else(|| {
            SceneError::at(
                &params.loc_of("priority").unwrap_or_else(|| loc.clone()),
                format!(
                    "\"priority\" is {priority}; nested dielectric priorities run from 0 (not nested) to 1000000"
                ),
            )
        })
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

/// Kiln's "revolution": `"point2 contour"` (required: two or more points (r, z), r ≥ 0),
/// optional `"vector2 normals"` (one per point), `"float creaseangle"` (degrees, 30 by
/// default) and `"float phimax"`.
fn revolution_from_params(params: &ParamSet, loc: &Loc) -> Result<RevolutionDesc> {
    let at = |name: &str| params.loc_of(name).unwrap_or_else(|| loc.clone());
    let contour = params.point2s("contour")?.ok_or_else(|| {
        SceneError::at(
            loc,
            "revolution: \"point2 contour\" [r z ...] is required (two or more points)",
        )
    })?;
    if contour.len() < 2 {
        return Err(SceneError::at(
            &at("contour"),
            format!(
                "revolution: the contour has {} point(s); it needs two or more",
                contour.len()
            ),
        ));
    }
    if let Some(i) = contour
        .iter()
        .position(|p| !(p[0] >= 0.0 && p[0].is_finite() && p[1].is_finite()))
    {
        return Err(SceneError::at(
            &at("contour"),
            format!(
                "revolution: contour point {i} is ({}, {}); every point needs a finite radius r >= 0 and a finite height z",
                contour[i][0], contour[i][1]
            ),
        ));
    }
    let normals = params.point2s("normals")?;
    if let Some(n) = &normals {
        if n.len() != contour.len() {
            return Err(SceneError::at(
                &at("normals"),
                format!(
                    "revolution: {} normals for {} contour points; give one per point",
                    n.len(),
                    contour.len()
                ),
            ));
        }
        if let Some(i) = n
            .iter()
            .position(|v| !(v[0].is_finite() && v[1].is_finite() && (v[0] != 0.0 || v[1] != 0.0)))
        {
            return Err(SceneError::at(
                &at("normals"),
                format!("revolution: normal {i} must be a finite, non-zero vector"),
            ));
        }
    }
    let crease = params.float("creaseangle", 30.0)?;
    if !(0.0..=180.0).contains(&crease) {
        return Err(SceneError::at(
            &at("creaseangle"),
            format!("revolution: \"creaseangle\" is {crease}; it must be 0 to 180 degrees"),
        ));
    }
    Ok(RevolutionDesc {
        contour,
        normals,
        crease: crease.to_radians(),
        phi_max: phi_max(params, loc)?,
    })
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
    // Validated as a mesh of fours, then planar patches become two triangles.
    let normals = params.point3s("N")?;
    let uvs = params.point2s("uv")?;
    let mesh = validate_mesh(positions, normals, uvs, quads, 4, "bilinearmesh", loc)?;
    let quads = mesh.indices.clone();
    Ok(TriangleMeshData {
        indices: Vec::new(),
        ..mesh
    }
    .with_quads(&quads))
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
    if !indices.len().is_multiple_of(stride) {
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
        quads: Vec::new(),
    })
}
