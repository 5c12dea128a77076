//! What a denoised image is measured by against a reference: relative mean squared error
//! per channel (Rousselle et al.'s, the measure of equal-time comparisons), the structural
//! similarity of its tone-mapped luminance (SSIM, Wang et al. 2004), its mean, and the
//! regions where denoisers fail first: textures, edges and caustics.

/// Relative MSE over the pixels `mask` keeps (all, without one): each channel's squared
/// error over the reference's square plus 0.01, averaged.
pub fn rel_mse(image: &[[f32; 3]], reference: &[[f32; 3]], mask: Option<&[bool]>) -> f64 {
    let mut sum = 0.0f64;
    let mut count = 0u64;
    for (i, (a, r)) in image.iter().zip(reference).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        for c in 0..3 {
            let d = (a[c] - r[c]) as f64;
            sum += d * d / ((r[c] as f64).powi(2) + 0.01);
        }
        count += 3;
    }
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// Each channel's mean.
pub fn mean(image: &[[f32; 3]]) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    for p in image {
        for c in 0..3 {
            sum[c] += p[c] as f64;
        }
    }
    sum.map(|s| s / image.len().max(1) as f64)
}

/// A pixel as a display shows it: its luminance clamped to [0, 1] with a 2.2 gamma.
fn display(p: [f32; 3]) -> f64 {
    let y = 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64;
    libm::pow(y.clamp(0.0, 1.0), 1.0 / 2.2)
}

/// The mean structural similarity of the two images' displayed luminance over 7x7 windows
/// (1 for identical images).
pub fn ssim(image: &[[f32; 3]], reference: &[[f32; 3]], width: usize, height: usize) -> f64 {
    const R: usize = 3;
    let a: Vec<f64> = image.iter().map(|p| display(*p)).collect();
    let b: Vec<f64> = reference.iter().map(|p| display(*p)).collect();
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let mut total = 0.0;
    let mut windows = 0u64;
    for y in R..height.saturating_sub(R) {
        for x in R..width.saturating_sub(R) {
            let (mut ma, mut mb, mut aa, mut bb, mut ab) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for yy in y - R..=y + R {
                for xx in x - R..=x + R {
                    let (u, v) = (a[yy * width + xx], b[yy * width + xx]);
                    ma += u;
                    mb += v;
                    aa += u * u;
                    bb += v * v;
                    ab += u * v;
                }
            }
            let n = ((2 * R + 1) * (2 * R + 1)) as f64;
            let (ma, mb) = (ma / n, mb / n);
            let (va, vb, cov) = (aa / n - ma * ma, bb / n - mb * mb, ab / n - ma * mb);
            total += ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            windows += 1;
        }
    }
    if windows == 0 {
        1.0
    } else {
        total / windows as f64
    }
}

/// The largest difference of a per-pixel quantity between a pixel and its four neighbours.
fn largest_step(width: usize, height: usize, diff: impl Fn(usize, usize) -> f32) -> Vec<f32> {
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let mut m = 0.0f32;
            for (dx, dy) in [(-1isize, 0isize), (1, 0), (0, -1), (0, 1)] {
                let (qx, qy) = (x as isize + dx, y as isize + dy);
                if qx >= 0 && qy >= 0 && (qx as usize) < width && (qy as usize) < height {
                    m = m.max(diff(i, qy as usize * width + qx as usize));
                }
            }
            m
        })
        .collect()
}

/// Textured pixels: where the albedo changes by more than 0.05 to a neighbour.
pub fn textured(albedo: &[[f32; 3]], width: usize, height: usize) -> Vec<bool> {
    largest_step(width, height, |p, q| {
        (0..3)
            .map(|c| (albedo[p][c] - albedo[q][c]).abs())
            .fold(0.0, f32::max)
    })
    .into_iter()
    .map(|s| s > 0.05)
    .collect()
}

/// Geometric edges: where the normal turns by more than 25 degrees to a neighbour, or the
/// depth jumps by more than 5%, or a surface meets no surface.
pub fn edges(normal: &[[f32; 3]], depth: &[f32], width: usize, height: usize) -> Vec<bool> {
    largest_step(width, height, |p, q| {
        let (a, b) = (normal[p], normal[q]);
        let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let jump = (depth[p] - depth[q]).abs() / depth[p].abs().max(depth[q].abs()).max(1e-6);
        if (a == [0.0; 3]) != (b == [0.0; 3]) || (a != [0.0; 3] && cos < 0.906) || jump > 0.05 {
            1.0
        } else {
            0.0
        }
    })
    .into_iter()
    .map(|s| s > 0.5)
    .collect()
}

/// Caustic and other hard-to-sample pixels, found from a long reference render: the
/// `fraction` of pixels whose samples vary most for their brightness (the variance of a
/// sample, the pixel value's variance times `spp`, over the value squared plus 0.01).
pub fn hard_to_sample(
    color: &[[f32; 3]],
    variance: &[[f32; 3]],
    spp: u32,
    fraction: f64,
) -> Vec<bool> {
    let score: Vec<f64> = color
        .iter()
        .zip(variance)
        .map(|(c, v)| {
            (0..3)
                .map(|k| v[k] as f64 * spp as f64 / ((c[k] as f64).powi(2) + 0.01))
                .sum::<f64>()
        })
        .collect();
    let mut sorted = score.clone();
    sorted.sort_by(f64::total_cmp);
    let keep = ((sorted.len() as f64 * fraction) as usize).min(sorted.len());
    if keep == 0 {
        return vec![false; score.len()];
    }
    let threshold = sorted[sorted.len() - keep];
    score.iter().map(|s| *s >= threshold && *s > 0.0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_no_error_and_full_similarity() {
        let img: Vec<[f32; 3]> = (0..100).map(|i| [i as f32 / 100.0, 0.5, 0.1]).collect();
        assert_eq!(rel_mse(&img, &img, None), 0.0);
        assert!((ssim(&img, &img, 10, 10) - 1.0).abs() < 1e-12);
        let off: Vec<[f32; 3]> = img.iter().map(|p| [p[0] + 0.1, p[1], p[2]]).collect();
        let e = rel_mse(&off, &img, None);
        assert!(e > 0.0 && e < 0.34, "{e}");
        assert!(ssim(&off, &img, 10, 10) < 1.0);
    }

    #[test]
    fn masks_find_what_they_name() {
        // A 4x1 strip: albedo steps between the second and third pixels.
        let albedo = [[0.2; 3], [0.2; 3], [0.8; 3], [0.8; 3]];
        assert_eq!(textured(&albedo, 4, 1), [false, true, true, false]);
        let normal = [[0.0, 0.0, 1.0]; 4];
        let depth = [1.0, 1.0, 1.0, 2.0];
        assert_eq!(edges(&normal, &depth, 4, 1), [false, false, true, true]);
        let color = [[1.0; 3]; 4];
        let variance = [[0.0; 3], [0.1; 3], [0.0; 3], [0.0; 3]];
        assert_eq!(
            hard_to_sample(&color, &variance, 16, 0.25),
            [false, true, false, false]
        );
    }
}
