//! Lights: what emits, how to sample a direction towards it, and its pdf.
//!
//! Each triangle of an emitting mesh is its own light, so that the light
//! sampler can choose faces by power; the sampler is an alias table, O(1) per
//! sample whatever the number of emitters.

use crate::math::{Color, Frame, luminance};
use crate::sampling::{
    Distribution2D, uniform_cone, uniform_hemisphere, uniform_sphere, uniform_triangle,
};
use glam::{Affine3A, Vec2, Vec3A};
use std::f32::consts::PI;

#[derive(Debug, Clone)]
pub enum Light {
    Point {
        position: Vec3A,
        intensity: Color,
    },
    Spot {
        position: Vec3A,
        frame: Frame,
        intensity: Color,
        cos_start: f32,
        cos_end: f32,
    },
    /// `direction` points from the scene towards the light.
    Distant {
        direction: Vec3A,
        radiance: Color,
    },
    /// One emitting triangle; `n` is its emitting side.
    Triangle {
        p: [Vec3A; 3],
        n: Vec3A,
        area: f32,
        radiance: Color,
        two_sided: bool,
    },
    Sphere {
        center: Vec3A,
        radius: f32,
        radiance: Color,
        two_sided: bool,
        inward: bool,
    },
    /// One face of a VolumeLight mesh: sampled like a triangle light, its radiance comes
    /// from the shape's interior (volume.rs). `power` is estimated when the scene is built.
    VolumeTriangle {
        p: [Vec3A; 3],
        n: Vec3A,
        area: f32,
        tri: u32,
        volume: u32,
        power: f32,
    },
    /// A VolumeLight sphere, one light for the whole sphere.
    VolumeSphere {
        center: Vec3A,
        radius: f32,
        volume: u32,
        power: f32,
    },
    /// An emissive grid medium, sampled by its 3D emission distribution (scene.rs does it,
    /// as it needs the medium). `power` is its emitted luminance times 4 pi.
    Medium {
        medium: u32,
        power: f32,
    },
    UniformInfinite {
        radiance: Color,
    },
    ImageInfinite(Box<EnvironmentMap>),
    /// Constant radiance from the hemisphere around `frame.z` only.
    Dome {
        frame: Frame,
        radiance: Color,
    },
}

/// An environment map in the equal-area octahedral layout or lat-long.
#[derive(Debug, Clone)]
pub struct EnvironmentMap {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Color>,
    pub equal_area: bool,
    pub light_to_world: Affine3A,
    pub world_to_light: Affine3A,
    pub distribution: Distribution2D,
}

impl EnvironmentMap {
    pub fn new(
        width: usize,
        height: usize,
        pixels: Vec<Color>,
        equal_area: bool,
        light_to_world: Affine3A,
    ) -> EnvironmentMap {
        let mut func = Vec::with_capacity(width * height);
        for y in 0..height {
            // Lat-long rows near the poles cover less solid angle.
            let row_weight = if equal_area {
                1.0
            } else {
                (PI * (y as f32 + 0.5) / height as f32).sin()
            };
            for x in 0..width {
                func.push(luminance(pixels[y * width + x]).max(0.0) * row_weight);
            }
        }
        EnvironmentMap {
            width,
            height,
            distribution: Distribution2D::new(&func, width, height),
            pixels,
            equal_area,
            light_to_world,
            world_to_light: light_to_world.inverse(),
        }
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
            let theta = wl.z.clamp(-1.0, 1.0).acos();
            let phi = wl.y.atan2(wl.x).rem_euclid(2.0 * PI);
            Vec2::new(phi / (2.0 * PI), theta / PI)
        }
    }

    fn uv_to_dir(&self, uv: Vec2) -> (Vec3A, f32) {
        let (wl, jacobian) = if self.equal_area {
            (equal_area_square_to_sphere(uv), 4.0 * PI)
        } else {
            let theta = uv.y * PI;
            let phi = uv.x * 2.0 * PI;
            let s = theta.sin();
            (
                Vec3A::new(s * phi.cos(), s * phi.sin(), theta.cos()),
                2.0 * PI * PI * s,
            )
        };
        (
            self.light_to_world.transform_vector3a(wl).normalize(),
            jacobian,
        )
    }

    pub fn le(&self, w: Vec3A) -> Color {
        self.lookup(self.dir_to_uv(w))
    }

    fn pdf(&self, w: Vec3A) -> f32 {
        let uv = self.dir_to_uv(w);
        let jacobian = if self.equal_area {
            4.0 * PI
        } else {
            2.0 * PI * PI * (uv.y * PI).sin()
        };
        if jacobian == 0.0 {
            0.0
        } else {
            self.distribution.pdf(uv) / jacobian
        }
    }
}

