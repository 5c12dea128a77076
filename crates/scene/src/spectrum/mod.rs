//! Non-RGB colour parameters (named spectra, inline sampled spectra, blackbodies) → linear sRGB.
//!
//! pbrt-v4 renders spectrally; Kiln renders in linear sRGB (Rec.709 primaries, D65 white), so
//! every spectrum in a scene is reduced to an RGB triple once, at load time.
//!
//! Method, all in f64:
//! * Spectra are piecewise linear in λ (held constant beyond their end points); the CIE 1931 2°
//!   colour matching functions and D65 are tabulated every 5 nm over 360–830 nm and interpolated
//!   linearly too. Between consecutive breakpoints (table nodes plus the spectrum's own
//!   wavelengths) the integrand is a product of at most three linear functions, a cubic, which
//!   Simpson's rule integrates exactly: no sampling error, and narrow spikes in inline spectra
//!   are not missed.
//! * XYZ → linear sRGB uses the IEC 61966-2-1 matrix. Its white point is the rounded D65
//!   chromaticity, while the tabulated D65 integrates to a point a hair away (≤ 2e-4 in RGB),
//!   so every result is divided channel by channel by the RGB of the D65 table: a constant
//!   reflectance and the D65 illuminant then come out exactly neutral, as `rgb` values do.

mod conductor;
mod glass;
mod illuminants;
mod response;

pub use conductor::{FRESNEL_TABLE_LEN, conductor_fresnel_rgb};
pub use glass::glass_index;
pub use illuminants::{named_illuminant_spectrum, own_luminance};
pub use response::srgb_response_per_nm;

use std::sync::OnceLock;

/// Linear sRGB.
pub type Rgb = [f32; 3];

/// How a spectrum is used decides how it becomes RGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpectrumUse {
    /// Reflectances and other values in [0,1]: RGB as seen under the D65 illuminant, so a
    /// constant spectrum c maps to (c, c, c) (within 1e-3 relative).
    Albedo,
    /// Emission: XYZ from the CIE 1931 2-degree colour matching functions, then to linear sRGB.
    /// The D65 illuminant spectrum (pbrt's "stdillum-D65") must come out close to neutral
    /// (r≈g≈b within 1%), scaled so its luminance Y is 1.
    Illuminant,
    /// Unbounded non-emissive quantities (index of refraction eta, absorption k): each RGB
    /// channel is the spectrum averaged against that channel's response, such that a constant
    /// spectrum c maps to (c, c, c).
    Unbounded,
}

/// First wavelength of the tables and of the integration range, nm.
pub(crate) const LAMBDA_MIN: f64 = 360.0;
/// Last wavelength of the tables and of the integration range, nm.
pub(crate) const LAMBDA_MAX: f64 = 830.0;
/// Spacing of the tables, nm.
const TABLE_STEP: f64 = 5.0;
/// Entries per table: 360, 365, …, 830 nm.
const TABLE_LEN: usize = 95;

/// CIE 1931 2° x̄(λ), 360–830 nm every 5 nm (CIE 015:2018 tabulation).
#[rustfmt::skip]
const CIE_X: [f64; 95] = [
    0.0001299, 0.0002321, 0.0004149, 0.0007416, 0.001368, 0.002236, 0.004243, 0.00765, 0.01431,
    0.02319, 0.04351, 0.07763, 0.13438, 0.21477, 0.2839, 0.3285, 0.34828, 0.34806, 0.3362, 0.3187,
    0.2908, 0.2511, 0.19536, 0.1421, 0.09564, 0.05795001, 0.03201, 0.0147, 0.0049, 0.0024, 0.0093,
    0.0291, 0.06327, 0.1096, 0.1655, 0.2257499, 0.2904, 0.3597, 0.4334499, 0.5120501, 0.5945,
    0.6784, 0.7621, 0.8425, 0.9163, 0.9786, 1.0263, 1.0567, 1.0622, 1.0456, 1.0026, 0.9384,
    0.8544499, 0.7514, 0.6424, 0.5419, 0.4479, 0.3608, 0.2835, 0.2187, 0.1649, 0.1212, 0.0874,
    0.0636, 0.04677, 0.0329, 0.0227, 0.01584, 0.01135916, 0.008110916, 0.005790346, 0.004109457,
    0.002899327, 0.00204919, 0.001439971, 0.0009999493, 0.0006900786, 0.0004760213, 0.0003323011,
    0.0002348261, 0.0001661505, 0.000117413, 8.307527e-5, 5.870652e-5, 4.150994e-5, 2.935326e-5,
    2.067383e-5, 1.455977e-5, 1.025398e-5, 7.221456e-6, 5.085868e-6, 3.581652e-6, 2.522525e-6,
    1.776509e-6, 1.251141e-6,
];

/// CIE 1931 2° ȳ(λ), same grid.
#[rustfmt::skip]
const CIE_Y: [f64; 95] = [
    3.917e-6, 6.965e-6, 1.239e-5, 2.202e-5, 3.9e-5, 6.4e-5, 0.00012, 0.000217, 0.000396, 0.00064,
    0.00121, 0.00218, 0.004, 0.0073, 0.0116, 0.01684, 0.023, 0.0298, 0.038, 0.048, 0.06, 0.0739,
    0.09098, 0.1126, 0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, 0.503, 0.6082, 0.71, 0.7932,
    0.862, 0.9148501, 0.954, 0.9803, 0.9949501, 1.0, 0.995, 0.9786, 0.952, 0.9154, 0.87, 0.8163,
    0.757, 0.6949, 0.631, 0.5668, 0.503, 0.4412, 0.381, 0.321, 0.265, 0.217, 0.175, 0.1382, 0.107,
    0.0816, 0.061, 0.04458, 0.032, 0.0232, 0.017, 0.01192, 0.00821, 0.005723, 0.004102, 0.002929,
    0.002091, 0.001484, 0.001047, 0.00074, 0.00052, 0.0003611, 0.0002492, 0.0001719, 0.00012,
    8.48e-5, 6e-5, 4.24e-5, 3e-5, 2.12e-5, 1.499e-5, 1.06e-5, 7.4657e-6, 5.2578e-6, 3.7029e-6,
    2.6078e-6, 1.8366e-6, 1.2934e-6, 9.1093e-7, 6.4153e-7, 4.5181e-7,
];

/// CIE 1931 2° z̄(λ), same grid.
#[rustfmt::skip]
const CIE_Z: [f64; 95] = [
    0.0006061, 0.001086, 0.001946, 0.003486, 0.006450001, 0.01054999, 0.02005001, 0.03621,
    0.06785001, 0.1102, 0.2074, 0.3713, 0.6456, 1.03905, 1.3856, 1.62296, 1.74706, 1.7826, 1.77211,
    1.7441, 1.6692, 1.5281, 1.28764, 1.0419, 0.8129501, 0.6162, 0.46518, 0.3533, 0.272, 0.2123,
    0.1582, 0.1117, 0.07824999, 0.05725001, 0.04216, 0.02984, 0.0203, 0.0134, 0.008749999,
    0.005749999, 0.0039, 0.002749999, 0.0021, 0.0018, 0.001650001, 0.0014, 0.0011, 0.001, 0.0008,
    0.0006, 0.00034, 0.00024, 0.00019, 0.0001, 4.999999e-5, 3e-5, 2e-5, 1e-5, -1.905824e-21, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
];

