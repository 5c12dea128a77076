//! The built-in filter: an edge-avoiding à-trous wavelet filter (Dammertz et al. 2010)
//! guided by the features and by each pixel's variance (Schied et al. 2017's SVGF), with
//! Rousselle et al. 2012's variance-normalised colour distance, over irradiance (the
//! colour over the albedo, which keeps textures: they are put back afterwards).
//!
//! Each of its iterations is a 5x5 B3-spline kernel with holes, its taps twice as far
//! apart as the last's (1, 2, 4, 8, 16 pixels: a 125-pixel footprint after five), each tap
//! weighted by how alike the two pixels' normals, depths, albedos and colours are; the
//! variance is carried through as the weighted sum of the variances (weights squared), so
//! later iterations trust the colour more where it has become smoother.
//!
//! It is deterministic: every pixel of an iteration is computed on its own, from the last
//! iteration's pixels, in a fixed order of taps, in f32 with the `libm` crate's
//! exponential, so the output is the same bytes for any thread count and on any CPU.

use crate::Noisy;
use rayon::prelude::*;

/// The filter's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// À-trous iterations (the footprint is 4 * 2^iterations - 3 pixels wide).
    pub iterations: u32,
    /// How many standard deviations of noise a colour difference may be and still count
    /// as alike (Rousselle's k).
    pub color: f32,
    /// The normal weight is the cosine between the normals to this power (a power of two).
    pub normal_power: u32,
    /// A depth difference as large as the depth changes over the tap's offset, times this,
    /// weighs 1/e.
    pub depth: f32,
    /// An albedo difference of this size weighs 1/e.
    pub albedo: f32,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            iterations: 5,
            color: 6.0,
            normal_power: 64,
            depth: 1.0,
            albedo: 0.1,
        }
    }
}

/// The B3-spline kernel's weights at offsets -2..=2.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// The smallest albedo colour is divided by, so that black surfaces do not blow noise up.
const MIN_ALBEDO: f32 = 0.02;

/// One iteration's input: each pixel's irradiance and its variance, by channel.
struct Level {
    color: Vec<[f32; 3]>,
    variance: Vec<[f32; 3]>,
}

/// What the colour weights compare: each pixel's colour averaged over its 3x3
/// neighbourhood, and that average's variance (the neighbours' over 9, as if
/// independent), far less noisy than one pixel's.
struct Guide {
    color: Vec<[f32; 3]>,
    variance: Vec<[f32; 3]>,
}

impl Guide {
    fn of(level: &Level, w: usize, h: usize) -> Guide {
        let (color, variance) = (0..w * h)
            .into_par_iter()
            .with_min_len(256)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut c = [0.0f32; 3];
                let mut v = [0.0f32; 3];
                let mut n = 0.0f32;
                for qy in y.saturating_sub(1)..(y + 2).min(h) {
                    for qx in x.saturating_sub(1)..(x + 2).min(w) {
                        let q = qy * w + qx;
                        for k in 0..3 {
                            c[k] += level.color[q][k];
                            v[k] += level.variance[q][k];
                        }
                        n += 1.0;
                    }
                }
                (c.map(|s| s / n), v.map(|s| s / (n * n)))
            })
            .unzip();
        Guide { color, variance }
    }
}

/// Denoises `input` with `settings`, calling `progress(done, of)` after each iteration:
/// each pixel's colour and that colour's variance.
pub fn denoise(
    input: &Noisy,
    settings: &Settings,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let n = input.width * input.height;
    let divisor: Vec<[f32; 3]> = input
        .albedo
        .iter()
        .map(|a| a.map(|v| v.max(MIN_ALBEDO)))
        .collect();
    let mut level = Level {
        color: (0..n)
            .map(|i| std::array::from_fn(|c| input.color[i][c] / divisor[i][c]))
            .collect(),
        variance: (0..n)
            .map(|i| {
                std::array::from_fn(|c| input.variance[i][c] / (divisor[i][c] * divisor[i][c]))
            })
            .collect(),
    };
    let slope = depth_slopes(input);
    for it in 0..settings.iterations {
        level = iterate(input, &slope, &level, 1 << it, settings);
        progress(it + 1, settings.iterations + 1);
    }
    let color = (0..n)
        .map(|i| std::array::from_fn(|c| level.color[i][c] * divisor[i][c]))
        .collect();
    let variance = (0..n)
        .map(|i| std::array::from_fn(|c| level.variance[i][c] * divisor[i][c] * divisor[i][c]))
        .collect();
    (color, variance)
}

/// How fast each pixel's depth changes from one pixel to the next (the larger of its
/// central differences across and down), which scales how far apart two depths may be.
fn depth_slopes(input: &Noisy) -> Vec<f32> {
    let (w, h) = (input.width, input.height);
    let z = &input.depth;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let dx = z[y * w + (x + 1).min(w - 1)] - z[y * w + x.saturating_sub(1)];
            let dy = z[(y + 1).min(h - 1) * w + x] - z[y.saturating_sub(1) * w + x];
            0.5 * dx.abs().max(dy.abs())
        })
        .collect()
}

