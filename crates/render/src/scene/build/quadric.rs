//! Spheres, disks, cylinders, surfaces of revolution and bilinear patches: whole spheres
//! under similarity transforms in world space, every other quadric in its object space.

use super::{BuildError, Builder, WORLD_LIMIT_TEXT, power_scale, within_world_limit};
use crate::lights::EmissionImage;
use crate::lights::{Light, QuadricLight, SphereLight, VolumeQuadricLight, VolumeSphereLight};
use crate::math::rgb;
use crate::shapes::sphere::Rotation;
use crate::shapes::{Quadric, QuadricShape, Sphere, SurfaceInfo};
use glam::{DMat4, Vec3A};
use kiln_scene::{AreaLightDesc, ShapeDesc};
use std::sync::Arc;

/// Whether a surface of revolution encloses a volume: swept all the way round, and its
/// contour either closed or running from the axis back to the axis.
pub(super) fn revolution_is_closed(r: &kiln_scene::RevolutionDesc) -> bool {
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

impl Builder {
    /// A sphere in world space (uniform scales only); one light if it emits.
    /// A whole sphere under a similarity transform (uniform scale `scale`): in world space,
    /// sampled by its visible cone.
    pub(super) fn add_sphere(
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
        // The object's axes in the world, without the scale: the sphere is parametrised in
        // its object space, as pbrt-v4 does.
        let rotation = Rotation::from_columns(
            [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z]
                .map(|a| Vec3A::from((to_world.transform_vector3(a) / scale).as_vec3())),
        );
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
            spectrum,
            ..
        }) = &shape.area_light
        {
            debug_assert!(image.is_none(), "spheres with emission images are quadrics");
            let spectrum = self.light_spectrum(spectrum);
            self.note_area_light(media, &spectrum);
            // pbrt-v4's "power" divides by the object-space area, whatever the transform.
            let area = 4.0 * std::f32::consts::PI * (radius * radius) as f32;
            let (alpha, invisible) = self.light_alpha(surface(None).alpha);
            self.lights.push(Light::Sphere(SphereLight {
                center: center.as_vec3().into(),
                radius: world_radius,
                radiance: rgb(*radiance) * power_scale(*power, area, *two_sided, 1.0),
                two_sided: *two_sided,
                inward: flip,
                alpha,
                invisible,
                rotation,
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
            rotation,
            surface: surface(light),
            flip,
        });
        Ok(())
    }

    /// A disk, a cylinder, or a sphere that is partial or under a transform other than a
    /// similarity, intersected in its object space.
    pub(super) fn add_quadric(
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
    pub(super) fn add_revolution(
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
    pub(super) fn add_oriented_quadric(
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
            spectrum,
            ..
        }) = &shape.area_light
        {
            let image = image.clone().map(|i| Arc::new(EmissionImage::new(i)));
            let luminance = image.as_ref().map_or(1.0, |i| i.mean_luminance());
            let spectrum = self.light_spectrum(spectrum);
            self.note_area_light(surface.media, &spectrum);
            let (alpha, invisible) = self.light_alpha(surface.alpha);
            self.lights.push(Light::Quadric(QuadricLight {
                quadric: self.prims.quadrics.len() as u32,
                // pbrt-v4's "power" divides by the object-space area, whatever the transform.
                radiance: rgb(*radiance) * power_scale(*power, power_area, *two_sided, luminance),
                two_sided: *two_sided,
                area: quadric.world_area(),
                alpha,
                invisible,
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
