//! The film's response for spectral rendering: linear sRGB per wavelength.

use super::{LAMBDA_MAX, LAMBDA_MIN, cmf_at, d65_at, d65_reference, xyz_to_srgb};

/// For spectral rendering, every nanometre from 360 to 830: the linear sRGB response
/// (r̄, ḡ, b̄)(λ) = XYZ→sRGB · (x̄, ȳ, z̄)(λ), divided channel by channel by the D65
/// white correction as every conversion here is, and D65(λ) / ∫ D65·ȳ. A spectrum S then
/// has the sRGB ∫ S·(r̄, ḡ, b̄): D65 so normalised is (1, 1, 1) exactly, and a reflectance
/// ρ under it is the RGB [`SpectrumUse::Albedo`] gives ρ.
pub fn srgb_response_per_nm() -> Vec<[f64; 4]> {
    let (white, d65_y) = d65_reference();
    let n = (LAMBDA_MAX - LAMBDA_MIN) as usize;
    (0..=n)
        .map(|i| {
            let l = LAMBDA_MIN + i as f64;
            let rgb = xyz_to_srgb(cmf_at(l));
            [
                rgb[0] / white[0],
                rgb[1] / white[1],
                rgb[2] / white[2],
                d65_at(l) / d65_y,
            ]
        })
        .collect()
}