/// Clarberg's equal-area map from the unit square to the sphere, as pbrt-v4 uses for environment maps.
pub fn equal_area_square_to_sphere(p: Vec2) -> Vec3A {
    let u = 2.0 * p.x - 1.0;
    let v = 2.0 * p.y - 1.0;
    let up = u.abs();
    let vp = v.abs();
    let signed_distance = 1.0 - (up + vp);
    let d = signed_distance.abs();
    let r = 1.0 - d;
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * PI / 4.0;
    let z = (1.0 - r * r).copysign(signed_distance);
    let cos_phi = phi.cos().copysign(u);
    let sin_phi = phi.sin().copysign(v);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3A::new(cos_phi * s, sin_phi * s, z)
}

/// The inverse of [`equal_area_square_to_sphere`].
pub fn equal_area_sphere_to_square(d: Vec3A) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = x.min(y);
    let b = if a == 0.0 { 0.0 } else { b / a };
    let mut phi = b.atan() * 2.0 / PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    u = u.copysign(d.x);
    v = v.copysign(d.y);
    Vec2::new((u + 1.0) / 2.0, (v + 1.0) / 2.0)
}

/// A sampled direction towards a light.
#[derive(Debug, Clone, Copy)]
pub struct LightSample {
    pub radiance: Color,
    pub wi: Vec3A,
    /// Solid-angle pdf (1 for delta lights).
    pub pdf: f32,
    /// Distance to the sampled point (infinite for lights at infinity).
    pub distance: f32,
    /// The sampled point's normal, for offsetting the shadow ray's far end.
    pub n: Vec3A,
    pub delta: bool,
}

impl Light {
    pub fn is_infinite(&self) -> bool {
        matches!(
            self,
            Light::UniformInfinite { .. } | Light::ImageInfinite(_) | Light::Dome { .. }
        )
    }

