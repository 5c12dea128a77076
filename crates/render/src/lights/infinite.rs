//! Lights at infinity: uniform skies, environment maps and domes. Rays that escape the
//! scene collect their radiance ([`Light::infinite_le`](super::Light::infinite_le)).

use super::LightSample;
use crate::math::{Color, Frame, luminance};
use crate::sampling::{
    Distribution2D, equal_area_sphere_to_square, equal_area_square_to_sphere, uniform_hemisphere,
    uniform_sphere,
};
use glam::{Affine3A, Vec2, Vec3A};
use std::f32::consts::PI;

/// Constant radiance from every direction.
#[derive(Debug, Clone)]
pub struct UniformInfiniteLight {
    pub radiance: Color,
}

impl UniformInfiniteLight {
    pub fn power(&self, scene_radius: f32) -> f32 {
        4.0 * PI * disk(scene_radius) * luminance(self.radiance)
    }

    pub fn sample(&self, u: Vec2) -> Option<LightSample> {
        Some(LightSample::at_infinity(
            self.radiance,
            uniform_sphere(u),
            1.0 / (4.0 * PI),
        ))
    }

    pub fn pdf(&self) -> f32 {
        1.0 / (4.0 * PI)
    }
}

/// Constant radiance from the hemisphere around `frame.z` only.
#[derive(Debug, Clone)]
pub struct DomeLight {
    pub frame: Frame,
    pub radiance: Color,
}

impl DomeLight {
    pub fn power(&self, scene_radius: f32) -> f32 {
        2.0 * PI * disk(scene_radius) * luminance(self.radiance)
    }

    pub fn le(&self, w: Vec3A) -> Color {
        if w.dot(self.frame.z) > 0.0 {
            self.radiance
        } else {
            Color::ZERO
        }
    }

    pub fn sample(&self, u: Vec2) -> Option<LightSample> {
        Some(LightSample::at_infinity(
            self.radiance,
            self.frame.to_world(uniform_hemisphere(u)),
            1.0 / (2.0 * PI),
        ))
    }

    pub fn pdf(&self, wi: Vec3A) -> f32 {
        if wi.dot(self.frame.z) > 0.0 {
            1.0 / (2.0 * PI)
        } else {
            0.0
        }
    }
}

/// The area of a disk as wide as the scene: what a light at infinity shines on.
fn disk(scene_radius: f32) -> f32 {
    PI * scene_radius * scene_radius
}

/// An environment map in the equal-area octahedral layout or lat-long, importance-sampled
/// by its luminance.
#[derive(Debug, Clone)]
pub struct ImageInfiniteLight {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Color>,
    pub equal_area: bool,
    pub light_to_world: Affine3A,
    pub world_to_light: Affine3A,
    pub distribution: Distribution2D,
    /// pbrt-v4's portal: light arrives only through this window.
    pub portal: Option<Portal>,
}

/// A window onto an environment map (pbrt-v4's "portal"): a world-space rectangle with
/// corner `p0` and edges `e1` (to p1) and `e3` (to p3); light from the map reaches a point
/// only along rays through it heading out along its normal `n` = ê3 × ê1.
#[derive(Debug, Clone, Copy)]
pub struct Portal {
    p0: Vec3A,
    e1: Vec3A,
    e3: Vec3A,
    n: Vec3A,
    area: f32,
}

impl Portal {
    /// From its four corners, in pbrt-v4's order.
    pub fn new(corners: [Vec3A; 4]) -> Portal {
        let (e1, e3) = (corners[1] - corners[0], corners[3] - corners[0]);
        Portal {
            p0: corners[0],
            e1,
            e3,
            n: e3
                .normalize_or_zero()
                .cross(e1.normalize_or_zero())
                .normalize_or_zero(),
            area: e1.cross(e3).length(),
        }
    }

    /// The distance along the ray from `o` in unit direction `w` to the window, if the ray
    /// goes out through it.
    fn crossing(&self, o: Vec3A, w: Vec3A) -> Option<f32> {
        let wn = w.dot(self.n);
        if wn <= 0.0 {
            return None;
        }
        let t = (self.p0 - o).dot(self.n) / wn;
        if t <= 0.0 || !t.is_finite() {
            return None;
        }
        let d = o + w * t - self.p0;
        let (a, b) = (
            d.dot(self.e1) / self.e1.length_squared(),
            d.dot(self.e3) / self.e3.length_squared(),
        );
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
    }

    /// The solid-angle density of sampling the window uniformly by area from `o`, towards
    /// unit `w` crossing it at distance `t`.
    fn pdf(&self, w: Vec3A, t: f32) -> f32 {
        let cos = w.dot(self.n).abs();
        if cos == 0.0 || self.area == 0.0 {
            0.0
        } else {
            t * t / (self.area * cos)
        }
    }
}

