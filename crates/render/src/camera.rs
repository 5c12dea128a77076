//! Cameras (pbrt's perspective and orthographic, with a thin lens) and pixel filters.

use crate::math::Ray;
use crate::sampling::{Distribution1D, concentric_disk};
use glam::{Affine3A, Vec2, Vec3A};
use kiln_scene::{CameraDesc, FilterDesc, FilterKind, Projection};

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

/// A pixel filter sampled by importance: each sample lands inside its own pixel's
/// filter support and carries a weight, so no sample writes to another pixel.
#[derive(Debug, Clone)]
pub struct Filter {
    radius: Vec2,
    kind: FilterSampling,
}

#[derive(Debug, Clone)]
enum FilterSampling {
    Box,
    Triangle,
    /// Tabulated separable filter: per-axis distributions over [-r, r].
    Tabulated {
        x: Distribution1D,
        y: Distribution1D,
        sigma: f32,
    },
}

impl Filter {
    pub fn new(desc: &FilterDesc) -> Filter {
        let radius = Vec2::new(desc.radius[0] as f32, desc.radius[1] as f32);
        let kind = match desc.kind {
            FilterKind::Box => FilterSampling::Box,
            FilterKind::Triangle => FilterSampling::Triangle,
            FilterKind::Gaussian { sigma } => {
                let sigma = sigma as f32;
                let table = |r: f32| {
                    let n = 64;
                    let f: Vec<f32> = (0..n)
                        .map(|i| {
                            gaussian_1d(((i as f32 + 0.5) / n as f32 * 2.0 - 1.0) * r, sigma, r)
                        })
                        .collect();
                    Distribution1D::new(&f)
                };
                FilterSampling::Tabulated {
                    x: table(radius.x),
                    y: table(radius.y),
                    sigma,
                }
            }
        };
        Filter { radius, kind }
    }

    /// Returns the offset from the pixel centre and the sample's weight.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        match &self.kind {
            FilterSampling::Box => ((2.0 * u - Vec2::ONE) * self.radius, 1.0),
            FilterSampling::Triangle => (
                Vec2::new(
                    sample_tent(u.x, self.radius.x),
                    sample_tent(u.y, self.radius.y),
                ),
                1.0,
            ),
            FilterSampling::Tabulated { x, y, sigma } => {
                let (sx, px, _) = x.sample(u.x);
                let (sy, py, _) = y.sample(u.y);
                let offset = Vec2::new(
                    (2.0 * sx - 1.0) * self.radius.x,
                    (2.0 * sy - 1.0) * self.radius.y,
                );
                let f = gaussian_1d(offset.x, *sigma, self.radius.x)
                    * gaussian_1d(offset.y, *sigma, self.radius.y);
                // pdf over the offset, normalised by the tabulated integrals.
                let pdf = px * py / (4.0 * self.radius.x * self.radius.y);
                let norm = x.integral() * y.integral() * 4.0 * self.radius.x * self.radius.y;
                (offset, if pdf > 0.0 { f / (pdf * norm) } else { 0.0 })
            }
        }
    }
}

fn gaussian_1d(x: f32, sigma: f32, radius: f32) -> f32 {
    let g = |v: f32| (-v * v / (2.0 * sigma * sigma)).exp();
    (g(x) - g(radius)).max(0.0)
}

/// Inverts the CDF of a tent of half-width `r`.
fn sample_tent(u: f32, r: f32) -> f32 {
    if u < 0.5 {
        let v = 2.0 * u;
        r * (v.sqrt() - 1.0)
    } else {
        let v = 2.0 * u - 1.0;
        r * (1.0 - (1.0 - v).sqrt())
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

    #[test]
    fn filter_offsets_stay_inside_the_radius() {
        for kind in [
            FilterKind::Box,
            FilterKind::Triangle,
            FilterKind::Gaussian { sigma: 0.5 },
        ] {
            let f = Filter::new(&FilterDesc {
                kind,
                radius: [1.5, 1.5],
                loc: Loc::synthetic("t"),
            });
            for i in 0..256 {
                let u = Vec2::new((i % 16) as f32 / 16.0 + 0.01, (i / 16) as f32 / 16.0 + 0.02);
                let (o, w) = f.sample(u);
                assert!(o.x.abs() <= 1.5 && o.y.abs() <= 1.5, "{kind:?} {o}");
                assert!(w > 0.0 && w.is_finite());
            }
        }
    }

    #[test]
    fn tent_sampling_inverts_its_cdf() {
        assert!((sample_tent(0.5, 2.0)).abs() < 1e-6);
        assert!((sample_tent(0.125, 1.0) + 0.5).abs() < 1e-6);
        assert!((sample_tent(0.875, 1.0) - 0.5).abs() < 1e-6);
    }
}
