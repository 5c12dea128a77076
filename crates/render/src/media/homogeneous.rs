//! A homogeneous medium: constant absorption, scattering and emission per unit length.

use super::{MediumEvent, Phase};
use crate::math::Color;
use crate::sampling::TrackingRng;
use crate::spectral::{LightSpectrum, Wavelengths};
use std::sync::Arc;

/// Constant absorption and scattering per unit length, emission `le` (pbrt-v4's convention:
/// the source term is sigma_a * le).
#[derive(Debug, Clone)]
pub struct HomogeneousMedium {
    pub sigma_a: Color,
    pub sigma_s: Color,
    pub le: Color,
    /// For a spectral render, the spectrum of `le` where the scene gave it one.
    pub le_spectrum: Option<Arc<LightSpectrum>>,
    pub phase: Phase,
}

impl HomogeneousMedium {
    /// The medium as a spectral path at `waves` sees it: its coefficients unbounded spectra,
    /// its emission light's.
    pub fn at_wavelengths(&self, waves: &Wavelengths) -> HomogeneousMedium {
        HomogeneousMedium {
            sigma_a: waves.unbounded(self.sigma_a),
            sigma_s: waves.unbounded(self.sigma_s),
            le: match &self.le_spectrum {
                _ if self.le == Color::ZERO => Color::ZERO,
                Some(s) => s.at(waves, self.le),
                None => waves.illuminant(self.le),
            },
            le_spectrum: None,
            phase: self.phase,
        }
    }

    pub fn sigma_t(&self) -> Color {
        self.sigma_a + self.sigma_s
    }

    /// Transmittance along a straight segment of length `t`.
    pub fn transmittance(&self, t: f32) -> Color {
        if !t.is_finite() {
            return Color::select(self.sigma_t().cmpgt(Color::ZERO), Color::ZERO, Color::ONE);
        }
        (-self.sigma_t() * t).exp()
    }

    /// The emission a segment of length `t` sends back to its start: the integral of
    /// T(s) sigma_a le ds, in closed form.
    pub fn segment_emission(&self, t: f32) -> Color {
        let (sigma_a, le) = (&self.sigma_a, &self.le);
        if *le == Color::ZERO || *sigma_a == Color::ZERO {
            return Color::ZERO;
        }
        let st = self.sigma_t();
        let mut out = Color::ZERO;
        // Every lane: an RGB colour's fourth repeats its second, a spectral path's is its own.
        for c in 0..4 {
            out[c] = if st[c] > 0.0 {
                // (1 - exp(-st t)) / st, written to stay accurate for small st t.
                let x = st[c] * t.min(1e30);
                sigma_a[c] * le[c] * (-libm::expm1f(-x)) / st[c]
            } else {
                0.0
            };
        }
        out
    }

    /// Free-flight sampling over (0, `t_max`), updating the throughput `beta`: in RGB over
    /// the three channels at each event ([`track`]), for a spectral path by its hero
    /// wavelength with the path's `lane_pdfs` ([`track_hero`]).
    pub fn sample_interaction(
        &self,
        t_max: f32,
        rng: &mut TrackingRng,
        beta: &mut Color,
        lane_pdfs: Option<&mut Color>,
    ) -> MediumEvent {
        match lane_pdfs {
            None => track(self.sigma_t(), self.sigma_s, t_max, rng, beta, 3),
            Some(r) => track_hero(self.sigma_t(), self.sigma_s, t_max, rng, beta, r),
        }
    }
}

