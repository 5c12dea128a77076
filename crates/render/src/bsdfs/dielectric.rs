//! Dielectric interfaces (glass, water): Fresnel reflection and refraction, smooth or
//! rough, with the 1/eta^2 scaling of radiance across the boundary.

use super::fresnel::{fresnel_dielectric, refract};
use super::{BsdfSample, TrowbridgeReitz, reflect, same_hemisphere};
use crate::math::Color;
use glam::{Vec2, Vec3A};

/// A dielectric interface: Fresnel reflection and refraction, smooth or rough.
#[derive(Debug, Clone, Copy)]
pub struct DielectricBxdf {
    pub eta: f32,
    pub distrib: TrowbridgeReitz,
    /// Its index is the hero wavelength's of a dispersive glass: a spectral path keeps
    /// only that wavelength from here on (see `integrators::path`).
    pub dispersive: bool,
}

/// Which lobes a sample or a pdf may use (the layered BSDF asks for one at a time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lobes {
    All,
    Reflection,
    Transmission,
}

impl Lobes {
    fn reflection(self) -> bool {
        self != Lobes::Transmission
    }
    fn transmission(self) -> bool {
        self != Lobes::Reflection
    }
    /// The probabilities of reflection and transmission, those not allowed zeroed.
    fn weigh(self, r: f32, t: f32) -> (f32, f32) {
        (
            if self.reflection() { r } else { 0.0 },
            if self.transmission() { t } else { 0.0 },
        )
    }
}

impl DielectricBxdf {
    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        self.f_mode(wo, wi, false)
    }

    /// The BSDF for radiance (`importance` false: refraction scales by 1/eta²) or for
    /// importance (no scaling), as light paths and layered BSDFs need.
    pub fn f_mode(&self, wo: Vec3A, wi: Vec3A, importance: bool) -> Color {
        let DielectricBxdf { eta, distrib, .. } = *self;
        if eta == 1.0 || distrib.effectively_smooth() {
            return Color::ZERO;
        }
        Color::splat(rough_dielectric_f(eta, &distrib, wo, wi, importance))
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        self.pdf_lobes(wo, wi, Lobes::All)
    }

    pub fn pdf_lobes(&self, wo: Vec3A, wi: Vec3A, lobes: Lobes) -> f32 {
        let DielectricBxdf { eta, distrib, .. } = *self;
        if eta == 1.0 || distrib.effectively_smooth() {
            return 0.0;
        }
        rough_dielectric_pdf(eta, &distrib, wo, wi, lobes)
    }

    pub fn sample(&self, wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_lobes(wo, uc, u, Lobes::All, false)
    }

    pub fn sample_lobes(
        &self,
        wo: Vec3A,
        uc: f32,
        u: Vec2,
        lobes: Lobes,
        importance: bool,
    ) -> Option<BsdfSample> {
        let DielectricBxdf { eta, distrib, .. } = *self;
        sample_dielectric(eta, &distrib, wo, uc, u, lobes, importance)
    }

    pub fn is_specular(&self) -> bool {
        self.eta == 1.0 || self.distrib.effectively_smooth()
    }
}

fn rough_dielectric_f(
    eta: f32,
    distrib: &TrowbridgeReitz,
    wo: Vec3A,
    wi: Vec3A,
    importance: bool,
) -> f32 {
    let (cos_o, cos_i) = (wo.z, wi.z);
    let reflect = cos_o * cos_i > 0.0;
    let etap = if reflect {
        1.0
    } else if cos_o > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = wi * etap + wo;
    if cos_i == 0.0 || cos_o == 0.0 || wm.length_squared() == 0.0 {
        return 0.0;
    }
    let mut wm = wm.normalize();
    if wm.z < 0.0 {
        wm = -wm;
    }
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return 0.0;
    }
    let f = fresnel_dielectric(wo.dot(wm), eta);
    if reflect {
        distrib.d(wm) * distrib.g(wo, wi) * f / (4.0 * cos_i * cos_o).abs()
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * cos_i * cos_o;
        let ft =
            distrib.d(wm) * (1.0 - f) * distrib.g(wo, wi) * (wi.dot(wm) * wo.dot(wm) / denom).abs();
        // Radiance is compressed into a smaller solid angle when entering a denser medium.
        if importance { ft } else { ft / (etap * etap) }
    }
}

fn rough_dielectric_pdf(
    eta: f32,
    distrib: &TrowbridgeReitz,
    wo: Vec3A,
    wi: Vec3A,
    lobes: Lobes,
) -> f32 {
    let (cos_o, cos_i) = (wo.z, wi.z);
    let reflect = cos_o * cos_i > 0.0;
    let etap = if reflect {
        1.0
    } else if cos_o > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = wi * etap + wo;
    if cos_i == 0.0 || cos_o == 0.0 || wm.length_squared() == 0.0 {
        return 0.0;
    }
    let mut wm = wm.normalize();
    if wm.z < 0.0 {
        wm = -wm;
    }
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return 0.0;
    }
    let fr = fresnel_dielectric(wo.dot(wm), eta);
    let (r, t) = lobes.weigh(fr, 1.0 - fr);
    if r + t == 0.0 {
        return 0.0;
    }
    if reflect {
        distrib.pdf(wo, wm) / (4.0 * wo.dot(wm).abs()) * r / (r + t)
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
        let dwm_dwi = wi.dot(wm).abs() / denom;
        distrib.pdf(wo, wm) * dwm_dwi * t / (r + t)
    }
}

fn sample_dielectric(
    eta: f32,
    distrib: &TrowbridgeReitz,
    wo: Vec3A,
    uc: f32,
    u: Vec2,
    lobes: Lobes,
    importance: bool,
) -> Option<BsdfSample> {
    if eta == 1.0 || distrib.effectively_smooth() {
        let fr = fresnel_dielectric(wo.z, eta);
        let (r, t) = lobes.weigh(fr, 1.0 - fr);
        if r + t == 0.0 {
            return None;
        }
        if uc < r / (r + t) {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                f: Color::splat(fr / wi.z.abs()),
                wi,
                pdf: r / (r + t),
                specular: true,
                eta: 1.0,
            });
        }
        let (wi, etap) = refract(wo, Vec3A::Z, eta)?;
        let ft = (1.0 - fr) / wi.z.abs() / if importance { 1.0 } else { etap * etap };
        return Some(BsdfSample {
            f: Color::splat(ft),
            wi,
            pdf: t / (r + t),
            specular: true,
            eta: etap,
        });
    }
    // The sampled microfacet normal is always in the upper hemisphere; from inside
    // (wo.z < 0) the Fresnel term and refraction then see a negative cosine and
    // invert eta, as they must.
    let wm = distrib.sample_wm(wo, u);
    let fr = fresnel_dielectric(wo.dot(wm), eta);
    let (r, t) = lobes.weigh(fr, 1.0 - fr);
    if r + t == 0.0 {
        return None;
    }
    let (wi, etap) = if uc < r / (r + t) {
        let wi = reflect(wo, wm);
        if !same_hemisphere(wo, wi) {
            return None;
        }
        (wi, 1.0)
    } else {
        let (wi, etap) = refract(wo, wm, eta)?;
        if same_hemisphere(wo, wi) || wi.z == 0.0 {
            return None;
        }
        (wi, etap)
    };
    let pdf = rough_dielectric_pdf(eta, distrib, wo, wi, lobes);
    let f = rough_dielectric_f(eta, distrib, wo, wi, importance);
    (pdf > 0.0 && f > 0.0).then_some(BsdfSample {
        f: Color::splat(f),
        wi,
        pdf,
        specular: false,
        eta: etap,
    })
}
