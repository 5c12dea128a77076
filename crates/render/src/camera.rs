//! Cameras: pbrt's perspective and orthographic projections, with a thin lens for depth of
//! field. A camera turns a film position and a lens sample into a ray.

use crate::math::Ray;
use crate::sampling::concentric_disk;
use glam::{Affine3A, Vec2, Vec3A};
use kiln_scene::{CameraDesc, Projection};

#[derive(Debug, Clone)]
pub struct Camera {
    camera_to_world: Affine3A,
    orthographic: bool,
    /// tan(fov / 2) for perspective, 1 for orthographic.
    scale: f32,
    screen: [f32; 4],
    resolution: Vec2,
    lens_radius: f32,
    focal_distance: f32,
}

impl Camera {
    pub fn new(desc: &CameraDesc, xres: u32, yres: u32) -> Camera {
        let aspect = xres as f64 / yres as f64;
        let screen = desc.screen_window.unwrap_or(if aspect > 1.0 {
            [-aspect, aspect, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / aspect, 1.0 / aspect]
        });
        let (orthographic, scale) = match desc.projection {
            Projection::Perspective { fov_degrees } => {
                (false, (fov_degrees.to_radians() / 2.0).tan() as f32)
            }
            Projection::Orthographic => (true, 1.0),
        };
        Camera {
            camera_to_world: Affine3A::from_mat4(desc.camera_to_world.as_mat4()),
            orthographic,
            scale,
            screen: screen.map(|v| v as f32),
            resolution: Vec2::new(xres as f32, yres as f32),
            lens_radius: desc.lens_radius as f32,
            focal_distance: desc.focal_distance as f32,
        }
    }

    /// The world-space ray through continuous raster position `film` (pixels, y down), lens sample `lens`.
    pub fn generate_ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let [x0, x1, y0, y1] = self.screen;
        let sx = x0 + film.x / self.resolution.x * (x1 - x0);
        let sy = y1 - film.y / self.resolution.y * (y1 - y0);
        let (mut origin, mut dir) = if self.orthographic {
            (Vec3A::new(sx, sy, 0.0), Vec3A::Z)
        } else {
            (
                Vec3A::ZERO,
                Vec3A::new(sx * self.scale, sy * self.scale, 1.0).normalize(),
            )
        };
        if self.lens_radius > 0.0 {
            let p_lens = self.lens_radius * concentric_disk(lens);
            let ft = self.focal_distance / dir.z;
            let p_focus = origin + dir * ft;
            origin += Vec3A::new(p_lens.x, p_lens.y, 0.0);
            dir = (p_focus - origin).normalize();
        }
        Ray::new(
            self.camera_to_world.transform_point3a(origin),
            self.camera_to_world.transform_vector3a(dir).normalize(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;
    use kiln_scene::Loc;

    #[test]
    fn centre_pixel_looks_down_the_view_axis() {
        let desc = CameraDesc {
            projection: Projection::Perspective { fov_degrees: 90.0 },
            camera_to_world: DMat4::from_translation(glam::DVec3::new(1.0, 2.0, 3.0)),
            lens_radius: 0.0,
            focal_distance: 1e6,
            screen_window: None,
            loc: Loc::synthetic("t"),
        };
        let cam = Camera::new(&desc, 100, 50);
        let r = cam.generate_ray(Vec2::new(50.0, 25.0), Vec2::splat(0.5));
        assert!((r.dir - Vec3A::Z).length() < 1e-6);
        assert!((r.origin - Vec3A::new(1.0, 2.0, 3.0)).length() < 1e-6);
        // fov applies to the shorter (vertical) axis: the top edge is 45 degrees up.
        let top = cam.generate_ray(Vec2::new(50.0, 0.0), Vec2::splat(0.5));
        assert!((top.dir.y - top.dir.z).abs() < 1e-5 && top.dir.y > 0.0);
        // Raster x grows to the right, which is +x in camera space.
        let right = cam.generate_ray(Vec2::new(100.0, 25.0), Vec2::splat(0.5));
        assert!(right.dir.x > 0.0);
    }
}