/// Free-flight sampling for a spectral path, as pbrt-v4 does it (hero wavelength spectral
/// sampling, Wilkie et al. 2014): the distance by the hero's extinction (lane 0), the
/// weight by the balance heuristic over the whole path's four ways of being sampled (each
/// lane as the hero). `lane_pdfs` holds each lane's density of the path so far relative to
/// the others, normalised to a mean of 1 (pbrt-v4's r_u); one event's densities multiply
/// it, and the throughput is divided by their weighted mean. Weighing each event alone
/// (as [`track`] does, and this did before) is unbiased too, but over a long subsurface
/// walk of chromatic coefficients its weights multiply into a heavy tail.
fn track_hero(
    sigma_t: Color,
    sigma_s: Color,
    t_max: f32,
    rng: &mut TrackingRng,
    beta: &mut Color,
    lane_pdfs: &mut Color,
) -> MediumEvent {
    if sigma_t.max_element() <= 0.0 {
        return MediumEvent::Crossed;
    }
    let st = sigma_t.x;
    let t = if st > 0.0 {
        -libm::logf(1.0 - rng.next_f32()) / st
    } else {
        f32::INFINITY
    };
    // Each lane's density of what happened (a collision at t, or none before t_max), and
    // the weight that goes with it.
    let (f, p, event) = if t < t_max {
        let tr = (-sigma_t * t).exp();
        (sigma_s * tr, sigma_t * tr, MediumEvent::Scattered(t))
    } else {
        if !t_max.is_finite() {
            return MediumEvent::Absorbed;
        }
        let tr = (-sigma_t * t_max).exp();
        (tr, tr, MediumEvent::Crossed)
    };
    let weighted = *lane_pdfs * p;
    let density = super::lane_mean(weighted, 4);
    if density.is_nan() || density <= 0.0 {
        return MediumEvent::Absorbed;
    }
    *lane_pdfs = weighted / density;
    *beta *= f / density;
    if *beta == Color::ZERO {
        return MediumEvent::Absorbed;
    }
    event
}

/// Free-flight sampling in a homogeneous medium: a colour channel (a spectral path's
/// wavelength) is chosen uniformly and the distance sampled by its extinction; the weights
/// divide by the density averaged over channels (the one-sample balance heuristic, as
/// pbrt-v3's homogeneous medium does), so they stay bounded even when the channels'
/// extinctions differ.
fn track(
    sigma_t: Color,
    sigma_s: Color,
    t_max: f32,
    rng: &mut TrackingRng,
    beta: &mut Color,
    lanes: usize,
) -> MediumEvent {
    if sigma_t.max_element() <= 0.0 {
        return MediumEvent::Crossed;
    }
    let channel = ((rng.next_f32() * lanes as f32) as usize).min(lanes - 1);
    let st = sigma_t[channel];
    let t = if st > 0.0 {
        -libm::logf(1.0 - rng.next_f32()) / st
    } else {
        f32::INFINITY
    };
    if t < t_max {
        let tr = (-sigma_t * t).exp();
        let density = super::lane_mean(sigma_t * tr, lanes);
        if density <= 0.0 {
            return MediumEvent::Absorbed;
        }
        *beta *= sigma_s * tr / density;
        if *beta == Color::ZERO {
            return MediumEvent::Absorbed;
        }
        MediumEvent::Scattered(t)
    } else {
        if !t_max.is_finite() {
            return MediumEvent::Absorbed;
        }
        let tr = (-sigma_t * t_max).exp();
        let p_cross = super::lane_mean(tr, lanes);
        if p_cross <= 0.0 {
            return MediumEvent::Absorbed;
        }
        *beta *= tr / p_cross;
        MediumEvent::Crossed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn homogeneous_segment_emission_is_exact() {
        let m = HomogeneousMedium {
            sigma_a: Color::splat(2.0),
            sigma_s: Color::ZERO,
            le: Color::splat(3.0),
            le_spectrum: None,
            phase: Phase::HenyeyGreenstein { g: 0.0 },
        };
        let e = m.segment_emission(0.5);
        assert!((e.x - 3.0 * (1.0 - libm::expf(-1.0f32))).abs() < 1e-6);
        assert!((m.transmittance(0.5).x - libm::expf(-1.0f32)).abs() < 1e-6);
    }
}
