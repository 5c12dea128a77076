//! The interior of a "subsurface" material: a homogeneous medium that paths cross by random
//! walk inside the shape (a volumetric path behind the material's dielectric surface).
//!
//! The interior is given by its coefficients, or by the reflectance its walk should reach
//! and a mean free path. A textured reflectance makes the interior vary over the surface: as
//! production random-walk renderers do, a walk takes its coefficients from the texture where
//! it entered the shape ([`TexturedInterior::at`]) and keeps them until it leaves.

use super::{HomogeneousMedium, Medium, Phase};
use crate::math::{Color, rgb};
use crate::textures::{SpectrumTexture, TextureEvalContext, Textures};
use kiln_scene::{PhaseDesc, RgbValue, SubsurfaceInterior};

/// The medium inside a subsurface material (for a textured reflectance, the texture's value
/// where no entry point is known: its value at the origin of its coordinates), and the
/// texture a walk's coefficients come from, if any.
pub fn subsurface_medium(
    g: f32,
    interior: SubsurfaceInterior,
    textures: &Textures,
) -> (Medium, Option<TexturedInterior>) {
    let phase = Phase::new(PhaseDesc::HenyeyGreenstein { g });
    match interior {
        SubsurfaceInterior::Coefficients { sigma_a, sigma_s } => (
            Medium::Homogeneous(HomogeneousMedium {
                sigma_a: rgb(sigma_a),
                sigma_s: rgb(sigma_s),
                le: Color::ZERO,
                le_spectrum: None,
                phase,
            }),
            None,
        ),
        SubsurfaceInterior::Reflectance { reflectance, mfp } => match reflectance {
            RgbValue::Constant(c) => (reflectance_medium(rgb(c), rgb(mfp), phase), None),
            RgbValue::Texture(_) => {
                let textured = TexturedInterior {
                    reflectance: textures.rgb_value(&reflectance),
                    mfp: rgb(mfp),
                    phase,
                };
                (textured.at(&TextureEvalContext::default()), Some(textured))
            }
        },
    }
}

/// A subsurface interior whose reflectance is a texture.
#[derive(Debug, Clone)]
pub struct TexturedInterior {
    reflectance: SpectrumTexture,
    mfp: Color,
    phase: Phase,
}

impl TexturedInterior {
    /// The interior a walk that entered at `ctx` crosses.
    pub fn at(&self, ctx: &TextureEvalContext) -> Medium {
        let a = self.reflectance.evaluate(ctx);
        reflectance_medium(a, self.mfp, self.phase)
    }
}

/// The subsurface walk a path (or photon) is on: the coefficients it took from a textured
/// reflectance where it entered (scene medium `m`'s stand-in while the path is in `m`), and
/// the events it has taken, which count towards the integrator's `walk_depth` instead of
/// maxdepth. `Scene::enter_walk` keeps both up to date at every crossing.
#[derive(Debug, Clone, Default)]
pub struct Walk {
    /// Boxed: a path carries its walk through every stage of a wave, and a medium is large.
    entered: Option<Box<(u32, Medium)>>,
    events: u32,
}

impl Walk {
    /// Medium `m` as the path sees it: the walk's own coefficients if they were taken for
    /// `m`, else the scene's.
    #[inline]
    pub fn medium<'a>(&'a self, media: &'a [Medium], m: u32) -> &'a Medium {
        match self.entered.as_deref() {
            Some((w, medium)) if *w == m => medium,
            _ => &media[m as usize],
        }
    }

    /// The walk entered medium `m`, whose coefficients are `medium` there (None: the
    /// scene's own).
    pub fn set(&mut self, m: u32, medium: Option<Medium>) {
        self.entered = medium.map(|medium| Box::new((m, medium)));
    }

    /// The path left every subsurface interior: a later walk starts its count afresh.
    pub fn left(&mut self) {
        self.events = 0;
    }

    /// Counts one more event of the walk; false once it has taken `limit` (it should end).
    #[inline]
    pub fn take_event(&mut self, limit: u32) -> bool {
        if self.events == limit {
            return false;
        }
        self.events += 1;
        true
    }
}

/// The homogeneous medium whose random walk reflects `reflectance` (the multiple-scattering
/// albedo of a semi-infinite, index-matched slab) with mean free path `mfp`.
fn reflectance_medium(reflectance: Color, mfp: Color, phase: Phase) -> Medium {
    let mut sigma_a = Color::ZERO;
    let mut sigma_s = Color::ZERO;
    for c in 0..3 {
        let albedo = single_scattering_albedo(reflectance[c]);
        let sigma_t = 1.0 / mfp[c];
        sigma_s[c] = albedo * sigma_t;
        sigma_a[c] = (1.0 - albedo) * sigma_t;
    }
    Medium::Homogeneous(HomogeneousMedium {
        sigma_a,
        sigma_s,
        le: Color::ZERO,
        le_spectrum: None,
        phase,
    })
}

/// The single-scattering albedo whose random walk in a semi-infinite slab reflects the
/// multiple-scattering albedo `a`: the fit of Chiang, Kutz and Burley (2016), "Practical and
/// Controllable Subsurface Scattering for Production Path Tracing":
/// α = 1 − (4.09712 + 4.20863 A − √(9.59217 + 41.6808 A + 17.7126 A²))².
pub fn single_scattering_albedo(a: f32) -> f32 {
    let a = f64::from(if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) });
    let k = 4.09712 + 4.20863 * a - (9.59217 + 41.6808 * a + 17.7126 * a * a).sqrt();
    (1.0 - k * k).clamp(0.0, 1.0) as f32
}

#[cfg(test)]
mod tests {
    use super::single_scattering_albedo;

    /// The white-sky albedo (total diffuse reflectance under uniform light) of a
    /// semi-infinite, index-matched, isotropically scattering medium of single-scattering
    /// albedo `w`: 1 − 2 √(1 − w) ∫₀¹ μ H(μ) dμ, with Chandrasekhar's H-function iterated on a
    /// midpoint grid.
    fn white_sky_albedo(w: f64) -> f64 {
        let n = 1000;
        let grid: Vec<f64> = (0..n).map(|i| (i as f64 + 0.5) / n as f64).collect();
        let root = (1.0 - w).sqrt();
        let mut h = vec![1.0; n];
        for _ in 0..200 {
            h = grid
                .iter()
                .map(|&m| {
                    let integral: f64 = grid
                        .iter()
                        .zip(&h)
                        .map(|(mp, hp)| mp * hp / (m + mp))
                        .sum::<f64>()
                        / n as f64;
                    1.0 / (root + w / 2.0 * integral)
                })
                .collect();
        }
        1.0 - 2.0 * root * grid.iter().zip(&h).map(|(m, hm)| m * hm).sum::<f64>() / n as f64
    }

    /// The subsurface material's reflectance parametrisation: the single-scattering albedo
    /// it picks for a wanted reflectance A gives a walk whose exact white-sky albedo is A
    /// (within 0.005: the fit's own accuracy).
    #[test]
    fn reflectance_inverts_to_the_albedo_that_reflects_it() {
        for a in [0.05f32, 0.2, 0.4, 0.6, 0.8, 0.95] {
            let w = f64::from(single_scattering_albedo(a));
            let got = white_sky_albedo(w);
            assert!(
                (got - f64::from(a)).abs() < 0.005,
                "A {a}: alpha {w} reflects {got}"
            );
        }
        assert!(single_scattering_albedo(0.0) < 1e-4);
        assert!(single_scattering_albedo(1.0) > 0.9999);
        assert!(single_scattering_albedo(f32::NAN) < 1e-4);
    }
}
