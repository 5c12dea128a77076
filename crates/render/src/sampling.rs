//! Warps from the unit square to shapes and directions, and discrete distributions.

use glam::{Vec2, Vec3A};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// A cosine-weighted direction on the +z hemisphere (Malley's method).
pub fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let d = concentric_disk(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3A::new(d.x, d.y, z)
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// Shirley and Chiu's concentric map from the square to the unit disk.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

pub fn uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// A uniform direction on the +z hemisphere.
pub fn uniform_hemisphere(u: Vec2) -> Vec3A {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// A uniform direction inside the cone of half-angle acos(cos_max) around +z.
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3A {
    let cos_theta = (1.0 - u.x) + u.x * cos_max;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = u.y * 2.0 * PI;
    Vec3A::new(phi.cos() * sin_theta, phi.sin() * sin_theta, cos_theta)
}

/// Barycentrics (b0, b1, b2) of a uniform point on a triangle (the low-distortion square-to-triangle map).
pub fn uniform_triangle(u: Vec2) -> [f32; 3] {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    [b0, b1, 1.0 - b0 - b1]
}

/// Veach's power heuristic with beta = 2, for one sample from each strategy.
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a.is_infinite() {
        return 1.0;
    }
    if a + b == 0.0 { 0.0 } else { a / (a + b) }
}

/// Walker's alias table: O(1) sampling of a discrete distribution of any size.
#[derive(Debug, Clone, Default)]
pub struct AliasTable {
    bins: Vec<AliasBin>,
}

#[derive(Debug, Clone, Copy)]
struct AliasBin {
    /// Probability of keeping this bin rather than its alias.
    q: f32,
    /// The probability mass of this bin's own entry.
    pmf: f32,
    alias: u32,
}

impl AliasTable {
    /// Builds the table; weights must be finite and non-negative. All-zero weights give an empty table.
    pub fn new(weights: &[f64]) -> AliasTable {
        let total: f64 = weights.iter().sum();
        if weights.is_empty() || total <= 0.0 || !total.is_finite() {
            return AliasTable { bins: Vec::new() };
        }
        let n = weights.len();
        let mut bins: Vec<AliasBin> = weights
            .iter()
            .map(|&w| AliasBin {
                q: 0.0,
                pmf: (w / total) as f32,
                alias: u32::MAX,
            })
            .collect();
        // Scaled probabilities: an average bin holds exactly 1.
        let mut scaled: Vec<f64> = weights.iter().map(|&w| w / total * n as f64).collect();
        let mut small: Vec<usize> = Vec::new();
        let mut large: Vec<usize> = Vec::new();
        for (i, &p) in scaled.iter().enumerate() {
            if p < 1.0 {
                small.push(i)
            } else {
                large.push(i)
            }
        }
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            bins[s].q = scaled[s] as f32;
            bins[s].alias = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Whatever is left is 1 up to rounding.
        for i in small.into_iter().chain(large) {
            bins[i].q = 1.0;
            bins[i].alias = i as u32;
        }
        AliasTable { bins }
    }

    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Picks an entry with one uniform number; returns (index, pmf).
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        if self.bins.is_empty() {
            return None;
        }
        let n = self.bins.len();
        let scaled = u * n as f32;
        let i = (scaled as usize).min(n - 1);
        let up = (scaled - i as f32).min(1.0);
        let bin = &self.bins[i];
        let chosen = if up < bin.q { i } else { bin.alias as usize };
        Some((chosen, self.bins[chosen].pmf))
    }

    pub fn pmf(&self, index: usize) -> f32 {
        self.bins.get(index).map_or(0.0, |b| b.pmf)
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alias_table_reproduces_its_distribution() {
        let weights = [1.0, 0.0, 3.0, 6.0];
        let table = AliasTable::new(&weights);
        let mut counts = [0u32; 4];
        let n = 100_000;
        for i in 0..n {
            let (k, pmf) = table.sample((i as f32 + 0.5) / n as f32).unwrap();
            assert!((pmf - weights[k] as f32 / 10.0).abs() < 1e-6);
            counts[k] += 1;
        }
        for k in 0..4 {
            let expected = weights[k] / 10.0;
            assert!(
                (counts[k] as f64 / n as f64 - expected).abs() < 2e-3,
                "{counts:?}"
            );
        }
        assert_eq!(table.pmf(1), 0.0);
    }

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

    #[test]
    fn warps_land_where_they_should() {
        for i in 0..100 {
            let u = Vec2::new((i as f32 * 0.618_034) % 1.0, (i as f32 + 0.5) / 100.0);
            let d = cosine_hemisphere(u);
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-5);
            let c = uniform_cone(u, 0.9);
            assert!(c.z >= 0.9 - 1e-6);
            let b = uniform_triangle(u);
            assert!(b.iter().all(|&x| (-1e-6..=1.0 + 1e-6).contains(&x)));
        }
    }
}