/// CIE standard illuminant D65 relative SPD, same grid (CIE tabulation, 100 at 560 nm).
#[rustfmt::skip]
const D65: [f64; 95] = [
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, 82.7549, 87.1204,
    91.486, 92.4589, 93.4318, 90.057, 86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41, 117.812,
    116.336, 114.861, 115.392, 115.923, 112.367, 108.811, 109.082, 109.354, 108.578, 107.802,
    106.296, 104.79, 106.239, 107.689, 106.047, 104.405, 104.225, 104.046, 102.023, 100.0, 98.1671,
    96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459, 90.0062, 89.8026, 89.5991, 88.6489,
    87.6987, 85.4936, 83.2886, 83.4939, 83.6992, 81.863, 80.0268, 80.1207, 80.2146, 81.2462,
    82.2778, 80.281, 78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979, 74.349, 67.9765, 61.604,
    65.7448, 69.8856, 72.4863, 75.087, 69.3398, 63.5927, 55.0054, 46.4182, 56.6118, 66.8054,
    65.0941, 63.3828, 63.8434, 64.304, 61.8779, 59.4519, 55.7054, 51.959, 54.6998, 57.4406,
    58.8765, 60.3125,
];

/// CIE XYZ → linear sRGB (IEC 61966-2-1, D65 white).
pub(crate) const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
];

/// Linear interpolation in one of the 5 nm tables, clamped to its ends.
fn table_at(table: &[f64; TABLE_LEN], lambda: f64) -> f64 {
    let x = ((lambda - LAMBDA_MIN) / TABLE_STEP).clamp(0.0, (TABLE_LEN - 1) as f64);
    let i = (x as usize).min(TABLE_LEN - 2);
    let u = x - i as f64;
    table[i] * (1.0 - u) + table[i + 1] * u
}

/// A validated piecewise-linear spectrum (wavelengths strictly increasing) evaluated at
/// `lambda`; constant beyond its ends.
pub fn spectrum_at(pairs: &[(f64, f64)], lambda: f64) -> f64 {
    let (l_first, v_first) = pairs[0];
    let (l_last, v_last) = pairs[pairs.len() - 1];
    if lambda <= l_first {
        return v_first;
    }
    if lambda >= l_last {
        return v_last;
    }
    // First pair strictly above `lambda`; the checks above put it in 1..len.
    let j = pairs.partition_point(|p| p.0 <= lambda);
    let (l0, v0) = pairs[j - 1];
    let (l1, v1) = pairs[j];
    v0 + (v1 - v0) * (lambda - l0) / (l1 - l0)
}

/// ∫ S(λ) · D65(λ)? · (x̄, ȳ, z̄)(λ) dλ over 360–830 nm, exact for piecewise-linear S (see the
/// module docs). `under_d65` adds the D65 factor (reflectances seen under daylight).
fn integrate_xyz(pairs: &[(f64, f64)], under_d65: bool) -> [f64; 3] {
    integrate_xyz_over(pairs, under_d65, LAMBDA_MIN, LAMBDA_MAX)
}

/// [`integrate_xyz`] over `lo`..`hi` only (within 360–830 nm).
fn integrate_xyz_over(pairs: &[(f64, f64)], under_d65: bool, lo: f64, hi: f64) -> [f64; 3] {
    if lo >= hi {
        return [0.0; 3];
    }
    let mut breaks: Vec<f64> = (0..TABLE_LEN)
        .map(|i| LAMBDA_MIN + TABLE_STEP * i as f64)
        .filter(|&l| l > lo && l < hi)
        .collect();
    breaks.push(lo);
    breaks.push(hi);
    breaks.extend(pairs.iter().map(|p| p.0).filter(|&l| l > lo && l < hi));
    breaks.sort_by(f64::total_cmp);
    breaks.dedup();
    let integrand = |l: f64| {
        let light = if under_d65 { table_at(&D65, l) } else { 1.0 };
        let s = spectrum_at(pairs, l) * light;
        [
            s * table_at(&CIE_X, l),
            s * table_at(&CIE_Y, l),
            s * table_at(&CIE_Z, l),
        ]
    };
    let mut acc = [0.0; 3];
    let mut fa = integrand(breaks[0]);
    for w in breaks.windows(2) {
        let (a, b) = (w[0], w[1]);
        let fm = integrand(0.5 * (a + b));
        let fb = integrand(b);
        for (c, sum) in acc.iter_mut().enumerate() {
            *sum += (b - a) / 6.0 * (fa[c] + 4.0 * fm[c] + fb[c]);
        }
        fa = fb;
    }
    acc
}

/// Linear sRGB to CIE XYZ (the inverse of the conversion Kiln uses out of XYZ).
pub const SRGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124564, 0.3575761, 0.1804375],
    [0.2126729, 0.7151522, 0.0721750],
    [0.0193339, 0.1191920, 0.9503041],
];

/// The Bradford cone response matrix, which pbrt-v4 uses for its LMS space.
const LMS_FROM_XYZ: [[f64; 3]; 3] = [
    [0.8951, 0.2664, -0.1614],
    [-0.7502, 1.7135, 0.0367],
    [0.0389, -0.0685, 1.0296],
];

pub(crate) fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// The determinant of a 3×3 matrix.
pub(crate) fn det3(m: &[[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

pub(crate) fn inverse3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = det3(m);
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            // The cofactor of (j, i), over the determinant.
            let (r0, r1) = ([1, 0, 0][j], [2, 2, 1][j]);
            let (c0, c1) = ([1, 0, 0][i], [2, 2, 1][i]);
            let minor = m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
            let sign = if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
            sign * minor / det
        })
    })
}

/// The chromaticity (x, y) of pbrt-v4's "daylight" at colour temperature `kelvin`: the
/// temperature corrected for the revised second radiation constant (T · 1.4388 / 1.4380),
/// then the CIE daylight locus, or below 4000 K (where CIE daylight is not defined) a
/// blackbody at that temperature, as pbrt-v4's `Spectra::D` does.
pub fn daylight_xy(kelvin: f64) -> [f64; 2] {
    let t = kelvin * 1.4388 / 1.4380;
    if t < 4000.0 {
        let xyz = integrate_xyz(&blackbody_samples(t, false), false);
        let sum: f64 = xyz.iter().sum();
        return [xyz[0] / sum, xyz[1] / sum];
    }
    let x = if t <= 7000.0 {
        -4.6070e9 / t.powi(3) + 2.9678e6 / (t * t) + 0.09911e3 / t + 0.244063
    } else {
        -2.0064e9 / t.powi(3) + 1.9018e6 / (t * t) + 0.24748e3 / t + 0.237040
    };
    [x, -3.0 * x * x + 2.870 * x - 0.275]
}

