//! What a named camera `sensor` does to the image, as pbrt-v4's `PixelSensor` does it, for
//! a renderer whose radiance is linear sRGB.
//!
//! pbrt-v4 records each sample through the camera's red, green and blue responses (its
//! "raw" RGB, ∫ r̄·L dλ / ∫ ȳ dλ), clamps the largest raw component to
//! "maxcomponentvalue", then maps raw RGB to XYZ by a 3×3 matrix fitted by least squares:
//! training reflectances lit by daylight of the white-balance temperature, as the camera
//! records them, against the same reflectances lit by the output space's white (D65), as
//! the CIE observer sees them. So a white lit by that daylight comes out white, and other
//! colours come out with the camera's own errors: a camera is not a colorimeter.
//!
//! A spectral render's sample is recorded as pbrt-v4 records it: its raw RGB is the
//! camera's curves ([`CameraResponse::per_nm`]) at the sample's wavelengths times its
//! radiance there, over each wavelength's density. An RGB render's radiance has no
//! spectrum, so it gives each sample the spectrum pbrt-v4 gives an
//! RGB light of that colour: twice its largest component times the smooth spectrum
//! (`rgb_spectrum`) of the colour scaled to a largest component of ½, times D65. The camera's
//! raw RGB of those spectra is tabulated once per camera ([`RawTable`]) and interpolated per
//! sample. Either way the fitted matrix then takes raw RGB to XYZ, and XYZ goes to linear
//! sRGB.
//!
//! The training reflectances are a measured colour chart's where the sensor data folder
//! holds one (`files::training_chart`), else Kiln's own: 125 smooth spectra of the same
//! sigmoid form, spanning greys, pastels and saturated colours. pbrt-v4 trains on the 24
//! patches of a measured ColorChecker, which Kiln may not copy; with Kiln's own spectra the
//! two fits differ by a few percent in saturated colours (the manual's Films page,
//! docs/src/scene-format/films.md).

use crate::files::sensor_curves::SensorCurves;
use crate::files::training_chart::TrainingChart;
use crate::rgb_spectrum::{Upsampler, grid};
use crate::spectrum::{
    LAMBDA_MAX, LAMBDA_MIN, XYZ_TO_SRGB, cmf_at, d65_at, daylight_samples, det3, inverse3, mul3,
    spectrum_at,
};

/// A camera's colour response and white balance.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraResponse {
    /// The sensor's name in the scene.
    pub name: String,
    /// Linear sRGB radiance to the camera's raw RGB (where "maxcomponentvalue" clamps).
    pub raw: RawTable,
    /// Raw RGB to the image's linear sRGB, white balanced.
    pub raw_to_srgb: [[f64; 3]; 3],
    /// The camera's red, green and blue responses every nanometre from 360 to 830 nm, for
    /// spectral rendering: a sample's raw RGB is ∫ L·(r̄, ḡ, b̄) dλ over them, in the units
    /// of [`RawTable::raw`] (radiance whose ∫ D65·ȳ is 1 for the sRGB white).
    pub per_nm: Vec<[f32; 3]>,
}

/// Lattice points along each side of a face of the [`RawTable`].
const TABLE_N: usize = 25;

/// A camera's raw RGB of every colour, tabulated on the three faces of the cube where the
/// largest component is ½ (face k: channel k largest; the other two, in channel order, on a
/// `TABLE_N`² lattice over [0, ½]). A colour is scaled onto its face, looked up bilinearly,
/// and scaled back: raw RGB is proportional to the colour's largest component, as pbrt-v4's
/// RGB illuminant spectra are.
#[derive(Clone, PartialEq)]
pub struct RawTable {
    entries: Vec<[f32; 3]>,
}

impl std::fmt::Debug for RawTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RawTable(3 faces of {TABLE_N}x{TABLE_N})")
    }
}

