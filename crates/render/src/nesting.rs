//! Nested dielectrics by priority (a Kiln extension; pbrt-v4 and Mitsuba 3 have none): a
//! liquid in a glass shares one boundary with it, without relative indices written by hand.
//!
//! Each dielectric (or interface) shape declared with `"integer priority" p`, p ≥ 1, is a
//! nested shape. A ray carries the set of nested shapes it is inside ([`Nesting`]); the one
//! with the highest priority (the latest entered among equals) is the stuff the ray travels
//! through. Where shapes overlap, the boundary of the lower-priority one is not there: a
//! ray crosses it unbent, only noting that it is now inside (or outside) that shape too. At
//! a true boundary the relative index is the shape's own eta over the eta of what lies on
//! its outer side: the highest-priority other shape the ray is (or will be) inside, or
//! vacuum (eta 1). A liquid is therefore modelled as a volume that reaches a little into
//! the glass wall, with a lower priority than the glass; the glass's inner wall becomes the
//! glass-liquid boundary (eta 1.5 / 1.33) and the liquid's surface the liquid-air one.
//!
//! The medium inside a nested shape is its MediumInterface's inside (vacuum without one);
//! outside every nested shape the ray is back in the medium it had before it entered the
//! first. Shapes without a priority behave exactly as pbrt-v4's: a scene with none renders
//! as before, bit for bit. Shadow rays are unaware of nesting: dielectric surfaces block
//! them, nested or not, as they always do.

use crate::shapes::SurfaceHit;
use glam::Vec3A;

/// The most nested shapes a ray can be inside at once; a ray that would enter more ends.
pub const MAX_NESTING: usize = 8;

/// A nested shape: its priority, its index of refraction and its interior medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NestedShape {
    /// Higher wins where shapes overlap; at least 1.
    pub priority: u32,
    /// The shape's own index (its dielectric's eta; 1 for an interface).
    pub eta: f32,
    /// The medium inside (None: vacuum).
    pub medium: Option<u32>,
}

/// How a ray meets the surface of a nested shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crossing {
    /// A boundary hidden by a higher-priority shape, or one between equal indices: the
    /// ray goes straight on.
    Through,
    /// A true boundary: the relative index, inside over outside as the normal sees them.
    Interface { eta: f32 },
}

/// The nested shapes a ray is inside, and the medium outside them all.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Nesting {
    inside: [u32; MAX_NESTING],
    len: u8,
    /// The medium the ray was in before it entered its first nested shape.
    base: Option<u32>,
}

impl Nesting {
    fn entries(&self) -> &[u32] {
        &self.inside[..self.len as usize]
    }

    /// The shape that decides what the ray travels through, ignoring `except`.
    fn top(&self, shapes: &[NestedShape], except: u32) -> Option<NestedShape> {
        let mut best: Option<NestedShape> = None;
        for &id in self.entries() {
            if id == except {
                continue;
            }
            let s = shapes[id as usize];
            if best.is_none_or(|b| s.priority >= b.priority) {
                best = Some(s);
            }
        }
        best
    }

    /// How a ray travelling along `dir` meets `hit` on nested shape `id`.
    pub fn crossing(
        &self,
        shapes: &[NestedShape],
        id: u32,
        hit: &SurfaceHit,
        dir: Vec3A,
    ) -> Crossing {
        let shape = shapes[id as usize];
        // Entering or leaving, what lies on the shape's outer side is the strongest other
        // shape the ray is inside.
        let outside = self.top(shapes, id);
        let entering = dir.dot(hit.ng) < 0.0;
        let hidden = outside.is_some_and(|o| o.priority > shape.priority)
            && (entering || self.entries().contains(&id));
        if hidden {
            return Crossing::Through;
        }
        let eta = shape.eta / outside.map_or(1.0, |o| o.eta);
        if eta == 1.0 {
            Crossing::Through
        } else {
            Crossing::Interface { eta }
        }
    }

    /// Notes that a ray that met `hit` along `dir` leaves it along `wi`: if it crossed a
    /// nested shape's surface it is now inside (or outside) that shape, and `medium`
    /// becomes what it travels through. On other surfaces the medium follows the surface's
    /// MediumInterface, as in pbrt-v4. False when the ray would be inside more than
    /// [`MAX_NESTING`] shapes (it should end).
    #[must_use]
    #[inline]
    pub fn cross(
        &mut self,
        shapes: &[NestedShape],
        hit: &SurfaceHit,
        dir: Vec3A,
        wi: Vec3A,
        medium: &mut Option<u32>,
    ) -> bool {
        match hit.surface.nest {
            None => {
                if let Some(next) = hit.surface.medium_towards(wi, hit.ng) {
                    *medium = next;
                }
                true
            }
            Some(id) => self.cross_nested(shapes, id, hit, dir, wi, medium),
        }
    }

    /// [`Nesting::cross`] on nested shape `id`'s surface.
    #[inline(never)]
    fn cross_nested(
        &mut self,
        shapes: &[NestedShape],
        id: u32,
        hit: &SurfaceHit,
        dir: Vec3A,
        wi: Vec3A,
        medium: &mut Option<u32>,
    ) -> bool {
        let (came, goes) = (dir.dot(hit.ng), wi.dot(hit.ng));
        if (came < 0.0) != (goes < 0.0) {
            // Reflected: still where it was.
            return true;
        }
        let at = self.entries().iter().position(|&e| e == id);
        if goes < 0.0 {
            // Entering (once: a ray already inside, by rounding, stays inside once).
            if at.is_none() {
                if self.len as usize == MAX_NESTING {
                    return false;
                }
                if self.len == 0 {
                    self.base = *medium;
                }
                self.inside[self.len as usize] = id;
                self.len += 1;
            }
        } else if let Some(at) = at {
            self.inside.copy_within(at + 1..self.len as usize, at);
            self.len -= 1;
        }
        *medium = match self.top(shapes, u32::MAX) {
            Some(s) => s.medium,
            None => self.base,
        };
        true
    }
}
