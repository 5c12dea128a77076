//! Phase functions: how light scatters at a point in a medium (and in the scattering layer
//! of a layered BSDF, which is why they sit below both).

use crate::math::Frame;
use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// A phase function; `wo` and `wi` both point away from the scattering point, and both kinds
/// are sampled exactly (the value over the pdf is 1).
#[derive(Debug, Clone, Copy)]
pub enum Phase {
    HenyeyGreenstein {
        g: f32,
    },
    /// Schlick's rational approximation of Henyey-Greenstein, with k from g (Blasi et al.).
    Schlick {
        k: f32,
    },
}

impl Phase {
    pub fn new(desc: kiln_scene::PhaseDesc) -> Phase {
        match desc {
            kiln_scene::PhaseDesc::HenyeyGreenstein { g } => Phase::HenyeyGreenstein { g },
            kiln_scene::PhaseDesc::Schlick { g } => Phase::Schlick {
                k: (1.55 * g - 0.55 * g * g * g).clamp(-0.999, 0.999),
            },
        }
    }

    /// Density over `wi` given `wo`.
    pub fn p(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        // The cosine between the directions of travel before and after scattering.
        let c = -wo.dot(wi);
        match *self {
            Phase::HenyeyGreenstein { g } => {
                let denom = 1.0 + g * g - 2.0 * g * c;
                (1.0 - g * g) / (4.0 * PI * denom * denom.max(1e-12).sqrt())
            }
            Phase::Schlick { k } => {
                let d = 1.0 - k * c;
                (1.0 - k * k) / (4.0 * PI * d * d)
            }
        }
    }

    /// Samples `wi`; returns it with its pdf.
    pub fn sample(&self, wo: Vec3A, u: Vec2) -> (Vec3A, f32) {
        // The cosine between the directions of travel, inverted from the CDF.
        let c = match *self {
            Phase::HenyeyGreenstein { g } => {
                if g.abs() < 1e-3 {
                    2.0 * u.x - 1.0
                } else {
                    let sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
                    (1.0 + g * g - sq * sq) / (2.0 * g)
                }
            }
            Phase::Schlick { k } => (2.0 * u.x + k - 1.0) / (2.0 * k * u.x + 1.0 - k),
        }
        .clamp(-1.0, 1.0);
        let sin = (1.0 - c * c).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let frame = Frame::from_z(-wo);
        let wi = frame.to_world(Vec3A::new(sin * libm::cosf(phi), sin * libm::sinf(phi), c));
        (wi, self.p(wo, wi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PixelSampler;

    fn check_phase(phase: Phase, g: f32, mean_tolerance: f64) {
        let wo = Vec3A::new(0.3, -0.4, 0.866).normalize();
        let n = 1 << 15;
        let (mut integral, mut mean_cos, mut mean_cos_p) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let s = PixelSampler::new(1, 2, i, 3);
            let wi = crate::sampling::uniform_sphere(Vec2::new(s.value(0), s.value(1)));
            let w = phase.p(wo, wi) as f64 * 4.0 * std::f64::consts::PI / n as f64;
            integral += w;
            mean_cos_p += w * wi.dot(-wo) as f64;
            let (ws, pdf) = phase.sample(wo, Vec2::new(s.value(2), s.value(3)));
            assert!((pdf - phase.p(wo, ws)).abs() < 1e-4 * pdf.max(1.0));
            assert!((ws.length() - 1.0).abs() < 1e-4);
            mean_cos += ws.dot(-wo) as f64 / n as f64;
        }
        assert!(
            (integral - 1.0).abs() < 0.02,
            "{phase:?}: integral {integral}"
        );
        // Sampling follows the density: the same mean cosine (in the direction of travel).
        assert!(
            (mean_cos - mean_cos_p).abs() < 0.01,
            "{phase:?}: sampled mean cosine {mean_cos}, density's {mean_cos_p}"
        );
        assert!(
            (mean_cos - g as f64).abs() < mean_tolerance,
            "{phase:?}: mean cosine {mean_cos}, g {g}"
        );
    }

    #[test]
    fn phase_functions_integrate_to_one_and_sample_their_density() {
        for g in [-0.7f32, 0.0, 0.3, 0.9] {
            // HG's mean cosine is g exactly; Schlick's k(g) = 1.55 g - 0.55 g^3 is a fit
            // that misses it by 0.06 at |g| = 0.7
            check_phase(Phase::HenyeyGreenstein { g }, g, 0.01);
            // (and by 0.07 at g = 0.9, where the fit is poorest).
            check_phase(Phase::new(kiln_scene::PhaseDesc::Schlick { g }), g, 0.075);
        }
    }
}
