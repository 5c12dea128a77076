//! Building a [`Scene`] from a description: instances flattened into world space, one
//! light per emitting triangle, VolumeLight interiors, media, the power-proportional light
//! sampler and the VolumeLights' power estimates.

mod curve;
mod mesh;
mod motion;
mod quadric;
mod volume;

use super::Scene;
use crate::camera::Camera;
use crate::filter::Filter;
use crate::lights::volume::{VOLUME_POWER_SEED, power_estimates};
use crate::lights::{
    Light, LightSampler, MediumLight, VolumeInterior, VolumeQuadricLight, VolumeSphereLight,
    VolumeTriangleLight,
};
use crate::materials::{Material, Model};
use crate::math::rgb;
use crate::media::subsurface::{TexturedInterior, subsurface_medium};
use crate::media::{GridMedium, HomogeneousMedium, Medium, Phase};
use crate::nesting::NestedShape;
use crate::shapes::cylinder::Cylinder;
use crate::shapes::disk::Disk;
use crate::shapes::sphere::PartialSphere;
use crate::shapes::{Geometry, NO_MEDIUM, Primitives, QuadricShape, SurfaceInfo};
use crate::spectral::LightSpectrum;
use crate::textures::Textures;
use glam::{DMat4, Vec2, Vec3A};
use kiln_scene::spectrum::EmissionSpectrum;
use kiln_scene::{AreaLightDesc, MaterialKind, MediumKind, SceneDescription, ShapeDesc, ShapeKind};
use motion::Place;
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

/// Whether a scene is built with its participating media. pbrt-v4's "path" integrator
/// ignores them (interfaces vanish, media-bounded shapes keep only their materials).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MediaPolicy {
    Render,
    Ignore,
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
    /// For a spectral render, the spectrum of each area light's emission given as one.
    light_spectra: Vec<Option<Arc<LightSpectrum>>>,
    spectral: bool,
    textures: Textures,
    nested: Vec<NestedShape>,
    /// For each material, the medium (index into the scene's media) a "subsurface"
    /// material fills its shapes with.
    subsurface_media: Vec<Option<u32>>,
}

impl Builder {
    /// A builder with the description's materials and textures, and nothing placed yet.
    fn new(desc: &SceneDescription, media: MediaPolicy) -> Result<Builder, BuildError> {
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
        Ok(Builder {
            prims: Primitives::default(),
            lights: Vec::new(),
            materials,
            volumes: Vec::new(),
            use_media: media == MediaPolicy::Render,
            light_media: Vec::new(),
            light_spectra: Vec::new(),
            spectral: desc.spectral,
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
        })
    }

