//! Measured BRDFs in the RGL format (Dupuy & Jakob 2018, "An Adaptive Parameterization for
//! Efficient Material Acquisition and Rendering"; pbrt-v4's `measured` material): the tables
//! of a `.bsdf` tensor file, checked for consistent shapes, with the spectral reflectance
//! projected to linear sRGB as Kiln renders in RGB.

use super::read_bytes;
use super::tensor::{Field, parse_tensor};
use crate::error::{Loc, Result, SceneError};
use crate::spectrum;
use std::collections::BTreeMap;
use std::path::Path;

/// A grid of `values` over the unit square, `nx` columns (fastest) by `ny` rows, repeated
/// for every combination of the parameters it is conditioned on.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid2 {
    pub nx: usize,
    pub ny: usize,
    pub values: Vec<f32>,
}

/// The tables of a measured BRDF. `vndf`, `luminance` and `rgb` are conditioned on the
/// direction the BRDF is seen from, (phi_i, theta_i); `rgb` also on the channel (outermost
/// to innermost: phi, theta, channel, then the grid).
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredBrdf {
    pub phi_i: Vec<f32>,
    pub theta_i: Vec<f32>,
    /// The microfacet distribution over the warped half-vector square.
    pub ndf: Grid2,
    /// The projected microfacet area seen from a direction.
    pub sigma: Grid2,
    /// The visible-normal distribution, per incident direction.
    pub vndf: Grid2,
    /// The luminance of the BRDF over the sample square, per incident direction.
    pub luminance: Grid2,
    /// Reflectance (linear sRGB) over the sample square, per incident direction and channel.
    pub rgb: Grid2,
    /// The file's wavelengths (nm, increasing) and its reflectance over the sample square
    /// per incident direction and wavelength, for spectral rendering.
    pub wavelengths: Vec<f32>,
    pub spectra: Grid2,
    /// One or two phi_i values: the data do not depend on the azimuth.
    pub isotropic: bool,
    /// The file's description text.
    pub description: String,
}

/// The largest grid dimension accepted (RGL files use 32 or 64 per side).
const MAX_SIDE: usize = 4096;

/// Reads a `.bsdf` file; errors name the directive's location and the file.
pub fn read_measured(path: &Path, loc: &Loc) -> Result<MeasuredBrdf> {
    let bytes = read_bytes(path, loc)?;
    parse_measured(&bytes)
        .map_err(|e| SceneError::at(loc, format!("measured BRDF '{}': {e}", path.display())))
}