impl RawTable {
    /// The camera's raw RGB of linear sRGB radiance `rgb` (negative components count as 0).
    pub fn raw(&self, rgb: [f32; 3]) -> [f32; 3] {
        let l = rgb.map(|v| v.max(0.0));
        let k = if l[0] >= l[1] && l[0] >= l[2] {
            0
        } else if l[1] >= l[2] {
            1
        } else {
            2
        };
        let m = l[k];
        if !(m > 0.0 && m.is_finite()) {
            return if m > 0.0 { [m; 3] } else { [0.0; 3] };
        }
        let (a, b) = [(1, 2), (0, 2), (0, 1)][k];
        let last = (TABLE_N - 1) as f32;
        let u = (l[a] / m * last).clamp(0.0, last);
        let v = (l[b] / m * last).clamp(0.0, last);
        let (i, j) = ((u as usize).min(TABLE_N - 2), (v as usize).min(TABLE_N - 2));
        let (fu, fv) = (u - i as f32, v - j as f32);
        let at = |i: usize, j: usize| self.entries[(k * TABLE_N + i) * TABLE_N + j];
        let (e00, e10, e01, e11) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        std::array::from_fn(|c| {
            let lo = e00[c] + (e10[c] - e00[c]) * fu;
            let hi = e01[c] + (e11[c] - e01[c]) * fu;
            2.0 * m * (lo + (hi - lo) * fv)
        })
    }
}

/// The camera's curves at `lambda`: linear between samples, zero beyond them (as pbrt-v4's
/// piecewise-linear spectra are).
fn curves_at(samples: &[(f64, [f64; 3])], lambda: f64) -> [f64; 3] {
    let (first, last) = (samples[0].0, samples[samples.len() - 1].0);
    if lambda < first || lambda > last {
        return [0.0; 3];
    }
    let j = samples
        .partition_point(|s| s.0 <= lambda)
        .min(samples.len() - 1);
    let (l0, v0) = samples[j.max(1) - 1];
    let (l1, v1) = samples[j.max(1)];
    let u = ((lambda - l0) / (l1 - l0)).clamp(0.0, 1.0);
    std::array::from_fn(|c| v0[c] + (v1[c] - v0[c]) * u)
}

/// The 3×3 matrix M minimising Σ |M·a_k − b_k|² (the normal equations, in f64), or None
/// when the a_k do not span three dimensions.
fn least_squares(a: &[[f64; 3]], b: &[[f64; 3]]) -> Option<[[f64; 3]; 3]> {
    let mut ata = [[0.0; 3]; 3];
    let mut bta = [[0.0; 3]; 3];
    for (a, b) in a.iter().zip(b) {
        for i in 0..3 {
            for j in 0..3 {
                ata[i][j] += a[i] * a[j];
                bta[i][j] += b[i] * a[j];
            }
        }
    }
    let scale = (0..3).map(|i| ata[i][i]).sum::<f64>();
    let det = det3(&ata);
    if !(det.is_finite() && det > 1e-12 * scale.powi(3)) {
        return None;
    }
    Some(mul3(&bta, &inverse3(&ata)))
}

fn apply(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|k| m[r][k] * v[k]).sum())
}

/// Sums over the grid for one camera.
struct Sums {
    cam: Vec<[f64; 3]>,
    cmf: Vec<[f64; 3]>,
    d65: Vec<f64>,
    d65_y: f64,
}

impl Sums {
    /// Σ ρ·E·w over the grid, for a spectrum ρ, an illuminant E and three weights w.
    fn project(rho: &[f64], light: &[f64], w: &[[f64; 3]]) -> [f64; 3] {
        let mut acc = [0.0; 3];
        for ((r, e), w) in rho.iter().zip(light).zip(w) {
            let s = r * e;
            for c in 0..3 {
                acc[c] += s * w[c];
            }
        }
        acc
    }

    /// The camera's raw RGB of reflectance ρ lit by D65 of luminance 1.
    fn raw_under_d65(&self, rho: &[f64]) -> [f64; 3] {
        Self::project(rho, &self.d65, &self.cam).map(|v| v / self.d65_y)
    }
}

/// The raw table: each lattice colour's spectrum fitted with continuation from grey (the
/// corner (½, ½) of each face) towards the saturated corner.
fn raw_table(up: &Upsampler, sums: &Sums) -> RawTable {
    let n = TABLE_N;
    let mut entries = vec![[0.0f32; 3]; 3 * n * n];
    for k in 0..3 {
        let (a, b) = [(1, 2), (0, 2), (0, 1)][k];
        let mut coeffs = vec![[0.0f64; 3]; n * n];
        for i in (0..n).rev() {
            for j in (0..n).rev() {
                let start = if j + 1 < n {
                    coeffs[i * n + j + 1]
                } else if i + 1 < n {
                    coeffs[(i + 1) * n + j]
                } else {
                    [0.0; 3]
                };
                let mut target = [0.0; 3];
                target[k] = 0.5;
                target[a] = 0.5 * i as f64 / (n - 1) as f64;
                target[b] = 0.5 * j as f64 / (n - 1) as f64;
                let c = up.fit(target, start);
                coeffs[i * n + j] = c;
                let raw = sums.raw_under_d65(&up.spectrum(c));
                entries[(k * n + i) * n + j] = raw.map(|v| v as f32);
            }
        }
    }
    RawTable { entries }
}

