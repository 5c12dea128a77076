//! VolumeLights' interiors: the closed shape's material made the boundary the interior is
//! seen through, and the grid placed over the shape's object-space box.

use super::quadric::revolution_is_closed;
use super::{BuildError, Builder};
use crate::lights::VolumeInterior;
use crate::materials::{DielectricMaterial, Material, Model, Perturbation, RoughnessTexture};
use crate::math::rgb;
use crate::media::SampledGrid;
use glam::{Affine3A, DMat4};
use kiln_scene::{ShapeDesc, ShapeKind, VolumeLightDesc};

impl Builder {
    /// Registers a VolumeLight's interior; returns the material its surface uses and its index.
    pub(super) fn add_volume(
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
                    dispersion: None,
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
}
