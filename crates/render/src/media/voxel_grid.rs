//! The one voxel-grid type: a scalar grid over the unit box, sampled at voxel centres (or on
//! a NanoVDB grid's lattice, mapped into the box affinely) and trilinear in between. Grid media (density, emission, temperature) and VolumeLight
//! interiors both use it; they differ only in what lies beyond the outermost centres, so
//! that choice is the caller's: [`SampledGrid::lookup`] (zero outside, pbrt-v4's
//! `SampledGrid`) or [`SampledGrid::lookup_clamped`] (the nearest centre's value, seed 000's).

use glam::{Affine3A, Vec3A, Vec4};

/// A scalar grid over the unit box: sample (i, j, k) at the centre of voxel (i, j, k),
/// or where a lattice map puts it; trilinear in between.
#[derive(Debug, Clone)]
pub struct SampledGrid {
    pub(crate) n: [usize; 3],
    values: Vec<f32>,
    /// Unit box to sample coordinates (sample (i, j, k) at the point (i, j, k)); None for the
    /// centred lattice, p · n − 1/2.
    to_samples: Option<Affine3A>,
}

impl SampledGrid {
    /// A grid on pbrt-v4's centred lattice.
    pub fn new(g: &kiln_scene::VoxelGrid) -> SampledGrid {
        SampledGrid::on(g, &kiln_scene::Lattice::Centred)
    }

    pub fn on(g: &kiln_scene::VoxelGrid, lattice: &kiln_scene::Lattice) -> SampledGrid {
        SampledGrid {
            n: [g.nx, g.ny, g.nz],
            values: g.values.clone(),
            to_samples: match lattice {
                kiln_scene::Lattice::Centred => None,
                kiln_scene::Lattice::Affine { to_samples } => {
                    Some(Affine3A::from_mat4(to_samples.as_mat4()))
                }
            },
        }
    }

    /// Sample coordinates of a point of the unit box.
    fn sample_coords(&self, p: Vec3A) -> Vec3A {
        match &self.to_samples {
            None => p * Vec3A::new(self.n[0] as f32, self.n[1] as f32, self.n[2] as f32) - 0.5,
            Some(m) => m.transform_point3a(p),
        }
    }

    fn at(&self, x: i64, y: i64, z: i64) -> f32 {
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        self.values[((z * ny + y) * nx + x) as usize]
    }

    /// The value at `p` in the unit box; zero beyond the outermost samples, as pbrt-v4's
    /// `SampledGrid` (half way to zero at the box's faces).
    pub fn lookup(&self, p: Vec3A) -> f32 {
        let s = self.sample_coords(p);
        let f = s.floor();
        let d = s - f;
        let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
        let lerp = |t: f32, a: f32, b: f32| a + t * (b - a);
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        if x >= 0 && y >= 0 && z >= 0 && x + 1 < nx && y + 1 < ny && z + 1 < nz {
            // All eight samples inside: one index computation, no per-sample checks.
            let (sy, sz) = (nx as usize, (nx * ny) as usize);
            let i = ((z * ny + y) * nx + x) as usize;
            let v = &self.values[i..i + sz + sy + 2];
            let c00 = lerp(d.x, v[0], v[1]);
            let c10 = lerp(d.x, v[sy], v[sy + 1]);
            let c01 = lerp(d.x, v[sz], v[sz + 1]);
            let c11 = lerp(d.x, v[sz + sy], v[sz + sy + 1]);
            return lerp(d.z, lerp(d.y, c00, c10), lerp(d.y, c01, c11));
        }
        let c00 = lerp(d.x, self.at(x, y, z), self.at(x + 1, y, z));
        let c10 = lerp(d.x, self.at(x, y + 1, z), self.at(x + 1, y + 1, z));
        let c01 = lerp(d.x, self.at(x, y, z + 1), self.at(x + 1, y, z + 1));
        let c11 = lerp(d.x, self.at(x, y + 1, z + 1), self.at(x + 1, y + 1, z + 1));
        lerp(d.z, lerp(d.y, c00, c10), lerp(d.y, c01, c11))
    }

