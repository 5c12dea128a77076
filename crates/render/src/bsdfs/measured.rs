//! Measured BRDFs in the RGL format (Dupuy & Jakob 2018), as pbrt-v4's `MeasuredBxDF`
//! evaluates and samples them: in RGB from the spectra projected to linear sRGB, or at a
//! spectral path's wavelengths from the file's spectra, interpolated between its
//! wavelengths as pbrt-v4 does.
//!
//! The data are tabulated over a warped square: the half vector `wm` maps to
//! u_wm = (√(θ_m·2/π), φ_m/2π + ½) (φ relative to the viewing azimuth when isotropic), the
//! visible-normal distribution `vndf` maps a "sample" square to u_wm, and the reflectance is
//! tabulated over the sample square, so f(wo, wi) = R(vndf⁻¹(u_wm)) · D(u_wm) /
//! (4 σ(wo) cos θ_i). `wo` is the direction the data were measured from (the camera's side in
//! pbrt-v4 and Mitsuba).

use super::{BsdfSample, reflect, same_hemisphere, upper};
use crate::math::Color;
use crate::sampling::Warp2D;
use glam::{Vec2, Vec3A, Vec4};
use kiln_scene::files::measured::{Grid2, MeasuredBrdf};
use std::f32::consts::{FRAC_PI_2, PI};

/// A measured BRDF's tables, ready to evaluate and sample.
pub struct MeasuredTables {
    ndf: Warp2D,
    sigma: Warp2D,
    vndf: Warp2D,
    luminance: Warp2D,
    rgb: Warp2D,
    /// Reflectance per wavelength (the file's), for spectral paths.
    spectra: Warp2D,
    isotropic: bool,
}

impl MeasuredTables {
    pub fn new(brdf: &MeasuredBrdf) -> Result<MeasuredTables, String> {
        let dir = vec![brdf.phi_i.clone(), brdf.theta_i.clone()];
        let warp = |g: &Grid2, params: Vec<Vec<f32>>, sampled: bool| {
            Warp2D::new(&g.values, g.nx, g.ny, params, sampled)
        };
        let mut by_channel = dir.clone();
        by_channel.push(vec![0.0, 1.0, 2.0]);
        let mut by_wavelength = dir.clone();
        by_wavelength.push(brdf.wavelengths.clone());
        Ok(MeasuredTables {
            ndf: warp(&brdf.ndf, vec![], false)?,
            sigma: warp(&brdf.sigma, vec![], false)?,
            vndf: warp(&brdf.vndf, dir.clone(), true)?,
            luminance: warp(&brdf.luminance, dir, true)?,
            rgb: warp(&brdf.rgb, by_channel, false)?,
            spectra: warp(&brdf.spectra, by_wavelength, false)?,
            isotropic: brdf.isotropic,
        })
    }
}

impl std::fmt::Debug for MeasuredTables {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MeasuredTables {{ isotropic: {} }}", self.isotropic)
    }
}

fn theta_to_u(theta: f32) -> f32 {
    (theta * (2.0 / PI)).max(0.0).sqrt()
}

fn phi_to_u(phi: f32) -> f32 {
    phi * (0.5 / PI) + 0.5
}

fn u_to_theta(u: f32) -> f32 {
    u * u * FRAC_PI_2
}

fn u_to_phi(u: f32) -> f32 {
    (2.0 * u - 1.0) * PI
}

/// (θ, φ) of a unit vector; θ by atan2, which keeps its precision near the pole (where the
/// warped square's Jacobian is steepest), unlike acos.
fn spherical(w: Vec3A) -> (f32, f32) {
    (
        libm::atan2f((w.x * w.x + w.y * w.y).sqrt(), w.z),
        libm::atan2f(w.y, w.x),
    )
}

#[derive(Debug, Clone, Copy)]
pub struct MeasuredBxdf<'a> {
    pub tables: &'a MeasuredTables,
    /// A spectral path's four wavelengths (nm); None in RGB.
    pub lambda: Option<Vec4>,
}

