//! Turns a [`SceneDescription`] into a scene ready to render: world-space
//! geometry in BVHs, materials, lights and the light sampler.

use crate::bsdf::{Bsdf, TrowbridgeReitz, refract};
use crate::camera::{Camera, Filter};
use crate::geometry::{Geometry, MeshInfo, Sphere, SurfaceInfo};
use crate::lights::{EnvironmentMap, Light};
use crate::lights::{LightSample, sample_sphere_point, sample_triangle_point};
use crate::materials::Material;
use crate::math::{Color, Frame, Ray, luminance, rgb};
use crate::media::{GridMedium, Medium, Phase, TrackingRng};
use crate::sampler::PixelSampler;
use crate::sampling::AliasTable;
use crate::sampling::cosine_hemisphere;
use crate::volume::{Grid, VolumeEmitter};
use glam::{Affine3A, DMat4, Vec2, Vec3A};
use kiln_scene::{
    AreaLightDesc, EnvironmentLayout, LightKind, MaterialKind, SceneDescription, ShapeDesc,
    ShapeKind, VolumeLightDesc,
};
use rayon::prelude::*;

/// Why a description cannot be turned into a renderable scene.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("{loc}: {message}")]
    Unsupported {
        loc: kiln_scene::Loc,
        message: String,
    },
}

/// The seed of the Sobol points that VolumeLight power estimates draw.
pub const VOLUME_POWER_SEED: u32 = 0x766f_6c75;

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
    /// The interiors of VolumeLights, referred to by `SurfaceInfo::volume`.
    pub volumes: Vec<VolumeEmitter>,
    /// Participating media, referred to by `SurfaceInfo::media`.
    pub media: Vec<Medium>,
    pub camera_medium: Option<u32>,
    /// The light of each medium that is one (an emissive grid).
    pub medium_lights: Vec<Option<u32>>,
    /// The media on either side of each area light's surface (inside, outside), by light
    /// index; for photons leaving it.
    pub light_media: Vec<Option<[u32; 2]>>,
    /// Caustic photon maps, when the integrator asks for them.
    pub caustics: Option<crate::photons::CausticMaps>,
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
    materials: Vec<Material>,
    interface_materials: Vec<bool>,
    volumes: Vec<VolumeEmitter>,
    /// False for Integrator "path", which (as pbrt-v4's) ignores participating media.
    use_media: bool,
    /// The media on either side of each area light's surface (by light index).
    light_media: Vec<Option<[u32; 2]>>,
}

