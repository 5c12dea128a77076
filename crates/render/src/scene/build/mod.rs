//! Building a [`Scene`] from a description: instances flattened into world space, one
//! light per emitting triangle, VolumeLight interiors, media, the power-proportional light
//! sampler and the VolumeLights' power estimates.

use super::Scene;
use crate::camera::Camera;
use crate::filter::Filter;
use crate::lights::volume::{VOLUME_POWER_SEED, power_estimates};
use crate::lights::{
    EmissionImage, Light, LightSampler, MediumLight, QuadricLight, SphereLight, TriangleLight,
    VolumeInterior, VolumeQuadricLight, VolumeSphereLight, VolumeTriangleLight,
};
use crate::materials::{DielectricMaterial, Material, Model, Perturbation, RoughnessTexture};
use crate::math::rgb;
use crate::media::subsurface::{TexturedInterior, subsurface_medium};
use crate::media::{GridMedium, HomogeneousMedium, Medium, Phase, SampledGrid};
use crate::motion::AnimatedTransform;
use crate::nesting::NestedShape;
use crate::shapes::bilinear::BilinearPatch;
use crate::shapes::curve::{CurvePiece, CurveSegment};
use crate::shapes::cylinder::Cylinder;
use crate::shapes::disk::Disk;
use crate::shapes::mover::{Mover, Outer};
use crate::shapes::sphere::PartialSphere;
use crate::shapes::{
    Geometry, MeshInfo, NO_MEDIUM, Primitives, Quadric, QuadricShape, Sphere, SurfaceInfo,
};
use crate::textures::Textures;
use glam::{Affine3A, DMat4, Vec2, Vec3A};
use kiln_scene::{
    AreaLightDesc, MaterialKind, MediumKind, SceneDescription, ShapeDesc, ShapeKind,
    TriangleMeshData, VolumeLightDesc,
};
use std::sync::Arc;

/// Why a description cannot be turned into a renderable scene.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("{loc}: {message}")]
    Unsupported {
        loc: kiln_scene::Loc,
        message: String,
    },
}

/// The most curve pieces (BVH primitives, about 48 bytes each with their segment's share)
/// a scene may hold: 2^26, some 3 GB.
const CURVE_PIECE_LIMIT: u64 = 1 << 26;

/// The largest world-space coordinate a shape may reach. The BVH builder and intersection
/// tests multiply coordinates (areas, determinants), so a coordinate near f32's range, or
/// beyond it once transformed, would overflow inside them; 10^15 is far beyond any scene.
pub const WORLD_LIMIT: f32 = 1e15;

const WORLD_LIMIT_TEXT: &str =
    "coordinates must be finite and within 1e15 of the origin (Kiln's limit for geometry)";

fn within_world_limit(p: Vec3A) -> bool {
    p.is_finite() && p.abs().max_element() <= WORLD_LIMIT
}

/// What an area light's radiance is multiplied by for pbrt-v4's "power" (lumens per shape:
/// Φ = π · area · sides · radiance, the image's mean luminance standing for radiance).
fn power_scale(power: Option<f32>, area: f32, two_sided: bool, image_luminance: f32) -> f32 {
    match power {
        Some(phi) => {
            let k_e =
                image_luminance * if two_sided { 2.0 } else { 1.0 } * area * std::f32::consts::PI;
            if k_e > 0.0 { phi / k_e } else { 0.0 }
        }
        None => 1.0,
    }
}

/// Whether a surface of revolution encloses a volume: swept all the way round, and its
/// contour either closed or running from the axis back to the axis.
fn revolution_is_closed(r: &kiln_scene::RevolutionDesc) -> bool {
    let (first, last) = (r.contour[0], r.contour[r.contour.len() - 1]);
    r.phi_max >= std::f64::consts::TAU && (first == last || (first[0] == 0.0 && last[0] == 0.0))
}

/// The signed area of a contour in the (r, z) plane, closed along the axis where it is
/// open: positive when it runs counterclockwise (up its outer side), so its normals face out.
fn contour_area(contour: &[[f32; 2]]) -> f64 {
    let mut pts: Vec<[f64; 2]> = contour.iter().map(|p| [p[0] as f64, p[1] as f64]).collect();
    let (first, last) = (pts[0], pts[pts.len() - 1]);
    if first != last {
        pts.push([0.0, last[1]]);
        pts.push([0.0, first[1]]);
    }
    let n = pts.len();
    (0..n)
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// Whether a scene is built with its participating media. pbrt-v4's "path" integrator
/// ignores them (interfaces vanish, media-bounded shapes keep only their materials).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MediaPolicy {
    Render,
    Ignore,
}

/// Where a moving group goes after its own motion.
#[derive(Clone, Copy)]
enum Place {
    /// Its motion is in world space.
    World,
    /// Inside an instance placed by a still transform.
    Still(DMat4),
    /// Inside an instance moving from the first transform to the second.
    Moving(DMat4, DMat4),
}