/// The components S0, S1, S2 of CIE daylight, 360–830 nm every 10 nm (CIE 015:2018
/// tabulation): daylight of any correlated colour temperature is S0 + M1·S1 + M2·S2.
#[rustfmt::skip]
const DAYLIGHT_S: [[f64; 3]; 48] = [
    [61.5, 38.0, 5.3], [68.8, 42.4, 6.1], [63.4, 38.5, 3.0], [65.8, 35.0, 1.2], [94.8, 43.4, -1.1],
    [104.8, 46.3, -0.5], [105.9, 43.9, -0.7], [96.8, 37.1, -1.2], [113.9, 36.7, -2.6],
    [125.6, 35.9, -2.9], [125.5, 32.6, -2.8], [121.3, 27.9, -2.6], [121.3, 24.3, -2.6],
    [113.5, 20.1, -1.8], [113.1, 16.2, -1.5], [110.8, 13.2, -1.3], [106.5, 8.6, -1.2],
    [108.8, 6.1, -1.0], [105.3, 4.2, -0.5], [104.4, 1.9, -0.3], [100.0, 0.0, 0.0],
    [96.0, -1.6, 0.2], [95.1, -3.5, 0.5], [89.1, -3.5, 2.1], [90.5, -5.8, 3.2], [90.3, -7.2, 4.1],
    [88.4, -8.6, 4.7], [84.0, -9.5, 5.1], [85.1, -10.9, 6.7], [81.9, -10.7, 7.3],
    [82.6, -12.0, 8.6], [84.9, -14.0, 9.8], [81.3, -13.6, 10.2], [71.9, -12.0, 8.3],
    [74.3, -13.3, 9.6], [76.4, -12.9, 8.5], [63.3, -10.6, 7.0], [71.7, -11.6, 7.6],
    [77.0, -12.2, 8.0], [65.2, -10.2, 6.7], [47.7, -7.8, 5.2], [68.6, -11.2, 7.4],
    [65.0, -10.4, 6.8], [66.0, -10.6, 7.0], [61.0, -9.7, 6.4], [53.3, -8.3, 5.5],
    [58.9, -9.3, 6.1], [61.9, -9.8, 6.5],
];

/// pbrt-v4's daylight illuminant D(T) (`Spectra::D`) as (wavelength nm, relative power)
/// pairs, piecewise linear: for a corrected temperature of 4000 K or more the CIE daylight
/// at the chromaticity [`daylight_xy`] gives, below it a blackbody. Only its shape is
/// meaningful (it is normalised wherever it is used).
pub(crate) fn daylight_samples(kelvin: f64) -> Vec<(f64, f64)> {
    let t = kelvin * 1.4388 / 1.4380;
    if t < 4000.0 {
        return blackbody_samples(t, false);
    }
    let [x, y] = daylight_xy(kelvin);
    let m = 0.0241 + 0.2562 * x - 0.7341 * y;
    let m1 = (-1.3515 - 1.7703 * x + 5.9114 * y) / m;
    let m2 = (0.0300 - 31.4424 * x + 30.0717 * y) / m;
    DAYLIGHT_S
        .iter()
        .enumerate()
        .map(|(i, s)| (LAMBDA_MIN + 10.0 * i as f64, s[0] + m1 * s[1] + m2 * s[2]))
        .collect()
}

/// The CIE 1931 colour matching functions (x̄, ȳ, z̄) at `lambda` nm, interpolated linearly
/// in the 5 nm tables (0 is never returned inside 360–830 nm; held at the ends beyond).
pub(crate) fn cmf_at(lambda: f64) -> [f64; 3] {
    [
        table_at(&CIE_X, lambda),
        table_at(&CIE_Y, lambda),
        table_at(&CIE_Z, lambda),
    ]
}

/// The CIE D65 illuminant at `lambda` nm (relative, 100 at 560 nm).
pub(crate) fn d65_at(lambda: f64) -> f64 {
    table_at(&D65, lambda)
}

/// pbrt-v4's white balance for a film ("whitebalance" in kelvin): a von Kries adaptation in
/// Bradford's cone space from daylight at that temperature to the sRGB white (D65), as a
/// matrix on linear sRGB.
pub fn white_balance_srgb(kelvin: f64) -> [[f64; 3]; 3] {
    let xyz_of = |xy: [f64; 2]| [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]];
    let xyz_wb = bradford_between(xyz_of(daylight_xy(kelvin)), xyz_of([0.3127, 0.3290]));
    mul3(&XYZ_TO_SRGB, &mul3(&xyz_wb, &SRGB_TO_XYZ))
}

/// The von Kries adaptation in Bradford's cone space taking white `src` to white `dst`
/// (both XYZ), as a matrix on XYZ.
pub(crate) fn bradford_between(src: [f64; 3], dst: [f64; 3]) -> [[f64; 3]; 3] {
    let lms = |xyz: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| (0..3).map(|k| LMS_FROM_XYZ[r][k] * xyz[k]).sum())
    };
    let (src, dst) = (lms(src), lms(dst));
    let mut diag = [[0.0; 3]; 3];
    for c in 0..3 {
        diag[c][c] = dst[c] / src[c];
    }
    mul3(&inverse3(&LMS_FROM_XYZ), &mul3(&diag, &LMS_FROM_XYZ))
}

fn xyz_to_srgb(xyz: [f64; 3]) -> [f64; 3] {
    XYZ_TO_SRGB.map(|row| row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2])
}

/// The D65 reference: (RGB of the D65 table normalised to Y = 1, ∫ D65·ȳ). The first is the
/// per-channel white correction, the second normalises reflectances.
fn d65_reference() -> ([f64; 3], f64) {
    static REF: OnceLock<([f64; 3], f64)> = OnceLock::new();
    *REF.get_or_init(|| {
        let xyz = integrate_xyz(&[(560.0, 1.0)], true);
        (xyz_to_srgb(xyz.map(|v| v / xyz[1])), xyz[1])
    })
}

/// What a sampled spectrum is beyond its first and last wavelengths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ends {
    /// Its end values carry on (pbrt-v4's named spectra, which it extends to the visible
    /// range).
    Constant,
    /// Zero: pbrt-v4's `PiecewiseLinearSpectrum` for a spectrum a scene gives, inline or in
    /// a file, which it does not extend.
    Zero,
}

/// Shared conversion for validated spectra. Negative channels (spectra outside the sRGB gamut)
/// are clamped to 0: negative reflectance, IOR or emission is meaningless to the renderer.
fn spectrum_to_rgb(pairs: &[(f64, f64)], usage: SpectrumUse) -> Result<[f32; 3], String> {
    spectrum_to_rgb_with(pairs, usage, Ends::Constant)
}