impl ImageInfiniteLight {
    pub fn new(
        width: usize,
        height: usize,
        pixels: Vec<Color>,
        equal_area: bool,
        light_to_world: Affine3A,
        portal: Option<Portal>,
    ) -> ImageInfiniteLight {
        let mut light = ImageInfiniteLight {
            width,
            height,
            distribution: Distribution2D::new(&[1.0], 1, 1),
            pixels,
            equal_area,
            light_to_world,
            world_to_light: light_to_world.inverse(),
            portal,
        };
        let mut func = Vec::with_capacity(width * height);
        for y in 0..height {
            // Lat-long rows near the poles cover less solid angle.
            let row_weight = if equal_area {
                1.0
            } else {
                libm::sinf(PI * (y as f32 + 0.5) / height as f32)
            };
            for x in 0..width {
                func.push(luminance(light.pixels[y * width + x]).max(0.0) * row_weight);
            }
        }
        light.distribution = Distribution2D::new(&func, width, height);
        light
    }

    fn lookup(&self, uv: Vec2) -> Color {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.pixels[y * self.width + x]
    }

    fn dir_to_uv(&self, w: Vec3A) -> Vec2 {
        let wl = self.world_to_light.transform_vector3a(w).normalize();
        if self.equal_area {
            equal_area_sphere_to_square(wl)
        } else {
            let theta = libm::acosf(wl.z.clamp(-1.0, 1.0));
            let phi = libm::atan2f(wl.y, wl.x).rem_euclid(2.0 * PI);
            Vec2::new(phi / (2.0 * PI), theta / PI)
        }
    }

    fn uv_to_dir(&self, uv: Vec2) -> (Vec3A, f32) {
        let (wl, jacobian) = if self.equal_area {
            (equal_area_square_to_sphere(uv), 4.0 * PI)
        } else {
            let theta = uv.y * PI;
            let phi = uv.x * 2.0 * PI;
            let s = libm::sinf(theta);
            (
                Vec3A::new(s * libm::cosf(phi), s * libm::sinf(phi), libm::cosf(theta)),
                2.0 * PI * PI * s,
            )
        };
        (
            self.light_to_world.transform_vector3a(wl).normalize(),
            jacobian,
        )
    }

    pub fn power(&self, scene_radius: f32) -> f32 {
        let mean: f32 = self.pixels.iter().map(|p| luminance(*p)).sum::<f32>()
            / self.pixels.len().max(1) as f32;
        4.0 * PI * disk(scene_radius) * mean
    }

    /// A direction from `p` towards the map: by the map's own distribution, or through a
    /// portal uniformly by its area.
    pub fn sample(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        if let Some(portal) = &self.portal {
            let q = portal.p0 + portal.e1 * u.x + portal.e3 * u.y;
            let d = q - p;
            let t = d.length();
            if t == 0.0 {
                return None;
            }
            let wi = d / t;
            if wi.dot(portal.n) <= 0.0 {
                return None;
            }
            let pdf = portal.pdf(wi, t);
            let radiance = self.lookup(self.dir_to_uv(wi));
            return (pdf > 0.0 && radiance != Color::ZERO)
                .then(|| LightSample::at_infinity(radiance, wi, pdf));
        }
        let (uv, pdf_uv) = self.distribution.sample(u);
        if pdf_uv == 0.0 {
            return None;
        }
        let (wi, jacobian) = self.uv_to_dir(uv);
        if jacobian == 0.0 {
            return None;
        }
        Some(LightSample::at_infinity(
            self.lookup(uv),
            wi,
            pdf_uv / jacobian,
        ))
    }

    /// A direction towards the map by its own distribution, whatever the portal (photons
    /// leave the map from outside the scene, where a portal does not choose directions).
    pub fn sample_direction(&self, u: Vec2) -> Option<LightSample> {
        let (uv, pdf_uv) = self.distribution.sample(u);
        let (wi, jacobian) = self.uv_to_dir(uv);
        (pdf_uv > 0.0 && jacobian > 0.0)
            .then(|| LightSample::at_infinity(self.lookup(uv), wi, pdf_uv / jacobian))
    }

    /// The radiance along the ray from `origin` in direction `w` that left the scene.
    pub fn le(&self, origin: Vec3A, w: Vec3A) -> Color {
        if let Some(portal) = &self.portal
            && portal.crossing(origin, w).is_none()
        {
            return Color::ZERO;
        }
        self.lookup(self.dir_to_uv(w))
    }

    /// The density with which [`ImageInfiniteLight::sample`] from `p` gives `w`.
    pub fn pdf(&self, p: Vec3A, w: Vec3A) -> f32 {
        if let Some(portal) = &self.portal {
            return portal.crossing(p, w).map_or(0.0, |t| portal.pdf(w, t));
        }
        let uv = self.dir_to_uv(w);
        let jacobian = if self.equal_area {
            4.0 * PI
        } else {
            2.0 * PI * PI * libm::sinf(uv.y * PI)
        };
        if jacobian == 0.0 {
            0.0
        } else {
            self.distribution.pdf(uv) / jacobian
        }
    }
}
