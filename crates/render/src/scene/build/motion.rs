//! Moving groups (motion blur): shapes built in their group's own space into a geometry of
//! their own, moved over the shutter and then placed (in the world, or inside an object
//! instance that may move too).

use super::{BuildError, Builder, WORLD_LIMIT_TEXT, finish_primitives, within_world_limit};
use crate::motion::AnimatedTransform;
use crate::shapes::Geometry;
use crate::shapes::mover::{Mover, Outer};
use glam::DMat4;
use kiln_scene::ShapeDesc;

/// Where a moving group goes after its own motion.
#[derive(Clone, Copy)]
pub(super) enum Place {
    /// Its motion is in world space.
    World,
    /// Inside an instance placed by a still transform.
    Still(DMat4),
    /// Inside an instance moving from the first transform to the second.
    Moving(DMat4, DMat4),
}

impl Builder {
    /// Shapes that move over the shutter: each placed by `to_object` (its place in the
    /// group), all built in the group's own space and moved together from `start` to `end`.
    pub(super) fn add_mover(
        &mut self,
        shapes: &[(&ShapeDesc, DMat4)],
        start: DMat4,
        end: DMat4,
        times: [f64; 2],
        loc: &kiln_scene::Loc,
    ) -> Result<(), BuildError> {
        self.add_placed_mover(shapes, start, end, Place::World, times, loc)
    }

    /// As [`Self::add_mover`], the group then placed by `place` (a shape moving inside an
    /// object instance, which may move too).
    pub(super) fn add_placed_mover(
        &mut self,
        shapes: &[(&ShapeDesc, DMat4)],
        start: DMat4,
        end: DMat4,
        place: Place,
        times: [f64; 2],
        loc: &kiln_scene::Loc,
    ) -> Result<(), BuildError> {
        let refuse = |loc: &kiln_scene::Loc, message: &str| {
            Err(BuildError::Unsupported {
                loc: loc.clone(),
                message: message.into(),
            })
        };
        for (shape, _) in shapes {
            if shape.area_light.is_some() {
                return refuse(
                    &shape.loc,
                    "a moving area light is not supported (pbrt-v4 refuses animated area lights too; motion blur covers surfaces that do not emit)",
                );
            }
        }
        let (d0, d1) = (start.determinant(), end.determinant());
        let (d2, d3) = match place {
            Place::World => (1.0, 1.0),
            Place::Still(m) => (m.determinant(), 1.0),
            Place::Moving(a, b) => (a.determinant(), b.determinant()),
        };
        if !(d0 > 0.0 && d1 > 0.0 && d2 > 0.0 && d3 > 0.0 && start.is_finite() && end.is_finite()) {
            return refuse(
                loc,
                "a moving transform must be invertible and keep its handedness throughout (a mirrored or degenerate one is not supported)",
            );
        }
        let outer = std::mem::take(&mut self.prims);
        let built = shapes
            .iter()
            .try_for_each(|(shape, to_group)| self.add_shape(shape, *to_group));
        let inner = std::mem::replace(&mut self.prims, outer);
        built?;
        let inner = finish_primitives(inner);
        if inner.triangle_vertices.is_empty()
            && inner.spheres.is_empty()
            && inner.quadrics.is_empty()
            && inner.curve_pieces.is_empty()
        {
            return Ok(());
        }
        let motion = AnimatedTransform::new(start, end, times);
        let outer = match place {
            Place::World => Outer::None,
            Place::Still(m) => {
                let m = glam::Affine3A::from_mat4(m.as_mat4());
                Outer::Still(m, m.inverse())
            }
            Place::Moving(a, b) => Outer::Moving(AnimatedTransform::new(a, b, times)),
        };
        let mover = Mover::placed(Geometry::new(inner), motion, outer);
        let (lo, hi) = mover.bounds();
        if !within_world_limit(lo) || !within_world_limit(hi) {
            return Err(BuildError::Unsupported {
                loc: loc.clone(),
                message: format!(
                    "this moving shape sweeps {lo} to {hi} in world space: {WORLD_LIMIT_TEXT}"
                ),
            });
        }
        self.prims.movers.push(mover);
        Ok(())
    }
}