    /// Emitted power, used to choose lights in proportion to it.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let disk = PI * scene_radius * scene_radius;
        match self {
            Light::Point { intensity, .. } => 4.0 * PI * luminance(*intensity),
            Light::Spot {
                intensity,
                cos_start,
                cos_end,
                ..
            } => 2.0 * PI * luminance(*intensity) * (1.0 - 0.5 * (cos_start + cos_end)),
            Light::Distant { radiance, .. } => disk * luminance(*radiance),
            Light::Triangle {
                area,
                radiance,
                two_sided,
                ..
            } => PI * area * luminance(*radiance) * if *two_sided { 2.0 } else { 1.0 },
            Light::Sphere {
                radius,
                radiance,
                two_sided,
                ..
            } => {
                PI * 4.0
                    * PI
                    * radius
                    * radius
                    * luminance(*radiance)
                    * if *two_sided { 2.0 } else { 1.0 }
            }
            Light::UniformInfinite { radiance } => 4.0 * PI * disk * luminance(*radiance),
            Light::ImageInfinite(map) => {
                let mean: f32 = map.pixels.iter().map(|p| luminance(*p)).sum::<f32>()
                    / map.pixels.len().max(1) as f32;
                4.0 * PI * disk * mean
            }
            Light::Dome { radiance, .. } => 2.0 * PI * disk * luminance(*radiance),
            Light::VolumeTriangle { power, .. }
            | Light::VolumeSphere { power, .. }
            | Light::Medium { power, .. } => *power,
        }
    }

    /// Radiance leaving an area light's point with normal `n` in direction `w`.
    pub fn area_le(&self, n: Vec3A, w: Vec3A) -> Color {
        match self {
            Light::Triangle {
                radiance,
                two_sided,
                ..
            }
            | Light::Sphere {
                radiance,
                two_sided,
                ..
            } => {
                if *two_sided || n.dot(w) > 0.0 {
                    *radiance
                } else {
                    Color::ZERO
                }
            }
            _ => Color::ZERO,
        }
    }

    /// Radiance arriving along a ray that escaped the scene in direction `w`.
    pub fn infinite_le(&self, w: Vec3A) -> Color {
        match self {
            Light::UniformInfinite { radiance } => *radiance,
            Light::ImageInfinite(map) => map.le(w),
            Light::Dome { frame, radiance } => {
                if w.dot(frame.z) > 0.0 {
                    *radiance
                } else {
                    Color::ZERO
                }
            }
            _ => Color::ZERO,
        }
    }

    /// Samples a direction from `p` towards the light.
    pub fn sample(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        match self {
            Light::Point {
                position,
                intensity,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                Some(LightSample {
                    radiance: *intensity / dist2,
                    wi: d / dist,
                    pdf: 1.0,
                    distance: dist,
                    n: Vec3A::ZERO,
                    delta: true,
                })
            }
            Light::Spot {
                position,
                frame,
                intensity,
                cos_start,
                cos_end,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                let dist = dist2.sqrt();
                let wi = d / dist;
                let cos = (-wi).dot(frame.z);
                let falloff = smoothstep(*cos_end, *cos_start, cos);
                (falloff > 0.0).then(|| LightSample {
                    radiance: *intensity * falloff / dist2,
                    wi,
                    pdf: 1.0,
                    distance: dist,
                    n: Vec3A::ZERO,
                    delta: true,
                })
            }
            Light::Distant {
                direction,
                radiance,
            } => Some(LightSample {
                radiance: *radiance,
                wi: *direction,
                pdf: 1.0,
                distance: f32::INFINITY,
                n: Vec3A::ZERO,
                delta: true,
            }),
            Light::Triangle { p: v, n, area, .. } => {
                let (point, _) = sample_triangle_point(v, *n, *area, p, u)?;
                let radiance = self.area_le(*n, -point.wi);
                (radiance != Color::ZERO).then_some(point.with_radiance(radiance))
            }
            Light::Sphere {
                center,
                radius,
                inward,
                ..
            } => {
                let mut point = sample_sphere_point(*center, *radius, p, u)?;
                if *inward {
                    point.n = -point.n;
                }
                let radiance = self.area_le(point.n, -point.wi);
                (radiance != Color::ZERO).then_some(point.with_radiance(radiance))
            }
            // A VolumeLight's radiance and a medium's points need the scene:
            // Scene::sample_light samples them.
            Light::VolumeTriangle { .. } | Light::VolumeSphere { .. } | Light::Medium { .. } => {
                None
            }
            Light::UniformInfinite { radiance } => {
                let wi = uniform_sphere(u);
                Some(LightSample {
                    radiance: *radiance,
                    wi,
                    pdf: 1.0 / (4.0 * PI),
                    distance: f32::INFINITY,
                    n: Vec3A::ZERO,
                    delta: false,
                })
            }
            Light::ImageInfinite(map) => {
                let (uv, pdf_uv) = map.distribution.sample(u);
                if pdf_uv == 0.0 {
                    return None;
                }
                let (wi, jacobian) = map.uv_to_dir(uv);
                if jacobian == 0.0 {
                    return None;
                }
                Some(LightSample {
                    radiance: map.lookup(uv),
                    wi,
                    pdf: pdf_uv / jacobian,
                    distance: f32::INFINITY,
                    n: Vec3A::ZERO,
                    delta: false,
                })
            }
            Light::Dome { frame, radiance } => Some(LightSample {
                radiance: *radiance,
                wi: frame.to_world(uniform_hemisphere(u)),
                pdf: 1.0 / (2.0 * PI),
                distance: f32::INFINITY,
                n: Vec3A::ZERO,
                delta: false,
            }),
        }
    }

    /// The solid-angle pdf that [`Light::sample`] from `p` produces direction `wi`
    /// reaching the light at `q` (with normal `n`); `q` is unused for lights at infinity.
    pub fn pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        match self {
            Light::Point { .. } | Light::Spot { .. } | Light::Distant { .. } => 0.0,
            // Emission met inside a medium is weighted by the integrator, which knows the
            // medium (GridMedium::emission_pdf).
            Light::Medium { .. } => 0.0,
            Light::Triangle { area, .. } | Light::VolumeTriangle { area, .. } => {
                let dist2 = (q - p).length_squared();
                let cos_l = n.dot(wi).abs();
                if cos_l == 0.0 {
                    0.0
                } else {
                    dist2 / (cos_l * area)
                }
            }
            Light::Sphere { center, radius, .. } | Light::VolumeSphere { center, radius, .. } => {
                let dc2 = (p - *center).length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 * 1.0001 {
                    let dist2 = (q - p).length_squared();
                    let cos = n.dot(wi).abs();
                    if cos == 0.0 {
                        0.0
                    } else {
                        dist2 / (cos * 4.0 * PI * r2)
                    }
                } else {
                    let sin2_max = r2 / dc2;
                    let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                    1.0 / (2.0 * PI * (sin2_max / (1.0 + cos_max)))
                }
            }
            Light::UniformInfinite { .. } => 1.0 / (4.0 * PI),
            Light::ImageInfinite(map) => map.pdf(wi),
            Light::Dome { frame, .. } => {
                if wi.dot(frame.z) > 0.0 {
                    1.0 / (2.0 * PI)
                } else {
                    0.0
                }
            }
        }
    }
}