/// One à-trous iteration with taps `step` pixels apart.
fn iterate(input: &Noisy, slope: &[f32], level: &Level, step: usize, s: &Settings) -> Level {
    let (w, h) = (input.width, input.height);
    let guide = Guide::of(level, w, h);
    let out: Vec<([f32; 3], [f32; 3])> = (0..w * h)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| filter_pixel(input, slope, level, &guide, step, s, (i % w, i / w), (w, h)))
        .collect();
    let (color, variance) = out.into_iter().unzip();
    Level { color, variance }
}

/// One pixel of an iteration: the weighted mean of its taps and the variance of that mean.
#[allow(clippy::too_many_arguments)]
fn filter_pixel(
    input: &Noisy,
    slope: &[f32],
    level: &Level,
    guide: &Guide,
    step: usize,
    s: &Settings,
    (x, y): (usize, usize),
    (w, h): (usize, usize),
) -> ([f32; 3], [f32; 3]) {
    let p = y * w + x;
    let (cp, vp) = (guide.color[p], guide.variance[p]);
    let (own_c, own_v) = (level.color[p], level.variance[p]);
    let (np, zp, ap) = (input.normal[p], input.depth[p], input.albedo[p]);
    let p_has_surface = np != [0.0; 3];
    let mut sum_w = 0.0f32;
    let mut sum_c = [0.0f32; 3];
    let mut sum_v = [0.0f32; 3];
    for (j, ky) in KERNEL.iter().enumerate() {
        let qy = y as isize + (j as isize - 2) * step as isize;
        if qy < 0 || qy >= h as isize {
            continue;
        }
        for (i, kx) in KERNEL.iter().enumerate() {
            let qx = x as isize + (i as isize - 2) * step as isize;
            if qx < 0 || qx >= w as isize {
                continue;
            }
            let q = qy as usize * w + qx as usize;
            let wgt = if q == p {
                1.0
            } else {
                let nq = input.normal[q];
                let normal = match (p_has_surface, nq != [0.0; 3]) {
                    (true, true) => cosine_power(dot(np, nq), s.normal_power),
                    (false, false) => 1.0,
                    _ => 0.0,
                };
                if normal == 0.0 {
                    continue;
                }
                let offset = step as f32 * ((i as f32 - 2.0).abs() + (j as f32 - 2.0).abs());
                let dz = (zp - input.depth[q]).abs()
                    / (s.depth * slope[p] * offset + 1e-3 * zp.abs() + 1e-6);
                let aq = input.albedo[q];
                let da = (0..3)
                    .map(|c| (ap[c] - aq[c]) * (ap[c] - aq[c]))
                    .sum::<f32>()
                    / (s.albedo * s.albedo);
                // Alike both on average over their neighbourhoods and one to one (with
                // more leeway): the averages find shading edges through the noise, the
                // pixels themselves lines too thin for the averages.
                let dc = color_distance(cp, vp, guide.color[q], guide.variance[q], s.color).max(
                    color_distance(
                        own_c,
                        own_v,
                        level.color[q],
                        level.variance[q],
                        4.0 * s.color,
                    ),
                );
                normal * libm::expf(-(dz + da + dc))
            };
            let k = kx * ky * wgt;
            if k == 0.0 {
                continue;
            }
            let (cq, vq) = (level.color[q], level.variance[q]);
            sum_w += k;
            for c in 0..3 {
                sum_c[c] += k * cq[c];
                sum_v[c] += k * k * vq[c];
            }
        }
    }
    // The centre tap's weight is never zero.
    let inv = 1.0 / sum_w;
    (sum_c.map(|v| v * inv), sum_v.map(|v| v * inv * inv))
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// max(cos, 0) to `power` (a power of two) by repeated squaring.
fn cosine_power(cos: f32, power: u32) -> f32 {
    let mut v = cos.max(0.0);
    let mut p = 1;
    while p < power {
        v *= v;
        p *= 2;
    }
    v
}

/// Rousselle et al.'s distance between two pixels' colours: their squared difference less
/// what their noise alone would make it, over the noise, averaged over the channels (zero
/// for colours as alike as their noise allows).
pub(crate) fn color_distance(
    cp: [f32; 3],
    vp: [f32; 3],
    cq: [f32; 3],
    vq: [f32; 3],
    k: f32,
) -> f32 {
    let mut d = 0.0;
    for c in 0..3 {
        let diff = cp[c] - cq[c];
        let noise = vp[c] + vp[c].min(vq[c]);
        d += (diff * diff - noise) / (1e-10 + k * k * noise);
    }
    (d / 3.0).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_powers_square() {
        assert_eq!(cosine_power(0.5, 4), 0.0625);
        assert_eq!(cosine_power(-0.5, 64), 0.0);
        assert_eq!(cosine_power(1.0, 64), 1.0);
    }

    #[test]
    fn colours_within_their_noise_are_alike() {
        assert_eq!(
            color_distance([1.0; 3], [1.0; 3], [2.0; 3], [1.0; 3], 1.0),
            0.0
        );
        assert!(color_distance([1.0; 3], [0.01; 3], [2.0; 3], [0.01; 3], 1.0) > 20.0);
    }
}
