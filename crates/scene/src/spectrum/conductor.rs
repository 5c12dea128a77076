//! Conductors' Fresnel reflectance computed spectrally from their sampled eta and k, then
//! tabulated as linear sRGB over the cosine: what an RGB renderer needs to keep a saturated
//! metal's colour.

use super::{
    LAMBDA_MIN, TABLE_LEN, TABLE_STEP, d65_reference, integrate_xyz, spectrum_at, xyz_to_srgb,
};

/// Entries of a [`conductor_fresnel_rgb`] table: cos θ = i / (N − 1), i = 0..N.
pub const FRESNEL_TABLE_LEN: usize = 65;

/// A conductor's Fresnel reflectance as linear sRGB at [`FRESNEL_TABLE_LEN`] evenly spaced
/// cosines from 0 to 1, computed spectrally: at each cosine the reflectance spectrum
/// F(λ) from the complex index (eta(λ) + i k(λ)) / `outside_eta` (every 5 nm), projected to
/// RGB as a reflectance. Projecting eta and k to RGB first and taking the Fresnel of those
/// is what an RGB renderer otherwise does; for gold it misses the spectral red by 5% at
/// normal incidence (pbrt-v4 renders it spectrally). Channels may pass 1, as the spectral
/// reflectance's RGB does for saturated metals.
pub fn conductor_fresnel_rgb(
    eta: &[(f32, f32)],
    k: &[(f32, f32)],
    outside_eta: f32,
) -> Result<Vec<[f32; 3]>, String> {
    let check = |pairs: &[(f32, f32)], what: &str| -> Result<Vec<(f64, f64)>, String> {
        if pairs.is_empty()
            || pairs.iter().any(|p| !p.0.is_finite() || !p.1.is_finite())
            || pairs.windows(2).any(|w| w[1].0 <= w[0].0)
        {
            return Err(format!(
                "{what}: wavelengths must be increasing and values finite"
            ));
        }
        Ok(pairs
            .iter()
            .map(|&(l, v)| (f64::from(l), f64::from(v)))
            .collect())
    };
    let (eta, k) = (check(eta, "eta")?, check(k, "k")?);
    let outside = f64::from(outside_eta);
    let lambdas: Vec<f64> = (0..TABLE_LEN)
        .map(|i| LAMBDA_MIN + TABLE_STEP * i as f64)
        .collect();
    let (white, d65_y) = d65_reference();
    Ok((0..FRESNEL_TABLE_LEN)
        .map(|i| {
            let cos = i as f64 / (FRESNEL_TABLE_LEN - 1) as f64;
            let f: Vec<(f64, f64)> = lambdas
                .iter()
                .map(|&l| {
                    let (n, kk) = (spectrum_at(&eta, l) / outside, spectrum_at(&k, l) / outside);
                    (l, fresnel_conductor(cos, n, kk))
                })
                .collect();
            let rgb = xyz_to_srgb(integrate_xyz(&f, true).map(|v| v / d65_y));
            std::array::from_fn(|c| (rgb[c] / white[c]).max(0.0) as f32)
        })
        .collect())
}

/// Unpolarised Fresnel reflectance of a conductor of complex index n + i k at cos θ.
fn fresnel_conductor(cos: f64, n: f64, k: f64) -> f64 {
    // With a² + b² = |η² − sin²θ| and a² − b² = Re(η² − sin²θ) (the textbook form).
    let cos = cos.clamp(0.0, 1.0);
    let sin2 = 1.0 - cos * cos;
    let re = n * n - k * k - sin2;
    let im = 2.0 * n * k;
    let modulus = (re * re + im * im).sqrt();
    let a2 = (0.5 * (modulus + re)).max(0.0);
    let a = a2.sqrt();
    let rs = (modulus + cos * cos - 2.0 * a * cos) / (modulus + cos * cos + 2.0 * a * cos);
    let rp = rs * (cos * cos * modulus + sin2 * sin2 - 2.0 * a * cos * sin2)
        / (cos * cos * modulus + sin2 * sin2 + 2.0 * a * cos * sin2);
    let r = 0.5 * (rs + rp);
    if r.is_finite() { r } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flat spectra have no colour to lose: the table is the Fresnel of the constants
    /// (aluminium-like n = 1.2, k = 7: 0.92 at normal incidence by the closed form
    /// ((n−1)² + k²)/((n+1)² + k²)), and 1 at grazing.
    #[test]
    fn flat_spectra_give_the_fresnel_of_the_constants() {
        let flat = |v: f32| vec![(300.0, v), (900.0, v)];
        let t = conductor_fresnel_rgb(&flat(1.2), &flat(7.0), 1.0).unwrap();
        let r0 = (0.2f32 * 0.2 + 49.0) / (2.2 * 2.2 + 49.0);
        for c in 0..3 {
            assert!(
                (t[FRESNEL_TABLE_LEN - 1][c] - r0).abs() < 1e-3,
                "{:?}",
                t.last()
            );
            assert!((t[0][c] - 1.0).abs() < 1e-3, "{:?}", t[0]);
        }
        // Seen from inside a coat of index 1.5, eta and k are divided by it.
        let coated = conductor_fresnel_rgb(&flat(1.8), &flat(10.5), 1.5).unwrap();
        assert!((coated[FRESNEL_TABLE_LEN - 1][1] - r0).abs() < 1e-3);
        assert!(conductor_fresnel_rgb(&[(500.0, 1.0), (400.0, 1.0)], &flat(1.0), 1.0).is_err());
    }
}