/// Parses a measured BRDF from a tensor file's bytes.
pub fn parse_measured(bytes: &[u8]) -> std::result::Result<MeasuredBrdf, String> {
    let fields = parse_tensor(bytes)?;
    let field = |name: &str| {
        fields
            .get(name)
            .ok_or_else(|| format!("it has no field '{name}' (is it an RGL .bsdf file?)"))
    };
    let floats = |name: &str, ndim: usize| field(name)?.f32s(name, ndim);
    let theta_i = floats("theta_i", 1)?;
    let phi_i = floats("phi_i", 1)?;
    let wavelengths = floats("wavelengths", 1)?;
    let shape =
        |name: &str| -> std::result::Result<Vec<usize>, String> { Ok(field(name)?.shape.clone()) };
    let (s_ndf, s_sigma, s_vndf, s_lum, s_spec) = (
        shape("ndf")?,
        shape("sigma")?,
        shape("vndf")?,
        shape("luminance")?,
        shape("spectra")?,
    );
    let (np, nt, nl) = (phi_i.len(), theta_i.len(), wavelengths.len());
    let ok = s_ndf.len() == 2
        && s_sigma.len() == 2
        && s_vndf.len() == 4
        && s_vndf[..2] == [np, nt]
        && s_lum.len() == 4
        && s_lum[..2] == [np, nt]
        && s_spec.len() == 5
        && s_spec[..3] == [np, nt, nl]
        && s_spec[3..] == s_lum[2..];
    if !ok {
        return Err(format!(
            "its tables' shapes do not fit together (phi_i {np}, theta_i {nt}, wavelengths {nl}, ndf {s_ndf:?}, sigma {s_sigma:?}, vndf {s_vndf:?}, luminance {s_lum:?}, spectra {s_spec:?})"
        ));
    }
    for s in [
        &s_ndf,
        &s_sigma,
        &s_vndf[2..].to_vec(),
        &s_lum[2..].to_vec(),
    ] {
        if s.iter().any(|&n| !(2..=MAX_SIDE).contains(&n)) {
            return Err(format!(
                "a table of {s:?} samples: each side needs 2 to {MAX_SIDE}"
            ));
        }
    }
    if np == 0 || nt == 0 || nl == 0 {
        return Err("it has no phi_i, theta_i or wavelength samples".into());
    }
    for (name, axis) in [
        ("phi_i", &phi_i),
        ("theta_i", &theta_i),
        ("wavelengths", &wavelengths),
    ] {
        if axis.iter().any(|v| !v.is_finite()) || axis.windows(2).any(|w| w[1] <= w[0]) {
            return Err(format!("'{name}' must be finite and increasing"));
        }
    }
    let isotropic = np <= 2;
    if !isotropic {
        let span = phi_i[np - 1] - phi_i[0];
        let reduction = (2.0 * std::f32::consts::PI / span).round();
        if reduction != 1.0 {
            return Err(format!(
                "its phi_i samples cover 1/{reduction} of a turn; Kiln reads full turns only, as pbrt-v4"
            ));
        }
    }
    let grid = |name: &str, s: &[usize], ndim: usize| -> std::result::Result<Grid2, String> {
        let values = floats(name, ndim)?;
        if values.iter().any(|v| !v.is_finite()) {
            return Err(format!("'{name}' holds a value that is not finite"));
        }
        Ok(Grid2 {
            nx: s[s.len() - 1],
            ny: s[s.len() - 2],
            values,
        })
    };
    let (ndf, sigma) = (grid("ndf", &s_ndf, 2)?, grid("sigma", &s_sigma, 2)?);
    let (vndf, luminance) = (grid("vndf", &s_vndf, 4)?, grid("luminance", &s_lum, 4)?);
    if [&vndf, &luminance]
        .iter()
        .any(|g| g.values.iter().any(|v| *v < 0.0))
    {
        return Err("'vndf' and 'luminance' are densities and must not be negative".into());
    }
    let spectra = grid("spectra", &s_spec, 5)?;
    let rgb = spectra_to_rgb(&spectra, np * nt, &wavelengths)?;
    let description = match fields.get("description") {
        Some(Field { bytes, .. }) => String::from_utf8_lossy(bytes).into_owned(),
        None => String::new(),
    };
    Ok(MeasuredBrdf {
        phi_i,
        theta_i,
        ndf,
        sigma,
        vndf,
        luminance,
        rgb,
        wavelengths,
        spectra,
        isotropic,
        description,
    })
}

/// Projects each cell's spectrum to linear sRGB as a reflectance (the same linear map
/// [`spectrum::SpectrumUse::Albedo`] uses, applied to the samples' piecewise-linear
/// interpolant), keeping the layout with 3 channels in place of the wavelengths.
fn spectra_to_rgb(
    spectra: &Grid2,
    slices: usize,
    wavelengths: &[f32],
) -> std::result::Result<Grid2, String> {
    let weights = spectrum::albedo_rgb_weights(wavelengths)?;
    let cells = spectra.nx * spectra.ny;
    let nl = wavelengths.len();
    let mut values = vec![0.0f32; slices * 3 * cells];
    for s in 0..slices {
        for (l, w) in weights.iter().enumerate() {
            let src = &spectra.values[(s * nl + l) * cells..][..cells];
            for (c, wc) in w.iter().enumerate() {
                let dst = &mut values[(s * 3 + c) * cells..][..cells];
                for (d, v) in dst.iter_mut().zip(src) {
                    *d += (*wc * f64::from(*v)) as f32;
                }
            }
        }
    }
    Ok(Grid2 {
        nx: spectra.nx,
        ny: spectra.ny,
        values,
    })
}