struct Builder {
    prims: Primitives,
    lights: Vec<Light>,
    materials: Vec<Material>,
    volumes: Vec<VolumeInterior>,
    /// False for Integrator "path", which (as pbrt-v4's) ignores participating media.
    use_media: bool,
    /// The media on either side of each area light's surface (by light index).
    light_media: Vec<Option<[u32; 2]>>,
    textures: Textures,
    nested: Vec<NestedShape>,
    /// For each material, the medium (index into the scene's media) a "subsurface"
    /// material fills its shapes with.
    subsurface_media: Vec<Option<u32>>,
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

    /// Registers a nested dielectric shape (one with a priority); returns its index.
    fn add_nested(
        &mut self,
        shape: &ShapeDesc,
        media: Option<kiln_scene::MediumInterfaceDesc>,
    ) -> Result<Option<u32>, BuildError> {
        if shape.priority == 0 {
            return Ok(None);
        }
        let unsupported = |message: &str| BuildError::Unsupported {
            loc: shape.loc.clone(),
            message: message.to_string(),
        };
        if shape.area_light.is_some() {
            return Err(unsupported(
                "a shape with a \"priority\" (a nested dielectric) cannot also emit",
            ));
        }
        let eta = match &self.materials[shape.material.0 as usize].model {
            Model::Dielectric(d) => d.eta,
            Model::Interface => 1.0,
            _ => {
                return Err(unsupported(
                    "\"priority\" (nested dielectrics) applies to shapes with a \"dielectric\" or \"interface\" material",
                ));
            }
        };
        self.nested.push(NestedShape {
            priority: shape.priority,
            eta,
            medium: media.and_then(|m| m.inside).map(|m| m.0),
        });
        Ok(Some((self.nested.len() - 1) as u32))
    }

