//! Scattering functions in a local shading frame (z along the shading normal).
//!
//! [`Bsdf`] is the closed set of BSDFs and its dispatch; each BSDF lives in its own file.
//! The formulas follow pbrt-v4's BxDFs: Lambertian diffuse, conductors and dielectrics with
//! Fresnel and an anisotropic Trowbridge-Reitz (GGX) microfacet distribution sampled by
//! visible normals, thin dielectrics, a dielectric coat over a diffuse base, measured
//! BRDFs and hair fibres.
//!
//! BSDFs know nothing of materials, textures or scenes: a material makes one at a hit.

mod conductor;
pub mod dielectric;
mod diffuse;
mod diffuse_transmission;
pub mod fresnel;
mod hair;
mod layered;
mod measured;
mod microfacet;
mod thin_dielectric;

pub use conductor::ConductorBxdf;
pub use dielectric::DielectricBxdf;
pub use diffuse::DiffuseBxdf;
pub use diffuse_transmission::DiffuseTransmissionBxdf;
pub use fresnel::{FresnelTable, fresnel_complex, fresnel_dielectric, refract};
pub use hair::HairBxdf;
pub use layered::{Base, LayeredBxdf};
pub use measured::{MeasuredBxdf, MeasuredTables};
pub use microfacet::TrowbridgeReitz;
pub use thin_dielectric::ThinDielectricBxdf;

use crate::math::Color;
use glam::{Vec2, Vec3A};

#[derive(Debug, Clone, Copy)]
pub struct BsdfSample {
    /// The BSDF value (not multiplied by the cosine).
    pub f: Color,
    pub wi: Vec3A,
    pub pdf: f32,
    /// Sampled from a delta lobe: pdf and f are relative to a Dirac delta.
    pub specular: bool,
    /// Relative index of refraction crossed (1 for reflection).
    pub eta: f32,
}

#[derive(Debug, Clone, Copy)]
pub enum Bsdf<'a> {
    Diffuse(DiffuseBxdf),
    DiffuseTransmission(DiffuseTransmissionBxdf),
    Conductor(ConductorBxdf<'a>),
    Dielectric(DielectricBxdf),
    ThinDielectric(ThinDielectricBxdf),
    Layered(LayeredBxdf<'a>),
    Measured(MeasuredBxdf<'a>),
    Hair(HairBxdf),
}

impl Bsdf<'_> {
    /// True when every lobe is a delta: light sampling cannot help.
    pub fn is_specular(&self) -> bool {
        match self {
            Bsdf::Diffuse(_)
            | Bsdf::DiffuseTransmission(_)
            | Bsdf::Layered(_)
            | Bsdf::Measured(_)
            | Bsdf::Hair(_) => false,
            Bsdf::Conductor(b) => b.distrib.effectively_smooth(),
            Bsdf::Dielectric(b) => b.distrib.effectively_smooth(),
            Bsdf::ThinDielectric(_) => true,
        }
    }

    /// pbrt-v4's "regularize": microfacet lobes roughened (near-specular ones made glossy)
    /// so that paths after a diffuse bounce can find small lights; the other kinds stay.
    pub fn regularize(&mut self) {
        match self {
            Bsdf::Conductor(b) => b.distrib.regularize(),
            Bsdf::Dielectric(b) => b.distrib.regularize(),
            Bsdf::Layered(b) => {
                b.top.distrib.regularize();
                if let layered::Base::Conductor(c) = &mut b.bottom {
                    c.distrib.regularize();
                }
            }
            Bsdf::Diffuse(_)
            | Bsdf::DiffuseTransmission(_)
            | Bsdf::ThinDielectric(_)
            | Bsdf::Measured(_)
            | Bsdf::Hair(_) => {}
        }
    }

    /// True when the BSDF reflects nothing at all (a black diffuse, as emitters often use).
    pub fn is_black(&self) -> bool {
        match self {
            Bsdf::Diffuse(b) => b.r == Color::ZERO,
            Bsdf::DiffuseTransmission(b) => b.r == Color::ZERO && b.t == Color::ZERO,
            _ => false,
        }
    }

    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        match self {
            Bsdf::Diffuse(b) => b.f(wo, wi),
            Bsdf::DiffuseTransmission(b) => b.f(wo, wi),
            Bsdf::Conductor(b) => b.f(wo, wi),
            Bsdf::Dielectric(b) => b.f(wo, wi),
            Bsdf::ThinDielectric(b) => b.f(wo, wi),
            Bsdf::Layered(b) => b.f(wo, wi),
            Bsdf::Measured(b) => b.f(wo, wi),
            Bsdf::Hair(b) => b.f(wo, wi),
        }
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        match self {
            Bsdf::Diffuse(b) => b.pdf(wo, wi),
            Bsdf::DiffuseTransmission(b) => b.pdf(wo, wi),
            Bsdf::Conductor(b) => b.pdf(wo, wi),
            Bsdf::Dielectric(b) => b.pdf(wo, wi),
            Bsdf::ThinDielectric(b) => b.pdf(wo, wi),
            Bsdf::Layered(b) => b.pdf(wo, wi),
            Bsdf::Measured(b) => b.pdf(wo, wi),
            Bsdf::Hair(b) => b.pdf(wo, wi),
        }
    }

    /// Samples an incident direction. `uc` picks a lobe, `u` the direction.
    pub fn sample(&self, wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        match self {
            Bsdf::Diffuse(b) => b.sample(wo, uc, u),
            Bsdf::DiffuseTransmission(b) => b.sample(wo, uc, u),
            Bsdf::Conductor(b) => b.sample(wo, uc, u),
            Bsdf::Dielectric(b) => b.sample(wo, uc, u),
            Bsdf::ThinDielectric(b) => b.sample(wo, uc, u),
            Bsdf::Measured(b) => b.sample(wo, uc, u),
            Bsdf::Hair(b) => b.sample(wo, uc, u),
            // The walk's f and pdf have the right ratio, but its pdf is only proportional to
            // the density multiple importance sampling needs: rescale both to the estimated
            // density (pbrt-v4's pdfIsProportional), keeping the ratio.
            Bsdf::Layered(b) => b.sample_walk(wo, uc, u).map(|mut s| {
                if !s.specular {
                    let pdf = b.pdf(wo, s.wi);
                    // (The walk's own pdf can be tiny after many bounces: divide first.)
                    let ratio = s.f / s.pdf;
                    if pdf > 0.0 && ratio.is_finite() {
                        s.f = ratio * pdf;
                        s.pdf = pdf;
                    }
                }
                s
            }),
        }
    }
}