/// Kiln's own training reflectances, on the grid: 125 sigmoid spectra spanning greys,
/// pastels and saturated colours.
fn own_training_spectra(up: &Upsampler) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(125);
    for c0 in [-3.0, -1.5, 0.0, 1.5, 3.0] {
        for c1 in [-6.0, -3.0, 0.0, 3.0, 6.0] {
            for c2 in [-12.0, -6.0, 0.0, 6.0, 12.0] {
                out.push(up.spectrum([c0, c1, c2]));
            }
        }
    }
    out
}

/// The response of camera `name` with curves `curves`, white balanced for daylight at
/// `kelvin` (pbrt-v4's "whitebalance"; it defaults to 6500 for a camera), its matrix fitted
/// on `chart`'s patches where one is given, else on Kiln's own training spectra.
pub fn camera_response(
    name: &str,
    curves: &SensorCurves,
    kelvin: f64,
    chart: Option<&TrainingChart>,
) -> Result<CameraResponse, String> {
    let lambdas: Vec<f64> = grid().collect();
    let cmf: Vec<[f64; 3]> = lambdas.iter().map(|&l| cmf_at(l)).collect();
    let d65: Vec<f64> = lambdas.iter().map(|&l| d65_at(l)).collect();
    let ones = vec![1.0; lambdas.len()];
    let d65_xyz = Sums::project(&ones, &d65, &cmf);
    let sums = Sums {
        cam: lambdas
            .iter()
            .map(|&l| curves_at(&curves.samples, l))
            .collect(),
        cmf,
        d65,
        d65_y: d65_xyz[1],
    };
    let daylight = daylight_samples(kelvin);
    let illum: Vec<f64> = lambdas.iter().map(|&l| spectrum_at(&daylight, l)).collect();
    let illum_g = Sums::project(&ones, &illum, &sums.cam)[1];
    let illum_y = Sums::project(&ones, &illum, &sums.cmf)[1];
    if illum_g.is_nan() || illum_g <= 0.0 {
        return Err(format!(
            "camera '{name}' does not respond in green to daylight at {kelvin} K"
        ));
    }

    let up = Upsampler::new();
    let training = match chart {
        Some(chart) => (0..chart.patches.len())
            .map(|k| lambdas.iter().map(|&l| chart.reflectance(k, l)).collect())
            .collect(),
        None => own_training_spectra(&up),
    };
    let mut raw_balanced = Vec::with_capacity(training.len());
    let mut xyz_out = Vec::with_capacity(training.len());
    for rho in &training {
        raw_balanced.push(Sums::project(rho, &illum, &sums.cam).map(|v| v / illum_g));
        xyz_out.push(
            Sums::project(rho, &sums.d65, &sums.cmf).map(|v| v / sums.d65_y * illum_y / illum_g),
        );
    }
    let xyz_from_raw = least_squares(&raw_balanced, &xyz_out).ok_or_else(|| match chart {
        Some(chart) => format!(
            "camera '{name}' ('{}') on the training chart '{}': the patches' raw colours do not span three dimensions",
            curves.path.display(),
            chart.path.display()
        ),
        None => format!(
            "camera '{name}' ('{}'): its red, green and blue responses are not independent",
            curves.path.display()
        ),
    })?;
    let white = apply(&XYZ_TO_SRGB, d65_xyz.map(|v| v / sums.d65_y));
    let mut raw_to_srgb = mul3(&XYZ_TO_SRGB, &xyz_from_raw);
    for (row, w) in raw_to_srgb.iter_mut().zip(white) {
        *row = row.map(|v| v / w);
    }
    Ok(CameraResponse {
        name: name.to_string(),
        raw: raw_table(&up, &sums),
        raw_to_srgb,
        per_nm: (0..=(LAMBDA_MAX - LAMBDA_MIN) as u32)
            .map(|i| curves_at(&curves.samples, LAMBDA_MIN + f64::from(i)).map(|v| v as f32))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::{SpectrumUse, sampled_to_rgb};

    /// A camera whose responses are mixtures of the CIE observer's, sampled every 5 nm.
    fn mixed_observer(mix: [[f64; 3]; 3]) -> SensorCurves {
        SensorCurves {
            samples: (0..=94)
                .map(|i| {
                    let l = 360.0 + 5.0 * i as f64;
                    (l, apply(&mix, cmf_at(l)))
                })
                .collect(),
            path: "mixed.json".into(),
        }
    }

    const MIX: [[f64; 3]; 3] = [[0.9, 0.3, -0.05], [0.1, 1.0, 0.05], [0.0, 0.1, 0.8]];

    fn through(c: &CameraResponse, rgb: [f64; 3]) -> [f64; 3] {
        let raw = c.raw.raw(rgb.map(|v| v as f32)).map(f64::from);
        apply(&c.raw_to_srgb, raw)
    }

    #[test]
    fn a_camera_that_is_a_mixture_of_the_observer_changes_no_colour() {
        // Its raw RGB is MIX · XYZ exactly, and the fit undoes MIX: at 6500 K (pbrt-v4's
        // D(6500) is D65 within the tables' rounding) every colour comes back.
        let cam = camera_response("mixed", &mixed_observer(MIX), 6500.0, None).unwrap();
        for rgb in [
            [1.0, 1.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.8, 0.3, 0.1],
        ] {
            let out = through(&cam, rgb);
            for c in 0..3 {
                assert!((out[c] - rgb[c]).abs() < 3e-3, "{rgb:?} -> {out:?}");
            }
        }
        // The raw RGB of white is MIX applied to D65's XYZ (Y = 1).
        let raw = cam.raw.raw([1.0; 3]).map(f64::from);
        let want = apply(&MIX, [0.9505, 1.0, 1.089]);
        for c in 0..3 {
            assert!((raw[c] - want[c]).abs() < 2e-3, "{raw:?} vs {want:?}");
        }
    }

    #[test]
    fn white_balance_makes_daylight_of_its_temperature_white() {
        let curves = mixed_observer(MIX);
        for kelvin in [3200.0, 4500.0, 6000.0, 9000.0] {
            let cam = camera_response("mixed", &curves, kelvin, None).unwrap();
            // A white surface lit by daylight at `kelvin`, as Kiln's light colour of it.
            let pairs: Vec<(f32, f32)> = daylight_samples(kelvin)
                .iter()
                .map(|&(l, v)| (l as f32, v as f32))
                .collect();
            let light = sampled_to_rgb(&pairs, SpectrumUse::Illuminant)
                .unwrap()
                .map(f64::from);
            let out = through(&cam, light);
            let mean = out.iter().sum::<f64>() / 3.0;
            for c in 0..3 {
                assert!(
                    (out[c] / mean - 1.0).abs() < 0.01,
                    "{kelvin} K: {light:?} -> {out:?}"
                );
            }
            // Uncorrected, that light is far from white below 6500 K and beyond it.
            let spread = light.iter().cloned().fold(0.0, f64::max)
                / light.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!(spread > 1.1, "{kelvin} K: {light:?}");
        }
    }

    /// The chart's own colours through a camera: each patch lit by D65, recorded raw and
    /// mapped to linear sRGB, against the patch's sRGB as the observer sees it. The squared
    /// error summed over the patches, after the one scale that fits best (the fit's
    /// exposure is not what the training decides).
    fn chart_error(cam: &CameraResponse, curves: &SensorCurves, chart: &TrainingChart) -> f64 {
        let lambdas: Vec<f64> = grid().collect();
        let d65_y: f64 = lambdas.iter().map(|&l| d65_at(l) * cmf_at(l)[1]).sum();
        let mut pairs = Vec::new();
        for k in 0..chart.patches.len() {
            let (mut raw, mut xyz) = ([0.0; 3], [0.0; 3]);
            for &l in &lambdas {
                let e = chart.reflectance(k, l) * d65_at(l) / d65_y;
                let (c, o) = (curves_at(&curves.samples, l), cmf_at(l));
                for i in 0..3 {
                    raw[i] += e * c[i];
                    xyz[i] += e * o[i];
                }
            }
            pairs.push((apply(&cam.raw_to_srgb, raw), apply(&XYZ_TO_SRGB, xyz)));
        }
        let (mut gw, mut gg) = (0.0, 0.0);
        for (g, w) in &pairs {
            gw += (0..3).map(|i| g[i] * w[i]).sum::<f64>();
            gg += (0..3).map(|i| g[i] * g[i]).sum::<f64>();
        }
        let scale = gw / gg;
        pairs
            .iter()
            .map(|(g, w)| (0..3).map(|i| (scale * g[i] - w[i]).powi(2)).sum::<f64>())
            .sum()
    }

    #[test]
    fn a_measured_chart_trains_the_matrix_in_place_of_kilns_spectra() {
        // A camera whose curves are no mixture of the observer's, so that no matrix is
        // exact and the training set decides its errors.
        let bump = |l: f64, mu: f64, w: f64| libm::exp(-((l - mu) / w).powi(2) / 2.0);
        let curves = SensorCurves {
            samples: (0..=94)
                .map(|i| {
                    let l = 360.0 + 5.0 * i as f64;
                    (
                        l,
                        [
                            bump(l, 610.0, 30.0),
                            bump(l, 535.0, 35.0),
                            bump(l, 455.0, 25.0),
                        ],
                    )
                })
                .collect(),
            path: "bumps.json".into(),
        };
        // Twelve patches of steps and notches, nothing like sigmoid-quadratic spectra, on
        // 380..730 nm as pbrt-v4's chart is.
        let lambdas: Vec<f64> = (0..=35).map(|i| 380.0 + 10.0 * f64::from(i)).collect();
        let patches: Vec<Vec<f64>> = (0..12)
            .map(|k| {
                let edge = 420.0 + 25.0 * f64::from(k);
                lambdas
                    .iter()
                    .map(|&l| match k % 3 {
                        0 => {
                            if l < edge {
                                0.05
                            } else {
                                0.8
                            }
                        }
                        1 => {
                            if l < edge {
                                0.7
                            } else {
                                0.1
                            }
                        }
                        _ => {
                            if (l - edge).abs() < 30.0 {
                                0.05
                            } else {
                                0.6
                            }
                        }
                    })
                    .collect()
            })
            .collect();
        let chart = TrainingChart {
            lambdas,
            patches,
            path: "chart.csv".into(),
        };
        let own = camera_response("bumps", &curves, 6504.0, None).unwrap();
        let trained = camera_response("bumps", &curves, 6504.0, Some(&chart)).unwrap();
        let (e_own, e_trained) = (
            chart_error(&own, &curves, &chart),
            chart_error(&trained, &curves, &chart),
        );
        assert!(
            e_trained < 0.9 * e_own,
            "on the chart's own patches: {e_trained} trained on it, {e_own} on Kiln's spectra"
        );
        // A chart whose patches are all one grey spans one dimension: refused, named.
        let grey = TrainingChart {
            patches: vec![vec![0.5; 36]; 3],
            ..chart
        };
        let e = camera_response("bumps", &curves, 6504.0, Some(&grey)).unwrap_err();
        assert!(
            e.contains("chart.csv") && e.contains("three dimensions"),
            "{e}"
        );
    }

    #[test]
    fn curves_are_zero_outside_their_range() {
        let s = [(400.0, [1.0, 2.0, 3.0]), (500.0, [3.0, 2.0, 1.0])];
        assert_eq!(curves_at(&s, 399.0), [0.0; 3]);
        assert_eq!(curves_at(&s, 501.0), [0.0; 3]);
        assert_eq!(curves_at(&s, 400.0), [1.0, 2.0, 3.0]);
        assert_eq!(curves_at(&s, 450.0), [2.0, 2.0, 2.0]);
        assert_eq!(curves_at(&s, 500.0), [3.0, 2.0, 1.0]);
    }

    #[test]
    fn dependent_curves_are_refused() {
        let same = SensorCurves {
            samples: (0..=94)
                .map(|i| {
                    let l = 360.0 + 5.0 * i as f64;
                    (l, [cmf_at(l)[1]; 3])
                })
                .collect(),
            path: "grey.json".into(),
        };
        let e = camera_response("grey", &same, 6500.0, None).unwrap_err();
        assert!(
            e.contains("not independent") && e.contains("grey.json"),
            "{e}"
        );
    }
}
