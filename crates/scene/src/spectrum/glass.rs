//! Glasses' dispersion: the index of refraction over wavelength, for spectral rendering.

/// The index of refraction of a named glass over 360–830 nm (every 10 nm), for glasses
/// whose dispersion Kiln knows: `glass-BK7` from Schott's Sellmeier coefficients for
/// N-BK7 (n(λ)² = 1 + Σ Bᵢ λ² / (λ² − Cᵢ), λ in µm; 1.5185 at 550 nm). Other names: None
/// (they refract by their index at 550 nm, without dispersion).
pub fn glass_index(name: &str) -> Option<Vec<(f32, f32)>> {
    let (b, c): ([f64; 3], [f64; 3]) = match name {
        "glass-BK7" => (
            [1.039_612_12, 0.231_792_344, 1.010_469_45],
            [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
        ),
        _ => return None,
    };
    Some(
        (0..=47)
            .map(|i| {
                let lambda = 360.0 + 10.0 * i as f64;
                let l2 = (lambda / 1000.0).powi(2);
                let n2 = 1.0 + (0..3).map(|k| b[k] * l2 / (l2 - c[k])).sum::<f64>();
                (lambda as f32, n2.sqrt() as f32)
            })
            .collect(),
    )
}