    /// The trilinear blend at `p` of per-sample values `value(index)` gives (an index into the
    /// grid's samples), zero beyond the outermost samples as in [`SampledGrid::lookup`]: a
    /// grid of spectra interpolates its eight samples' values at a path's wavelengths, as
    /// pbrt-v4's `SampledGrid::Lookup` with a conversion does.
    pub fn blend(&self, p: Vec3A, value: impl Fn(usize) -> Vec4) -> Vec4 {
        let s = self.sample_coords(p);
        let f = s.floor();
        let d = s - f;
        let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        let at = |x: i64, y: i64, z: i64| {
            if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
                Vec4::ZERO
            } else {
                value(((z * ny + y) * nx + x) as usize)
            }
        };
        let lerp = |t: f32, a: Vec4, b: Vec4| a + (b - a) * t;
        let c00 = lerp(d.x, at(x, y, z), at(x + 1, y, z));
        let c10 = lerp(d.x, at(x, y + 1, z), at(x + 1, y + 1, z));
        let c01 = lerp(d.x, at(x, y, z + 1), at(x + 1, y, z + 1));
        let c11 = lerp(d.x, at(x, y + 1, z + 1), at(x + 1, y + 1, z + 1));
        lerp(d.z, lerp(d.y, c00, c10), lerp(d.y, c01, c11))
    }

    /// The grid's samples, in x-fastest order.
    pub(crate) fn values(&self) -> &[f32] {
        &self.values
    }

    /// A grid on the same lattice holding `values` instead (as many as this one's).
    pub(crate) fn with_values(&self, values: Vec<f32>) -> SampledGrid {
        assert_eq!(values.len(), self.values.len());
        SampledGrid {
            n: self.n,
            values,
            to_samples: self.to_samples,
        }
    }

    /// The value at `p` in the unit box; voxel centres hold their values exactly, points
    /// between interpolate trilinearly, points beyond the outermost centres take the nearest
    /// centre's value along that axis (seed 000's VolumeLight grids).
    pub fn lookup_clamped(&self, p: Vec3A) -> f32 {
        debug_assert!(
            self.to_samples.is_none(),
            "clamped lookups are on the centred lattice"
        );
        let axis = |v: f32, n: usize| -> (usize, usize, f32) {
            let c = (v * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i0 = (c.floor() as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            (i0, i1, c - i0 as f32)
        };
        let (x0, x1, fx) = axis(p.x, self.n[0]);
        let (y0, y1, fy) = axis(p.y, self.n[1]);
        let (z0, z1, fz) = axis(p.z, self.n[2]);
        let at = |x: usize, y: usize, z: usize| self.values[(z * self.n[1] + y) * self.n[0] + x];
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(at(x0, y0, z0), at(x1, y0, z0), fx);
        let c10 = lerp(at(x0, y1, z0), at(x1, y1, z0), fx);
        let c01 = lerp(at(x0, y0, z1), at(x1, y0, z1), fx);
        let c11 = lerp(at(x0, y1, z1), at(x1, y1, z1), fx);
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }

    /// An upper bound of the value over the box `lo`..`hi` of the unit box: the largest
    /// sample whose interpolation reaches into it.
    pub fn max_over(&self, lo: Vec3A, hi: Vec3A) -> f32 {
        // The box's extent in sample coordinates: its corners' bounds.
        let (s0, s1) = match &self.to_samples {
            None => (self.sample_coords(lo), self.sample_coords(hi)),
            Some(m) => {
                let (mut s0, mut s1) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
                for c in 0..8 {
                    let corner = Vec3A::select(
                        glam::BVec3A::new(c & 1 == 1, c & 2 == 2, c & 4 == 4),
                        hi,
                        lo,
                    );
                    let s = m.transform_point3a(corner);
                    (s0, s1) = (s0.min(s), s1.max(s));
                }
                (s0, s1)
            }
        };
        let range = |a: usize| {
            let n = self.n[a] as f32;
            let i0 = s0[a].floor().max(0.0) as usize;
            let i1 = (s1[a].floor() + 1.0).clamp(0.0, n - 1.0) as usize;
            i0.min(self.n[a] - 1)..=i1
        };
        let mut m = 0.0f32;
        for z in range(2) {
            for y in range(1) {
                for x in range(0) {
                    m = m.max(self.values[(z * self.n[1] + y) * self.n[0] + x]);
                }
            }
        }
        m
    }

    pub fn max(&self) -> f32 {
        self.values.iter().copied().fold(0.0, f32::max)
    }
}

/// A description-side grid whose value at voxel (x, y, z) is `f(x, y, z)`, for tests.
#[cfg(test)]
pub(crate) fn grid_from_fn(
    n: [usize; 3],
    f: impl Fn(usize, usize, usize) -> f32,
) -> kiln_scene::VoxelGrid {
    let mut values = Vec::new();
    for z in 0..n[2] {
        for y in 0..n[1] {
            for x in 0..n[0] {
                values.push(f(x, y, z));
            }
        }
    }
    kiln_scene::VoxelGrid {
        nx: n[0],
        ny: n[1],
        nz: n[2],
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grid_from_fn as grid;

    #[test]
    fn sampled_grid_interpolates_like_pbrt() {
        let g = SampledGrid::new(&grid([2, 1, 1], |x, _, _| [1.0, 3.0][x]));
        // Sample centres at x = 0.25 and 0.75; zero beyond them, half way at the faces.
        assert_eq!(g.lookup(Vec3A::new(0.25, 0.5, 0.5)), 1.0);
        assert_eq!(g.lookup(Vec3A::new(0.5, 0.5, 0.5)), 2.0);
        assert_eq!(g.lookup(Vec3A::new(0.75, 0.5, 0.5)), 3.0);
        assert!((g.lookup(Vec3A::new(0.0, 0.5, 0.5)) - 0.5).abs() < 1e-6);
        assert!((g.lookup(Vec3A::new(0.5, 0.5, 0.0)) - 1.0).abs() < 1e-6);
        assert_eq!(g.lookup(Vec3A::new(-0.5, 0.5, 0.5)), 0.0);
        assert_eq!(g.max_over(Vec3A::ZERO, Vec3A::new(0.2, 1.0, 1.0)), 1.0);
        assert_eq!(g.max_over(Vec3A::ZERO, Vec3A::new(0.3, 1.0, 1.0)), 3.0);
    }

    #[test]
    fn clamped_lookup_is_exact_at_centres_trilinear_between_and_holds_the_edge() {
        let g = SampledGrid::new(&grid([3, 3, 3], |x, y, z| {
            (x * 100 + y * 10 + z) as f32 + 0.25 * (x * y * z) as f32
        }));
        let at = |x: usize, y: usize, z: usize| g.values[(z * 3 + y) * 3 + x];
        let centre = |i: usize| (i as f32 + 0.5) / 3.0;
        for z in 0..3 {
            for y in 0..3 {
                for x in 0..3 {
                    let v = g.lookup_clamped(Vec3A::new(centre(x), centre(y), centre(z)));
                    assert_eq!(v, at(x, y, z), "centre ({x},{y},{z})");
                }
            }
        }
        // The midpoint of the cell between centres (0,0,0) and (1,1,1) is the mean of its 8 corners.
        let mid = Vec3A::splat(1.0 / 3.0);
        let mut mean = 0.0;
        for (x, y, z) in (0..8).map(|k| (k & 1, (k >> 1) & 1, k >> 2)) {
            mean += at(x, y, z) / 8.0;
        }
        assert!(
            (g.lookup_clamped(mid) - mean).abs() < 1e-4,
            "{} vs {mean}",
            g.lookup_clamped(mid)
        );
        // Between two centres along x only: linear.
        let p = Vec3A::new(0.5 / 3.0 + 0.25 / 3.0, centre(1), centre(2));
        let expected = 0.75 * at(0, 1, 2) + 0.25 * at(1, 1, 2);
        assert!((g.lookup_clamped(p) - expected).abs() < 1e-4);
        // Beyond the outer centres the edge value holds (where `lookup` fades to zero).
        let edge = Vec3A::new(0.0, centre(0), centre(0));
        assert_eq!(g.lookup_clamped(edge), at(0, 0, 0));
        let far = Vec3A::new(1.0, centre(1), centre(2));
        assert!((g.lookup_clamped(far) - at(2, 1, 2)).abs() < 1e-3);
        assert!((g.lookup(far) - 0.5 * at(2, 1, 2)).abs() < 1e-3);
    }
}