    /// Every shape of the description, still or moving, and every instance's.
    fn add_shapes(&mut self, desc: &SceneDescription) -> Result<(), BuildError> {
        let times = desc.transform_times;
        for shape in &desc.shapes {
            match shape.object_to_world_end {
                None => self.add_shape(shape, shape.object_to_world)?,
                Some(end) => self.add_mover(
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
                None => self.add_still_instance(shapes, instance.instance_to_world, times)?,
                Some(end) => {
                    self.add_moving_instance(shapes, instance, end, times)?;
                }
            }
        }
        Ok(())
    }

    /// An object's shapes placed by a still instance transform.
    fn add_still_instance(
        &mut self,
        shapes: &[ShapeDesc],
        instance_to_world: DMat4,
        times: [f64; 2],
    ) -> Result<(), BuildError> {
        for shape in shapes {
            match shape.object_to_world_end {
                None => self.add_shape(shape, instance_to_world * shape.object_to_world)?,
                // A shape moving inside a still instance: its motion, then the instance's
                // place.
                Some(end) => self.add_placed_mover(
                    &[(shape, DMat4::IDENTITY)],
                    shape.object_to_world,
                    end,
                    Place::Still(instance_to_world),
                    times,
                    &shape.loc,
                )?,
            }
        }
        Ok(())
    }

    /// An object's shapes in an instance moving to `end`: the object's still shapes move
    /// with the instance as one group; each moving shape moves by its own motion, then by
    /// the instance's at the same time (pbrt-v4's animated primitive inside an animated
    /// instance).
    fn add_moving_instance(
        &mut self,
        shapes: &[ShapeDesc],
        instance: &kiln_scene::InstanceDesc,
        end: DMat4,
        times: [f64; 2],
    ) -> Result<(), BuildError> {
        let group: Vec<(&ShapeDesc, DMat4)> = shapes
            .iter()
            .filter(|s| s.object_to_world_end.is_none())
            .map(|s| (s, s.object_to_world))
            .collect();
        if !group.is_empty() {
            self.add_mover(
                &group,
                instance.instance_to_world,
                end,
                times,
                &instance.loc,
            )?;
        }
        for shape in shapes {
            if let Some(shape_end) = shape.object_to_world_end {
                self.add_placed_mover(
                    &[(shape, DMat4::IDENTITY)],
                    shape.object_to_world,
                    shape_end,
                    Place::Moving(instance.instance_to_world, end),
                    times,
                    &shape.loc,
                )?;
            }
        }
        Ok(())
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

    /// What a shape's surface refers to (material, media, alpha, nesting, VolumeLight
    /// interior), registering its nesting and interior; None for a surface that has no
    /// effect at all.
    fn surface_of(
        &mut self,
        shape: &ShapeDesc,
        to_world: DMat4,
    ) -> Result<Option<SurfaceInfo>, BuildError> {
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
            return Ok(None);
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
        Ok(Some(SurfaceInfo {
            material,
            light: None,
            volume,
            media,
            alpha,
            nest,
        }))
    }

    /// One shape placed by `to_world`, as the primitives its kind is traced as.
    fn add_shape(&mut self, shape: &ShapeDesc, to_world: DMat4) -> Result<(), BuildError> {
        let Some(surface) = self.surface_of(shape, to_world)? else {
            return Ok(());
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
                let sphere = PartialSphere {
                    radius: radius as f32,
                    z_min: z_min as f32,
                    z_max: z_max as f32,
                    phi_max: phi_max as f32,
                };
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
                    _ => self.add_quadric(shape, QuadricShape::Sphere(sphere), to_world, surface),
                }
            }
            &ShapeKind::Disk {
                height,
                radius,
                inner_radius,
                phi_max,
            } => {
                let disk = Disk {
                    height: height as f32,
                    radius: radius as f32,
                    inner_radius: inner_radius as f32,
                    phi_max: phi_max as f32,
                };
                self.add_quadric(shape, QuadricShape::Disk(disk), to_world, surface)
            }
            ShapeKind::Curve(curve) => self.add_curve(shape, curve, to_world, surface),
            ShapeKind::Revolution(r) => self.add_revolution(shape, r, to_world, surface),
            &ShapeKind::Cylinder {
                radius,
                z_min,
                z_max,
                phi_max,
            } => {
                let cylinder = Cylinder {
                    radius: radius as f32,
                    z_min: z_min as f32,
                    z_max: z_max as f32,
                    phi_max: phi_max as f32,
                };
                self.add_quadric(shape, QuadricShape::Cylinder(cylinder), to_world, surface)
            }
        }
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

/// The description's media (none for a scene built without them), then the interiors of
/// its subsurface materials.
fn scene_media(desc: &SceneDescription, use_media: bool, walk_media: Vec<Medium>) -> Vec<Medium> {
    desc.media
        .iter()
        .filter(|_| use_media)
        .map(|m| match &m.kind {
            MediumKind::Homogeneous {
                sigma_a,
                sigma_s,
                le,
                le_spectrum,
                phase,
            } => Medium::Homogeneous(HomogeneousMedium {
                sigma_a: rgb(*sigma_a),
                sigma_s: rgb(*sigma_s),
                le: rgb(*le),
                le_spectrum: light_spectrum(desc.spectral, le_spectrum),
                phase: Phase::new(*phase),
            }),
            MediumKind::Grid(g) => Medium::Grid(Box::new(GridMedium::new(g, desc.spectral))),
        })
        .chain(walk_media)
        .collect()
}

impl Builder {
    /// The spectrum of an emission given as one, for a spectral render.
    fn light_spectrum(&self, s: &Option<EmissionSpectrum>) -> Option<Arc<LightSpectrum>> {
        light_spectrum(self.spectral, s)
    }

    /// The alpha an area light on a surface of alpha `alpha` keeps, and whether it is
    /// pbrt-v4's "invisible area light": a constant alpha of 0 lets every ray through the
    /// surface but not its light, which emits in full and is found by light samples alone
    /// (see [`crate::lights::SphereLight::invisible`]).
    fn light_alpha(&self, alpha: Option<u32>) -> (Option<u32>, bool) {
        match alpha.map(|a| &self.prims.alphas[a as usize]) {
            Some(crate::textures::Texture::Constant(a)) if *a <= 0.0 => (None, true),
            _ => (alpha, false),
        }
    }

    /// Notes the media around, and the spectrum of, the area light about to be pushed.
    fn note_area_light(&mut self, media: Option<[u32; 2]>, spectrum: &Option<Arc<LightSpectrum>>) {
        self.light_media.resize(self.lights.len(), None);
        self.light_media.push(media);
        self.light_spectra.resize(self.lights.len(), None);
        self.light_spectra.push(spectrum.clone());
    }
}

/// The spectrum of an emission given as one, for a spectral render (None in RGB).
pub(super) fn light_spectrum(
    spectral: bool,
    s: &Option<EmissionSpectrum>,
) -> Option<Arc<LightSpectrum>> {
    s.as_deref()
        .filter(|_| spectral)
        .and_then(LightSpectrum::new)
        .map(Arc::new)
}

impl Scene {
    /// Builds the scene `desc` describes, with or without its participating media.
    pub fn build(desc: &SceneDescription, media: MediaPolicy) -> Result<Scene, BuildError> {
        let mut b = Builder::new(desc, media)?;
        b.add_shapes(desc)?;
        let has_motion = !b.prims.movers.is_empty();
        let geometry = Geometry::new(finish_primitives(b.prims));
        let (lo, hi) = geometry.bounds();
        let radius = ((hi - lo).length() / 2.0).max(1e-3);
        let mut lights = b.lights;
        let mut light_media = b.light_media;
        light_media.resize(lights.len(), None);
        let mut light_spectra = b.light_spectra;
        light_spectra.resize(lights.len(), None);
        for l in &desc.lights {
            lights.push(Light::from_description(&l.kind));
            // A light in space starts its photons in the medium it was declared in.
            light_media.push(l.medium.filter(|_| b.use_media).map(|m| [m.0, m.0]));
            light_spectra.push(light_spectrum(desc.spectral, &l.spectrum));
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
            media: scene_media(desc, b.use_media, walk_media),
            camera_medium: desc.camera_medium.filter(|_| b.use_media).map(|m| m.0),
            medium_lights: Vec::new(),
            light_media,
            light_spectra,
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
        scene.add_medium_lights();
        scene.light_spectra.resize(scene.lights.len(), None);
        scene.sample_lights_by_power(desc.integrator.light_sampler);
        Ok(scene)
    }

    /// Each emissive grid medium is a light, sampled by its emission distribution.
    fn add_medium_lights(&mut self) {
        self.medium_lights = vec![None; self.media.len()];
        for (i, m) in self.media.iter().enumerate() {
            if let Some(power) = m.light_power() {
                self.medium_lights[i] = Some(self.lights.len() as u32);
                self.lights.push(Light::Medium(MediumLight {
                    medium: i as u32,
                    power,
                }));
            }
        }
    }

    /// Estimates the VolumeLights' powers, then builds the light sampler over every light's.
    fn sample_lights_by_power(&mut self, kind: kiln_scene::LightSamplerKind) {
        let estimates = power_estimates(&self.lights, &self.light_context(), VOLUME_POWER_SEED);
        for (light, estimate) in self.lights.iter_mut().zip(estimates) {
            if let (Light::VolumeTriangle(VolumeTriangleLight { power, .. }), Some(e))
            | (Light::VolumeSphere(VolumeSphereLight { power, .. }), Some(e))
            | (Light::VolumeQuadric(VolumeQuadricLight { power, .. }), Some(e)) =
                (light, estimate)
            {
                *power = e;
            }
        }
        let powers: Vec<f64> = self
            .lights
            .iter()
            .map(|l| l.power(self.radius).max(0.0) as f64)
            .collect();
        self.light_sampler = LightSampler::new(kind, &self.lights, &powers, &self.light_context());
    }
}

#[cfg(test)]
mod tests;
