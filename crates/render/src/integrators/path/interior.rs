//! The VolumeLight interior a path is in: which, and whether the current segment's emission
//! is still to be counted (it is not on the first segment after entering: the entry hit
//! already counted it as the light's surface emission).

use super::PathState;
use crate::math::Ray;
use crate::scene::Scene;
use crate::shapes::SurfaceHit;
use crate::spectral::Wavelengths;
use glam::Vec3A;

/// The VolumeLight whose interior the path is in, and whether its current segment emits.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Interior {
    inside: Option<(u32, bool)>,
}

impl Interior {
    /// The path scattered (in a medium, or off something inside the shape): its next
    /// segment inside emits.
    pub fn scattered(&mut self) {
        if let Some((volume, _)) = self.inside {
            self.inside = Some((volume, true));
        }
    }

    /// The path left a surface along `wi`: a VolumeLight's own surface (`volume`, normal
    /// `ng`) it enters (its emission was counted as the surface's, so the first segment
    /// does not count it again), reflects inside, or leaves; any other surface is
    /// something inside the shape, if the path is inside one.
    pub fn crossed(&mut self, volume: Option<u32>, ng: Vec3A, wi: Vec3A) {
        let Some(volume) = volume else {
            self.scattered();
            return;
        };
        self.inside = if wi.dot(ng) < 0.0 {
            // Entering (not counted again) or reflecting inside (counted).
            let entering = self.inside.is_none();
            Some((volume, !entering))
        } else {
            None
        };
    }
}

impl PathState {
    /// Inside a VolumeLight: the interior's emission along the segment to `found` (unless
    /// the entry hit counted it) and its absorption.
    pub(super) fn interior_segment(
        &mut self,
        scene: &Scene,
        ray: &Ray,
        found: Option<&SurfaceHit>,
        waves: Option<&Wavelengths>,
    ) {
        let Some((volume, count)) = self.interior.inside else {
            return;
        };
        let interior = &scene.volumes[volume as usize];
        let t = found.map_or(0.0, |h| h.t);
        if count {
            self.l += self.beta * interior.segment(ray.origin, ray.dir, t, waves);
        }
        self.beta *= interior.transmittance(t, waves);
        if found.is_none() {
            // Only rounding lets a ray out of a closed shape without a hit.
            self.interior.inside = None;
        }
    }
}
