//! pbrt-v4's hair BSDF, the model of Chiang, Bitterli, Tappan and Burley ("A Practical and
//! Controllable Hair and Fur Model for Production Path Tracing", 2016): light scatters off
//! a dielectric cylinder with absorbing interior, as a sum of lobes p = 0 (reflection), 1
//! (transmission), 2 (transmission, internal reflection, transmission) and a last lobe for
//! everything after. Each lobe is a longitudinal function M_p (a von Mises-Fisher-like
//! lobe of variance v_p, its centre tilted by the cuticle scales' angle α), an attenuation
//! A_p (Fresnel and absorption along the path through the fibre) and an azimuthal function
//! N_p (a trimmed logistic around the lobe's exit angle).
//!
//! The local frame is the curve's: x along the fibre (dp/du), z the normal at the hit, so
//! sin θ = ω.x and φ = atan2(ω.z, ω.y). `h` in [−1, 1] is where across the fibre's width the
//! ray struck (the curve's v, remapped). f includes the 1/|cos θ_i| that the integrator's
//! cosine cancels, as in pbrt-v4.

use super::BsdfSample;
use super::fresnel::fresnel_dielectric;
use crate::math::Color;
use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// Lobes modelled explicitly before the remainder lobe.
const P_MAX: usize = 3;

#[derive(Debug, Clone, Copy)]
pub struct HairBxdf {
    h: f32,
    eta: f32,
    sigma_a: Color,
    /// Longitudinal variance per lobe.
    v: [f32; P_MAX + 1],
    /// Azimuthal logistic scale.
    s: f32,
    /// sin and cos of 2^k α, k = 0, 1, 2 (the cuticle tilt doubled per lobe).
    sin_2k_alpha: [f32; P_MAX],
    cos_2k_alpha: [f32; P_MAX],
    /// The colour's lanes that lobes' attenuations are averaged over: 3 in RGB, a spectral
    /// path's 4 wavelengths.
    lanes: u8,
}

/// The geometry of a direction around the fibre: sin θ, cos θ, φ.
#[derive(Clone, Copy)]
struct Angles {
    sin_theta: f32,
    cos_theta: f32,
    phi: f32,
}

impl Angles {
    fn of(w: Vec3A) -> Angles {
        let sin_theta = w.x.clamp(-1.0, 1.0);
        Angles {
            sin_theta,
            cos_theta: (1.0 - sin_theta * sin_theta).max(0.0).sqrt(),
            phi: libm::atan2f(w.z, w.y),
        }
    }
}

/// What every lobe needs of the outgoing direction.
struct Outgoing {
    o: Angles,
    gamma_o: f32,
    gamma_t: f32,
    /// The attenuation per lobe.
    ap: [Color; P_MAX + 1],
}

impl HairBxdf {
    /// A fibre struck at `h` ∈ [−1, 1], of index `eta` and absorption `sigma_a` (per unit
    /// of diameter), longitudinal roughness `beta_m`, azimuthal roughness `beta_n` (both
    /// in (0, 1]), cuticle tilt `alpha_degrees`.
    pub fn new(
        h: f32,
        eta: f32,
        sigma_a: Color,
        beta_m: f32,
        beta_n: f32,
        alpha_degrees: f32,
    ) -> HairBxdf {
        // The roughness to variance and to logistic scale maps Chiang et al. fitted.
        let v0 = (0.726 * beta_m + 0.812 * beta_m * beta_m + 3.7 * beta_m.powi(20)).powi(2);
        let s = (PI / 8.0).sqrt()
            * (0.265 * beta_n + 1.194 * beta_n * beta_n + 5.372 * beta_n.powi(22));
        let mut sin_2k_alpha = [0.0; P_MAX];
        let mut cos_2k_alpha = [0.0; P_MAX];
        sin_2k_alpha[0] = libm::sinf(alpha_degrees.to_radians());
        cos_2k_alpha[0] = (1.0 - sin_2k_alpha[0] * sin_2k_alpha[0]).max(0.0).sqrt();
        for i in 1..P_MAX {
            sin_2k_alpha[i] = 2.0 * cos_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
            cos_2k_alpha[i] = cos_2k_alpha[i - 1].powi(2) - sin_2k_alpha[i - 1].powi(2);
        }
        HairBxdf {
            h: h.clamp(-1.0, 1.0),
            eta,
            sigma_a: sigma_a.max(Color::ZERO),
            v: [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0],
            s,
            sin_2k_alpha,
            cos_2k_alpha,
            lanes: 3,
        }
    }

