//! The emitted power of pbrt-v4's image-shaped point lights per unit of their scale: what
//! a scene's "power" is divided by (pbrt-v4's k_e), and what the renderer weighs them by
//! when it chooses lights. One place, so the two always agree.

use kiln_image::ImageRgb;

/// The mean over a goniometric image's pixels of their RGB mean (the intensity it gives
/// a light of intensity 1); the light's power is 4π times this, times its intensity.
pub fn goniometric_mean(image: &ImageRgb) -> f64 {
    let sum: f64 = image
        .pixels
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]) / 3.0)
        .sum();
    sum / image.pixels.len().max(1) as f64
}

/// A projection light's power (luminance) at scale 1: the image's area on the plane at
/// distance 1, times the mean over its pixels of luminance · cos³θ (the solid angle each
/// pixel subtends there), as pbrt-v4 computes it.
pub fn projection_power(image: &ImageRgb, fov_degrees: f64) -> f64 {
    let (w, h) = (image.width, image.height);
    let aspect = f64::from(w) / f64::from(h);
    let tan = libm::tan(fov_degrees.to_radians() / 2.0);
    let (sx, sy) = if aspect > 1.0 {
        (aspect, 1.0)
    } else {
        (1.0, 1.0 / aspect)
    };
    let mut sum = 0.0;
    for y in 0..h {
        for x in 0..w {
            let px = -sx + 2.0 * sx * (f64::from(x) + 0.5) / f64::from(w);
            let py = -sy + 2.0 * sy * (f64::from(y) + 0.5) / f64::from(h);
            let cos = 1.0 / (px * px * tan * tan + py * py * tan * tan + 1.0).sqrt();
            let p = image.pixels[(y * w + x) as usize];
            let lum = 0.2126 * f64::from(p[0].max(0.0))
                + 0.7152 * f64::from(p[1].max(0.0))
                + 0.0722 * f64::from(p[2].max(0.0));
            sum += lum * cos.powi(3);
        }
    }
    4.0 * tan * tan * aspect.max(1.0 / aspect) * sum / image.pixels.len().max(1) as f64
}