    /// Registers a VolumeLight's interior; returns the material its surface uses and its index.
    fn add_volume(
        &mut self,
        shape: &ShapeDesc,
        v: &VolumeLightDesc,
        to_world: DMat4,
    ) -> Result<(u32, Option<u32>), BuildError> {
        let unsupported = |message: String| BuildError::Unsupported {
            loc: shape.loc.clone(),
            message,
        };
        let closed = match shape.kind {
            ShapeKind::Mesh(_) => true,
            ShapeKind::Sphere {
                radius,
                z_min,
                z_max,
                phi_max,
            } => z_min <= -radius && z_max >= radius && phi_max >= std::f64::consts::TAU,
            ShapeKind::Revolution(ref r) => revolution_is_closed(r),
            ShapeKind::Disk { .. } | ShapeKind::Cylinder { .. } | ShapeKind::Curve(_) => false,
        };
        if !closed {
            return Err(unsupported(
                "a VolumeLight (AreaLightSource \"volume\") needs a closed shape with an inside: a mesh or a whole sphere".into(),
            ));
        }
        let material = shape.material.0;
        let eta = match &self.materials[material as usize] {
            Material {
                model: Model::Dielectric(d),
                normal: Perturbation::None,
            } if d.is_smooth() => d.eta,
            Material {
                model: Model::Interface,
                ..
            } => 1.0,
            _ => {
                return Err(unsupported(
                    "a VolumeLight (AreaLightSource \"volume\") needs a smooth \"dielectric\" or an \"interface\" material".into(),
                ));
            }
        };
        // An interface around a VolumeLight is a dielectric of eta 1: rays cross it unbent.
        let material = if eta == 1.0 {
            self.materials
                .push(Material::plain(Model::Dielectric(DielectricMaterial {
                    eta: 1.0,
                    roughness: RoughnessTexture::smooth(),
                })));
            (self.materials.len() - 1) as u32
        } else {
            material
        };
        // The grid spans the shape's object-space bounding box.
        let (lo, hi) = match &shape.kind {
            ShapeKind::Mesh(mesh) => mesh.positions.iter().fold(
                (
                    glam::DVec3::splat(f64::INFINITY),
                    glam::DVec3::splat(f64::NEG_INFINITY),
                ),
                |(lo, hi), p| {
                    let p = glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                    (lo.min(p), hi.max(p))
                },
            ),
            ShapeKind::Sphere { radius, .. } => {
                (glam::DVec3::splat(-radius), glam::DVec3::splat(*radius))
            }
            ShapeKind::Revolution(r) => {
                let r_max = r.contour.iter().fold(0.0f32, |m, p| m.max(p[0])) as f64;
                let (z_lo, z_hi) = r
                    .contour
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p[1] as f64), hi.max(p[1] as f64))
                    });
                (
                    glam::DVec3::new(-r_max, -r_max, z_lo),
                    glam::DVec3::new(r_max, r_max, z_hi),
                )
            }
            ShapeKind::Disk { .. } | ShapeKind::Cylinder { .. } | ShapeKind::Curve(_) => {
                unreachable!("open shapes were refused above")
            }
        };
        let extent = (hi - lo).max(glam::DVec3::splat(1e-12));
        let object_to_grid = DMat4::from_scale(extent.recip()) * DMat4::from_translation(-lo);
        let world_to_grid = object_to_grid * to_world.inverse();
        if !world_to_grid.is_finite() {
            return Err(unsupported(
                "the VolumeLight's transform cannot be inverted".into(),
            ));
        }
        self.volumes.push(VolumeInterior {
            le: rgb(v.le),
            sigma_a: rgb(v.sigma_a),
            grid: v.grid.as_deref().map(SampledGrid::new),
            world_to_grid: Affine3A::from_mat4(world_to_grid.as_mat4()),
            steps: v.steps,
            eta,
            power_samples: v.power_samples,
        });
        Ok((material, Some((self.volumes.len() - 1) as u32)))
    }

    fn add_shape(&mut self, shape: &ShapeDesc, to_world: DMat4) -> Result<(), BuildError> {
        let material = shape.material.0;
        let is_interface = self.materials[material as usize].is_interface();
        // Without media an interface surface has no effect at all, unless it emits.
        let shape_media = shape.media.filter(|_| self.use_media);
        // A subsurface material fills its shape with its own medium: the random walk.
        let shape_media = match self.subsurface_media[material as usize] {
            Some(m) if self.use_media => Some(kiln_scene::MediumInterfaceDesc {
                inside: Some(kiln_scene::MediumId(m)),
                outside: shape_media.and_then(|m| m.outside),
            }),
            _ => shape_media,
        };
        // (A nested interface still hides the boundaries of lower-priority shapes.)
        if is_interface
            && shape.area_light.is_none()
            && shape_media.is_none()
            && shape.priority == 0
        {
            return Ok(());
        }
        let nest = self.add_nested(shape, shape_media)?;
        let (material, volume) = match &shape.area_light {
            Some(AreaLightDesc::Volume(v)) => self.add_volume(shape, v, to_world)?,
            _ => (material, None),
        };
        let media =
            shape_media.map(|m| [m.inside, m.outside].map(|x| x.map_or(NO_MEDIUM, |id| id.0)));
        let alpha = shape.alpha.map(|a| {
            self.prims.alphas.push(self.textures.float_value(&a));
            (self.prims.alphas.len() - 1) as u32
        });
        let surface = SurfaceInfo {
            material,
            light: None,
            volume,
            media,
            alpha,
            nest,
        };
        match &shape.kind {
            ShapeKind::Mesh(mesh) => match &shape.displacement {
                Some(d) => {
                    let texture = self.textures.float_value(&d.texture);
                    let displaced =
                        crate::shapes::displace::displace(mesh, to_world, d.edge_length, &texture)
                            .map_err(|message| BuildError::Unsupported {
                                loc: shape.loc.clone(),
                                message: format!("plymesh: {message}"),
                            })?;
                    self.add_mesh(shape, &displaced, to_world, surface)
                }
                None => self.add_mesh(shape, mesh, to_world, surface),
            },
            &ShapeKind::Sphere {
                radius,
                z_min,
                z_max,
                phi_max,
            } => {
                // A sphere with an emission image needs (u, v) on its light samples, which
                // quadrics have.
                let imaged = matches!(
                    &shape.area_light,
                    Some(AreaLightDesc::Diffuse { image: Some(_), .. })
                );
                let whole = !imaged
                    && z_min <= -radius
                    && z_max >= radius
                    && phi_max >= std::f64::consts::TAU;
                match similarity_scale(&to_world) {
                    Some(scale) if whole => {
                        self.add_sphere(shape, radius, scale, to_world, surface)
                    }
                    _ => self.add_quadric(
                        shape,
                        QuadricShape::Sphere(PartialSphere {
                            radius: radius as f32,
                            z_min: z_min as f32,
                            z_max: z_max as f32,
                            phi_max: phi_max as f32,
                        }),
                        to_world,
                        surface,
                    ),
                }
            }
            &ShapeKind::Disk {
                height,
                radius,
                inner_radius,
                phi_max,
            } => self.add_quadric(
                shape,
                QuadricShape::Disk(Disk {
                    height: height as f32,
                    radius: radius as f32,
                    inner_radius: inner_radius as f32,
                    phi_max: phi_max as f32,
                }),
                to_world,
                surface,
            ),
            ShapeKind::Curve(curve) => self.add_curve(shape, curve, to_world, surface),
            ShapeKind::Revolution(r) => self.add_revolution(shape, r, to_world, surface),
            &ShapeKind::Cylinder {
                radius,
                z_min,
                z_max,
                phi_max,
            } => self.add_quadric(
                shape,
                QuadricShape::Cylinder(Cylinder {
                    radius: radius as f32,
                    z_min: z_min as f32,
                    z_max: z_max as f32,
                    phi_max: phi_max as f32,
                }),
                to_world,
                surface,
            ),
        }
    }

    /// A triangle mesh in world space; one light per face if it emits.
    fn add_mesh(
        &mut self,
        shape: &ShapeDesc,
        mesh: &TriangleMeshData,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let (volume, media) = (surface.volume, surface.media);
        let swaps_handedness = to_world.determinant() < 0.0;
        let surface = |light| SurfaceInfo { light, ..surface };
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
        let has_normals = mesh.normals.is_some();
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
        let has_uvs = mesh.uvs.is_some();
        if let Some(uv) = &mesh.uvs {
            self.prims.uvs.resize(base as usize, Vec2::ZERO);
            self.prims.uvs.extend(uv.iter().map(|v| Vec2::from(*v)));
        }
        let mesh_id = self.prims.meshes.len() as u32;
        let flip = shape.reverse_orientation ^ swaps_handedness;
        let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
        let first_triangle = self.prims.triangle_vertices.len() as u32;
        for t in mesh.indices.chunks_exact(3) {
            self.prims
                .triangle_vertices
                .push([base + t[0], base + t[1], base + t[2]]);
            self.prims.triangle_mesh.push(mesh_id);
        }
        if let Some(AreaLightDesc::Diffuse {
            radiance,
            image,
            two_sided,
            power,
            ..
        }) = &shape.area_light
        {
            let image = image
                .as_ref()
                .map(|image| Arc::new(EmissionImage::new(image.clone())));
            let image_luminance = image.as_ref().map_or(1.0, |i| i.mean_luminance());
            for t in mesh.indices.chunks_exact(3) {
                let p = [0, 1, 2].map(|k| self.prims.positions[(base + t[k]) as usize]);
                let area = 0.5 * (p[0] - p[2]).cross(p[1] - p[2]).length();
                let n = self.face_normal(
                    p,
                    flip,
                    has_normals,
                    [base + t[0], base + t[1], base + t[2]],
                );
                self.light_media.resize(self.lights.len(), None);
                self.light_media.push(media);
                let uv = if has_uvs {
                    [0, 1, 2].map(|k| self.prims.uvs[(base + t[k]) as usize])
                } else {
                    [Vec2::ZERO, Vec2::X, Vec2::ONE]
                };
                self.lights.push(Light::Triangle(TriangleLight {
                    p,
                    n,
                    area,
                    radiance: rgb(*radiance)
                        * power_scale(*power, area, *two_sided, image_luminance),
                    two_sided: *two_sided,
                    uv,
                    alpha: surface(None).alpha,
                    image: image.clone(),
                }));
            }
        }
        if let Some(volume) = volume {
            for (i, t) in mesh.indices.chunks_exact(3).enumerate() {
                let p = [0, 1, 2].map(|k| self.prims.positions[(base + t[k]) as usize]);
                let tri = first_triangle + i as u32;
                let cross = (p[0] - p[2]).cross(p[1] - p[2]);
                // The same orientation a hit on this face gets.
                let n = self.face_normal(
                    p,
                    flip,
                    has_normals,
                    [base + t[0], base + t[1], base + t[2]],
                );
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
        // Non-planar quads: pbrt-v4's bilinear patches, in world space.
        if !mesh.quads.is_empty() && volume.is_some() {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: "a VolumeLight (AreaLightSource \"volume\") on a mesh with non-planar quads (bilinear patches) is not supported yet".into(),
            });
        }
        for q in mesh.quads.chunks_exact(4) {
            let at = |k: usize| (base + q[k]) as usize;
            let patch = BilinearPatch::new(
                [0, 1, 2, 3].map(|k| self.prims.positions[at(k)]),
                has_normals.then(|| [0, 1, 2, 3].map(|k| self.prims.normals[at(k)])),
                has_uvs.then(|| [0, 1, 2, 3].map(|k| self.prims.uvs[at(k)])),
            );
            let kind = QuadricShape::Patch(Box::new(patch));
            // pbrt-v4's "power" is per patch: each is a shape of its own.
            let area = kind.area();
            self.add_oriented_quadric(shape, kind, DMat4::IDENTITY, surface(None), flip, area)?;
        }
        self.prims.meshes.push(MeshInfo {
            surface: surface(light),
            first_triangle,
            has_normals,
            has_uvs,
            flip,
        });
        Ok(())
    }

    /// A sphere in world space (uniform scales only); one light if it emits.
    /// A whole sphere under a similarity transform (uniform scale `scale`): in world space,
    /// sampled by its visible cone.
    fn add_sphere(
        &mut self,
        shape: &ShapeDesc,
        radius: f64,
        scale: f64,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let (volume, media) = (surface.volume, surface.media);
        let surface = |light| SurfaceInfo { light, ..surface };
        let center = to_world.transform_point3(glam::DVec3::ZERO);
        // pbrt-v4 orients quadrics by the object-space normal carried to the world and then
        // flips them for ReverseOrientation xor a handedness-swapping transform.
        // (A VolumeLight's sphere always faces out: its inside is its inside.)
        let flip = volume.is_none() && (shape.reverse_orientation ^ (to_world.determinant() < 0.0));
        let world_radius = (radius * scale) as f32;
        let center_f32 = Vec3A::from(center.as_vec3());
        if !within_world_limit(center_f32 + world_radius)
            || !within_world_limit(center_f32 - world_radius)
        {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: format!(
                    "this sphere (center {center_f32}, radius {world_radius} in world space): {WORLD_LIMIT_TEXT}"
                ),
            });
        }
        let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
        if let Some(AreaLightDesc::Diffuse {
            radiance,
            image,
            two_sided,
            power,
            ..
        }) = &shape.area_light
        {
            debug_assert!(image.is_none(), "spheres with emission images are quadrics");
            self.light_media.resize(self.lights.len(), None);
            self.light_media.push(media);
            // pbrt-v4's "power" divides by the object-space area, whatever the transform.
            let area = 4.0 * std::f32::consts::PI * (radius * radius) as f32;
            self.lights.push(Light::Sphere(SphereLight {
                center: center.as_vec3().into(),
                radius: world_radius,
                radiance: rgb(*radiance) * power_scale(*power, area, *two_sided, 1.0),
                two_sided: *two_sided,
                inward: flip,
                alpha: surface(None).alpha,
            }));
        }
        if let Some(volume) = volume {
            if shape.reverse_orientation {
                return Err(BuildError::Unsupported {
                    loc: shape.loc.clone(),
                    message: "a VolumeLight sphere cannot have ReverseOrientation: its inside is its inside".into(),
                });
            }
            self.lights.push(Light::VolumeSphere(VolumeSphereLight {
                center: center.as_vec3().into(),
                radius: world_radius,
                volume,
                power: 0.0,
            }));
        }
        self.prims.spheres.push(Sphere {
            center: center.as_vec3().into(),
            radius: world_radius,
            surface: surface(light),
            flip,
        });
        Ok(())
    }

    /// Shapes that move over the shutter: each placed by `to_object` (its place in the
    /// group), all built in the group's own space and moved together from `start` to `end`.
    fn add_mover(
        &mut self,
        shapes: &[(&ShapeDesc, DMat4)],
        start: DMat4,
        end: DMat4,
        times: [f64; 2],
        loc: &kiln_scene::Loc,
    ) -> Result<(), BuildError> {
        self.add_placed_mover(shapes, start, end, Place::World, times, loc)
    }

    /// As [`Self::add_mover`], the group then placed by `place` (a shape moving inside an
    /// object instance, which may move too).
    fn add_placed_mover(
        &mut self,
        shapes: &[(&ShapeDesc, DMat4)],
        start: DMat4,
        end: DMat4,
        place: Place,
        times: [f64; 2],
        loc: &kiln_scene::Loc,
    ) -> Result<(), BuildError> {
        let refuse = |loc: &kiln_scene::Loc, message: &str| {
            Err(BuildError::Unsupported {
                loc: loc.clone(),
                message: message.into(),
            })
        };
        for (shape, _) in shapes {
            if shape.area_light.is_some() {
                return refuse(
                    &shape.loc,
                    "a moving area light is not supported (pbrt-v4 refuses animated area lights too; motion blur covers surfaces that do not emit)",
                );
            }
        }
        let (d0, d1) = (start.determinant(), end.determinant());
        let (d2, d3) = match place {
            Place::World => (1.0, 1.0),
            Place::Still(m) => (m.determinant(), 1.0),
            Place::Moving(a, b) => (a.determinant(), b.determinant()),
        };
        if !(d0 > 0.0 && d1 > 0.0 && d2 > 0.0 && d3 > 0.0 && start.is_finite() && end.is_finite()) {
            return refuse(
                loc,
                "a moving transform must be invertible and keep its handedness throughout (a mirrored or degenerate one is not supported)",
            );
        }
        let outer = std::mem::take(&mut self.prims);
        let built = shapes
            .iter()
            .try_for_each(|(shape, to_group)| self.add_shape(shape, *to_group));
        let inner = std::mem::replace(&mut self.prims, outer);
        built?;
        let inner = finish_primitives(inner);
        if inner.triangle_vertices.is_empty()
            && inner.spheres.is_empty()
            && inner.quadrics.is_empty()
            && inner.curve_pieces.is_empty()
        {
            return Ok(());
        }
        let motion = AnimatedTransform::new(start, end, times);
        let outer = match place {
            Place::World => Outer::None,
            Place::Still(m) => {
                let m = glam::Affine3A::from_mat4(m.as_mat4());
                Outer::Still(m, m.inverse())
            }
            Place::Moving(a, b) => Outer::Moving(AnimatedTransform::new(a, b, times)),
        };
        let mover = Mover::placed(Geometry::new(inner), motion, outer);
        let (lo, hi) = mover.bounds();
        if !within_world_limit(lo) || !within_world_limit(hi) {
            return Err(BuildError::Unsupported {
                loc: loc.clone(),
                message: format!(
                    "this moving shape sweeps {lo} to {hi} in world space: {WORLD_LIMIT_TEXT}"
                ),
            });
        }
        self.prims.movers.push(mover);
        Ok(())
    }

    /// A curve's segments in world space, each split into 2^splitdepth BVH pieces.
    fn add_curve(
        &mut self,
        shape: &ShapeDesc,
        curve: &kiln_scene::CurveData,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let refuse = |message: &str| {
            Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: message.into(),
            })
        };
        if shape.area_light.is_some() {
            return refuse("a curve cannot be an area light (pbrt-v4 cannot sample curves either)");
        }
        if surface.alpha.is_some() {
            return refuse("\"alpha\" on a curve is not supported yet");
        }
        let m = to_world.as_mat4();
        let normal_m = to_world.inverse().transpose().as_mat4();
        // Widths scale with the transform's mean scale (exact for similarity transforms).
        let scale = libm::cbrt(to_world.determinant().abs()) as f32;
        if !(scale > 0.0 && scale.is_finite()) {
            return refuse("this curve's transform cannot be inverted (a zero scale?)");
        }
        let pieces = 1u32 << curve.split_depth;
        let total =
            self.prims.curve_pieces.len() as u64 + curve.segments.len() as u64 * u64::from(pieces);
        if total > CURVE_PIECE_LIMIT {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: format!(
                    "the scene's curves would make {total} BVH pieces ({} segments here, {pieces} pieces each by \"splitdepth\"); Kiln's limit is {CURVE_PIECE_LIMIT} (a lower splitdepth makes fewer)",
                    curve.segments.len()
                ),
            });
        }
        for (i, (cp, width)) in curve.segments.iter().zip(&curve.widths).enumerate() {
            let cp = cp.map(|p| Vec3A::from(m.transform_point3(glam::Vec3::from(p))));
            if let Some(p) = cp.iter().find(|p| !within_world_limit(**p)) {
                return Err(BuildError::Unsupported {
                    loc: shape.loc.clone(),
                    message: format!(
                        "a curve control point is at {p} in world space: {WORLD_LIMIT_TEXT}"
                    ),
                });
            }
            let normals = curve.normals.as_ref().map(|ns| {
                let n = ns[i].map(|n| {
                    Vec3A::from(normal_m.transform_vector3(glam::Vec3::from(n))).normalize_or_zero()
                });
                (n, libm::acosf(n[0].dot(n[1]).clamp(-1.0, 1.0)))
            });
            let segment = CurveSegment {
                cp,
                width: width.map(|w| w * scale),
                normals,
                kind: curve.kind,
                surface,
                flip: shape.reverse_orientation,
            };
            let index = self.prims.curve_segments.len() as u32;
            for k in 0..pieces {
                let (u0, u1) = (k as f32 / pieces as f32, (k + 1) as f32 / pieces as f32);
                self.prims
                    .curve_pieces
                    .push(CurvePiece::new(&segment, index, u0, u1));
            }
            self.prims.curve_segments.push(segment);
        }
        Ok(())
    }

    /// A disk, a cylinder, or a sphere that is partial or under a transform other than a
    /// similarity, intersected in its object space.
    fn add_quadric(
        &mut self,
        shape: &ShapeDesc,
        kind: QuadricShape,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let area = kind.area();
        self.add_oriented_quadric(
            shape,
            kind,
            to_world,
            surface,
            shape.reverse_orientation,
            area,
        )
    }

    /// A surface of revolution: its strips' sectors, each a quadric (and, if the shape
    /// emits, a light; pbrt-v4's "power" is spread over the whole shape's area).
    fn add_revolution(
        &mut self,
        shape: &ShapeDesc,
        r: &kiln_scene::RevolutionDesc,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let strips = crate::shapes::revolution::strips(
            &r.contour,
            r.normals.as_deref(),
            r.crease as f32,
            r.phi_max as f32,
        )
        .map_err(|e| BuildError::Unsupported {
            loc: shape.loc.clone(),
            message: format!("revolution: {}", e.0),
        })?;
        if surface.volume.is_some() {
            // A VolumeLight's surface must face out of its interior.
            if shape.reverse_orientation || contour_area(&r.contour) <= 0.0 {
                return Err(BuildError::Unsupported {
                    loc: shape.loc.clone(),
                    message: "a VolumeLight revolution must face outwards: list its contour counterclockwise in the (r, z) plane (up its outer side) and without ReverseOrientation".into(),
                });
            }
        }
        let area: f32 = strips.iter().map(|s| s.area()).sum();
        for strip in strips {
            self.add_oriented_quadric(
                shape,
                QuadricShape::Strip(strip),
                to_world,
                surface,
                shape.reverse_orientation,
                area,
            )?;
        }
        Ok(())
    }

    /// As [`Self::add_quadric`], with the orientation given (a mesh's bilinear patches lie
    /// in world space already, oriented by their mesh's transform).
    fn add_oriented_quadric(
        &mut self,
        shape: &ShapeDesc,
        kind: QuadricShape,
        to_world: DMat4,
        surface: SurfaceInfo,
        reverse_orientation: bool,
        power_area: f32,
    ) -> Result<(), BuildError> {
        let object_area = kind.area();
        if surface.volume.is_some() && !matches!(kind, QuadricShape::Strip(_)) {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: "a VolumeLight (AreaLightSource \"volume\") on a partial sphere, or on a sphere under a non-uniform scale, is not supported yet".into(),
            });
        }
        if object_area.is_nan() || object_area <= 0.0 {
            // pbrt-v4 accepts an empty quadric (zero radius, zmin = zmax, phimax 0) and draws
            // nothing; so does Kiln.
            return Ok(());
        }
        // The light this quadric will be: a diffuse area light, or a VolumeLight's surface.
        let light = (matches!(shape.area_light, Some(AreaLightDesc::Diffuse { .. }))
            || surface.volume.is_some())
        .then_some(self.lights.len() as u32);
        let quadric = Quadric::new(
            kind,
            to_world,
            SurfaceInfo { light, ..surface },
            reverse_orientation,
        )
        .ok_or_else(|| BuildError::Unsupported {
            loc: shape.loc.clone(),
            message: "this shape's transform cannot be inverted (a zero scale?)".into(),
        })?;
        let (lo, hi) = quadric.bounds();
        if !within_world_limit(lo) || !within_world_limit(hi) {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: format!(
                    "this shape (bounds {lo} to {hi} in world space): {WORLD_LIMIT_TEXT}"
                ),
            });
        }
        if let Some(AreaLightDesc::Diffuse {
            radiance,
            image,
            two_sided,
            power,
            ..
        }) = &shape.area_light
        {
            let image = image.clone().map(|i| Arc::new(EmissionImage::new(i)));
            let luminance = image.as_ref().map_or(1.0, |i| i.mean_luminance());
            self.light_media.resize(self.lights.len(), None);
            self.light_media.push(surface.media);
            self.lights.push(Light::Quadric(QuadricLight {
                quadric: self.prims.quadrics.len() as u32,
                // pbrt-v4's "power" divides by the object-space area, whatever the transform.
                radiance: rgb(*radiance) * power_scale(*power, power_area, *two_sided, luminance),
                two_sided: *two_sided,
                area: quadric.world_area(),
                alpha: surface.alpha,
                image,
            }));
        }
        if let Some(volume) = surface.volume {
            self.lights.push(Light::VolumeQuadric(VolumeQuadricLight {
                quadric: self.prims.quadrics.len() as u32,
                volume,
                area: quadric.world_area(),
                power: 0.0,
            }));
        }
        self.prims.quadrics.push(quadric);
        Ok(())
    }
}