impl LightSample {
    fn with_radiance(mut self, radiance: Color) -> LightSample {
        self.radiance = radiance;
        self
    }
}

/// A uniform point on a triangle seen from `p`: the sample (radiance unset) and its barycentrics.
pub fn sample_triangle_point(
    v: &[Vec3A; 3],
    n: Vec3A,
    area: f32,
    p: Vec3A,
    u: Vec2,
) -> Option<(LightSample, [f32; 3])> {
    let b = uniform_triangle(u);
    let q = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
    let d = q - p;
    let dist2 = d.length_squared();
    if dist2 == 0.0 {
        return None;
    }
    let dist = dist2.sqrt();
    let wi = d / dist;
    let cos_l = n.dot(-wi).abs();
    if cos_l == 0.0 {
        return None;
    }
    let sample = LightSample {
        radiance: Color::ZERO,
        wi,
        pdf: dist2 / (cos_l * area),
        distance: dist,
        n,
        delta: false,
    };
    Some((sample, b))
}

/// A point on a sphere seen from `p` (radiance unset, `n` outward): the visible cone
/// uniformly in solid angle from outside, the area uniformly from inside.
pub fn sample_sphere_point(center: Vec3A, radius: f32, p: Vec3A, u: Vec2) -> Option<LightSample> {
    let dc2 = (p - center).length_squared();
    let r2 = radius * radius;
    let (q, pdf) = if dc2 <= r2 * 1.0001 {
        let nq = uniform_sphere(u);
        let q = center + nq * radius;
        let d = q - p;
        let dist2 = d.length_squared();
        let cos = nq.dot(-d.normalize_or_zero()).abs();
        if cos == 0.0 || dist2 == 0.0 {
            return None;
        }
        (q, dist2 / (cos * 4.0 * PI * r2))
    } else {
        let dc = dc2.sqrt();
        let sin2_max = r2 / dc2;
        let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
        let one_minus_cos = sin2_max / (1.0 + cos_max);
        let frame = Frame::from_z((center - p) / dc);
        let w = frame.to_world(uniform_cone(u, cos_max));
        // Where that direction meets the sphere (the tangent point if rounding misses it).
        let b = (center - p).dot(w);
        let disc = (b * b - (dc2 - r2)).max(0.0);
        let t = b - disc.sqrt();
        (p + w * t, 1.0 / (2.0 * PI * one_minus_cos))
    };
    let d = q - p;
    let dist = d.length();
    if dist == 0.0 {
        return None;
    }
    Some(LightSample {
        radiance: Color::ZERO,
        wi: d / dist,
        pdf,
        distance: dist,
        n: (q - center).normalize(),
        delta: false,
    })
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::PixelSampler;

    #[test]
    fn equal_area_map_round_trips() {
        for i in 0..400 {
            let uv = Vec2::new(
                (i % 20) as f32 / 20.0 + 0.025,
                (i / 20) as f32 / 20.0 + 0.025,
            );
            let d = equal_area_square_to_sphere(uv);
            assert!((d.length() - 1.0).abs() < 1e-4);
            let back = equal_area_sphere_to_square(d);
            assert!((back - uv).length() < 1e-4, "{uv} -> {d} -> {back}");
        }
    }

    /// The pdf a light reports for a direction must be the density its sampler produces:
    /// integrating 1/pdf over samples estimates the subtended solid angle.
    #[test]
    fn sphere_and_triangle_pdfs_integrate_to_their_solid_angle() {
        let sphere = Light::Sphere {
            center: Vec3A::new(0.0, 0.0, 5.0),
            radius: 1.0,
            radiance: Color::ONE,
            two_sided: false,
            inward: false,
        };
        let n = 4096;
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = PixelSampler::new(0, 0, i, 2);
            let ls = sphere
                .sample(Vec3A::ZERO, Vec2::new(s.value(0), s.value(1)))
                .unwrap();
            let q = ls.wi * ls.distance;
            let pdf = sphere.pdf(Vec3A::ZERO, ls.wi, q, ls.n);
            assert!((pdf - ls.pdf).abs() < 1e-3 * pdf);
            sum += 1.0 / ls.pdf as f64;
        }
        let expected = 2.0 * std::f64::consts::PI * (1.0 - (1.0f64 - 1.0 / 25.0).sqrt());
        assert!(((sum / n as f64) - expected).abs() < 1e-4 * expected.max(1.0));

        let tri = Light::Triangle {
            p: [
                Vec3A::new(-1.0, -1.0, 2.0),
                Vec3A::new(1.0, -1.0, 2.0),
                Vec3A::new(0.0, 1.0, 2.0),
            ],
            n: -Vec3A::Z,
            area: 2.0,
            radiance: Color::ONE,
            two_sided: false,
        };
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = PixelSampler::new(1, 0, i, 2);
            let ls = tri
                .sample(Vec3A::ZERO, Vec2::new(s.value(0), s.value(1)))
                .unwrap();
            sum += 1.0 / ls.pdf as f64;
        }
        // Solid angle of the triangle by a fine numerical integral over its area.
        let mut omega = 0.0f64;
        let m = 400;
        for i in 0..m {
            for j in 0..m {
                let u = Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                let b = uniform_triangle(u);
                let q = Vec3A::new(-1.0, -1.0, 2.0) * b[0]
                    + Vec3A::new(1.0, -1.0, 2.0) * b[1]
                    + Vec3A::new(0.0, 1.0, 2.0) * b[2];
                omega += (2.0 * q.z / q.length().powi(3)) as f64 / (m * m) as f64;
            }
        }
        assert!(
            ((sum / n as f64) - omega).abs() < 0.01 * omega,
            "{} vs {omega}",
            sum / n as f64
        );
    }

    #[test]
    fn one_sided_area_lights_emit_on_their_normal_side() {
        let tri = Light::Triangle {
            p: [Vec3A::ZERO, Vec3A::X, Vec3A::Y],
            n: Vec3A::Z,
            area: 0.5,
            radiance: Color::ONE,
            two_sided: false,
        };
        assert_eq!(tri.area_le(Vec3A::Z, Vec3A::Z), Color::ONE);
        assert_eq!(tri.area_le(Vec3A::Z, -Vec3A::Z), Color::ZERO);
        assert!(
            tri.sample(Vec3A::new(0.2, 0.2, -1.0), Vec2::splat(0.3))
                .is_none()
        );
    }
}
