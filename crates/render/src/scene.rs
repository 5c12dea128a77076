//! Turns a [`SceneDescription`] into a scene ready to render: world-space
//! geometry in BVHs, materials, lights and the light sampler.

use crate::bsdf::internal_diffuse_reflectance;
use crate::camera::{Camera, Filter};
use crate::geometry::{Geometry, MeshInfo, Sphere, SurfaceInfo};
use crate::lights::{EnvironmentMap, Light};
use crate::materials::Material;
use crate::math::{Frame, rgb};
use crate::sampling::AliasTable;
use glam::{Affine3A, DMat4, Vec2, Vec3A};
use kiln_scene::{
    AreaLightDesc, EnvironmentLayout, LightKind, MaterialKind, SceneDescription, ShapeDesc,
    ShapeKind,
};

/// Why a description cannot be turned into a renderable scene.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("{loc}: {message}")]
    Unsupported {
        loc: kiln_scene::Loc,
        message: String,
    },
}

/// A scene ready to trace.
pub struct Scene {
    pub geometry: Geometry,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Chooses lights in proportion to their power.
    pub light_sampler: AliasTable,
    /// Lights at infinity, whose radiance escaped rays collect.
    pub infinite_lights: Vec<u32>,
    pub camera: Camera,
    pub filter: Filter,
    pub resolution: (u32, u32),
    /// Radius of the scene's bounding sphere.
    pub radius: f32,
}

struct Builder {
    positions: Vec<Vec3A>,
    normals: Vec<Vec3A>,
    uvs: Vec<Vec2>,
    meshes: Vec<MeshInfo>,
    triangle_vertices: Vec<[u32; 3]>,
    triangle_mesh: Vec<u32>,
    spheres: Vec<Sphere>,
    lights: Vec<Light>,
    interface_materials: Vec<bool>,
}

impl Builder {
    fn add_shape(&mut self, shape: &ShapeDesc, to_world: DMat4) -> Result<(), BuildError> {
        let material = shape.material.0;
        let is_interface = self.interface_materials[material as usize];
        // Without media (not supported yet) an interface surface has no effect at all,
        // unless it emits.
        if is_interface && shape.area_light.is_none() {
            return Ok(());
        }
        let swaps_handedness = to_world.determinant() < 0.0;
        match &shape.kind {
            ShapeKind::Mesh(mesh) => {
                let m = to_world.as_mat4();
                let normal_m = to_world.inverse().transpose().as_mat4();
                let base = self.positions.len() as u32;
                self.positions.extend(
                    mesh.positions
                        .iter()
                        .map(|p| Vec3A::from(m.transform_point3(glam::Vec3::from(*p)))),
                );
                let has_normals = mesh.normals.is_some();
                if let Some(n) = &mesh.normals {
                    // Normals transform by the inverse transpose.
                    self.normals.resize(base as usize, Vec3A::Z);
                    self.normals.extend(n.iter().map(|v| {
                        Vec3A::from(normal_m.transform_vector3(glam::Vec3::from(*v)))
                            .normalize_or_zero()
                    }));
                }
                let has_uvs = mesh.uvs.is_some();
                if let Some(uv) = &mesh.uvs {
                    self.uvs.resize(base as usize, Vec2::ZERO);
                    self.uvs.extend(uv.iter().map(|v| Vec2::from(*v)));
                }
                let first_triangle = self.triangle_vertices.len() as u32;
                let mesh_id = self.meshes.len() as u32;
                let flip = shape.reverse_orientation ^ swaps_handedness;
                let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
                for t in mesh.indices.chunks_exact(3) {
                    self.triangle_vertices
                        .push([base + t[0], base + t[1], base + t[2]]);
                    self.triangle_mesh.push(mesh_id);
                }
                if let Some(AreaLightDesc::Diffuse {
                    radiance,
                    two_sided,
                    ..
                }) = &shape.area_light
                {
                    for t in mesh.indices.chunks_exact(3) {
                        let p = [0, 1, 2].map(|k| self.positions[(base + t[k]) as usize]);
                        let cross = (p[0] - p[2]).cross(p[1] - p[2]);
                        let area = 0.5 * cross.length();
                        let mut n = cross.normalize_or_zero();
                        if flip {
                            n = -n;
                        }
                        if has_normals {
                            // Orient by the shading normals, as hits on the mesh do.
                            let ns: Vec3A =
                                t.iter().map(|&k| self.normals[(base + k) as usize]).sum();
                            if n.dot(ns) < 0.0 {
                                n = -n;
                            }
                        }
                        self.lights.push(Light::Triangle {
                            p,
                            n,
                            area,
                            radiance: rgb(*radiance),
                            two_sided: *two_sided,
                        });
                    }
                }
                self.meshes.push(MeshInfo {
                    surface: SurfaceInfo { material, light },
                    first_triangle,
                    has_normals,
                    has_uvs,
                    flip,
                });
            }
            ShapeKind::Sphere { radius } => {
                let center = to_world.transform_point3(glam::DVec3::ZERO);
                let axes = [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z]
                    .map(|a| to_world.transform_vector3(a).length());
                if (axes[0] - axes[1]).abs() > 1e-6 * axes[0]
                    || (axes[0] - axes[2]).abs() > 1e-6 * axes[0]
                {
                    return Err(BuildError::Unsupported {
                        loc: shape.loc.clone(),
                        message:
                            "a sphere under a non-uniform scale (an ellipsoid) is not supported yet"
                                .into(),
                    });
                }
                let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
                let world_radius = (radius * axes[0]) as f32;
                if let Some(AreaLightDesc::Diffuse {
                    radiance,
                    two_sided,
                    ..
                }) = &shape.area_light
                {
                    self.lights.push(Light::Sphere {
                        center: center.as_vec3().into(),
                        radius: world_radius,
                        radiance: rgb(*radiance),
                        two_sided: *two_sided,
                        inward: shape.reverse_orientation,
                    });
                }
                self.spheres.push(Sphere {
                    center: center.as_vec3().into(),
                    radius: world_radius,
                    surface: SurfaceInfo { material, light },
                    flip: shape.reverse_orientation,
                });
            }
        }
        Ok(())
    }
}

