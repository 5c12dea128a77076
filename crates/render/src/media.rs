//! Participating media and phase functions.

use crate::math::{Color, Frame};
use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// A medium: what fills the space between surfaces.
#[derive(Debug, Clone)]
pub enum Medium {
    /// Constant absorption and scattering per unit length, emission `le` (pbrt-v4's convention:
    /// the source term is sigma_a * le), Henyey-Greenstein phase function with asymmetry `g`.
    Homogeneous {
        sigma_a: Color,
        sigma_s: Color,
        le: Color,
        g: f32,
    },
}

impl Medium {
    pub fn sigma_t(&self) -> Color {
        match self {
            Medium::Homogeneous {
                sigma_a, sigma_s, ..
            } => *sigma_a + *sigma_s,
        }
    }

    /// Transmittance along a straight segment of length `t`.
    pub fn transmittance(&self, t: f32) -> Color {
        if !t.is_finite() {
            return Color::select(self.sigma_t().cmpgt(Color::ZERO), Color::ZERO, Color::ONE);
        }
        (-self.sigma_t() * t).exp()
    }

    /// The emission a segment of length `t` sends back to its start: the integral of
    /// T(s) sigma_a le ds, in closed form for a homogeneous medium.
    pub fn segment_emission(&self, t: f32) -> Color {
        match self {
            Medium::Homogeneous { sigma_a, le, .. } => {
                if *le == Color::ZERO || *sigma_a == Color::ZERO {
                    return Color::ZERO;
                }
                let st = self.sigma_t();
                let mut out = Color::ZERO;
                for c in 0..3 {
                    out[c] = if st[c] > 0.0 {
                        // (1 - exp(-st t)) / st, written to stay accurate for small st t.
                        let x = st[c] * t.min(1e30);
                        sigma_a[c] * le[c] * (-(-x).exp_m1()) / st[c]
                    } else {
                        0.0
                    };
                }
                out
            }
        }
    }

    pub fn phase(&self) -> HenyeyGreenstein {
        match self {
            Medium::Homogeneous { g, .. } => HenyeyGreenstein { g: *g },
        }
    }
}

/// The Henyey-Greenstein phase function; `wo` and `wi` both point away from the scattering point.
#[derive(Debug, Clone, Copy)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

impl HenyeyGreenstein {
    /// Density over `wi` given `wo` (it is its own pdf when sampled exactly).
    pub fn p(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        hg(wo.dot(wi), self.g)
    }

    /// Samples `wi`; returns it with its pdf (equal to the phase value).
    pub fn sample(&self, wo: Vec3A, u: Vec2) -> (Vec3A, f32) {
        let g = self.g;
        // The cosine between wi and wo, inverted from HG's CDF (pbrt-v4's SampleHenyeyGreenstein).
        let cos_theta = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let sq = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
            -(1.0 + g * g - sq * sq) / (2.0 * g)
        };
        let cos_theta = cos_theta.clamp(-1.0, 1.0);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let frame = Frame::from_z(wo);
        let wi = frame.to_world(Vec3A::new(
            sin_theta * phi.cos(),
            sin_theta * phi.sin(),
            cos_theta,
        ));
        let pdf = self.p(wo, wi);
        (wi, pdf)
    }
}

/// HG with `cos` the cosine between wo and wi (pbrt's convention: g > 0 scatters forward,
/// where wi = -wo, that is cos = -1).
fn hg(cos: f32, g: f32) -> f32 {
    let c = -cos;
    let denom = 1.0 + g * g - 2.0 * g * c;
    (1.0 - g * g) / (4.0 * PI * denom * denom.max(1e-12).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::PixelSampler;

    #[test]
    fn hg_integrates_to_one_and_samples_its_density() {
        for g in [-0.7f32, 0.0, 0.3, 0.9] {
            let phase = HenyeyGreenstein { g };
            let wo = Vec3A::new(0.3, -0.4, 0.866).normalize();
            let n = 1 << 14;
            let (mut integral, mut mean_cos) = (0.0f64, 0.0f64);
            for i in 0..n {
                let s = PixelSampler::new(1, 2, i, 3);
                let wi = crate::sampling::uniform_sphere(Vec2::new(s.value(0), s.value(1)));
                integral += phase.p(wo, wi) as f64 * 4.0 * std::f64::consts::PI / n as f64;
                let (ws, pdf) = phase.sample(wo, Vec2::new(s.value(2), s.value(3)));
                assert!((pdf - phase.p(wo, ws)).abs() < 1e-4 * pdf.max(1.0));
                mean_cos += ws.dot(-wo) as f64 / n as f64;
            }
            assert!((integral - 1.0).abs() < 0.02, "g {g}: {integral}");
            // HG's mean cosine (in the direction of travel) is g.
            assert!(
                (mean_cos - g as f64).abs() < 0.01,
                "g {g}: mean cosine {mean_cos}"
            );
        }
    }

    #[test]
    fn homogeneous_segment_emission_is_exact() {
        let m = Medium::Homogeneous {
            sigma_a: Color::splat(2.0),
            sigma_s: Color::ZERO,
            le: Color::splat(3.0),
            g: 0.0,
        };
        let e = m.segment_emission(0.5);
        assert!((e.x - 3.0 * (1.0 - (-1.0f32).exp())).abs() < 1e-6);
        assert!((m.transmittance(0.5).x - (-1.0f32).exp()).abs() < 1e-6);
    }
}