impl Builder {
    /// A triangle's geometric normal, oriented as hits on it are (see Geometry::triangle_hit).
    fn face_normal(&self, p: [Vec3A; 3], flip: bool, has_normals: bool, v: [u32; 3]) -> Vec3A {
        let mut n = (p[0] - p[2]).cross(p[1] - p[2]).normalize_or_zero();
        if flip {
            n = -n;
        }
        if has_normals {
            let ns: Vec3A = v.iter().map(|&k| self.normals[k as usize]).sum();
            if n.dot(ns) < 0.0 {
                n = -n;
            }
        }
        n
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
        let material = shape.material.0;
        let eta = match &self.materials[material as usize] {
            Material::Uniform(Bsdf::Dielectric { eta, distrib })
                if distrib.effectively_smooth() =>
            {
                *eta
            }
            Material::Interface => 1.0,
            _ => {
                return Err(unsupported(
                    "a VolumeLight (AreaLightSource \"volume\") needs a smooth \"dielectric\" or an \"interface\" material".into(),
                ));
            }
        };
        // An interface around a VolumeLight is a dielectric of eta 1: rays cross it unbent.
        let material = if eta == 1.0 {
            self.materials.push(Material::Uniform(Bsdf::Dielectric {
                eta: 1.0,
                distrib: TrowbridgeReitz::new(0.0, 0.0),
            }));
            self.interface_materials.push(false);
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
            ShapeKind::Sphere { radius } => {
                (glam::DVec3::splat(-radius), glam::DVec3::splat(*radius))
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
        self.volumes.push(VolumeEmitter {
            le: rgb(v.le),
            sigma_a: rgb(v.sigma_a),
            grid: v.grid.as_deref().map(Grid::new),
            world_to_grid: Affine3A::from_mat4(world_to_grid.as_mat4()),
            steps: v.steps,
            eta,
            power_samples: v.power_samples,
        });
        Ok((material, Some((self.volumes.len() - 1) as u32)))
    }

    fn add_shape(&mut self, shape: &ShapeDesc, to_world: DMat4) -> Result<(), BuildError> {
        let material = shape.material.0;
        let is_interface = self.interface_materials[material as usize];
        // Without media an interface surface has no effect at all, unless it emits.
        let shape_media = shape.media.filter(|_| self.use_media);
        if is_interface && shape.area_light.is_none() && shape_media.is_none() {
            return Ok(());
        }
        let swaps_handedness = to_world.determinant() < 0.0;
        let (material, volume) = match &shape.area_light {
            Some(AreaLightDesc::Volume(v)) => self.add_volume(shape, v, to_world)?,
            _ => (material, None),
        };
        let media = shape_media.map(|m| {
            [m.inside, m.outside].map(|x| x.map_or(crate::geometry::NO_MEDIUM, |id| id.0))
        });
        let surface = |light| SurfaceInfo {
            material,
            light,
            volume,
            media,
        };
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
                let mesh_id = self.meshes.len() as u32;
                let flip = shape.reverse_orientation ^ swaps_handedness;
                let light = shape.area_light.as_ref().map(|_| self.lights.len() as u32);
                let first_triangle = self.triangle_vertices.len() as u32;
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
                        let area = 0.5 * (p[0] - p[2]).cross(p[1] - p[2]).length();
                        let n = self.face_normal(
                            p,
                            flip,
                            has_normals,
                            [base + t[0], base + t[1], base + t[2]],
                        );
                        self.light_media.resize(self.lights.len(), None);
                        self.light_media.push(media);
                        self.lights.push(Light::Triangle {
                            p,
                            n,
                            area,
                            radiance: rgb(*radiance),
                            two_sided: *two_sided,
                        });
                    }
                }
                if let Some(volume) = volume {
                    for (i, t) in mesh.indices.chunks_exact(3).enumerate() {
                        let p = [0, 1, 2].map(|k| self.positions[(base + t[k]) as usize]);
                        let tri = first_triangle + i as u32;
                        let cross = (p[0] - p[2]).cross(p[1] - p[2]);
                        // The same orientation a hit on this face gets.
                        let n = self.face_normal(
                            p,
                            flip,
                            has_normals,
                            [base + t[0], base + t[1], base + t[2]],
                        );
                        self.lights.push(Light::VolumeTriangle {
                            p,
                            n,
                            area: 0.5 * cross.length(),
                            tri,
                            volume,
                            power: 0.0,
                        });
                    }
                }
                self.meshes.push(MeshInfo {
                    surface: surface(light),
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
                    self.light_media.resize(self.lights.len(), None);
                    self.light_media.push(media);
                    self.lights.push(Light::Sphere {
                        center: center.as_vec3().into(),
                        radius: world_radius,
                        radiance: rgb(*radiance),
                        two_sided: *two_sided,
                        inward: shape.reverse_orientation,
                    });
                }
                if let Some(volume) = volume {
                    if shape.reverse_orientation {
                        return Err(BuildError::Unsupported {
                            loc: shape.loc.clone(),
                            message: "a VolumeLight sphere cannot have ReverseOrientation: its inside is its inside".into(),
                        });
                    }
                    self.lights.push(Light::VolumeSphere {
                        center: center.as_vec3().into(),
                        radius: world_radius,
                        volume,
                        power: 0.0,
                    });
                }
                self.spheres.push(Sphere {
                    center: center.as_vec3().into(),
                    radius: world_radius,
                    surface: surface(light),
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
            materials,
            interface_materials,
            volumes: Vec::new(),
            use_media: desc.integrator.name != "path",
            light_media: Vec::new(),
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
        let infinite_lights = lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_infinite())
            .map(|(i, _)| i as u32)
            .collect();
        let film = &desc.film;
        let mut scene = Scene {
            geometry,
            materials: b.materials,
            light_sampler: AliasTable::default(),
            lights,
            infinite_lights,
            camera: Camera::new(&desc.camera, film.xresolution, film.yresolution),
            filter: Filter::new(&desc.filter),
            resolution: (film.xresolution, film.yresolution),
            radius,
            volumes: b.volumes,
            media: desc
                .media
                .iter()
                .filter(|_| b.use_media)
                .map(|m| match &m.kind {
                    kiln_scene::MediumKind::Homogeneous {
                        sigma_a,
                        sigma_s,
                        le,
                        phase,
                    } => Medium::Homogeneous {
                        sigma_a: rgb(*sigma_a),
                        sigma_s: rgb(*sigma_s),
                        le: rgb(*le),
                        phase: Phase::new(*phase),
                    },
                    kiln_scene::MediumKind::Grid(g) => Medium::Grid(Box::new(GridMedium::new(g))),
                })
                .collect(),
            camera_medium: desc.camera_medium.filter(|_| b.use_media).map(|m| m.0),
            medium_lights: Vec::new(),
            light_media: b.light_media,
            caustics: None,
        };
        scene.light_media.resize(scene.lights.len(), None);
        // Each emissive grid medium is a light, sampled by its emission distribution.
        scene.medium_lights = vec![None; scene.media.len()];
        for (i, m) in scene.media.iter().enumerate() {
            if let Medium::Grid(g) = m
                && g.emission_distribution.is_some()
            {
                scene.medium_lights[i] = Some(scene.lights.len() as u32);
                scene.lights.push(Light::Medium {
                    medium: i as u32,
                    power: g.emitted_power(),
                });
            }
        }
        scene.estimate_volume_powers();
        let powers: Vec<f64> = scene
            .lights
            .iter()
            .map(|l| l.power(radius).max(0.0) as f64)
            .collect();
        scene.light_sampler = AliasTable::new(&powers);
        if desc.integrator.caustic_photons > 0 {
            let radius = if desc.integrator.caustic_radius > 0.0 {
                desc.integrator.caustic_radius
            } else {
                scene.radius / 200.0
            };
            let maps = crate::photons::CausticMaps::build(
                &scene,
                crate::photons::CausticSettings {
                    photons: desc.integrator.caustic_photons,
                    radius,
                },
            );
            scene.caustics = (!maps.is_empty()).then_some(maps);
        }
        Ok(scene)
    }

    /// Transmittance from `origin` along `dir` over `tmax`, starting in `medium`, through
    /// media and the interface surfaces that bound them; zero if any other surface blocks it.
    /// Also returns the medium the segment ends in. Grid media are crossed by ratio
    /// tracking, with numbers from `rng`.
    pub fn transmittance(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        mut medium: Option<u32>,
        rng: &mut TrackingRng,
        rays: &mut u64,
    ) -> (Color, Option<u32>) {
        if self.media.is_empty() {
            *rays += 1;
            let tr = if self.geometry.unoccluded(origin, dir, tmax) {
                Color::ONE
            } else {
                Color::ZERO
            };
            return (tr, None);
        }
        let mut tr = Color::ONE;
        let mut o = origin;
        let mut remaining = tmax;
        for _ in 0..64 {
            *rays += 1;
            let hit = self.geometry.intersect(&Ray::new(o, dir), remaining);
            let seg = hit.as_ref().map_or(remaining, |h| h.t);
            if let Some(m) = medium {
                tr *= match &self.media[m as usize] {
                    Medium::Grid(g) => g.transmittance(o, dir, seg, rng),
                    homogeneous => homogeneous.transmittance(seg),
                };
                if tr == Color::ZERO {
                    return (tr, medium);
                }
            }
            let Some(h) = hit else {
                return (tr, medium);
            };
            if self.materials[h.surface.material as usize].bsdf().is_some() {
                return (Color::ZERO, medium);
            }
            // An interface: cross it into the medium on its other side.
            if let Some(next) = h.surface.medium_towards(dir, h.ng) {
                medium = next;
            }
            o = crate::math::offset_origin(h.p, h.ng, dir);
            remaining -= h.t;
        }
        (Color::ZERO, medium)
    }

    /// Radiance leaving VolumeLight `volume` at surface point `p` (normals `ng`, `ns`,
    /// outward) in direction `w`: the interior emission along the segment that refracts
    /// into `w`, through the surface. Returns it with the number of rays traced (0 or 1).
    pub fn volume_le(&self, volume: u32, p: Vec3A, ng: Vec3A, ns: Vec3A, w: Vec3A) -> (Color, u64) {
        let emitter = &self.volumes[volume as usize];
        let cos_o = w.dot(ns);
        if cos_o <= 0.0 || w.dot(ng) <= 0.0 {
            return (Color::ZERO, 0);
        }
        let Some((inward, _)) = refract(w, ns, emitter.eta) else {
            return (Color::ZERO, 0);
        };
        let t = self.interior_length(p, ng, inward);
        (
            emitter.segment(p, inward, t) * emitter.exit_factor(cos_o),
            1,
        )
    }

    /// How far the ray from surface point `p` (geometric normal `ng`) along the inward
    /// `dir` goes before it meets a surface again (0 if it escapes: a leak).
    ///
    /// The ray starts a little way along `dir` itself rather than off along the normal:
    /// a sideways offset would change a grazing chord's length by far more than the offset.
    fn interior_length(&self, p: Vec3A, ng: Vec3A, dir: Vec3A) -> f32 {
        let eps = 2e-4 * (1.0 + p.abs().max_element());
        let step = eps / dir.dot(ng).abs().max(0.05);
        self.geometry
            .hit_distance(&Ray::new(p + dir * step, dir), f32::INFINITY)
            .map_or(0.0, |t| t + step)
    }

    /// Samples light `index` from `p`, evaluating VolumeLights' radiance, which needs
    /// the scene; returns the sample and the rays traced.
    pub fn sample_light(
        &self,
        index: usize,
        p: Vec3A,
        u: glam::Vec2,
    ) -> (Option<LightSample>, u64) {
        match &self.lights[index] {
            Light::VolumeTriangle {
                p: v,
                n,
                area,
                tri,
                volume,
                ..
            } => {
                let Some((mut ls, b)) = sample_triangle_point(v, *n, *area, p, u) else {
                    return (None, 0);
                };
                let (q, ng, ns) = self.geometry.surface_point(*tri, b);
                let (le, rays) = self.volume_le(*volume, q, ng, ns, -ls.wi);
                ls.radiance = le;
                ((le != Color::ZERO).then_some(ls), rays)
            }
            Light::VolumeSphere {
                center,
                radius,
                volume,
                ..
            } => {
                let Some(mut ls) = sample_sphere_point(*center, *radius, p, u) else {
                    return (None, 0);
                };
                let q = *center + ls.n * *radius;
                let (le, rays) = self.volume_le(*volume, q, ls.n, ls.n, -ls.wi);
                ls.radiance = le;
                ((le != Color::ZERO).then_some(ls), rays)
            }
            Light::Medium { medium, .. } => {
                let Medium::Grid(g) = &self.media[*medium as usize] else {
                    return (None, 0);
                };
                // Three numbers pick the voxel: two from the sampler, one (and the point
                // within the voxel) from a generator seeded by them.
                let mut rng = TrackingRng::from_values(&[u.x, u.y], 1);
                let Some((q, pdf_volume)) = g.sample_emission([u.x, u.y, rng.next_f32()], &mut rng)
                else {
                    return (None, 0);
                };
                let d = q - p;
                let dist2 = d.length_squared();
                let source = g.source(g.to_box(q));
                if dist2 == 0.0 || source == Color::ZERO {
                    return (None, 0);
                }
                let distance = dist2.sqrt();
                // Per unit volume to per unit solid angle and length: dV = r^2 dw dt.
                (
                    Some(LightSample {
                        radiance: source,
                        wi: d / distance,
                        pdf: pdf_volume * dist2,
                        distance,
                        n: Vec3A::ZERO,
                        delta: false,
                    }),
                    0,
                )
            }
            light => (light.sample(p, u), 0),
        }
    }

    /// Seed 000's power estimate for each VolumeLight face (or sphere): the interior
    /// radiance averaged over `powersamples` cosine-distributed inward segments from
    /// uniform points on it, times its area and pi. Each face draws its own Sobol points,
    /// so the estimates do not depend on the thread count.
    fn estimate_volume_powers(&mut self) {
        let estimates = self.volume_power_estimates(VOLUME_POWER_SEED);
        for (light, estimate) in self.lights.iter_mut().zip(estimates) {
            if let (
                Light::VolumeTriangle { power, .. } | Light::VolumeSphere { power, .. },
                Some(e),
            ) = (light, estimate)
            {
                *power = e;
            }
        }
    }

    /// The power estimate of every VolumeLight face (None for other lights), drawn with
    /// `seed`; the scene uses [`VOLUME_POWER_SEED`].
    ///
    /// Seed 000's estimate: the interior radiance averaged over `powersamples` segments
    /// from uniform points on the face in cosine-weighted inward directions, times the
    /// face's area and pi (exitance times area). The points come from each face's own
    /// Owen-scrambled Sobol sequence, which measured ten times steadier per face than
    /// reusing the segments' far ends as samples of the faces they land on (a trick that
    /// halves the rays but loses the stratification).
    pub fn volume_power_estimates(&self, seed: u32) -> Vec<Option<f32>> {
        self.lights
            .par_iter()
            .enumerate()
            .map(|(i, light)| match light {
                Light::VolumeTriangle {
                    p, n, area, volume, ..
                } => Some(self.face_power(i as u32, *volume, seed, *area, |u| {
                    let b = crate::sampling::uniform_triangle(u);
                    (p[0] * b[0] + p[1] * b[1] + p[2] * b[2], *n)
                })),
                Light::VolumeSphere {
                    center,
                    radius,
                    volume,
                    ..
                } => {
                    let area = 4.0 * std::f32::consts::PI * radius * radius;
                    Some(self.face_power(i as u32, *volume, seed, area, |u| {
                        let n = crate::sampling::uniform_sphere(u);
                        (*center + n * *radius, n)
                    }))
                }
                _ => None,
            })
            .collect()
    }

    /// One face's power; `point` maps a 2D sample to a point on the face and its outward normal.
    fn face_power(
        &self,
        light: u32,
        volume: u32,
        seed: u32,
        area: f32,
        point: impl Fn(glam::Vec2) -> (Vec3A, Vec3A),
    ) -> f32 {
        let emitter = &self.volumes[volume as usize];
        let samples = emitter
            .power_samples
            .min(crate::sampler::MAX_SAMPLES_PER_PIXEL);
        let mut sum = 0.0f64;
        for i in 0..samples {
            let mut s = PixelSampler::new(light, volume, i, seed);
            let (q, n) = point(s.get_2d());
            let dir = Frame::from_z(-n).to_world(cosine_hemisphere(s.get_2d()));
            let t = self.interior_length(q, n, dir);
            sum += luminance(emitter.segment(q, dir, t)) as f64;
        }
        (sum / samples.max(1) as f64) as f32 * area * std::f32::consts::PI
    }
}