pub(crate) fn same_hemisphere(a: Vec3A, b: Vec3A) -> bool {
    a.z * b.z > 0.0
}

pub(crate) fn reflect(wo: Vec3A, n: Vec3A) -> Vec3A {
    -wo + 2.0 * wo.dot(n) * n
}

/// Coated materials scatter the same from both sides.
fn upper(wo: Vec3A, wi: Vec3A) -> (Vec3A, Vec3A) {
    if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PixelSampler;
    use std::f32::consts::PI;

    fn wo_at(cos: f32) -> Vec3A {
        Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos)
    }

    /// Directional albedo by sampling, and by integrating f*cos over the sphere
    /// with the sampled pdf replaced by uniform directions: the two must agree,
    /// which checks that sample(), f() and pdf() describe the same function.
    fn check_consistency(bsdf: Bsdf, wo: Vec3A) {
        let n = 1 << 14;
        let mut by_sampling = Color::ZERO;
        let mut by_uniform = Color::ZERO;
        // Energy with the 1/eta^2 radiance scaling of refraction undone: never above 1.
        let mut energy = Color::ZERO;
        for i in 0..n {
            let s = PixelSampler::new(3, 4, i, 11);
            let u = Vec2::new(s.value(1), s.value(2));
            if let Some(bs) = bsdf.sample(wo, s.value(0), u) {
                assert!(bs.pdf > 0.0 && bs.f.is_finite(), "{bsdf:?} {bs:?}");
                if !bs.specular {
                    let pdf = bsdf.pdf(wo, bs.wi);
                    assert!(
                        (pdf - bs.pdf).abs() <= 1e-3 * pdf.max(1.0),
                        "{bsdf:?}: pdf {} vs {}",
                        pdf,
                        bs.pdf
                    );
                    let f = bsdf.f(wo, bs.wi);
                    assert!((f - bs.f).abs().max_element() <= 1e-3 * f.max_element().max(1.0));
                }
                by_sampling += bs.f * bs.wi.z.abs() / bs.pdf;
                energy += bs.f * bs.wi.z.abs() / bs.pdf * bs.eta * bs.eta;
            }
            let wi = crate::sampling::uniform_sphere(Vec2::new(s.value(3), s.value(4)));
            by_uniform += bsdf.f(wo, wi) * wi.z.abs() * 4.0 * PI;
        }
        by_sampling /= n as f32;
        by_uniform /= n as f32;
        if !bsdf.is_specular() {
            let diff = (by_sampling - by_uniform).abs().max_element();
            assert!(
                diff < 0.03 * by_sampling.max_element().max(0.2),
                "{bsdf:?} at {wo}: sampled {by_sampling} uniform {by_uniform}"
            );
        }
        energy /= n as f32;
        assert!(
            energy.max_element() <= 1.02,
            "{bsdf:?} at {wo} gains energy: {energy}"
        );
    }

    #[test]
    fn sampling_f_and_pdf_agree() {
        let bsdfs = [
            Bsdf::Diffuse(DiffuseBxdf {
                r: Color::splat(0.8),
            }),
            Bsdf::DiffuseTransmission(DiffuseTransmissionBxdf {
                r: crate::math::rgb3(0.2, 0.5, 0.1),
                t: crate::math::rgb3(0.6, 0.3, 0.0),
            }),
            Bsdf::Conductor(ConductorBxdf {
                eta: crate::math::rgb3(0.2, 0.9, 1.1),
                k: crate::math::rgb3(3.9, 2.4, 2.1),
                distrib: TrowbridgeReitz::new(0.3, 0.3),
                table: None,
            }),
            Bsdf::Conductor(ConductorBxdf {
                eta: Color::splat(0.2),
                k: Color::splat(3.0),
                distrib: TrowbridgeReitz::new(0.1, 0.4),
                table: None,
            }),
            Bsdf::Dielectric(DielectricBxdf {
                eta: 1.5,
                distrib: TrowbridgeReitz::new(0.3, 0.3),
                dispersive: false,
            }),
            Bsdf::Dielectric(DielectricBxdf {
                eta: 1.5,
                distrib: TrowbridgeReitz::new(0.0, 0.0),
                dispersive: false,
            }),
            Bsdf::ThinDielectric(ThinDielectricBxdf { eta: 1.5 }),
        ];
        for b in bsdfs {
            for cos in [0.9, 0.5, 0.2, -0.6] {
                check_consistency(b, wo_at(cos));
            }
        }
    }

    /// A measured BRDF tabulated from a Lambertian of reflectance 0.6 (the RGL stand-in):
    /// its f, pdf and sampling agree, and its albedo is 0.6 at every angle, by sampling and
    /// by integrating f over uniform directions (within the tables' interpolation error).
    #[test]
    fn a_measured_lambertian_reflects_as_one() {
        let bytes = kiln_scene::files::measured::lambertian_bsdf_file(0.6, 16, 32);
        let brdf = kiln_scene::files::measured::parse_measured(&bytes).unwrap();
        assert!(brdf.isotropic);
        let tables = MeasuredTables::new(&brdf).unwrap();
        let b = Bsdf::Measured(MeasuredBxdf {
            tables: &tables,
            lambda: None,
        });
        for cos in [0.95, 0.7, 0.4, 0.15, -0.6] {
            check_consistency(b, wo_at(cos));
            let (sampled, uniform) = albedo_both_ways(b, wo_at(cos), 1 << 16);
            for (how, a) in [("sampled", sampled), ("uniform", uniform)] {
                assert!((a - 0.6).abs() < 0.015, "cos {cos}: {how} albedo {a}");
            }
        }
        // Reciprocal, as the Lambertian it was made from.
        let (a, c) = (wo_at(0.8), Vec3A::new(-0.3, 0.5, 0.81).normalize());
        let (fa, fc) = (b.f(a, c).x, b.f(c, a).x);
        assert!((fa - fc).abs() < 0.02 * fa, "{fa} vs {fc}");
        assert!((fa - 0.6 / PI).abs() < 0.02 * fa, "{fa}");
    }

    /// At a spectral path's wavelengths a measured BRDF reads the file's spectra, each
    /// wavelength interpolated between the file's (and held beyond them): a Lambertian whose
    /// reflectance ramps from 0.2 at 360 nm to 0.8 at 830 nm reflects ρ(λ)/π at each.
    #[test]
    fn a_measured_brdf_reflects_each_wavelength_by_its_spectrum() {
        let bytes = kiln_scene::files::measured::lambertian_ramp_bsdf_file(0.2, 0.8, 16, 32);
        let brdf = kiln_scene::files::measured::parse_measured(&bytes).unwrap();
        let tables = MeasuredTables::new(&brdf).unwrap();
        let lambda = glam::Vec4::new(400.0, 500.0, 650.0, 800.0);
        let b = Bsdf::Measured(MeasuredBxdf {
            tables: &tables,
            lambda: Some(lambda),
        });
        let (wo, wi) = (wo_at(0.8), Vec3A::new(-0.3, 0.5, 0.81).normalize());
        let f = b.f(wo, wi);
        for l in 0..4 {
            let rho = 0.2 + 0.6 * (lambda[l] - 360.0) / 470.0;
            assert!(
                (f[l] - rho / PI).abs() < 0.02 * f[l],
                "{} nm: {} vs {}",
                lambda[l],
                f[l],
                rho / PI
            );
        }
        check_consistency(b, wo);
        // Below the file's first wavelength, its first value.
        let held = Bsdf::Measured(MeasuredBxdf {
            tables: &tables,
            lambda: Some(glam::Vec4::new(300.0, 360.0, 830.0, 900.0)),
        })
        .f(wo, wi);
        assert!((held[0] - held[1]).abs() < 1e-6 && (held[2] - held[3]).abs() < 1e-6);
    }

    fn layered(bottom: Base, albedo: f32, roughness: f32, max_depth: u32) -> LayeredBxdf {
        LayeredBxdf {
            top: DielectricBxdf {
                eta: 1.5,
                distrib: TrowbridgeReitz::new(roughness, roughness),
                dispersive: false,
            },
            bottom,
            thickness: 0.1,
            albedo: Color::splat(albedo),
            g: 0.3,
            max_depth,
            n_samples: 1,
        }
    }

    /// Directional albedo of a BSDF by sampling, and by integrating f·cos over uniform
    /// directions.
    fn albedo_both_ways(b: Bsdf, wo: Vec3A, n: u32) -> (f32, f32) {
        let (mut sampled, mut uniform) = (0.0f64, 0.0f64);
        for i in 0..n {
            let s = PixelSampler::new(5, 6, i, 3);
            if let Some(bs) = b.sample(wo, s.value(0), Vec2::new(s.value(1), s.value(2))) {
                sampled += (bs.f.x * bs.wi.z.abs() / bs.pdf) as f64;
            }
            let wi = crate::sampling::uniform_sphere(Vec2::new(s.value(3), s.value(4)));
            uniform += (b.f(wo, wi).x * wi.z.abs() * 4.0 * PI) as f64;
        }
        ((sampled / n as f64) as f32, (uniform / n as f64) as f32)
    }

    /// White furnace: a white base under a smooth clear coat over a medium that scatters
    /// without absorbing reflects everything (given walks long enough), whether the base is
    /// diffuse or a perfect mirror. (Rough microfacet interfaces lose the energy of their
    /// inter-reflections, in pbrt-v4 too: over the many crossings of a layer that adds up.)
    /// For rough coats, f, pdf and sampling must agree.
    #[test]
    fn layered_bsdfs_conserve_energy_and_agree_with_their_sampling() {
        let white = Base::Diffuse(DiffuseBxdf { r: Color::ONE });
        let mirror = |alpha| {
            Base::Conductor(ConductorBxdf {
                eta: Color::splat(0.0),
                k: Color::splat(1e4),
                distrib: TrowbridgeReitz::new(alpha, alpha),
                table: None,
            })
        };
        for base in [white, mirror(0.0)] {
            let b = Bsdf::Layered(layered(base, 1.0, 0.0, 400));
            for cos in [0.9, 0.4, -0.7] {
                let (sampled, _) = albedo_both_ways(b, wo_at(cos), 1 << 14);
                assert!((sampled - 1.0).abs() < 0.02, "{base:?} at {cos}: {sampled}");
            }
        }
        for (base, albedo) in [
            (white, 0.0),
            (white, 0.8),
            (mirror(0.2), 0.0),
            (mirror(0.6), 0.5),
        ] {
            let b = Bsdf::Layered(layered(base, albedo, 0.3, 10));
            for cos in [0.9, 0.4, -0.7] {
                let (sampled, uniform) = albedo_both_ways(b, wo_at(cos), 1 << 18);
                assert!(
                    sampled > 0.05 && (uniform - sampled).abs() < 0.03 + 0.05 * sampled,
                    "{base:?} albedo {albedo} at {cos}: f {uniform} vs sampling {sampled}"
                );
            }
        }
        // An absorbing layer (albedo 0.5) loses energy.
        let dark = albedo_both_ways(
            Bsdf::Layered(layered(white, 0.5, 0.0, 10)),
            wo_at(0.8),
            1 << 13,
        )
        .0;
        assert!(dark < 0.9, "{dark}");
    }

    #[test]
    fn rough_perfect_conductor_albedo_matches_numerical_integration() {
        // With Fresnel = 1, the directional albedo at normal incidence is what single-scattering
        // GGX keeps at alpha 0.2: 0.9475 by a 4M-sample numerical integral of D G / (4 cos) done
        // independently (numpy, uniform hemisphere directions).
        let b = Bsdf::Conductor(ConductorBxdf {
            eta: Color::splat(0.0),
            k: Color::splat(1e4),
            distrib: TrowbridgeReitz::new(0.2, 0.2),
            table: None,
        });
        let wo = wo_at(1.0);
        let n = 1 << 14;
        let mut sum = 0.0;
        for i in 0..n {
            let s = PixelSampler::new(0, 0, i, 1);
            if let Some(bs) = b.sample(wo, s.value(0), Vec2::new(s.value(1), s.value(2))) {
                sum += bs.f.x * bs.wi.z / bs.pdf;
            }
        }
        let albedo = sum / n as f32;
        assert!((albedo - 0.9475).abs() < 0.004, "{albedo}");
    }
}
