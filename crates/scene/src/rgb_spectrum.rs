//! Kiln's own RGB-to-spectrum upsampling: the smooth reflectance spectrum whose linear sRGB
//! under D65 is a given colour, of the form pbrt-v4 uses (Jakob and Hanika, "A
//! Low-Dimensional Function Space for Efficient Spectral Upsampling", 2019):
//!
//!   ρ(λ) = s(c0 + c1·t + c2·t²),  t = (λ − 555) / 175,  s(z) = ½ + z / (2·√(1 + z²)),
//!
//! so 0 < ρ < 1 everywhere. The coefficients are found by damped Gauss-Newton on the three
//! colour residuals. pbrt-v4 ships precomputed tables from its own optimiser; Kiln fits at
//! run time, where it needs spectra (a named camera's response to a colour), with
//! continuation from grey so that saturated colours start from a neighbour's solution.
//!
//! Sums are over 360–830 nm every 1 nm (pbrt-v4's `InnerProduct` grid).

use crate::spectrum::{LAMBDA_MAX, LAMBDA_MIN, XYZ_TO_SRGB, cmf_at, d65_at, det3};

/// Wavelengths of the sums: 360, 361, …, 830 nm.
pub(crate) fn grid() -> impl Iterator<Item = f64> {
    let n = (LAMBDA_MAX - LAMBDA_MIN) as usize;
    (0..=n).map(|i| LAMBDA_MIN + i as f64)
}

/// The sigmoid s(z) and its derivative.
fn sigmoid(z: f64) -> (f64, f64) {
    let q = 1.0 + z * z;
    (0.5 + z / (2.0 * q.sqrt()), 0.5 / (q * q.sqrt()))
}

/// The reduced wavelength t of each grid wavelength.
fn reduced(lambda: f64) -> f64 {
    (lambda - 555.0) / 175.0
}

/// Fits sigmoid-quadratic spectra to linear sRGB colours.
pub(crate) struct Upsampler {
    t: Vec<f64>,
    /// Per wavelength, the linear sRGB that a unit reflectance at that wavelength alone adds
    /// under D65 (white-corrected so that ρ = 1 is exactly (1, 1, 1)).
    weights: Vec<[f64; 3]>,
}

impl Upsampler {
    pub(crate) fn new() -> Upsampler {
        Upsampler::on(grid().collect())
    }

    /// An upsampler whose sums run over `lambdas` (nm, evenly spaced) instead of every
    /// nanometre: the coefficient tables use a coarser grid to be built in a fraction of a
    /// second.
    pub(crate) fn on(lambdas: Vec<f64>) -> Upsampler {
        let raw: Vec<[f64; 3]> = lambdas
            .iter()
            .map(|&l| {
                let xyz = cmf_at(l).map(|v| v * d65_at(l));
                std::array::from_fn(|r| (0..3).map(|k| XYZ_TO_SRGB[r][k] * xyz[k]).sum())
            })
            .collect();
        let mut white = [0.0; 3];
        for w in &raw {
            for c in 0..3 {
                white[c] += w[c];
            }
        }
        Upsampler {
            t: lambdas.iter().map(|&l| reduced(l)).collect(),
            weights: raw
                .iter()
                .map(|w| std::array::from_fn(|c| w[c] / white[c]))
                .collect(),
        }
    }

    /// The spectrum of coefficients `c` on the grid.
    pub(crate) fn spectrum(&self, c: [f64; 3]) -> Vec<f64> {
        self.t
            .iter()
            .map(|&t| sigmoid(c[0] + c[1] * t + c[2] * t * t).0)
            .collect()
    }

    /// Linear sRGB (under D65) of the spectrum of `c`, and its Jacobian by the coefficients.
    pub(crate) fn colour(&self, c: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let mut rgb = [0.0; 3];
        let mut jac = [[0.0; 3]; 3];
        for (&t, w) in self.t.iter().zip(&self.weights) {
            let (s, ds) = sigmoid(c[0] + c[1] * t + c[2] * t * t);
            let dz = [1.0, t, t * t];
            for r in 0..3 {
                rgb[r] += s * w[r];
                for (j, dzj) in dz.iter().enumerate() {
                    jac[r][j] += ds * dzj * w[r];
                }
            }
        }
        (rgb, jac)
    }