impl MeasuredBxdf<'_> {
    /// The reflectance table at sample point `u` seen from (phi_o, theta_o): RGB, or the
    /// spectra at the path's wavelengths.
    fn reflectance(&self, u: Vec2, phi_o: f32, theta_o: f32) -> Color {
        match self.lambda {
            None => {
                let c = |k: f32| self.tables.rgb.evaluate(u, &[phi_o, theta_o, k]).max(0.0);
                crate::math::rgb3(c(0.0), c(1.0), c(2.0))
            }
            Some(lambda) => Color::from_array(lambda.to_array().map(|l| {
                self.tables
                    .spectra
                    .evaluate(u, &[phi_o, theta_o, l])
                    .max(0.0)
            })),
        }
    }

    /// The half vector's point on the warped square, seen from `wo` (upper hemisphere).
    fn half_vector_u(&self, wo: Vec3A, wm: Vec3A) -> Vec2 {
        let (_, phi_o) = spherical(wo);
        let (theta_m, phi_m) = spherical(wm);
        let phi = if self.tables.isotropic {
            phi_m - phi_o
        } else {
            phi_m
        };
        let v = phi_to_u(phi);
        Vec2::new(theta_to_u(theta_m), v - v.floor())
    }

    /// The density of wi per unit of the warped half-vector square: dω_i / du_wm.
    fn jacobian(wo: Vec3A, wm: Vec3A, u_wm: Vec2) -> f32 {
        let sin_m = (wm.x * wm.x + wm.y * wm.y).sqrt();
        4.0 * wo.dot(wm) * (2.0 * PI * PI * u_wm.x * sin_m).max(1e-6)
    }

    fn value(&self, wo: Vec3A, u_wm: Vec2, sample: Vec2, cos_i: f32) -> Color {
        let (theta_o, phi_o) = spherical(wo);
        let u_wo = Vec2::new(theta_to_u(theta_o), phi_to_u(phi_o));
        let sigma = self.tables.sigma.evaluate(u_wo, &[]);
        if sigma <= 0.0 || cos_i <= 0.0 {
            return Color::ZERO;
        }
        self.reflectance(sample, phi_o, theta_o) * self.tables.ndf.evaluate(u_wm, &[])
            / (4.0 * sigma * cos_i)
    }

    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        if !same_hemisphere(wo, wi) {
            return Color::ZERO;
        }
        let (wo, wi) = upper(wo, wi);
        let wm = wo + wi;
        if wm.length_squared() == 0.0 {
            return Color::ZERO;
        }
        let wm = wm.normalize();
        let (theta_o, phi_o) = spherical(wo);
        let u_wm = self.half_vector_u(wo, wm);
        let (sample, _) = self.tables.vndf.invert(u_wm, &[phi_o, theta_o]);
        self.value(wo, u_wm, sample, wi.z)
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if !same_hemisphere(wo, wi) {
            return 0.0;
        }
        let (wo, wi) = upper(wo, wi);
        let wm = wo + wi;
        if wm.length_squared() == 0.0 {
            return 0.0;
        }
        let wm = wm.normalize();
        let (theta_o, phi_o) = spherical(wo);
        let u_wm = self.half_vector_u(wo, wm);
        let (sample, vndf_pdf) = self.tables.vndf.invert(u_wm, &[phi_o, theta_o]);
        let lum_pdf = self.tables.luminance.evaluate(sample, &[phi_o, theta_o]);
        vndf_pdf * lum_pdf / Self::jacobian(wo, wm, u_wm)
    }

    pub fn sample(&self, wo: Vec3A, _uc: f32, u: Vec2) -> Option<BsdfSample> {
        let flip = wo.z < 0.0;
        let wo = if flip { -wo } else { wo };
        let (theta_o, phi_o) = spherical(wo);
        let (sample, lum_pdf) = self.tables.luminance.sample(u, &[phi_o, theta_o]);
        let (u_wm, vndf_pdf) = self.tables.vndf.sample(sample, &[phi_o, theta_o]);
        let mut phi_m = u_to_phi(u_wm.y);
        if self.tables.isotropic {
            phi_m += phi_o;
        }
        let theta_m = u_to_theta(u_wm.x);
        let (sin_m, cos_m) = libm::sincosf(theta_m);
        let wm = Vec3A::new(sin_m * libm::cosf(phi_m), sin_m * libm::sinf(phi_m), cos_m);
        let wi = reflect(wo, wm);
        if wi.z <= 0.0 {
            return None;
        }
        if vndf_pdf * lum_pdf <= 0.0 {
            return None;
        }
        // The density and value where the sample landed, by the same inverse mapping that
        // f and pdf use: the forward warp gives them too, but rounding in the angles near
        // the pole (where the Jacobian is steepest) would set the two apart by a few
        // tenths of a percent, and multiple importance sampling needs them equal.
        let (pdf, f) = (self.pdf(wo, wi), self.f(wo, wi));
        (pdf > 0.0 && pdf.is_finite()).then_some(BsdfSample {
            f,
            wi: if flip { -wi } else { wi },
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}