fn spectrum_to_rgb_with(
    pairs: &[(f64, f64)],
    usage: SpectrumUse,
    ends: Ends,
) -> Result<[f32; 3], String> {
    let (lo, hi) = match ends {
        Ends::Constant => (LAMBDA_MIN, LAMBDA_MAX),
        Ends::Zero => (
            pairs[0].0.max(LAMBDA_MIN),
            pairs[pairs.len() - 1].0.min(LAMBDA_MAX),
        ),
    };
    let integrate_xyz =
        |pairs: &[(f64, f64)], under_d65| integrate_xyz_over(pairs, under_d65, lo, hi);
    let (white, d65_y) = d65_reference();
    let xyz = match usage {
        // rgb_c = ∫ S·w_c / ∫ w_c with w_c(λ) = (M · (x̄, ȳ, z̄)(λ))_c · D65(λ): the sRGB channel
        // responses under D65 (signed, as sRGB primaries lie inside the spectral locus; the
        // division by `white` is the ∫ w_c). Eta and k are weighted like reflectances, by what
        // the eye sees under white light, the light they will modulate. Checked against
        // spectral Fresnel: the normal-incidence reflectance computed from the RGB eta/k of
        // Cu, Ag and Al matches the RGB of the spectral reflectance within 0.011 (the
        // unweighted, equal-energy projection does slightly worse for Ag, Al and brass).
        SpectrumUse::Albedo | SpectrumUse::Unbounded => {
            integrate_xyz(pairs, true).map(|v| v / d65_y)
        }
        // As pbrt-v4 does for lights, only the colour is kept: the spectrum is normalised to
        // luminance Y = 1 and the scene's "scale"/"power" sets the brightness.
        SpectrumUse::Illuminant => {
            let xyz = integrate_xyz(pairs, false);
            if xyz[1] == 0.0 {
                return Ok([0.0; 3]);
            }
            if xyz[1] < 0.0 || !xyz[1].is_finite() {
                return Err(format!(
                    "emission spectrum has luminance Y = {} (it must be positive)",
                    xyz[1]
                ));
            }
            xyz.map(|v| v / xyz[1])
        }
    };
    let rgb = xyz_to_srgb(xyz);
    Ok(std::array::from_fn(|c| (rgb[c] / white[c]).max(0.0) as f32))
}

/// The linear map from a reflectance spectrum sampled at `wavelengths` (nm, increasing) to
/// linear sRGB, as [`SpectrumUse::Albedo`] converts it before clamping: entry k is the RGB of
/// the piecewise-linear "hat" that is 1 at wavelength k and 0 at the others (held constant
/// beyond the ends), so a spectrum's RGB is Σ_k value_k · weights[k].
pub fn albedo_rgb_weights(wavelengths: &[f32]) -> Result<Vec<[f64; 3]>, String> {
    if wavelengths.is_empty()
        || wavelengths.iter().any(|l| !l.is_finite())
        || wavelengths.windows(2).any(|w| w[1] <= w[0])
    {
        return Err("wavelengths must be finite and increasing".into());
    }
    let (white, d65_y) = d65_reference();
    let l: Vec<f64> = wavelengths.iter().map(|&v| f64::from(v)).collect();
    Ok((0..l.len())
        .map(|k| {
            let mut hat = Vec::with_capacity(3);
            if k > 0 {
                hat.push((l[k - 1], 0.0));
            }
            hat.push((l[k], 1.0));
            if k + 1 < l.len() {
                hat.push((l[k + 1], 0.0));
            }
            let rgb = xyz_to_srgb(integrate_xyz(&hat, true).map(|v| v / d65_y));
            std::array::from_fn(|c| rgb[c] / white[c])
        })
        .collect())
}

/// Linear sRGB of a piecewise-linear sampled spectrum given as (lambda nm, value) pairs sorted
/// by lambda (values outside the range are held constant at the end values). Returns
/// Err(message) if lambdas are not strictly increasing or fewer than 1 pair.
///
/// Also rejects non-finite numbers. [`SpectrumUse::Illuminant`] results are normalised to
/// luminance Y = 1 (an all-zero spectrum gives black); negative channels are clamped to 0.
pub fn sampled_to_rgb(pairs: &[(f32, f32)], usage: SpectrumUse) -> Result<[f32; 3], String> {
    sampled_to_rgb_with(pairs, usage, Ends::Constant)
}

/// [`sampled_to_rgb`] with the spectrum's values beyond its ends as `ends` says: a scene's
/// own spectra are zero there, as pbrt-v4 reads them.
pub fn sampled_to_rgb_with(
    pairs: &[(f32, f32)],
    usage: SpectrumUse,
    ends: Ends,
) -> Result<[f32; 3], String> {
    if pairs.is_empty() {
        return Err("a sampled spectrum needs at least one (wavelength, value) pair".into());
    }
    let mut checked: Vec<(f64, f64)> = Vec::with_capacity(pairs.len());
    for (i, &(lambda, value)) in pairs.iter().enumerate() {
        if !lambda.is_finite() || !value.is_finite() {
            return Err(format!(
                "pair {i} ({lambda} nm, {value}) is not a finite number"
            ));
        }
        let lambda = f64::from(lambda);
        if let Some(&(prev, _)) = checked.last()
            && lambda <= prev
        {
            return Err(format!(
                "wavelengths must be strictly increasing, but {lambda} nm follows {prev} nm"
            ));
        }
        checked.push((lambda, f64::from(value)));
    }
    spectrum_to_rgb_with(&checked, usage, ends)
}

