//! Triangle meshes in world space: their vertices, one light per emitting face (or a
//! VolumeLight's faces), and pbrt-v4's bilinear patches for their non-planar quads.

use super::{BuildError, Builder, WORLD_LIMIT_TEXT, power_scale, within_world_limit};
use crate::lights::{EmissionImage, Light, TriangleLight, VolumeTriangleLight};
use crate::math::rgb;
use crate::shapes::bilinear::BilinearPatch;
use crate::shapes::{MeshInfo, QuadricShape, SurfaceInfo};
use glam::{DMat4, Vec2, Vec3A};
use kiln_scene::{AreaLightDesc, ShapeDesc, TriangleMeshData};
use std::sync::Arc;

/// A mesh's place among the primitives: its first vertex, and whether it brought normals
/// and uvs, and faces flipped.
#[derive(Clone, Copy)]
struct Placed {
    base: u32,
    has_normals: bool,
    has_uvs: bool,
    flip: bool,
}

impl Placed {
    /// The primitives' indices of face `t`'s vertices.
    fn face(&self, t: &[u32]) -> [u32; 3] {
        [self.base + t[0], self.base + t[1], self.base + t[2]]
    }
}

impl Builder {
    /// A triangle's geometric normal, oriented as hits on it are (see Geometry::triangle_hit).
    fn face_normal(&self, p: [Vec3A; 3], flip: bool, has_normals: bool, v: [u32; 3]) -> Vec3A {
        let mut n = (p[0] - p[2]).cross(p[1] - p[2]).normalize_or_zero();
        if flip {
            n = -n;
        }
        if has_normals {
            let ns: Vec3A = v.iter().map(|&k| self.prims.normals[k as usize]).sum();
            if n.dot(ns) < 0.0 {
                n = -n;
            }
        }
        n
    }

    /// A triangle mesh in world space; one light per face if it emits.
    pub(super) fn add_mesh(
        &mut self,
        shape: &ShapeDesc,
        mesh: &TriangleMeshData,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let placed = self.add_vertices(shape, mesh, to_world)?;
        let mesh_id = self.prims.meshes.len() as u32;
        let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
        let first_triangle = self.prims.triangle_vertices.len() as u32;
        for t in mesh.indices.chunks_exact(3) {
            self.prims.triangle_vertices.push(placed.face(t));
            self.prims.triangle_mesh.push(mesh_id);
        }
        if let Some(AreaLightDesc::Diffuse {
            radiance,
            image,
            two_sided,
            power,
            spectrum,
            ..
        }) = &shape.area_light
        {
            let spectrum = self.light_spectrum(spectrum);
            let image = image
                .as_ref()
                .map(|image| Arc::new(EmissionImage::new(image.clone())));
            let image_luminance = image.as_ref().map_or(1.0, |i| i.mean_luminance());
            for t in mesh.indices.chunks_exact(3) {
                let p = [0, 1, 2].map(|k| self.prims.positions[(placed.base + t[k]) as usize]);
                let area = 0.5 * (p[0] - p[2]).cross(p[1] - p[2]).length();
                let n = self.face_normal(p, placed.flip, placed.has_normals, placed.face(t));
                self.note_area_light(surface.media, &spectrum);
                let uv = if placed.has_uvs {
                    [0, 1, 2].map(|k| self.prims.uvs[(placed.base + t[k]) as usize])
                } else {
                    [Vec2::ZERO, Vec2::X, Vec2::ONE]
                };
                let (alpha, invisible) = self.light_alpha(surface.alpha);
                self.lights.push(Light::Triangle(TriangleLight {
                    p,
                    n,
                    area,
                    radiance: rgb(*radiance)
                        * power_scale(*power, area, *two_sided, image_luminance),
                    two_sided: *two_sided,
                    uv,
                    alpha,
                    invisible,
                    image: image.clone(),
                }));
            }
        }
        if let Some(volume) = surface.volume {
            self.add_volume_faces(mesh, placed, first_triangle, volume);
        }
        self.add_patches(shape, mesh, placed, surface)?;
        self.prims.meshes.push(MeshInfo {
            surface: SurfaceInfo { light, ..surface },
            first_triangle,
            has_normals: placed.has_normals,
            has_uvs: placed.has_uvs,
            flip: placed.flip,
        });
        Ok(())
    }

