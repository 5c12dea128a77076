//! Curves in world space: each cubic Bézier segment split into BVH pieces.

use super::{BuildError, Builder, WORLD_LIMIT_TEXT, within_world_limit};
use crate::shapes::SurfaceInfo;
use crate::shapes::curve::{CurvePiece, CurveSegment};
use glam::{DMat4, Vec3A};
use kiln_scene::ShapeDesc;

/// The most curve pieces (BVH primitives, about 48 bytes each with their segment's share)
/// a scene may hold: 2^26, some 3 GB.
const CURVE_PIECE_LIMIT: u64 = 1 << 26;

impl Builder {
    /// A curve's segments in world space, each split into 2^splitdepth BVH pieces.
    pub(super) fn add_curve(
        &mut self,
        shape: &ShapeDesc,
        curve: &kiln_scene::CurveData,
        to_world: DMat4,
        surface: SurfaceInfo,
    ) -> Result<(), BuildError> {
        let refuse = |message: &str| {
            Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: message.into(),
            })
        };
        if shape.area_light.is_some() {
            return refuse("a curve cannot be an area light (pbrt-v4 cannot sample curves either)");
        }
        if surface.alpha.is_some() {
            return refuse("\"alpha\" on a curve is not supported yet");
        }
        let m = to_world.as_mat4();
        let normal_m = to_world.inverse().transpose().as_mat4();
        // Widths scale with the transform's mean scale (exact for similarity transforms).
        let scale = libm::cbrt(to_world.determinant().abs()) as f32;
        if !(scale > 0.0 && scale.is_finite()) {
            return refuse("this curve's transform cannot be inverted (a zero scale?)");
        }
        let pieces = 1u32 << curve.split_depth;
        let total =
            self.prims.curve_pieces.len() as u64 + curve.segments.len() as u64 * u64::from(pieces);
        if total > CURVE_PIECE_LIMIT {
            return Err(BuildError::Unsupported {
                loc: shape.loc.clone(),
                message: format!(
                    "the scene's curves would make {total} BVH pieces ({} segments here, {pieces} pieces each by \"splitdepth\"); Kiln's limit is {CURVE_PIECE_LIMIT} (a lower splitdepth makes fewer)",
                    curve.segments.len()
                ),
            });
        }
        for (i, (cp, width)) in curve.segments.iter().zip(&curve.widths).enumerate() {
            let cp = cp.map(|p| Vec3A::from(m.transform_point3(glam::Vec3::from(p))));
            if let Some(p) = cp.iter().find(|p| !within_world_limit(**p)) {
                return Err(BuildError::Unsupported {
                    loc: shape.loc.clone(),
                    message: format!(
                        "a curve control point is at {p} in world space: {WORLD_LIMIT_TEXT}"
                    ),
                });
            }
            let normals = curve.normals.as_ref().map(|ns| {
                let n = ns[i].map(|n| {
                    Vec3A::from(normal_m.transform_vector3(glam::Vec3::from(n))).normalize_or_zero()
                });
                (n, libm::acosf(n[0].dot(n[1]).clamp(-1.0, 1.0)))
            });
            let segment = CurveSegment {
                cp,
                width: width.map(|w| w * scale),
                normals,
                kind: curve.kind,
                surface,
                flip: shape.reverse_orientation,
            };
            let index = self.prims.curve_segments.len() as u32;
            for k in 0..pieces {
                let (u0, u1) = (k as f32 / pieces as f32, (k + 1) as f32 / pieces as f32);
                self.prims
                    .curve_pieces
                    .push(CurvePiece::new(&segment, index, u0, u1));
            }
            self.prims.curve_segments.push(segment);
        }
        Ok(())
    }
}