/// Fills in the per-vertex arrays that only some meshes gave.
fn finish_primitives(mut prims: Primitives) -> Primitives {
    let n_positions = prims.positions.len();
    if !prims.normals.is_empty() {
        prims.normals.resize(n_positions, Vec3A::Z);
    }
    if !prims.uvs.is_empty() {
        prims.uvs.resize(n_positions, Vec2::ZERO);
    }
    prims
}

/// The uniform scale of a similarity transform (rotation, reflection, translation and one
/// scale), or None.
fn similarity_scale(m: &DMat4) -> Option<f64> {
    let axes = [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z].map(|a| m.transform_vector3(a));
    let s = axes[0].length();
    let orthogonal = axes[0].dot(axes[1]).abs() <= 1e-6 * s * s
        && axes[0].dot(axes[2]).abs() <= 1e-6 * s * s
        && axes[1].dot(axes[2]).abs() <= 1e-6 * s * s;
    let equal =
        (axes[1].length() - s).abs() <= 1e-6 * s && (axes[2].length() - s).abs() <= 1e-6 * s;
    (s > 0.0 && orthogonal && equal && m.row(3) == glam::DVec4::new(0.0, 0.0, 0.0, 1.0))
        .then_some(s)
}

impl Scene {
    /// Builds the scene `desc` describes, with or without its participating media.
    pub fn build(desc: &SceneDescription, media: MediaPolicy) -> Result<Scene, BuildError> {
        let textures = Textures::from_description(&desc.float_textures, &desc.spectrum_textures);
        let materials = desc
            .materials
            .iter()
            .map(|m| {
                Material::from_description(m, &textures).map_err(|message| {
                    BuildError::Unsupported {
                        loc: m.loc.clone(),
                        message,
                    }
                })
            })
            .collect::<Result<Vec<Material>, BuildError>>()?;
        let mut b = Builder {
            prims: Primitives::default(),
            lights: Vec::new(),
            materials,
            volumes: Vec::new(),
            use_media: media == MediaPolicy::Render,
            light_media: Vec::new(),
            textures,
            nested: Vec::new(),
            subsurface_media: desc
                .materials
                .iter()
                .scan(desc.media.len() as u32, |next, m| {
                    Some(match m.kind {
                        MaterialKind::Subsurface { .. } => {
                            *next += 1;
                            Some(*next - 1)
                        }
                        _ => None,
                    })
                })
                .collect(),
        };
        let times = desc.transform_times;
        for shape in &desc.shapes {
            match shape.object_to_world_end {
                None => b.add_shape(shape, shape.object_to_world)?,
                Some(end) => b.add_mover(
                    &[(shape, DMat4::IDENTITY)],
                    shape.object_to_world,
                    end,
                    times,
                    &shape.loc,
                )?,
            }
        }
        // Instances are flattened into world space: simple and as fast to trace as
        // anything for the scene sizes Kiln renders today, at the cost of memory. A moving
        // instance is one moving group.
        for instance in &desc.instances {
            let shapes = &desc.objects[instance.object].shapes;
            match instance.instance_to_world_end {
                None => {
                    for shape in shapes {
                        match shape.object_to_world_end {
                            None => b.add_shape(
                                shape,
                                instance.instance_to_world * shape.object_to_world,
                            )?,
                            // A shape moving inside a still instance: its motion, then
                            // the instance's place.
                            Some(end) => b.add_placed_mover(
                                &[(shape, DMat4::IDENTITY)],
                                shape.object_to_world,
                                end,
                                Place::Still(instance.instance_to_world),
                                times,
                                &shape.loc,
                            )?,
                        }
                    }
                }
                Some(end) => {
                    // The object's still shapes move with the instance as one group; each
                    // moving shape moves by its own motion, then by the instance's at the
                    // same time (pbrt-v4's animated primitive inside an animated instance).
                    let group: Vec<(&ShapeDesc, DMat4)> = shapes
                        .iter()
                        .filter(|s| s.object_to_world_end.is_none())
                        .map(|s| (s, s.object_to_world))
                        .collect();
                    if !group.is_empty() {
                        b.add_mover(
                            &group,
                            instance.instance_to_world,
                            end,
                            times,
                            &instance.loc,
                        )?;
                    }
                    for shape in shapes {
                        if let Some(shape_end) = shape.object_to_world_end {
                            b.add_placed_mover(
                                &[(shape, DMat4::IDENTITY)],
                                shape.object_to_world,
                                shape_end,
                                Place::Moving(instance.instance_to_world, end),
                                times,
                                &shape.loc,
                            )?;
                        }
                    }
                }
            }
        }
        let has_motion = !b.prims.movers.is_empty();
        let geometry = Geometry::new(finish_primitives(b.prims));
        let (lo, hi) = geometry.bounds();
        let radius = ((hi - lo).length() / 2.0).max(1e-3);
        let mut lights = b.lights;
        let mut light_media = b.light_media;
        light_media.resize(lights.len(), None);
        for l in &desc.lights {
            lights.push(Light::from_description(&l.kind));
            // A light in space starts its photons in the medium it was declared in.
            light_media.push(l.medium.filter(|_| b.use_media).map(|m| [m.0, m.0]));
        }
        let infinite_lights = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        // The interiors of subsurface materials, in material order (the indices
        // `subsurface_media` gave out), follow the description's media.
        let walk_samples_lights = lights.iter().any(Light::is_point);
        let (walk_media, walk_textures): (Vec<Medium>, Vec<Option<TexturedInterior>>) = desc
            .materials
            .iter()
            .filter(|_| b.use_media)
            .filter_map(|m| match m.kind {
                MaterialKind::Subsurface { g, interior, .. } => {
                    Some(subsurface_medium(g, interior, &b.textures))
                }
                _ => None,
            })
            .unzip();
        let film = &desc.film;
        let mut scene = Scene {
            geometry,
            materials: b.materials,
            light_sampler: LightSampler::default(),
            lights,
            infinite_lights,
            camera: Camera::new_moving(
                &desc.camera,
                film.xresolution,
                film.yresolution,
                film.diagonal,
                desc.transform_times,
            )
            .map_err(|message| BuildError::Unsupported {
                loc: desc.camera.loc.clone(),
                message,
            })?,
            filter: Filter::new(&desc.filter),
            sensor: crate::sensor::Sensor::new(
                &film.sensor,
                desc.camera.shutter[1] - desc.camera.shutter[0],
            ),
            resolution: (film.xresolution, film.yresolution),
            shutter: [desc.camera.shutter[0] as f32, desc.camera.shutter[1] as f32],
            has_motion: has_motion || desc.camera.camera_to_world_end.is_some(),
            radius,
            volumes: b.volumes,
            media: desc
                .media
                .iter()
                .filter(|_| b.use_media)
                .map(|m| match &m.kind {
                    MediumKind::Homogeneous {
                        sigma_a,
                        sigma_s,
                        le,
                        phase,
                    } => Medium::Homogeneous(HomogeneousMedium {
                        sigma_a: rgb(*sigma_a),
                        sigma_s: rgb(*sigma_s),
                        le: rgb(*le),
                        phase: Phase::new(*phase),
                    }),
                    MediumKind::Grid(g) => Medium::Grid(Box::new(GridMedium::new(g))),
                })
                .chain(walk_media)
                .collect(),
            camera_medium: desc.camera_medium.filter(|_| b.use_media).map(|m| m.0),
            medium_lights: Vec::new(),
            light_media,
            nested: b.nested,
            first_walk_medium: if b.use_media {
                desc.media.len() as u32
            } else {
                0
            },
            walk_textures,
            walk_samples_lights,
        };
        scene.light_media.resize(scene.lights.len(), None);
        // Each emissive grid medium is a light, sampled by its emission distribution.
        scene.medium_lights = vec![None; scene.media.len()];
        for (i, m) in scene.media.iter().enumerate() {
            if let Some(power) = m.light_power() {
                scene.medium_lights[i] = Some(scene.lights.len() as u32);
                scene.lights.push(Light::Medium(MediumLight {
                    medium: i as u32,
                    power,
                }));
            }
        }
        let estimates = power_estimates(&scene.lights, &scene.light_context(), VOLUME_POWER_SEED);
        for (light, estimate) in scene.lights.iter_mut().zip(estimates) {
            if let (Light::VolumeTriangle(VolumeTriangleLight { power, .. }), Some(e))
            | (Light::VolumeSphere(VolumeSphereLight { power, .. }), Some(e))
            | (Light::VolumeQuadric(VolumeQuadricLight { power, .. }), Some(e)) =
                (light, estimate)
            {
                *power = e;
            }
        }
        let powers: Vec<f64> = scene
            .lights
            .iter()
            .map(|l| l.power(radius).max(0.0) as f64)
            .collect();
        scene.light_sampler = LightSampler::new(
            desc.integrator.light_sampler,
            &scene.lights,
            &powers,
            &scene.light_context(),
        );
        Ok(scene)
    }
}
