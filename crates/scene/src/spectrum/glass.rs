//! Glasses' dispersion: the index of refraction over wavelength, for spectral rendering.

/// The index of refraction of a named glass over 360–830 nm (every 10 nm), from Schott's
/// Sellmeier coefficients (n(λ)² = 1 + Σ Bᵢ λ² / (λ² − Cᵢ), λ in µm) for pbrt-v4's named
/// glasses: `glass-BK7` (N-BK7), `glass-BAF10` (N-BAF10), `glass-FK51A` (N-FK51A),
/// `glass-LASF9` (N-LASF9), and `glass-F5`, `glass-F10`, `glass-F11`, which are the dense
/// flints SF5, SF10 and SF11 (their indices at 550 nm are pbrt-v4's: the test
/// `named_glasses_have_their_index_at_550_nm`). Other names: None.
pub fn glass_index(name: &str) -> Option<Vec<(f32, f32)>> {
    let (b, c): ([f64; 3], [f64; 3]) = match name {
        "glass-BK7" => (
            [1.039_612_12, 0.231_792_344, 1.010_469_45],
            [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
        ),
        "glass-BAF10" => (
            [1.585_149_5, 0.143_559_385, 1.085_212_69],
            [0.009_266_812_82, 0.042_448_980_5, 105.613_573],
        ),
        "glass-FK51A" => (
            [0.971_247_817, 0.216_901_417, 0.904_651_666],
            [0.004_723_019_95, 0.015_357_561_2, 168.681_33],
        ),
        "glass-LASF9" => (
            [2.000_295_47, 0.298_926_886, 1.806_918_43],
            [0.012_142_601_7, 0.053_873_623_6, 156.530_829],
        ),
        "glass-F5" => (
            [1.524_818_89, 0.187_085_527, 1.427_290_15],
            [0.011_254_756, 0.058_899_539_2, 129.141_675],
        ),
        "glass-F10" => (
            [1.621_539_02, 0.256_287_842, 1.644_475_52],
            [0.012_224_145_7, 0.059_573_677_5, 147.468_793],
        ),
        "glass-F11" => (
            [1.737_596_95, 0.313_747_346, 1.898_781_01],
            [0.013_188_707, 0.062_306_814_2, 155.236_29],
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every named glass has pbrt-v4's index at 550 nm (the RGB table's, from pbrt-v4's
    /// data) within 1e-4, and disperses normally: its index falls with wavelength.
    #[test]
    fn named_glasses_have_their_index_at_550_nm() {
        for name in [
            "glass-BK7",
            "glass-BAF10",
            "glass-FK51A",
            "glass-LASF9",
            "glass-F5",
            "glass-F10",
            "glass-F11",
        ] {
            let n = glass_index(name).unwrap();
            let at_550 = n.iter().find(|p| p.0 == 550.0).unwrap().1;
            let want = crate::spectrum::named_spectrum_rgb(name).unwrap()[0];
            assert!((at_550 - want).abs() < 1e-4, "{name}: {at_550} vs {want}");
            assert!(n.windows(2).all(|w| w[1].1 < w[0].1), "{name}: {n:?}");
        }
        assert!(glass_index("glass-unknown").is_none());
    }
}