/// Writes a measured BRDF's tables as an RGL tensor file with the given wavelengths and
/// spectra (phi, theta, wavelength, y, x): for tests and stand-ins.
#[allow(clippy::too_many_arguments)]
pub fn write_measured(
    phi_i: &[f32],
    theta_i: &[f32],
    ndf: &Grid2,
    sigma: &Grid2,
    vndf: &Grid2,
    luminance: &Grid2,
    wavelengths: &[f32],
    spectra: &[f32],
) -> Vec<u8> {
    use super::tensor::{Dtype, f32_field, write_tensor};
    let (np, nt) = (phi_i.len(), theta_i.len());
    let fields: BTreeMap<&str, Field> = [
        ("phi_i", f32_field(&[np], phi_i)),
        ("theta_i", f32_field(&[nt], theta_i)),
        ("wavelengths", f32_field(&[wavelengths.len()], wavelengths)),
        ("ndf", f32_field(&[ndf.ny, ndf.nx], &ndf.values)),
        ("sigma", f32_field(&[sigma.ny, sigma.nx], &sigma.values)),
        ("vndf", f32_field(&[np, nt, vndf.ny, vndf.nx], &vndf.values)),
        (
            "luminance",
            f32_field(&[np, nt, luminance.ny, luminance.nx], &luminance.values),
        ),
        (
            "spectra",
            f32_field(
                &[np, nt, wavelengths.len(), luminance.ny, luminance.nx],
                spectra,
            ),
        ),
        (
            "description",
            Field {
                dtype: Dtype::U8,
                shape: vec![4],
                bytes: b"test".to_vec(),
            },
        ),
        (
            "jacobian",
            Field {
                dtype: Dtype::U8,
                shape: vec![1],
                bytes: vec![1],
            },
        ),
    ]
    .into_iter()
    .collect();
    let fields: Vec<(&str, Field)> = fields.into_iter().collect();
    write_tensor(&fields)
}

/// An RGL `.bsdf` file holding a Lambertian BRDF of reflectance `rho` (grey), tabulated on
/// `nt` viewing angles and `n` x `n` grids in the RGL parameterisation with a uniform
/// microfacet distribution: for tests, and as a stand-in where a scene's `.bsdf` file is
/// missing. Its luminance table follows the reflectance, so sampling is importance
/// sampling.
pub fn lambertian_bsdf_file(rho: f32, nt: usize, n: usize) -> Vec<u8> {
    lambertian_ramp_bsdf_file(rho, rho, nt, n)
}

/// [`lambertian_bsdf_file`] of a reflectance that is `rho_360` at 360 nm and `rho_830` at
/// 830 nm, linear in between (the file's two wavelengths).
pub fn lambertian_ramp_bsdf_file(rho_360: f32, rho_830: f32, nt: usize, n: usize) -> Vec<u8> {
    let rho = 1.0;
    use std::f32::consts::{FRAC_PI_2, PI};
    let theta_i: Vec<f32> = (0..nt)
        .map(|k| {
            let u = k as f32 / (nt - 1) as f32;
            u * u * FRAC_PI_2
        })
        .collect();
    let ones = |len: usize| Grid2 {
        nx: n,
        ny: n,
        values: vec![1.0; len],
    };
    // With D = σ = 1 and a uniform vndf, f = R(u_wm) / (4 cos θ_i): R = 4 ρ/π · cos θ_i.
    let mut r = Vec::with_capacity(nt * n * n);
    for &theta_o in &theta_i {
        let wo = [libm::sinf(theta_o), 0.0, libm::cosf(theta_o)];
        for y in 0..n {
            for x in 0..n {
                let (ux, uy) = (x as f32 / (n - 1) as f32, y as f32 / (n - 1) as f32);
                let (tm, pm) = (ux * ux * FRAC_PI_2, (2.0 * uy - 1.0) * PI);
                let wm = [
                    libm::sinf(tm) * libm::cosf(pm),
                    libm::sinf(tm) * libm::sinf(pm),
                    libm::cosf(tm),
                ];
                let d = wo[0] * wm[0] + wo[1] * wm[1] + wo[2] * wm[2];
                let wi_z = -wo[2] + 2.0 * d * wm[2];
                r.push(4.0 * rho / PI * wi_z.max(0.0));
            }
        }
    }
    let luminance = Grid2 {
        nx: n,
        ny: n,
        values: r
            .iter()
            .map(|v| v * 0.5 * (rho_360 + rho_830) + 0.05)
            .collect(),
    };
    // The reflectance at each end of the visible range (grey where they are equal).
    let spectra: Vec<f32> = r
        .chunks_exact(n * n)
        .flat_map(|slice| {
            let at = |rho: f32| slice.iter().map(move |v| v * rho);
            at(rho_360).chain(at(rho_830)).collect::<Vec<_>>()
        })
        .collect();
    write_measured(
        &[0.0],
        &theta_i,
        &ones(n * n),
        &ones(n * n),
        &ones(nt * n * n),
        &luminance,
        &[360.0, 830.0],
        &spectra,
    )
}