impl Scene {
    pub fn build(desc: &SceneDescription) -> Result<Scene, BuildError> {
        let materials: Vec<Material> = desc
            .materials
            .iter()
            .map(|m| Material::from_desc(&m.kind))
            .collect();
        let interface_materials = desc
            .materials
            .iter()
            .map(|m| matches!(m.kind, MaterialKind::Interface))
            .collect();
        let mut b = Builder {
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            meshes: Vec::new(),
            triangle_vertices: Vec::new(),
            triangle_mesh: Vec::new(),
            spheres: Vec::new(),
            lights: Vec::new(),
            interface_materials,
        };
        for shape in &desc.shapes {
            b.add_shape(shape, shape.object_to_world)?;
        }
        // Instances are flattened into world space: simple and as fast to trace as
        // anything for the scene sizes Kiln renders today, at the cost of memory.
        for instance in &desc.instances {
            for shape in &desc.objects[instance.object].shapes {
                b.add_shape(shape, instance.instance_to_world * shape.object_to_world)?;
            }
        }
        let n_positions = b.positions.len();
        if !b.normals.is_empty() {
            b.normals.resize(n_positions, Vec3A::Z);
        }
        if !b.uvs.is_empty() {
            b.uvs.resize(n_positions, Vec2::ZERO);
        }
        let geometry = Geometry::new(
            b.positions,
            b.normals,
            b.uvs,
            b.meshes,
            b.triangle_vertices,
            b.triangle_mesh,
            b.spheres,
        );
        let (lo, hi) = geometry.bounds();
        let radius = ((hi - lo).length() / 2.0).max(1e-3);
        let mut lights = b.lights;
        for l in &desc.lights {
            lights.push(match &l.kind {
                LightKind::Point {
                    position,
                    intensity,
                } => Light::Point {
                    position: position.as_vec3().into(),
                    intensity: rgb(*intensity),
                },
                LightKind::Spot {
                    position,
                    direction,
                    intensity,
                    cos_falloff_start,
                    cos_falloff_end,
                } => Light::Spot {
                    position: position.as_vec3().into(),
                    frame: Frame::from_z(Vec3A::from(direction.as_vec3()).normalize()),
                    intensity: rgb(*intensity),
                    cos_start: *cos_falloff_start as f32,
                    cos_end: *cos_falloff_end as f32,
                },
                LightKind::Distant {
                    direction,
                    radiance,
                } => Light::Distant {
                    direction: Vec3A::from(direction.as_vec3()).normalize(),
                    radiance: rgb(*radiance),
                },
                LightKind::UniformInfinite { radiance } => Light::UniformInfinite {
                    radiance: rgb(*radiance),
                },
                LightKind::ImageInfinite {
                    image,
                    layout,
                    scale,
                    light_to_world,
                } => {
                    let pixels = image.pixels.iter().map(|p| rgb(*p) * *scale).collect();
                    Light::ImageInfinite(Box::new(EnvironmentMap::new(
                        image.width as usize,
                        image.height as usize,
                        pixels,
                        *layout == EnvironmentLayout::EqualArea,
                        Affine3A::from_mat4(light_to_world.as_mat4()),
                    )))
                }
                LightKind::Dome { radiance, up } => Light::Dome {
                    frame: Frame::from_z(Vec3A::from(up.as_vec3()).normalize()),
                    radiance: rgb(*radiance),
                },
            });
        }
        let powers: Vec<f64> = lights
            .iter()
            .map(|l| l.power(radius).max(0.0) as f64)
            .collect();
        let infinite_lights = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        let film = &desc.film;
        Ok(Scene {
            geometry,
            materials,
            light_sampler: AliasTable::new(&powers),
            lights,
            infinite_lights,
            camera: Camera::new(&desc.camera, film.xresolution, film.yresolution),
            filter: Filter::new(&desc.filter),
            resolution: (film.xresolution, film.yresolution),
            radius,
        })
    }
}

/// Precomputes what coated materials need once per material.
pub(crate) fn coat_internal_reflectance(eta: f32) -> f32 {
    internal_diffuse_reflectance(eta)
}