    /// The fibre for a spectral path: its absorption is given at the path's four
    /// wavelengths, and lobes are chosen by their attenuation over all four.
    pub fn spectral(self) -> HairBxdf {
        HairBxdf { lanes: 4, ..self }
    }

    /// pbrt-v4's absorption from melanin concentrations (eumelanin, pheomelanin).
    pub fn sigma_a_from_melanin(eumelanin: f32, pheomelanin: f32) -> Color {
        crate::math::rgb3(0.419, 0.697, 1.37) * eumelanin.max(0.0)
            + crate::math::rgb3(0.187, 0.4, 1.05) * pheomelanin.max(0.0)
    }

    /// The absorption that gives roughly the colour `c` after multiple scattering, for
    /// azimuthal roughness `beta_n` (Chiang et al.'s fit).
    /// Lane by lane: a spectral path's reflectance spectrum gives its absorption spectrum.
    pub fn sigma_a_from_reflectance(c: Color, beta_n: f32) -> Color {
        let b = beta_n;
        let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3)
            + 5.574 * b.powi(4)
            + 0.245 * b.powi(5);
        let c = c.clamp(Color::splat(1e-4), Color::ONE);
        Color::from_array(c.to_array().map(|v| (libm::logf(v) / d).powi(2)))
    }

    fn outgoing(&self, wo: Vec3A) -> Outgoing {
        let o = Angles::of(wo);
        let sin_theta_t = o.sin_theta / self.eta;
        let cos_theta_t = (1.0 - sin_theta_t * sin_theta_t).max(0.0).sqrt();
        // The refracted ray's azimuthal offset, by the modified index of Bravais.
        let etap = (self.eta * self.eta - o.sin_theta * o.sin_theta)
            .max(0.0)
            .sqrt()
            / o.cos_theta.max(1e-7);
        let sin_gamma_t = (self.h / etap).clamp(-1.0, 1.0);
        let cos_gamma_t = (1.0 - sin_gamma_t * sin_gamma_t).max(0.0).sqrt();
        let transmittance = (-self.sigma_a * (2.0 * cos_gamma_t / cos_theta_t.max(1e-7))).exp();
        // Attenuation: Fresnel at the first interface, then each pass through the fibre.
        let cos_gamma_o = (1.0 - self.h * self.h).max(0.0).sqrt();
        let f = fresnel_dielectric(o.cos_theta * cos_gamma_o, self.eta);
        let mut ap = [Color::ZERO; P_MAX + 1];
        ap[0] = Color::splat(f);
        ap[1] = transmittance * (1.0 - f) * (1.0 - f);
        for p in 2..P_MAX {
            ap[p] = ap[p - 1] * transmittance * f;
        }
        let tf = transmittance * f;
        let rest = Color::ONE - tf;
        // Lane by lane (an RGB colour's fourth lane repeats green's arithmetic).
        ap[P_MAX] = Color::select(
            rest.cmpgt(Color::ZERO),
            ap[P_MAX - 1] * tf / rest,
            Color::ZERO,
        );
        Outgoing {
            o,
            gamma_o: libm::asinf(self.h),
            gamma_t: libm::asinf(sin_gamma_t),
            ap,
        }
    }

    /// θ_o tilted for lobe p by the cuticle scales: (sin, |cos|).
    fn tilted(&self, p: usize, o: &Angles) -> (f32, f32) {
        let (s, c) = (o.sin_theta, o.cos_theta);
        let (sin, cos) = match p {
            0 => (
                s * self.cos_2k_alpha[1] - c * self.sin_2k_alpha[1],
                c * self.cos_2k_alpha[1] + s * self.sin_2k_alpha[1],
            ),
            1 => (
                s * self.cos_2k_alpha[0] + c * self.sin_2k_alpha[0],
                c * self.cos_2k_alpha[0] - s * self.sin_2k_alpha[0],
            ),
            2 => (
                s * self.cos_2k_alpha[2] + c * self.sin_2k_alpha[2],
                c * self.cos_2k_alpha[2] - s * self.sin_2k_alpha[2],
            ),
            _ => (s, c),
        };
        (sin, cos.abs())
    }

    /// The lobes' choice probabilities: their attenuations' averages, normalised.
    fn lobe_pdf(&self, ap: &[Color; P_MAX + 1]) -> [f32; P_MAX + 1] {
        let avg = if self.lanes == 4 {
            ap.map(|a| a.element_sum() / 4.0)
        } else {
            ap.map(|a| (a.x + a.y + a.z) / 3.0)
        };
        let sum: f32 = avg.iter().sum();
        if sum > 0.0 {
            avg.map(|a| a / sum)
        } else {
            [0.0, 0.0, 0.0, 1.0]
        }
    }

    pub fn f(&self, wo: Vec3A, wi: Vec3A) -> Color {
        let out = self.outgoing(wo);
        let i = Angles::of(wi);
        let phi = i.phi - out.o.phi;
        let mut sum = Color::ZERO;
        for p in 0..P_MAX {
            let (sin_o, cos_o) = self.tilted(p, &out.o);
            sum += out.ap[p]
                * (mp(i.cos_theta, cos_o, i.sin_theta, sin_o, self.v[p])
                    * np(phi, p, self.s, out.gamma_o, out.gamma_t));
        }
        sum += out.ap[P_MAX]
            * (mp(
                i.cos_theta,
                out.o.cos_theta,
                i.sin_theta,
                out.o.sin_theta,
                self.v[P_MAX],
            ) / (2.0 * PI));
        if wi.z.abs() > 0.0 {
            sum /= wi.z.abs();
        }
        if sum.is_finite() { sum } else { Color::ZERO }
    }

    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let out = self.outgoing(wo);
        let i = Angles::of(wi);
        self.pdf_of(&out, &i, i.phi - out.o.phi)
    }

    fn pdf_of(&self, out: &Outgoing, i: &Angles, dphi: f32) -> f32 {
        let lobes = self.lobe_pdf(&out.ap);
        let mut pdf = 0.0;
        for (p, &weight) in lobes.iter().enumerate().take(P_MAX) {
            let (sin_o, cos_o) = self.tilted(p, &out.o);
            pdf += weight
                * mp(i.cos_theta, cos_o, i.sin_theta, sin_o, self.v[p])
                * np(dphi, p, self.s, out.gamma_o, out.gamma_t);
        }
        pdf += lobes[P_MAX]
            * mp(
                i.cos_theta,
                out.o.cos_theta,
                i.sin_theta,
                out.o.sin_theta,
                self.v[P_MAX],
            )
            / (2.0 * PI);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    pub fn sample(&self, wo: Vec3A, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let out = self.outgoing(wo);
        // Choose a lobe with `uc`, and keep what is left of it for the azimuth.
        let lobes = self.lobe_pdf(&out.ap);
        let mut p = P_MAX;
        let mut acc = 0.0;
        let mut uc_rest = uc;
        for (k, &w) in lobes.iter().enumerate() {
            if uc < acc + w || k == P_MAX {
                p = k;
                uc_rest = if w > 0.0 {
                    ((uc - acc) / w).clamp(0.0, 1.0 - f32::EPSILON)
                } else {
                    0.5
                };
                break;
            }
            acc += w;
        }
        // The longitudinal angle from M_p.
        let (sin_o, cos_o) = self.tilted(p, &out.o);
        let v = self.v[p];
        let cos_theta = 1.0 + v * libm::logf(u.x.max(1e-5) + (1.0 - u.x) * libm::expf(-2.0 / v));
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let cos_phi = libm::cosf(2.0 * PI * u.y);
        let sin_theta_i = (-cos_theta * sin_o + sin_theta * cos_phi * cos_o).clamp(-1.0, 1.0);
        let cos_theta_i = (1.0 - sin_theta_i * sin_theta_i).max(0.0).sqrt();
        // The azimuth from N_p.
        let dphi = if p < P_MAX {
            exit_phi(p, out.gamma_o, out.gamma_t) + sample_trimmed_logistic(uc_rest, self.s)
        } else {
            2.0 * PI * uc_rest
        };
        let phi_i = out.o.phi + dphi;
        let wi = Vec3A::new(
            sin_theta_i,
            cos_theta_i * libm::cosf(phi_i),
            cos_theta_i * libm::sinf(phi_i),
        );
        let i = Angles {
            sin_theta: sin_theta_i,
            cos_theta: cos_theta_i,
            phi: phi_i,
        };
        let pdf = self.pdf_of(&out, &i, dphi);
        (pdf > 0.0).then(|| BsdfSample {
            f: self.f(wo, wi),
            wi,
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}

/// The longitudinal scattering function M_p, in the form that stays finite for small
/// variances (through log I0) as in pbrt-v4.
fn mp(cos_i: f32, cos_o: f32, sin_i: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    let m = if v <= 0.1 {
        libm::expf(log_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + libm::logf(1.0 / (2.0 * v)))
    } else {
        libm::expf(-b) * i0(a) / (libm::sinhf(1.0 / v) * 2.0 * v)
    };
    if m.is_finite() { m } else { 0.0 }
}

/// The modified Bessel function I0, by its series (ten terms).
fn i0(x: f32) -> f32 {
    let mut val = 0.0f64;
    let mut term = 1.0f64;
    let x2 = f64::from(x) * f64::from(x) / 4.0;
    for k in 0..10 {
        if k > 0 {
            term *= x2 / (k * k) as f64;
        }
        val += term;
    }
    val as f32
}

fn log_i0(x: f32) -> f32 {
    if x > 12.0 {
        x + 0.5 * (-libm::logf(2.0 * PI) + libm::logf(1.0 / x) + 1.0 / (8.0 * x))
    } else {
        libm::logf(i0(x))
    }
}

/// The azimuth at which lobe p leaves, relative to the incoming one.
fn exit_phi(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    let p = p as f32;
    2.0 * p * gamma_t - 2.0 * gamma_o + p * PI
}

/// The azimuthal function N_p: a logistic of scale `s` around the lobe's exit azimuth,
/// trimmed to [−π, π].
fn np(phi: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut d = phi - exit_phi(p, gamma_o, gamma_t);
    d = (d + PI).rem_euclid(2.0 * PI) - PI;
    trimmed_logistic(d, s)
}

fn logistic(x: f32, s: f32) -> f32 {
    let e = libm::expf(-x.abs() / s);
    e / (s * (1.0 + e) * (1.0 + e))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + libm::expf(-x / s))
}

fn trimmed_logistic(x: f32, s: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(PI, s) - logistic_cdf(-PI, s))
}

/// Inverts the trimmed logistic's CDF.
fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    let (a, b) = (logistic_cdf(-PI, s), logistic_cdf(PI, s));
    let k = b - a;
    let x = -s * libm::logf(1.0 / (u * k + a) - 1.0);
    x.clamp(-PI, PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::uniform_sphere;

    /// The base-2 radical inverse of `i`.
    fn van_der_corput(i: u32) -> f32 {
        (i.reverse_bits() >> 8) as f32 / (1u32 << 24) as f32
    }

    fn sphere_points(n: u32, seed: u32) -> impl Iterator<Item = Vec3A> {
        (0..n).map(move |i| {
            let u = Vec2::new(van_der_corput(i ^ seed), (i as f32 + 0.5) / n as f32);
            uniform_sphere(u)
        })
    }

    /// A fibre that absorbs nothing conserves energy: for any outgoing direction, f · |cos|
    /// integrates to 1 over the sphere (the white furnace), whatever its roughness.
    #[test]
    fn a_clear_fibre_reflects_everything_it_receives() {
        for (k, (bm, bn)) in [(0.2, 0.2), (0.3, 0.3), (0.5, 0.7), (0.9, 0.9), (0.15, 0.6)]
            .into_iter()
            .enumerate()
        {
            let wo = uniform_sphere(Vec2::new(0.37 + 0.1 * k as f32, 0.61));
            let h = -0.8 + 0.4 * k as f32;
            let hair = HairBxdf::new(h, 1.55, Color::ZERO, bm, bn, 0.0);
            let n = 400_000;
            let sum: f64 = sphere_points(n, k as u32 * 7919)
                .map(|wi| f64::from(hair.f(wo, wi).y * wi.z.abs()) * 4.0 * f64::from(PI))
                .sum();
            let e = sum / f64::from(n);
            assert!((e - 1.0).abs() < 0.05, "beta_m {bm}, beta_n {bn}: {e}");
        }
    }

    /// Sampling draws directions with the density `pdf` reports, and f / pdf of the samples
    /// estimates the same white furnace: 1.
    #[test]
    fn sampling_matches_its_density() {
        for (k, (bm, bn, alpha)) in [(0.3, 0.3, 2.0), (0.2, 0.5, 0.0), (0.7, 0.2, 5.0)]
            .into_iter()
            .enumerate()
        {
            let wo = uniform_sphere(Vec2::new(0.21 + 0.2 * k as f32, 0.33));
            let hair = HairBxdf::new(0.3 - 0.2 * k as f32, 1.55, Color::ZERO, bm, bn, alpha);
            let n = 100_000u32;
            let mut sum = 0.0f64;
            for i in 0..n {
                let u = Vec2::new(van_der_corput(i), (i as f32 + 0.5) / n as f32);
                let uc = ((i as f32 * 0.618_034) % 1.0).min(0.999_999);
                let Some(s) = hair.sample(wo, uc, u) else {
                    continue;
                };
                let pdf = hair.pdf(wo, s.wi);
                assert!(
                    (pdf - s.pdf).abs() <= 1e-3 * pdf.max(1e-3),
                    "pdf {pdf} vs sampled {}",
                    s.pdf
                );
                sum += f64::from(s.f.y * s.wi.z.abs() / s.pdf);
            }
            let e = sum / f64::from(n);
            assert!((e - 1.0).abs() < 0.02, "case {k}: {e}");
        }
    }

    /// Melanin darkens: a fibre with eumelanin reflects less than a clear one, and more in
    /// red than in blue.
    #[test]
    fn melanin_absorbs_blue_most() {
        let sigma = HairBxdf::sigma_a_from_melanin(1.3, 0.0);
        let hair = HairBxdf::new(0.1, 1.55, sigma, 0.3, 0.3, 2.0);
        let wo = uniform_sphere(Vec2::new(0.4, 0.2));
        let n = 100_000;
        let mut sum = Color::ZERO;
        for wi in sphere_points(n, 3) {
            sum += hair.f(wo, wi) * (wi.z.abs() * 4.0 * PI / n as f32);
        }
        assert!(sum.x < 0.9 && sum.x > sum.y && sum.y > sum.z, "{sum}");
        // The reflectance inversion gives back a colour's order.
        let s = HairBxdf::sigma_a_from_reflectance(crate::math::rgb3(0.8, 0.5, 0.2), 0.3);
        assert!(s.x < s.y && s.y < s.z);
    }
}