    /// The mesh's vertices (and normals and uvs, where it has them) in world space.
    fn add_vertices(
        &mut self,
        shape: &ShapeDesc,
        mesh: &TriangleMeshData,
        to_world: DMat4,
    ) -> Result<Placed, BuildError> {
        let swaps_handedness = to_world.determinant() < 0.0;
        let m = to_world.as_mat4();
        let normal_m = to_world.inverse().transpose().as_mat4();
        let base = self.prims.positions.len() as u32;
        self.prims.positions.extend(
            mesh.positions
                .iter()
                .map(|p| Vec3A::from(m.transform_point3(glam::Vec3::from(*p)))),
        );
        let world = &self.prims.positions[base as usize..];
        if let Some(i) = world.iter().position(|p| !within_world_limit(*p)) {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: format!(
                    "vertex {i} of this mesh is at {} in world space (object space {:?}): {}",
                    world[i], mesh.positions[i], WORLD_LIMIT_TEXT
                ),
            });
        }
        if let Some(n) = &mesh.normals {
            // Normals transform by the inverse transpose; ReverseOrientation turns them round,
            // as pbrt-v4's meshes do (the geometric normal then follows them).
            let sign = if shape.reverse_orientation { -1.0 } else { 1.0 };
            self.prims.normals.resize(base as usize, Vec3A::Z);
            self.prims.normals.extend(n.iter().map(|v| {
                Vec3A::from(normal_m.transform_vector3(glam::Vec3::from(*v))).normalize_or_zero()
                    * sign
            }));
        }
        if let Some(uv) = &mesh.uvs {
            self.prims.uvs.resize(base as usize, Vec2::ZERO);
            self.prims.uvs.extend(uv.iter().map(|v| Vec2::from(*v)));
        }
        Ok(Placed {
            base,
            has_normals: mesh.normals.is_some(),
            has_uvs: mesh.uvs.is_some(),
            flip: shape.reverse_orientation ^ swaps_handedness,
        })
    }

    /// A VolumeLight's surface: one light per face, each facing as hits on it do.
    fn add_volume_faces(
        &mut self,
        mesh: &TriangleMeshData,
        placed: Placed,
        first_triangle: u32,
        volume: u32,
    ) {
        for (i, t) in mesh.indices.chunks_exact(3).enumerate() {
            let p = [0, 1, 2].map(|k| self.prims.positions[(placed.base + t[k]) as usize]);
            let tri = first_triangle + i as u32;
            let cross = (p[0] - p[2]).cross(p[1] - p[2]);
            // The same orientation a hit on this face gets.
            let n = self.face_normal(p, placed.flip, placed.has_normals, placed.face(t));
            self.lights.push(Light::VolumeTriangle(VolumeTriangleLight {
                p,
                n,
                area: 0.5 * cross.length(),
                tri,
                volume,
                power: 0.0,
            }));
        }
    }

    /// Non-planar quads: pbrt-v4's bilinear patches, in world space.
    fn add_patches(
        &mut self,
        shape: &ShapeDesc,
        mesh: &TriangleMeshData,
        placed: Placed,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        if !mesh.quads.is_empty() && surface.volume.is_some() {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: "a VolumeLight (AreaLightSource \"volume\") on a mesh with non-planar quads (bilinear patches) is not supported yet".into(),
            });
        }
        for q in mesh.quads.chunks_exact(4) {
            let at = |k: usize| (placed.base + q[k]) as usize;
            let patch = BilinearPatch::new(
                [0, 1, 2, 3].map(|k| self.prims.positions[at(k)]),
                placed
                    .has_normals
                    .then(|| [0, 1, 2, 3].map(|k| self.prims.normals[at(k)])),
                placed
                    .has_uvs
                    .then(|| [0, 1, 2, 3].map(|k| self.prims.uvs[at(k)])),
            );
            let kind = QuadricShape::Patch(Box::new(patch));
            // pbrt-v4's "power" is per patch: each is a shape of its own.
            let area = kind.area();
            let surface = SurfaceInfo {
                light: None,
                ..surface
            };
            self.add_oriented_quadric(shape, kind, DMat4::IDENTITY, surface, placed.flip, area)?;
        }
        Ok(())
    }
}
