//! Projection lights (pbrt-v4's "projection"): a point light that casts an image, like a
//! slide projector, through a frustum along its +z; the intensity towards a direction is
//! the image's RGB where the direction crosses the image plane (nearest pixel), times the
//! light's scale, and nothing outside the frame or behind.

use super::LightSample;
use crate::math::Color;
use glam::{Mat3A, Vec3A};
use kiln_scene::ImageRgb;
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct ProjectionLight {
    pub position: Vec3A,
    /// World directions into the light's space.
    pub to_light: Mat3A,
    pub scale: f32,
    /// 1 / tan(fov / 2).
    pub inv_tan: f32,
    /// The image's frame on the plane z = 1 / tan(fov / 2): [xmin, xmax, ymin, ymax].
    pub screen: [f32; 4],
    pub image: Arc<ImageRgb>,
    /// Emitted power (luminance), for choosing lights.
    pub phi: f32,
}

impl ProjectionLight {
    pub fn new(
        position: Vec3A,
        to_light: Mat3A,
        scale: f32,
        fov_degrees: f64,
        image: Arc<ImageRgb>,
    ) -> ProjectionLight {
        let aspect = image.width as f32 / image.height as f32;
        let screen = if aspect > 1.0 {
            [-aspect, aspect, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / aspect, 1.0 / aspect]
        };
        let tan = libm::tan(fov_degrees.to_radians() / 2.0) as f32;
        let phi = scale * kiln_scene::photometry::projection_power(&image, fov_degrees) as f32;
        ProjectionLight {
            position,
            to_light,
            scale,
            inv_tan: 1.0 / tan,
            screen,
            image,
            phi,
        }
    }

    /// The intensity towards light-space direction `w`.
    fn intensity(&self, w: Vec3A) -> Color {
        if w.z < 1e-3 {
            return Color::ZERO;
        }
        let (sx, sy) = (w.x / w.z * self.inv_tan, w.y / w.z * self.inv_tan);
        let [x0, x1, y0, y1] = self.screen;
        if !(sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1) {
            return Color::ZERO;
        }
        let (u, v) = ((sx - x0) / (x1 - x0), (sy - y0) / (y1 - y0));
        let (iw, ih) = (self.image.width, self.image.height);
        let x = ((u * iw as f32) as u32).min(iw - 1);
        let y = ((v * ih as f32) as u32).min(ih - 1);
        crate::math::rgb(self.image.pixels[(y * iw + x) as usize]).max(Color::ZERO) * self.scale
    }

    pub fn power(&self) -> f32 {
        self.phi
    }

    pub fn sample(&self, p: Vec3A) -> Option<LightSample> {
        super::shaped_point_sample(self.position, p, |w| self.intensity(self.to_light * w))
    }
}