/// Named spectra as precomputed linear sRGB, so no raw tables need to ship.
///
/// Computed offline (python3, f64) with exactly the integration in this file from pbrt-v4's
/// tables (`src/pbrt/util/spectrum.cpp`; CuZn from its later revision; glasses from
/// refractiveindex.info via pbrt) and the CIE-tabulated illuminants:
/// * `metal-*`: [`SpectrumUse::Unbounded`]; the test `copper_matches_its_spectrum` redoes Cu
///   from the raw data. MgO and TiO2 are dielectrics that pbrt files under "metal-".
///   The widely quoted copper RGB (eta 0.200 0.924 1.102, k 3.913 2.453 2.142) and gold RGB
///   (eta 0.143 0.375 1.442, k 3.983 2.386 1.603) come from pbrt-v3/Mitsuba's *unnormalised*
///   equal-energy projection, which maps a constant spectrum 1 to (1.205, 0.948, 0.909) and so
///   biases every channel. This file reproduces those figures from the same data in the test
///   `quoted_metal_values_are_the_biased_projection`, but embeds the neutral values below:
///   Ag eta (0.128 0.124 0.151) k (4.065 3.286 2.392); Al eta (1.407 0.927 0.584)
///   k (7.740 6.602 5.360); Au eta (0.080 0.405 1.561) k (3.390 2.504 1.771);
///   Cu eta (0.105 0.978 1.205) k (3.273 2.593 2.369).
/// * `glass-*`: the IOR at 550 nm (near the peak of ȳ) in all three channels, for RGB
///   rendering: per-channel dispersion in an RGB renderer gives channel-quantised fringes
///   instead of a spectrum. Spectral rendering disperses by [`glass_index`].
/// * `stdillum-*`, `illum-acesD60`: [`SpectrumUse::Illuminant`], luminance Y = 1, as pbrt-v4
///   normalises them. acesD60 is the CIE daylight spectrum for CCT 6000·1.4388/1.4380 K, as in
///   pbrt-v4.
const NAMED: [(&str, [f32; 3]); 37] = [
    ("metal-Ag-eta", [0.128478, 0.123535, 0.150894]),
    ("metal-Ag-k", [4.0648, 3.28621, 2.39178]),
    ("metal-Al-eta", [1.40738, 0.926656, 0.584077]),
    ("metal-Al-k", [7.74021, 6.60247, 5.3604]),
    ("metal-Au-eta", [0.0799507, 0.405108, 1.56084]),
    ("metal-Au-k", [3.39019, 2.50353, 1.77103]),
    ("metal-Cu-eta", [0.105161, 0.97792, 1.20467]),
    ("metal-Cu-k", [3.27348, 2.59252, 2.36918]),
    ("metal-CuZn-eta", [0.418404, 0.520092, 1.12303]),
    ("metal-CuZn-k", [3.66759, 2.68063, 1.77141]),
    ("metal-MgO-eta", [1.73372, 1.74095, 1.75355]),
    ("metal-MgO-k", [0.0, 0.0, 0.0]),
    ("metal-TiO2-eta", [2.86038, 2.95653, 3.18553]),
    ("metal-TiO2-k", [9.10288e-05, 0.0, 0.000566753]),
    ("glass-BK7", [1.51854, 1.51854, 1.51854]),
    ("glass-BAF10", [1.67305, 1.67305, 1.67305]),
    ("glass-FK51A", [1.4878, 1.4878, 1.4878]),
    ("glass-LASF9", [1.85581, 1.85581, 1.85581]),
    ("glass-F5", [1.67709, 1.67709, 1.67709]),
    ("glass-F10", [1.73357, 1.73357, 1.73357]),
    ("glass-F11", [1.79112, 1.79112, 1.79112]),
    ("stdillum-A", [1.84482, 0.826088, 0.233479]),
    ("stdillum-D50", [1.1761, 0.975677, 0.721998]),
    ("stdillum-D65", [1.0, 1.0, 1.0]),
    ("stdillum-F1", [0.953527, 1.01962, 0.942547]),
    ("stdillum-F2", [1.33897, 0.943382, 0.562011]),
    ("stdillum-F3", [1.57506, 0.891524, 0.380102]),
    ("stdillum-F4", [1.80459, 0.834743, 0.266285]),
    ("stdillum-F5", [0.914817, 1.0365, 0.889342]),
    ("stdillum-F6", [1.31509, 0.958179, 0.485756]),
    ("stdillum-F7", [1.00001, 1.00038, 0.996209]),
    ("stdillum-F8", [1.17654, 0.975832, 0.719169]),
    ("stdillum-F9", [1.37632, 0.931624, 0.568459]),
    ("stdillum-F10", [1.17296, 0.977013, 0.718028]),
    ("stdillum-F11", [1.4102, 0.925365, 0.530614]),
    ("stdillum-F12", [1.76591, 0.845844, 0.270266]),
    ("illum-acesD60", [1.04665, 0.99461, 0.915926]),
];

/// The names of [`NAMED`], in the same order.
static NAMES: [&str; NAMED.len()] = {
    let mut names = [""; NAMED.len()];
    let mut i = 0;
    while i < NAMED.len() {
        names[i] = NAMED[i].0;
        i += 1;
    }
    names
};

/// Linear sRGB of a named pbrt-v4 spectrum, or None if the name is unknown. Covers
/// metal-{Ag,Al,Au,Cu,CuZn,MgO,TiO2}-{eta,k} (as [`SpectrumUse::Unbounded`]),
/// glass-{BK7,BAF10,FK51A,LASF9,F5,F10,F11} (the IOR at 550 nm, (n, n, n)), stdillum-A,
/// stdillum-D50, stdillum-D65, stdillum-F1..F12 and illum-acesD60 (as
/// [`SpectrumUse::Illuminant`], luminance Y = 1; stdillum-D65 is (1, 1, 1)).
pub fn named_spectrum_rgb(name: &str) -> Option<[f32; 3]> {
    NAMED.iter().find(|(n, _)| *n == name).map(|&(_, rgb)| rgb)
}

/// All names named_spectrum_rgb knows, for error messages ("unknown spectrum 'x'; known: ...").
pub fn named_spectrum_names() -> &'static [&'static str] {
    &NAMES
}

/// Planck's law constants as pbrt-v4 uses them (SI units).
const PLANCK_H: f64 = 6.62606957e-34;
const LIGHT_C: f64 = 299_792_458.0;
const BOLTZMANN_K: f64 = 1.3806488e-23;

/// Linear sRGB colour of a blackbody at `kelvin`, normalised to luminance Y = 1 (as pbrt-v4
/// normalises light spectra to 1 nit before applying "scale"). Err for kelvin <= 0 or
/// non-finite.
///
/// Below about 1900 K the green and blue channels fall outside the sRGB gamut and are clamped
/// to 0, so the luminance there ends up a little above 1.
pub fn blackbody_rgb(kelvin: f32) -> Result<[f32; 3], String> {
    if !kelvin.is_finite() || kelvin <= 0.0 {
        return Err(format!(
            "blackbody temperature must be a positive, finite number of kelvin, got {kelvin}"
        ));
    }
    // Normalised by the largest visible value, not the true peak: the Y normalisation
    // cancels the factor either way, and cold bodies then do not underflow to black.
    spectrum_to_rgb(
        &blackbody_samples(f64::from(kelvin), true),
        SpectrumUse::Illuminant,
    )
}

/// A scene's emission given as a spectrum rather than RGB (a blackbody, an inline or file
/// spectrum), as (wavelength nm, value) pairs in increasing wavelength: its shape, for
/// spectral rendering. Its brightness is the RGB it came with; the pairs are only the
/// shape (any scale). Zero beyond the pairs' ends.
pub type EmissionSpectrum = std::sync::Arc<[(f32, f32)]>;

/// Planck's curve at `kelvin` (> 0) every nanometre over 360–830 nm, divided by its value
/// at the peak wavelength: a blackbody's [`EmissionSpectrum`].
pub fn blackbody_spectrum(kelvin: f32) -> EmissionSpectrum {
    blackbody_samples(f64::from(kelvin), false)
        .into_iter()
        .map(|(l, v)| (l as f32, v as f32))
        .collect()
}

