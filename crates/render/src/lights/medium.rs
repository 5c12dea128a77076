//! An emissive grid medium as a light (seed 001): points are sampled by the medium's 3D
//! emission distribution, and a path that meets the emission at a tentative collision
//! weighs it against that density.

use super::{LightContext, LightSample};
use crate::math::Color;
use crate::media::Medium;
use crate::sampling::TrackingRng;
use glam::{Vec2, Vec3A};

#[derive(Debug, Clone)]
pub struct MediumLight {
    /// Index into the scene's media.
    pub medium: u32,
    /// Emitted luminance times 4 pi.
    pub power: f32,
}

impl MediumLight {
    pub fn sample(&self, ctx: &LightContext, p: Vec3A, u: Vec2) -> Option<LightSample> {
        let Medium::Grid(g) = &ctx.media[self.medium as usize] else {
            return None;
        };
        // Three numbers pick the voxel: two from the sampler, one (and the point within the
        // voxel) from a generator seeded by them.
        let mut rng = TrackingRng::from_values(&[u.x, u.y], 1);
        let (q, pdf_volume) = g.sample_emission([u.x, u.y, rng.next_f32()], &mut rng)?;
        let d = q - p;
        let dist2 = d.length_squared();
        let source = g.source_at(g.to_box(q), ctx.waves);
        if dist2 == 0.0 || source == Color::ZERO {
            return None;
        }
        let distance = dist2.sqrt();
        let wi = d / distance;
        // The other strategy finds this point at a tentative collision, at the majorant's
        // rate; and the point emits only where the medium fills it, that is if the shadow
        // ray arrives in this medium (the grid's box may reach beyond its boundary).
        let rate = g.majorant_at(g.to_box(p + wi * distance));
        // Per unit volume to per unit solid angle and length: dV = r^2 dw dt.
        Some(LightSample {
            radiance: source,
            wi,
            pdf: pdf_volume * dist2,
            distance,
            n: Vec3A::ZERO,
            delta: false,
            medium: Some(self.medium),
            scatter_rate: rate,
        })
    }

    /// A photon leaving a point drawn by the emission distribution in a uniform direction:
    /// flux = source * 4 pi / (density of the point).
    pub fn emit(&self, ctx: &LightContext, u: [Vec2; 2], uc: f32) -> Option<super::EmittedRay> {
        let Medium::Grid(g) = &ctx.media[self.medium as usize] else {
            return None;
        };
        let mut rng = TrackingRng::from_values(&[u[0].x, u[0].y, uc], 2);
        let (q, pdf_volume) = g.sample_emission([u[0].x, u[0].y, uc], &mut rng)?;
        let source = g.source_at(g.to_box(q), ctx.waves);
        (pdf_volume > 0.0 && source != Color::ZERO).then(|| super::EmittedRay {
            origin: q,
            dir: crate::sampling::uniform_sphere(u[1]),
            n: Vec3A::ZERO,
            flux: source * (4.0 * std::f32::consts::PI / pdf_volume),
        })
    }

    /// The density, per unit solid angle and length, with which choosing this light with
    /// probability `pmf` and sampling it from `p` gives the point `q`.
    pub fn pdf(&self, ctx: &LightContext, pmf: f32, p: Vec3A, q: Vec3A) -> f32 {
        let Medium::Grid(g) = &ctx.media[self.medium as usize] else {
            return 0.0;
        };
        pmf * g.emission_pdf(q) * (q - p).length_squared()
    }
}
