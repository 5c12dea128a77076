//! Piecewise-constant distributions in one, two and three dimensions: environment maps
//! (2D) and emissive grid media (3D) are sampled by them.

use glam::Vec2;

/// A piecewise-constant 1D distribution on [0, 1).
#[derive(Debug, Clone)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    pub fn new(func: &[f32]) -> Distribution1D {
        let n = func.len().max(1);
        let func: Vec<f32> = if func.is_empty() {
            vec![1.0]
        } else {
            func.iter().map(|f| f.abs()).collect()
        };
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += func[i] as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral == 0.0 {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        } else {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        }
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    pub fn integral(&self) -> f32 {
        self.integral
    }

    pub fn count(&self) -> usize {
        self.func.len()
    }

    /// Returns (x in [0,1), pdf, bin).
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        // The last cdf entry <= u.
        let n = self.func.len();
        let mut lo = 0;
        let mut hi = n;
        while lo + 1 < hi {
            let mid = (lo + hi) / 2;
            if self.cdf[mid] <= u {
                lo = mid
            } else {
                hi = mid
            }
        }
        let i = lo;
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.0
        };
        let pdf = if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        };
        (((i as f32 + du) / n as f32).min(1.0 - f32::EPSILON), pdf, i)
    }

    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.func.len();
        let i = ((x * n as f32) as usize).min(n - 1);
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }
}

/// A piecewise-constant 2D distribution on [0,1)^2: marginal over rows (v), conditional over columns (u).
#[derive(Debug, Clone)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `func` is row-major, `width` entries per row.
    pub fn new(func: &[f32], width: usize, height: usize) -> Distribution2D {
        let conditional: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&func[y * width..(y + 1) * width]))
            .collect();
        let marginal_func: Vec<f32> = conditional.iter().map(|d| d.integral()).collect();
        Distribution2D {
            marginal: Distribution1D::new(&marginal_func),
            conditional,
        }
    }

    /// Returns ((u, v), pdf).
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample(u.y);
        let (x, pdf_u, _) = self.conditional[row].sample(u.x);
        (Vec2::new(x, v), pdf_u * pdf_v)
    }

    pub fn pdf(&self, p: Vec2) -> f32 {
        let h = self.conditional.len();
        let row = ((p.y * h as f32) as usize).min(h - 1);
        let integral = self.marginal.integral();
        if integral == 0.0 {
            return 0.0;
        }
        let c = &self.conditional[row];
        let w = c.count();
        let col = ((p.x * w as f32) as usize).min(w - 1);
        c.func[col] / integral
    }
}
/// A discrete distribution over the voxels of a grid, sampled as p(x) p(y | x) p(z | x, y)
/// (seed 001): a marginal over x, a conditional over y for each x, a conditional over z for
/// each (x, y), each a cumulative table searched by bisection.
#[derive(Debug, Clone)]
pub struct Distribution3D {
    pub n: [usize; 3],
    weights: Vec<f32>,
    /// Sum of the weights (f64: millions of them).
    pub total: f64,
    /// Cumulative sums, each table starting at 0: x (nx + 1), y per x, z per (x, y).
    cdf_x: Vec<f64>,
    cdf_y: Vec<f64>,
    cdf_z: Vec<f64>,
}

impl Distribution3D {
    /// `weights[(z * ny + y) * nx + x]`, non-negative.
    pub fn new(weights: Vec<f32>, n: [usize; 3]) -> Distribution3D {
        let [nx, ny, nz] = n;
        let w = |x: usize, y: usize, z: usize| f64::from(weights[(z * ny + y) * nx + x]);
        let mut cdf_z = vec![0.0f64; nx * ny * (nz + 1)];
        let mut cdf_y = vec![0.0f64; nx * (ny + 1)];
        let mut cdf_x = vec![0.0f64; nx + 1];
        for x in 0..nx {
            for y in 0..ny {
                let base = (x * ny + y) * (nz + 1);
                for z in 0..nz {
                    cdf_z[base + z + 1] = cdf_z[base + z] + w(x, y, z);
                }
                let by = x * (ny + 1);
                cdf_y[by + y + 1] = cdf_y[by + y] + cdf_z[base + nz];
            }
            cdf_x[x + 1] = cdf_x[x] + cdf_y[x * (ny + 1) + ny];
        }
        Distribution3D {
            n,
            total: cdf_x[nx],
            weights,
            cdf_x,
            cdf_y,
            cdf_z,
        }
    }

    /// The probability of voxel `v`.
    pub fn pmf(&self, v: [usize; 3]) -> f32 {
        if self.total <= 0.0 {
            return 0.0;
        }
        let [nx, ny, _] = self.n;
        (f64::from(self.weights[(v[2] * ny + v[1]) * nx + v[0]]) / self.total) as f32
    }

    /// Samples a voxel from three uniform numbers; returns it with its probability.
    pub fn sample(&self, u: [f32; 3]) -> ([usize; 3], f32) {
        let [nx, ny, nz] = self.n;
        let x = pick(&self.cdf_x, u[0]);
        let y = pick(&self.cdf_y[x * (ny + 1)..(x + 1) * (ny + 1)], u[1]);
        let base = (x * ny + y) * (nz + 1);
        let z = pick(&self.cdf_z[base..base + nz + 1], u[2]);
        debug_assert!(x < nx && y < ny && z < nz);
        let v = [x, y, z];
        (v, self.pmf(v))
    }
}

/// The bin of a cumulative table (starting at 0) that `u` in [0, 1) falls in, skipping
/// empty bins.
fn pick(cdf: &[f64], u: f32) -> usize {
    let n = cdf.len() - 1;
    let target = f64::from(u) * cdf[n];
    // The first bin whose upper end exceeds the target.
    let i = cdf[1..].partition_point(|&c| c <= target);
    if i < n {
        return i;
    }
    // Rounding put the target at the very top: the last non-empty bin.
    (0..n).rev().find(|&i| cdf[i + 1] > cdf[i]).unwrap_or(n - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distribution2d_pdf_matches_its_samples() {
        let func = [1.0, 2.0, 0.0, 4.0, 1.0, 1.0];
        let d = Distribution2D::new(&func, 3, 2);
        for i in 0..64 {
            let u = Vec2::new((i % 8) as f32 / 8.0 + 0.03, (i / 8) as f32 / 8.0 + 0.05);
            let (p, pdf) = d.sample(u);
            assert!((d.pdf(p) - pdf).abs() < 1e-5, "{p} {pdf} {}", d.pdf(p));
            assert!(pdf > 0.0);
        }
        // The average of func is 9/6, so the pdf of the cell holding 4 is 4 / 1.5.
        assert!((d.pdf(Vec2::new(0.1, 0.9)) - 4.0 / 1.5).abs() < 1e-5);
    }
}