/// Planck's curve at `kelvin` over the visible range, divided by its value at the peak
/// wavelength (which may lie outside the range), or by its largest value in the range if
/// `visible_peak`, sampled every 1 nm: far finer than the curve varies, and treated as
/// piecewise linear.
fn blackbody_samples(t: f64, visible_peak: bool) -> Vec<(f64, f64)> {
    // B(λ, T) = 2hc² / λ⁵ / (e^x − 1), x = hc / (λkT). Work with ln B: cold bodies (x far
    // beyond the range of exp) neither overflow nor vanish. ln(e^x − 1) = x + ln(1 − e^−x).
    let ln_b = |m: f64| {
        let x = PLANCK_H * LIGHT_C / (m * BOLTZMANN_K * t);
        -5.0 * libm::log(m) - x - libm::log(-libm::expm1(-x))
    };
    let ln: Vec<(f64, f64)> = (0..=470u32)
        .map(|i| {
            let nm = LAMBDA_MIN + f64::from(i);
            (nm, ln_b(nm * 1e-9))
        })
        .collect();
    let peak = if visible_peak {
        ln.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max)
    } else {
        // Wien's displacement law gives the peak.
        ln_b(2.897_771_955e-3 / t)
    };
    ln.iter()
        .map(|&(nm, l)| (nm, libm::exp(l - peak)))
        .collect()
}

