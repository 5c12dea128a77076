//! The photon maps' gathers along a path (seeds 003 and 004): caustic light at diffuse
//! surfaces, light scattered in media, and what the path must then leave out so that no
//! light is counted twice.

use super::PathContext;
use crate::bsdfs::Bsdf;
use crate::math::{Color, Frame};
use crate::media::{Medium, Phase};
use crate::shapes::SurfaceHit;
use glam::Vec3A;

/// What the gathers so far mean for the rest of the path.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Gather {
    /// With caustic photon maps: specular bounces since the last vertex that gathered
    /// photons (None before the first).
    specular_since_gather: Option<u32>,
    /// The path gathered a volume photon map's estimate at its last vertex: its current
    /// segment only collects emission, and it ends at the next scattering.
    pub ending: bool,
}

impl Gather {
    /// Whether the path reached its current segment through one or more specular bounces
    /// from a vertex that gathered caustic photons, which counted the light it would find.
    pub fn after_caustic_gather(&self) -> bool {
        matches!(self.specular_since_gather, Some(k) if k > 0)
    }
}

impl Gather {
    /// At a scattering event of a subsurface walk: the walk ends any caustic chain, as it
    /// does a photon's (photons that walked are stored as no caustic), so light the path
    /// finds from here on is its own to count, gathered or not before.
    pub fn walked(&mut self) {
        self.specular_since_gather = None;
    }

    /// At a scattering in medium `med` at `p` (not inside a subsurface walk, whose random
    /// walk goes on as a path): the light the photons scattered there (if the maps hold any), times the throughput
    /// `beta`. With a volume map the path then ends after its next segment: the map holds
    /// all light scattered here but the direct, which next-event estimation adds with full
    /// weight.
    pub fn in_medium(
        &mut self,
        ctx: &PathContext,
        med: &Medium,
        phase: Phase,
        p: Vec3A,
        wo: Vec3A,
        beta: Color,
    ) -> Option<Color> {
        let maps = ctx.prepass.photons.as_ref()?;
        if !(maps.has_volume_map() || maps.caustics) {
            return None;
        }
        // Light scattered here from the photons; the throughput already holds sigma_s, the
        // estimate divides it out.
        let waves = ctx.waves.as_ref();
        let sigma_s = med.sigma_s_at(p, waves);
        let lv = maps.medium_radiance(p, wo, |a, b| phase.p(a, b), waves);
        let inv = Color::select(
            sigma_s.cmpgt(Color::ZERO),
            Color::ONE / sigma_s,
            Color::ZERO,
        );
        self.specular_since_gather = Some(0);
        // After a volume map's gather, the phase-sampled segment only looks for the light
        // the map leaves out (the direct light, weighed against the light sample as usual).
        self.ending |= maps.has_volume_map();
        Some(beta * lv * inv)
    }

    /// At a surface with caustic maps: a specular bounce is counted, and at any other the
    /// caustic light reflected there (times the throughput `beta`) is gathered from the
    /// surface photon map, for the path arriving along `dir`.
    pub fn at_surface(
        &mut self,
        ctx: &PathContext,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        frame: &Frame,
        dir: Vec3A,
        beta: Color,
    ) -> Option<Color> {
        let maps = ctx.prepass.photons.as_ref().filter(|m| m.caustics)?;
        if bsdf.is_specular() {
            self.specular_since_gather = self.specular_since_gather.map(|k| k + 1);
            return None;
        }
        // Caustic light reflected here, from the surface photon map.
        let side = if dir.dot(hit.ns) < 0.0 {
            hit.ns
        } else {
            -hit.ns
        };
        self.specular_since_gather = Some(0);
        let wo = frame.to_local(-dir);
        let f = |wi| bsdf.f(wo, frame.to_local(wi));
        Some(beta * maps.surface_radiance(hit.p, side, f, ctx.waves.as_ref()))
    }
}
