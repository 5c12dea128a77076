//! Seed 000's VolumeLight: emission inside a shape, seen through its dielectric surface.
//!
//! The radiance leaving surface point p in direction w is the emission integrated along
//! the interior segment that refracts into w at p, times the Fresnel transmittance and
//! the 1/eta^2 by which radiance shrinks on leaving a denser medium. The integrator
//! evaluates it at hits (like an area light's emission) and for next-event estimation,
//! and adds the emission of interior segments that paths travel after reflecting inside.

use crate::bsdf::fresnel_dielectric;
use crate::math::Color;
use glam::{Affine3A, Vec3A};
use kiln_scene::VoxelGrid;

/// A voxel grid of multipliers over [0,1]^3, trilinear between voxel centres.
#[derive(Debug, Clone)]
pub struct Grid {
    nx: usize,
    ny: usize,
    nz: usize,
    values: Vec<f32>,
}

impl Grid {
    pub fn new(g: &VoxelGrid) -> Grid {
        Grid {
            nx: g.nx,
            ny: g.ny,
            nz: g.nz,
            values: g.values.clone(),
        }
    }

    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.values[(z * self.ny + y) * self.nx + x]
    }

    /// The value at `g` in grid space ([0,1]^3 is the bounding box); voxel centres hold
    /// their values exactly, points between interpolate trilinearly, points beyond the
    /// outermost centres take the nearest centre's value along that axis.
    pub fn eval(&self, g: Vec3A) -> f32 {
        let axis = |v: f32, n: usize| -> (usize, usize, f32) {
            let c = (v * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i0 = (c.floor() as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            (i0, i1, c - i0 as f32)
        };
        let (x0, x1, fx) = axis(g.x, self.nx);
        let (y0, y1, fy) = axis(g.y, self.ny);
        let (z0, z1, fz) = axis(g.z, self.nz);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(self.at(x0, y0, z0), self.at(x1, y0, z0), fx);
        let c10 = lerp(self.at(x0, y1, z0), self.at(x1, y1, z0), fx);
        let c01 = lerp(self.at(x0, y0, z1), self.at(x1, y0, z1), fx);
        let c11 = lerp(self.at(x0, y1, z1), self.at(x1, y1, z1), fx);
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }
}

/// One VolumeLight shape's interior.
#[derive(Debug, Clone)]
pub struct VolumeEmitter {
    /// Emitted radiance per unit length.
    pub le: Color,
    pub sigma_a: Color,
    pub grid: Option<Grid>,
    /// World space to grid space ([0,1]^3 over the shape's object-space bounding box).
    pub world_to_grid: Affine3A,
    pub steps: u32,
    /// Index of refraction of the surface (1 for an interface).
    pub eta: f32,
    pub power_samples: u32,
}

impl VolumeEmitter {
    /// Emission per unit length at a world-space point.
    pub fn emission_at(&self, p: Vec3A) -> Color {
        match &self.grid {
            None => self.le,
            Some(g) => self.le * g.eval(self.world_to_grid.transform_point3a(p)),
        }
    }

    /// Emission gathered along `origin + dir * s` for s in [0, t], each point attenuated
    /// by absorption over its distance from `origin`.
    pub fn segment(&self, origin: Vec3A, dir: Vec3A, t: f32) -> Color {
        if t <= 0.0 || !t.is_finite() {
            return Color::ZERO;
        }
        let absorbs = self.sigma_a != Color::ZERO;
        if self.grid.is_none() {
            // A uniform field integrates in closed form.
            return if absorbs {
                let s = self.sigma_a.max(Color::splat(1e-12));
                self.le * (Color::ONE - (-s * t).exp()) / s
            } else {
                self.le * t
            };
        }
        // The midpoint rule, as the seed integrates the voxel grid.
        let dt = t / self.steps as f32;
        let mut sum = Color::ZERO;
        for k in 0..self.steps {
            let s = (k as f32 + 0.5) * dt;
            let e = self.emission_at(origin + dir * s);
            sum += if absorbs {
                e * (-self.sigma_a * s).exp()
            } else {
                e
            };
        }
        sum * dt
    }

    /// Absorption over a distance `t`.
    pub fn transmittance(&self, t: f32) -> Color {
        if self.sigma_a == Color::ZERO || !t.is_finite() {
            Color::ONE
        } else {
            (-self.sigma_a * t).exp()
        }
    }

    /// The factor by which interior radiance leaving at cosine `cos_o` (outside, against
    /// the shading normal) reaches the outside: Fresnel transmittance over eta^2.
    pub fn exit_factor(&self, cos_o: f32) -> f32 {
        (1.0 - fresnel_dielectric(cos_o, self.eta)) / (self.eta * self.eta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, ny: usize, nz: usize, f: impl Fn(usize, usize, usize) -> f32) -> Grid {
        let mut values = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    values.push(f(x, y, z));
                }
            }
        }
        Grid { nx, ny, nz, values }
    }

    #[test]
    fn voxel_centres_are_exact_and_midpoints_trilinear() {
        let g = grid(3, 3, 3, |x, y, z| {
            (x * 100 + y * 10 + z) as f32 + 0.25 * (x * y * z) as f32
        });
        let centre = |i: usize| (i as f32 + 0.5) / 3.0;
        for z in 0..3 {
            for y in 0..3 {
                for x in 0..3 {
                    let v = g.eval(Vec3A::new(centre(x), centre(y), centre(z)));
                    assert_eq!(v, g.at(x, y, z), "centre ({x},{y},{z})");
                }
            }
        }
        // The midpoint of the cell between centres (0,0,0) and (1,1,1) is the mean of its 8 corners.
        let mid = Vec3A::splat(1.0 / 3.0);
        let mut mean = 0.0;
        for (x, y, z) in (0..8).map(|k| (k & 1, (k >> 1) & 1, k >> 2)) {
            mean += g.at(x, y, z) / 8.0;
        }
        assert!(
            (g.eval(mid) - mean).abs() < 1e-4,
            "{} vs {mean}",
            g.eval(mid)
        );
        // Between two centres along x only: linear.
        let p = Vec3A::new(0.5 / 3.0 + 0.25 / 3.0, centre(1), centre(2));
        let expected = 0.75 * g.at(0, 1, 2) + 0.25 * g.at(1, 1, 2);
        assert!((g.eval(p) - expected).abs() < 1e-4);
        // Beyond the outer centres the edge value holds.
        assert_eq!(g.eval(Vec3A::new(0.0, centre(0), centre(0))), g.at(0, 0, 0));
    }

    #[test]
    fn uniform_segments_integrate_exactly() {
        let e = VolumeEmitter {
            le: Color::new(1.0, 2.0, 3.0),
            sigma_a: Color::ZERO,
            grid: None,
            world_to_grid: Affine3A::IDENTITY,
            steps: 4,
            eta: 1.0,
            power_samples: 1,
        };
        assert_eq!(
            e.segment(Vec3A::ZERO, Vec3A::X, 2.0),
            Color::new(2.0, 4.0, 6.0)
        );
        let absorbing = VolumeEmitter {
            sigma_a: Color::splat(0.5),
            ..e.clone()
        };
        let s = absorbing.segment(Vec3A::ZERO, Vec3A::X, 2.0);
        assert!((s.x - (1.0 - (-1.0f32).exp()) / 0.5).abs() < 1e-5);
        // A grid of ones with many midpoint steps agrees with the closed form.
        let gridded = VolumeEmitter {
            grid: Some(grid(2, 2, 2, |_, _, _| 1.0)),
            steps: 4000,
            ..absorbing.clone()
        };
        let m = gridded.segment(Vec3A::ZERO, Vec3A::X, 2.0);
        assert!((m - s).abs().max_element() < 1e-4, "{m} vs {s}");
    }
}