/// Linear sRGB of the blackbody at `kelvin` normalised to 1 at its peak wavelength and not
/// otherwise (pbrt-v4's `BlackbodySpectrum`, which emissive temperature grids use): its
/// luminance grows with temperature. pbrt-v4 gives this spectrum no photometric
/// normalisation (lights and `Le` are divided by their luminance; a temperature grid's
/// blackbody is not), and its RGB film takes XYZ as ∫ S·(x̄, ȳ, z̄) dλ over nanometres without
/// dividing by ∫ ȳ (106.86): so Y here is ∫ B·ȳ dλ, about 90 at 6500 K, as pbrt-v4 renders it.
/// Zero for kelvin <= 0 or non-finite.
pub fn blackbody_peak_rgb(kelvin: f32) -> [f32; 3] {
    if !kelvin.is_finite() || kelvin <= 0.0 {
        return [0.0; 3];
    }
    let xyz = integrate_xyz(&blackbody_samples(f64::from(kelvin), false), false);
    let (white, _) = d65_reference();
    let rgb = xyz_to_srgb(xyz);
    std::array::from_fn(|c| (rgb[c] / white[c]).max(0.0) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(rgb: [f32; 3]) -> f32 {
        0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
    }

    fn assert_close(got: [f32; 3], want: [f32; 3], rel: f32, what: &str) {
        for (c, (g, w)) in got.iter().zip(want).enumerate() {
            let tol = rel * w.abs().max(1e-3);
            assert!(
                (g - w).abs() <= tol,
                "{what}: channel {c}: got {got:?}, want {want:?} (±{rel} relative)"
            );
        }
    }

    const CU_LAMBDA: [f32; 56] = [
        298.76, 302.4, 306.13, 309.96, 313.88, 317.91, 322.04, 326.27, 330.62, 335.09, 339.68,
        344.4, 349.25, 354.24, 359.37, 364.66, 370.1, 375.71, 381.49, 387.45, 393.6, 399.95,
        406.51, 413.28, 420.29, 427.53, 435.03, 442.8, 450.85, 459.2, 467.86, 476.86, 486.21,
        495.94, 506.06, 516.6, 527.59, 539.06, 551.04, 563.56, 576.67, 590.4, 604.8, 619.92,
        635.82, 652.55, 670.18, 688.8, 708.48, 729.32, 751.42, 774.9, 799.9, 826.56, 855.06, 885.6,
    ];
    const CU_ETA: [f32; 56] = [
        1.400313, 1.38, 1.358438, 1.34, 1.329063, 1.325, 1.3325, 1.34, 1.334375, 1.325, 1.317812,
        1.31, 1.300313, 1.29, 1.281563, 1.27, 1.249062, 1.225, 1.2, 1.18, 1.174375, 1.175, 1.1775,
        1.18, 1.178125, 1.175, 1.172812, 1.17, 1.165312, 1.16, 1.155312, 1.15, 1.142812, 1.135,
        1.131562, 1.12, 1.092437, 1.04, 0.950375, 0.826, 0.645875, 0.468, 0.35125, 0.272, 0.230813,
        0.214, 0.20925, 0.213, 0.21625, 0.223, 0.2365, 0.25, 0.254188, 0.26, 0.28, 0.3,
    ];
    const CU_K: [f32; 56] = [
        1.662125, 1.687, 1.703313, 1.72, 1.744563, 1.77, 1.791625, 1.81, 1.822125, 1.834, 1.85175,
        1.872, 1.89425, 1.916, 1.931688, 1.95, 1.972438, 2.015, 2.121562, 2.21, 2.177188, 2.13,
        2.160063, 2.21, 2.249938, 2.289, 2.326, 2.362, 2.397625, 2.433, 2.469187, 2.504, 2.535875,
        2.564, 2.589625, 2.605, 2.595562, 2.583, 2.5765, 2.599, 2.678062, 2.809, 3.01075, 3.24,
        3.458187, 3.67, 3.863125, 4.05, 4.239563, 4.43, 4.619563, 4.817, 5.034125, 5.26, 5.485625,
        5.717,
    ];

    fn cu_pairs(values: &[f32; 56]) -> Vec<(f32, f32)> {
        CU_LAMBDA
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect()
    }

    /// Normal-incidence Fresnel reflectance of a conductor.
    fn fresnel0(eta: f32, k: f32) -> f32 {
        ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k)
    }

    #[test]
    fn constant_spectrum_is_neutral_for_albedo_and_unbounded() {
        for usage in [SpectrumUse::Albedo, SpectrumUse::Unbounded] {
            for c in [0.0f32, 0.05, 0.18, 0.5, 1.0, 1.5, 7.25] {
                let want = [c; 3];
                assert_close(
                    sampled_to_rgb(&[(550.0, c)], usage).unwrap(),
                    want,
                    1e-3,
                    "1 pair",
                );
                let pairs = [(300.0, c), (421.5, c), (700.0, c), (900.0, c)];
                assert_close(
                    sampled_to_rgb(&pairs, usage).unwrap(),
                    want,
                    1e-3,
                    "4 pairs",
                );
            }
        }
    }

    /// pbrt-v4 reads a scene's spectrum as zero beyond its ends and a named spectrum as
    /// carrying its end values on: a reflector given only from 600 to 700 nm is red as a
    /// scene spectrum, and as one whose ends carry on, 1 everywhere, white.
    #[test]
    fn a_scene_spectrum_is_zero_beyond_its_ends() {
        let band = [(600.0, 1.0), (700.0, 1.0)];
        let red = sampled_to_rgb_with(&band, SpectrumUse::Albedo, Ends::Zero).unwrap();
        assert!(red[0] > 0.5 && red[1] < 0.1 && red[2] < 0.01, "{red:?}");
        let white = sampled_to_rgb_with(&band, SpectrumUse::Albedo, Ends::Constant).unwrap();
        assert_close(white, [1.0; 3], 1e-3, "constant ends");
        assert_eq!(white, sampled_to_rgb(&band, SpectrumUse::Albedo).unwrap());
        // Spectra covering 360-830 nm are the same either way.
        let wide = [(300.0, 0.2), (500.0, 0.9), (900.0, 0.4)];
        for usage in [SpectrumUse::Albedo, SpectrumUse::Illuminant] {
            assert_close(
                sampled_to_rgb_with(&wide, usage, Ends::Zero).unwrap(),
                sampled_to_rgb(&wide, usage).unwrap(),
                1e-6,
                "covering",
            );
        }
        // Nothing within 360-830 nm: black.
        let beyond = [(900.0, 1.0), (950.0, 1.0)];
        assert_eq!(
            sampled_to_rgb_with(&beyond, SpectrumUse::Albedo, Ends::Zero).unwrap(),
            [0.0; 3]
        );
    }

    #[test]
    fn albedo_of_a_red_reflector_is_red_and_never_negative() {
        let red = [(380.0, 0.05), (580.0, 0.05), (600.0, 0.9), (780.0, 0.9)];
        let rgb = sampled_to_rgb(&red, SpectrumUse::Albedo).unwrap();
        assert!(
            rgb[0] > 0.5 && rgb[0] > 4.0 * rgb[1] && rgb[0] > 4.0 * rgb[2],
            "{rgb:?}"
        );
        // A 1 nm wide spike at 520 nm is far outside the gamut: clamped, not negative, and
        // not missed by the integration.
        let spike = [(519.5, 0.0), (520.0, 1.0), (520.5, 0.0)];
        for usage in [SpectrumUse::Albedo, SpectrumUse::Illuminant] {
            let rgb = sampled_to_rgb(&spike, usage).unwrap();
            assert!(
                rgb.iter().all(|&v| v >= 0.0) && rgb[1] > 0.0,
                "{usage:?}: {rgb:?}"
            );
        }
    }

    #[test]
    fn d65_illuminant_is_neutral_with_unit_luminance() {
        let pairs: Vec<(f32, f32)> = (0..TABLE_LEN)
            .map(|i| ((LAMBDA_MIN + TABLE_STEP * i as f64) as f32, D65[i] as f32))
            .collect();
        let from_table = sampled_to_rgb(&pairs, SpectrumUse::Illuminant).unwrap();
        let named = named_spectrum_rgb("stdillum-D65").unwrap();
        for rgb in [from_table, named] {
            assert_close(rgb, [1.0; 3], 0.01, "D65");
            assert!((luminance(rgb) - 1.0).abs() < 1e-3, "{rgb:?}");
        }
        // The brightness of an emission spectrum is dropped, only its colour kept.
        let doubled: Vec<(f32, f32)> = pairs.iter().map(|&(l, v)| (l, 2.0 * v)).collect();
        assert_close(
            sampled_to_rgb(&doubled, SpectrumUse::Illuminant).unwrap(),
            from_table,
            1e-5,
            "2×D65",
        );
        assert_eq!(
            sampled_to_rgb(&[(500.0, 0.0)], SpectrumUse::Illuminant).unwrap(),
            [0.0; 3]
        );
        assert!(sampled_to_rgb(&[(500.0, -1.0)], SpectrumUse::Illuminant).is_err());
    }

    #[test]
    fn albedo_weights_are_the_albedo_conversion() {
        let l = [380.0, 450.0, 520.0, 600.0, 700.0];
        let v = [0.2, 0.5, 0.9, 0.4, 0.7];
        let w = albedo_rgb_weights(&l).unwrap();
        let by_weights: [f32; 3] =
            std::array::from_fn(|c| (0..5).map(|k| w[k][c] * f64::from(v[k])).sum::<f64>() as f32);
        let pairs: Vec<(f32, f32)> = l.iter().copied().zip(v).collect();
        let direct = sampled_to_rgb(&pairs, SpectrumUse::Albedo).unwrap();
        assert_close(by_weights, direct, 1e-4, "weights vs direct");
        // A constant spectrum is grey.
        let grey: [f32; 3] =
            std::array::from_fn(|c| (0..5).map(|k| w[k][c] * 0.6).sum::<f64>() as f32);
        assert_close(grey, [0.6; 3], 2e-3, "constant 0.6");
        assert!(albedo_rgb_weights(&[500.0, 400.0]).is_err());
    }

    #[test]
    fn white_balance_keeps_its_own_white_and_warms_cool_light() {
        // At the temperature whose daylight is (nearly) D65, the balance is (nearly) the
        // identity; D65 itself maps to white exactly.
        let m = white_balance_srgb(6500.0);
        for (i, row) in m.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 0.01, "{i},{j}: {v}");
            }
        }
        let xy = daylight_xy(6500.0);
        assert!(
            (xy[0] - 0.3127).abs() < 2e-3 && (xy[1] - 0.3290).abs() < 2e-3,
            "{xy:?}"
        );
        // Balancing for 3000 K daylight takes a 3000 K daylight white to neutral grey: the
        // white of that daylight in sRGB, balanced, has equal channels.
        let d3000 = {
            let xy = daylight_xy(3000.0);
            let xyz = [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]];
            xyz_to_srgb(xyz)
        };
        assert!(d3000[0] > d3000[2], "3000 K light is warm: {d3000:?}");
        let m = white_balance_srgb(3000.0);
        let out: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| m[i][k] * d3000[k]).sum());
        assert!(
            (out[0] - out[1]).abs() < 0.01 * out[1] && (out[2] - out[1]).abs() < 0.01 * out[1],
            "{out:?}"
        );
        let id = mul3(&SRGB_TO_XYZ, &inverse3(&SRGB_TO_XYZ));
        for (i, row) in id.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn peak_normalised_blackbody_grows_with_temperature() {
        // At 6500 K the peak (446 nm) lies in the visible range and the curve is nearly flat
        // there: luminance close to, and below, that of a constant 1 spectrum, ∫ ȳ dλ =
        // 106.86 (pbrt-v4's CIE_Y_integral; no photometric normalisation).
        let y = |t: f32| luminance(blackbody_peak_rgb(t));
        let y_integral = integrate_xyz(&[(560.0, 1.0)], false)[1];
        assert!((y_integral - 106.857).abs() < 0.05, "{y_integral}");
        assert!(y(6500.0) > 75.0 && y(6500.0) < 106.86, "{}", y(6500.0));
        assert!(y(1000.0) < 1e-3 * y(3000.0));
        assert!(y(1500.0) < y(2000.0) && y(2000.0) < y(4000.0));
        // Same colour as the luminance-normalised blackbody.
        let (a, b) = (blackbody_peak_rgb(3000.0), blackbody_rgb(3000.0).unwrap());
        let ya = luminance(a);
        assert_close(a.map(|v| v / ya), b, 1e-3, "3000 K colour");
        assert_eq!(blackbody_peak_rgb(0.0), [0.0; 3]);
    }

    #[test]
    fn blackbody_colours_and_luminance() {
        let warm = blackbody_rgb(2000.0).unwrap();
        assert!(warm[0] > warm[1] && warm[1] > warm[2], "2000 K: {warm:?}");
        let cool = blackbody_rgb(10000.0).unwrap();
        assert!(cool[2] > cool[1] && cool[2] > cool[0], "10000 K: {cool:?}");
        let white = blackbody_rgb(6500.0).unwrap();
        assert_close(white, [1.0; 3], 0.06, "6500 K");
        for (t, rgb) in [(2000.0, warm), (6500.0, white), (10000.0, cool)] {
            assert!((luminance(rgb) - 1.0).abs() < 2e-3, "{t} K: {rgb:?}");
        }
        // Illuminant A is, by definition, a 2856 K blackbody.
        let a = named_spectrum_rgb("stdillum-A").unwrap();
        assert_close(
            blackbody_rgb(2856.0).unwrap(),
            a,
            5e-3,
            "2856 K vs stdillum-A",
        );
        // Extreme temperatures stay finite.
        for t in [1.0, 300.0, 1e6, 1e30] {
            let rgb = blackbody_rgb(t).unwrap();
            assert!(
                rgb.iter().all(|v| v.is_finite() && *v >= 0.0) && luminance(rgb) > 0.5,
                "{t} K: {rgb:?}"
            );
        }
        for bad in [0.0, -100.0, f32::NAN, f32::INFINITY] {
            assert!(blackbody_rgb(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn copper_matches_its_spectrum() {
        let eta = named_spectrum_rgb("metal-Cu-eta").unwrap();
        let k = named_spectrum_rgb("metal-Cu-k").unwrap();
        // The embedded triples are what this file's own conversion gives for the raw data.
        let eta_now = sampled_to_rgb(&cu_pairs(&CU_ETA), SpectrumUse::Unbounded).unwrap();
        let k_now = sampled_to_rgb(&cu_pairs(&CU_K), SpectrumUse::Unbounded).unwrap();
        assert_close(eta, eta_now, 1e-3, "Cu eta");
        assert_close(k, k_now, 1e-3, "Cu k");
        // Near the expected values (neutral projection: see NAMED's docs for the pbrt-v3 ones).
        assert_close(eta, [0.105, 0.978, 1.205], 0.1, "Cu eta");
        assert_close(k, [3.27, 2.59, 2.37], 0.1, "Cu k");
        // Copper's look: reddish reflectance from the RGB eta/k close to the reflectance
        // spectrum's own RGB.
        let spectral: Vec<(f32, f32)> = CU_LAMBDA
            .iter()
            .zip(CU_ETA.iter().zip(CU_K.iter()))
            .map(|(&l, (&n, &kk))| (l, fresnel0(n, kk)))
            .collect();
        let want = sampled_to_rgb(&spectral, SpectrumUse::Albedo).unwrap();
        let got: [f32; 3] = std::array::from_fn(|c| fresnel0(eta[c], k[c]));
        assert!(got[0] > got[1] && got[1] > got[2], "{got:?}");
        assert_close(got, want, 0.03, "R0 from RGB eta/k vs spectral R0");
    }

    #[test]
    fn quoted_metal_values_are_the_biased_projection() {
        // pbrt-v3/Mitsuba: M · ∫S·(x̄,ȳ,z̄) / ∫ȳ, with no white correction.
        let biased = |values: &[f32; 56]| -> [f32; 3] {
            let pairs: Vec<(f64, f64)> = cu_pairs(values)
                .iter()
                .map(|&(l, v)| (f64::from(l), f64::from(v)))
                .collect();
            let y1 = integrate_xyz(&[(560.0, 1.0)], false)[1];
            xyz_to_srgb(integrate_xyz(&pairs, false).map(|v| v / y1)).map(|v| v as f32)
        };
        assert_close(
            biased(&CU_ETA),
            [0.200438, 0.924033, 1.10221],
            0.03,
            "v3 Cu eta",
        );
        assert_close(biased(&CU_K), [3.91295, 2.45285, 2.14219], 0.03, "v3 Cu k");
    }

    #[test]
    fn named_spectra_cover_the_pbrt_names() {
        let mut required: Vec<String> = Vec::new();
        for m in ["Ag", "Al", "Au", "Cu", "CuZn", "MgO", "TiO2"] {
            required.push(format!("metal-{m}-eta"));
            required.push(format!("metal-{m}-k"));
        }
        for g in ["BK7", "BAF10", "FK51A", "LASF9", "F5", "F10", "F11"] {
            required.push(format!("glass-{g}"));
        }
        required.extend(
            [
                "stdillum-A",
                "stdillum-D50",
                "stdillum-D65",
                "illum-acesD60",
            ]
            .map(String::from),
        );
        required.extend((1..=12).map(|i| format!("stdillum-F{i}")));
        for name in &required {
            assert!(
                named_spectrum_names().contains(&name.as_str()),
                "{name} not listed"
            );
        }
        assert_eq!(named_spectrum_names().len(), required.len());
        for name in named_spectrum_names() {
            let rgb = named_spectrum_rgb(name).unwrap();
            assert!(
                rgb.iter().all(|v| v.is_finite() && *v >= 0.0),
                "{name}: {rgb:?}"
            );
            if name.starts_with("stdillum") || name.starts_with("illum") {
                assert!((luminance(rgb) - 1.0).abs() < 2e-3, "{name}: {rgb:?}");
            }
        }
        let bk7 = named_spectrum_rgb("glass-BK7").unwrap();
        assert_close(bk7, [1.5185; 3], 1e-3, "BK7");
        let au_k = named_spectrum_rgb("metal-Au-k").unwrap();
        assert!(au_k[0] > au_k[1] && au_k[1] > au_k[2], "{au_k:?}");
        assert_eq!(named_spectrum_rgb("metal-Unobtainium-eta"), None);
        assert_eq!(named_spectrum_rgb("Metal-Cu-eta"), None);
        assert_eq!(named_spectrum_rgb(""), None);
    }

    #[test]
    fn bad_sampled_spectra_are_rejected() {
        let usage = SpectrumUse::Albedo;
        assert!(sampled_to_rgb(&[], usage).is_err());
        assert!(sampled_to_rgb(&[(500.0, 0.5), (400.0, 0.5)], usage).is_err());
        assert!(sampled_to_rgb(&[(400.0, 0.5), (400.0, 0.6)], usage).is_err());
        assert!(sampled_to_rgb(&[(400.0, 0.5), (500.0, f32::NAN)], usage).is_err());
        assert!(sampled_to_rgb(&[(f32::INFINITY, 0.5)], usage).is_err());
        assert!(sampled_to_rgb(&[(400.0, 0.5), (500.0, 0.5)], usage).is_ok());
    }
}
