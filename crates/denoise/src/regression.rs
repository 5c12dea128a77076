//! The built-in denoiser's second stage: a first-order regression of the first stage's
//! colours on the features over each pixel's neighbourhood (after Bitterli et al. 2016 and
//! Rousselle et al. 2013), weighted by how alike those colours are.
//!
//! Where the zero-order à-trous filter averages pixels that look alike, the regression
//! fits colour that changes with the features: a silhouette's pixels mixing two surfaces,
//! a texture seen through the albedo, shading along a curved normal. Each pixel fits the
//! model `colour = b0 + b . (feature - its own feature)` by ridge-regularised weighted least
//! squares in f64, solved by Cholesky in a fixed order, and keeps b0: the same bytes on any
//! thread count and CPU. It fits the first stage's colours rather than the noisy ones: on
//! the four scenes of `benches/denoise.rs` fitting the noisy colours spread their rare
//! bright samples over the whole neighbourhood (the lily pond's error 0.0162 against
//! 0.0072).

use crate::Noisy;
use rayon::prelude::*;

/// Features of the model: albedo (3), normal (3), depth (relative), and the constant.
const DIM: usize = 8;

/// The smooth first-stage image the weights compare, and its variance.
pub struct Smooth<'a> {
    pub color: &'a [[f32; 3]],
    pub variance: &'a [[f32; 3]],
}

/// The regression's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regression {
    /// The neighbourhood's radius in pixels.
    pub radius: usize,
    /// How many standard deviations of the smooth colours' noise two may differ by.
    pub color: f32,
    /// The ridge added to each feature's weighted second moment, relative to the weights.
    pub ridge: f64,
}

impl Default for Regression {
    fn default() -> Regression {
        // Measured on the four scenes of benches/denoise.rs (2026-11-29): against the
        // à-trous stage alone, the relative error drops on the martini (0.00300 to
        // 0.00179) and the headline (0.00938 to 0.00477) and in every scene's textured,
        // edge and caustic regions, and rises on the Cornell box (0.00056 to 0.00060) and
        // the lily pond's water (0.0094 to 0.0162), whose noisy features it follows.
        // Measured on the four scenes of benches/denoise.rs (2026-11-29): against the
        // à-trous stage alone, the relative error drops on the Cornell box (0.00056 to
        // 0.00054), the lily pond (0.0094 to 0.0072), the martini (0.00300 to 0.00161)
        // and the headline (0.00938 to 0.00528). Fitting every other pixel of a radius of 6
        // instead costs a third less and adds 2-8% to those errors.
        Regression {
            radius: 5,
            color: 4.0,
            ridge: 1e-2,
        }
    }
}

/// The first stage's colours `smooth` regressed on the features of `input`, weighted by
/// how alike they are.
pub fn refine(input: &Noisy, smooth: &Smooth, r: &Regression) -> Vec<[f32; 3]> {
    let (w, h) = (input.width, input.height);
    (0..w * h)
        .into_par_iter()
        .with_min_len(64)
        .map(|i| fit(input, smooth, r, (i % w, i / w)))
        .collect()
}

/// A pixel's features, relative to the pixel `p`'s (depth relative to its depth).
fn features(input: &Noisy, q: usize, p: usize) -> [f64; DIM] {
    let (a, n) = (input.albedo[q], input.normal[q]);
    let (ap, np) = (input.albedo[p], input.normal[p]);
    let zp = input.depth[p].abs().max(1e-6) as f64;
    [
        1.0,
        (a[0] - ap[0]) as f64,
        (a[1] - ap[1]) as f64,
        (a[2] - ap[2]) as f64,
        (n[0] - np[0]) as f64,
        (n[1] - np[1]) as f64,
        (n[2] - np[2]) as f64,
        (input.depth[q] - input.depth[p]) as f64 / zp,
    ]
}

/// One pixel's fit: its colour as the model predicts it at its own features. (Indices,
/// as the normal equations are written, read better here than iterators.)
#[allow(clippy::needless_range_loop)]
fn fit(input: &Noisy, smooth: &Smooth, r: &Regression, (x, y): (usize, usize)) -> [f32; 3] {
    let (w, h) = (input.width, input.height);
    let p = y * w + x;
    let (sp, vp) = (smooth.color[p], smooth.variance[p]);
    let mut xtx = [[0.0f64; DIM]; DIM];
    let mut xty = [[0.0f64; 3]; DIM];
    let mut total = 0.0f64;
    for qy in y.saturating_sub(r.radius)..(y + r.radius + 1).min(h) {
        for qx in x.saturating_sub(r.radius)..(x + r.radius + 1).min(w) {
            let q = qy * w + qx;
            let weight = if q == p {
                1.0
            } else {
                let d = crate::atrous::color_distance(
                    sp,
                    vp,
                    smooth.color[q],
                    smooth.variance[q],
                    r.color,
                );
                libm::exp(-(d as f64))
            };
            if weight < 1e-4 {
                continue;
            }
            total += weight;
            let f = features(input, q, p);
            for i in 0..DIM {
                let wf = weight * f[i];
                for j in 0..=i {
                    xtx[i][j] += wf * f[j];
                }
                for c in 0..3 {
                    xty[i][c] += wf * smooth.color[q][c] as f64;
                }
            }
        }
    }
    // Ridge on the features (not the constant), scaled with the weights.
    for (i, row) in xtx.iter_mut().enumerate().skip(1) {
        row[i] += r.ridge * total;
    }
    match solve(&mut xtx, &xty) {
        Some(b) => b.map(|v| v as f32),
        None => smooth.color[p],
    }
}

/// The first row of the solution of `a b = y` (a symmetric, its lower triangle filled) by
/// Cholesky: the intercept for each of the three channels. None if `a` is not positive
/// definite.
#[allow(clippy::needless_range_loop)]
fn solve(a: &mut [[f64; DIM]; DIM], y: &[[f64; 3]; DIM]) -> Option<[f64; 3]> {
    // a = L L^T, L in the lower triangle of `a`.
    for j in 0..DIM {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..DIM {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / d;
        }
    }
    let mut out = [0.0f64; 3];
    for (c, o) in out.iter_mut().enumerate() {
        // L z = y, then L^T b = z; b[0] last.
        let mut z = [0.0f64; DIM];
        for i in 0..DIM {
            let mut s = y[i][c];
            for k in 0..i {
                s -= a[i][k] * z[k];
            }
            z[i] = s / a[i][i];
        }
        let mut b = [0.0f64; DIM];
        for i in (0..DIM).rev() {
            let mut s = z[i];
            for k in i + 1..DIM {
                s -= a[k][i] * b[k];
            }
            b[i] = s / a[i][i];
        }
        *o = b[0];
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_small_system() {
        // a = [[4, 2], [2, 3]] padded with the identity; y = a * [1, 2] for channel 0.
        let mut a = [[0.0; DIM]; DIM];
        for (i, row) in a.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        a[0][0] = 4.0;
        a[1][0] = 2.0;
        a[1][1] = 3.0;
        let mut y = [[0.0; 3]; DIM];
        y[0] = [8.0, 0.0, 4.0];
        y[1] = [8.0, 0.0, 2.0];
        let b = solve(&mut a, &y).unwrap();
        assert!((b[0] - 1.0).abs() < 1e-12 && b[1].abs() < 1e-12 && (b[2] - 1.0).abs() < 1e-12);
    }
}