    /// The coefficients whose spectrum's colour is nearest `target` (each component in
    /// [0, 1]), starting from `start`. Colours outside what 0 < ρ < 1 can reach get the
    /// nearest it can.
    pub(crate) fn fit(&self, target: [f64; 3], start: [f64; 3]) -> [f64; 3] {
        self.fit_within(target, start, 1e-22)
    }

    /// [`Upsampler::fit`], stopping once the squared colour error is below `tolerance`.
    pub(crate) fn fit_within(&self, target: [f64; 3], start: [f64; 3], tolerance: f64) -> [f64; 3] {
        let mut c = start;
        let residual = |rgb: [f64; 3]| -> [f64; 3] { std::array::from_fn(|i| rgb[i] - target[i]) };
        let norm = |r: [f64; 3]| r.iter().map(|v| v * v).sum::<f64>();
        let (mut rgb, mut jac) = self.colour(c);
        let mut err = norm(residual(rgb));
        let mut damping = 1e-3;
        for _ in 0..200 {
            if err < tolerance {
                break;
            }
            let r = residual(rgb);
            // (JᵀJ + μ·diag(JᵀJ)) Δ = −Jᵀr.
            let mut a = [[0.0; 3]; 3];
            let mut g = [0.0; 3];
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] = (0..3).map(|k| jac[k][i] * jac[k][j]).sum();
                }
                g[i] = -(0..3).map(|k| jac[k][i] * r[k]).sum::<f64>();
            }
            let mut improved = false;
            while damping < 1e12 {
                let mut m = a;
                for (i, row) in m.iter_mut().enumerate() {
                    row[i] += damping * a[i][i].max(1e-12);
                }
                let Some(step) = solve3(m, g) else {
                    damping *= 10.0;
                    continue;
                };
                let trial = std::array::from_fn(|i| c[i] + step[i]);
                let (trgb, tjac) = self.colour(trial);
                let terr = norm(residual(trgb));
                if terr < err {
                    (c, rgb, jac, err) = (trial, trgb, tjac, terr);
                    damping = (damping * 0.3).max(1e-9);
                    improved = true;
                    break;
                }
                damping *= 10.0;
            }
            if !improved {
                break;
            }
        }
        c
    }
}

/// Solves the 3×3 system m·x = b by Cramer's rule; None when m is singular.
fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let d = det3(&m);
    if !d.is_finite() || d.abs() <= 1e-300 {
        return None;
    }
    let x: [f64; 3] = std::array::from_fn(|col| {
        let mut mc = m;
        for row in 0..3 {
            mc[row][col] = b[row];
        }
        det3(&mc) / d
    });
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_reproduce_colours_inside_the_reachable_set() {
        let up = Upsampler::new();
        // Grey is the flat spectrum 0.5 (c = 0) exactly.
        let (rgb, _) = up.colour([0.0; 3]);
        for v in rgb {
            assert!((v - 0.5).abs() < 1e-12, "{rgb:?}");
        }
        for target in [
            [0.5, 0.5, 0.5],
            [0.8, 0.4, 0.1],
            [0.1, 0.8, 0.1],
            [0.1, 0.1, 0.8],
            [0.5, 0.05, 0.05],
            [0.05, 0.5, 0.05],
            [0.05, 0.05, 0.5],
            [0.9, 0.9, 0.2],
        ] {
            let c = up.fit(target, [0.0; 3]);
            let (rgb, _) = up.colour(c);
            for i in 0..3 {
                assert!(
                    (rgb[i] - target[i]).abs() < 1e-6,
                    "{target:?} -> {c:?} -> {rgb:?}"
                );
            }
            assert!(up.spectrum(c).iter().all(|&v| v > 0.0 && v < 1.0));
        }
    }
}
