//! pbrt-v4's curves: cubic Bézier segments swept to a width, drawn as ribbons (`flat`,
//! facing every ray; `cylinder`, a flat ribbon whose normal turns across its width to look
//! round; `ribbon`, oriented by normals given at the segment ends). Hair is made of them.
//!
//! Each segment is split into 2^splitdepth pieces, each a BVH primitive over the shared
//! segment. A ray is tested against a piece in the ray's own frame (the ray along +z from
//! the origin, the piece's chord along +x): the piece is halved recursively, culled by the
//! bounds of its control points grown by half its width, until it is flat enough to stand
//! for a line, whose nearest point to the ray is then tested against the width there. The
//! recursion depth comes from the piece's curvature against its width (the bound in the
//! pbrt book, "Curves"). Curves live in world space: their control points are transformed
//! (exact for Bézier curves under affine maps) and their widths scaled by the transform's
//! mean scale.
//!
//! A ray ignores curve hits closer to its origin than the curve's width there: a flat
//! ribbon turns to face every ray, so the ribbon a scattered or shadow ray leaves would
//! otherwise stand across its path. (pbrt-v4 offsets rays leaving a curve by the width, to
//! the same end.) Rays from elsewhere lose only what lies within a width of their origin:
//! a strand resting on a surface shades it up to a width from the contact.

use super::{Geometry, SurfaceHit, SurfaceInfo};
use crate::math::Ray;
use glam::{Vec2, Vec3A};
use kiln_scene::CurveType;
use obvhs::Boundable;
use obvhs::aabb::Aabb;

/// One cubic Bézier segment of a curve, in world space.
#[derive(Debug, Clone)]
pub struct CurveSegment {
    pub cp: [Vec3A; 4],
    /// Widths at u = 0 and u = 1.
    pub width: [f32; 2],
    /// A ribbon's unit normals at u = 0 and 1, and the angle between them.
    pub normals: Option<([Vec3A; 2], f32)>,
    pub kind: CurveType,
    pub surface: SurfaceInfo,
    /// Normals point the other way (ReverseOrientation).
    pub flip: bool,
}

/// A piece [u0, u1] of a segment: what the BVH holds.
#[derive(Debug, Clone, Copy)]
pub struct CurvePiece {
    pub segment: u32,
    pub u0: f32,
    pub u1: f32,
    lo: Vec3A,
    hi: Vec3A,
}

impl CurvePiece {
    pub fn new(segment: &CurveSegment, index: u32, u0: f32, u1: f32) -> CurvePiece {
        let cp = sub_curve(&segment.cp, u0, u1);
        let half = 0.5 * segment.width[0].max(segment.width[1]);
        let lo = cp
            .iter()
            .fold(Vec3A::splat(f32::INFINITY), |a, p| a.min(*p))
            - half;
        let hi = cp
            .iter()
            .fold(Vec3A::splat(f32::NEG_INFINITY), |a, p| a.max(*p))
            + half;
        CurvePiece {
            segment: index,
            u0,
            u1,
            lo,
            hi,
        }
    }

    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        (self.lo, self.hi)
    }
}

impl Boundable for CurvePiece {
    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo, self.hi)
    }
}

/// A hit on a curve: distance, the segment's u and the v across its width.
#[derive(Debug, Clone, Copy)]
pub struct CurveHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// The blossom of a cubic Bézier curve at (a, b, c).
fn blossom(cp: &[Vec3A; 4], a: f32, b: f32, c: f32) -> Vec3A {
    let l = |p: Vec3A, q: Vec3A, t: f32| p + (q - p) * t;
    let a0 = l(cp[0], cp[1], a);
    let a1 = l(cp[1], cp[2], a);
    let a2 = l(cp[2], cp[3], a);
    let b0 = l(a0, a1, b);
    let b1 = l(a1, a2, b);
    l(b0, b1, c)
}

/// The control points of the piece [u0, u1] of a cubic Bézier curve.
pub fn sub_curve(cp: &[Vec3A; 4], u0: f32, u1: f32) -> [Vec3A; 4] {
    [
        blossom(cp, u0, u0, u0),
        blossom(cp, u0, u0, u1),
        blossom(cp, u0, u1, u1),
        blossom(cp, u1, u1, u1),
    ]
}

/// The point and derivative of a cubic Bézier curve at `u`.
pub fn evaluate(cp: &[Vec3A; 4], u: f32) -> (Vec3A, Vec3A) {
    let l = |p: Vec3A, q: Vec3A| p + (q - p) * u;
    let (a, b, c) = (l(cp[0], cp[1]), l(cp[1], cp[2]), l(cp[2], cp[3]));
    let (d, e) = (l(a, b), l(b, c));
    let deriv = if (e - d).length_squared() > 0.0 {
        3.0 * (e - d)
    } else if u == 0.0 {
        // A degenerate end: the chord stands in.
        cp[2] - cp[0]
    } else {
        cp[3] - cp[1]
    };
    (l(d, e), deriv)
}

/// The two halves of a cubic Bézier curve, sharing their middle point.
fn halves(cp: &[Vec3A; 4]) -> [[Vec3A; 4]; 2] {
    let m = |p: Vec3A, q: Vec3A| (p + q) * 0.5;
    let (a, b, c) = (m(cp[0], cp[1]), m(cp[1], cp[2]), m(cp[2], cp[3]));
    let (d, e) = (m(a, b), m(b, c));
    let mid = m(d, e);
    [[cp[0], a, d, mid], [mid, e, c, cp[3]]]
}

/// An orthonormal frame with z along a ray and x along the piece's chord seen across it.
struct RayFrame {
    origin: Vec3A,
    x: Vec3A,
    y: Vec3A,
    z: Vec3A,
}

impl RayFrame {
    fn new(origin: Vec3A, dir: Vec3A, chord: Vec3A) -> RayFrame {
        let z = dir.normalize();
        let across = chord - z * z.dot(chord);
        let x = if across.length_squared() > 1e-20 * chord.length_squared().max(1e-30) {
            across.normalize()
        } else {
            crate::math::Frame::from_z(z).x
        };
        RayFrame {
            origin,
            x,
            y: z.cross(x),
            z,
        }
    }

    fn point(&self, p: Vec3A) -> Vec3A {
        let d = p - self.origin;
        Vec3A::new(d.dot(self.x), d.dot(self.y), d.dot(self.z))
    }

    fn vector(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    fn to_world(&self, v: Vec3A) -> Vec3A {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

impl CurveSegment {
    fn width_at(&self, u: f32) -> f32 {
        self.width[0] + (self.width[1] - self.width[0]) * u
    }

    /// A ribbon's normal at `u`, turned between the end normals.
    fn ribbon_normal(&self, u: f32) -> Option<Vec3A> {
        let ([n0, n1], angle) = self.normals?;
        if angle.abs() < 1e-6 {
            return Some(n0);
        }
        let s = libm::sinf(angle);
        Some((n0 * libm::sinf((1.0 - u) * angle) + n1 * libm::sinf(u * angle)) / s)
    }

    /// The nearest hit of the ray on piece [u0, u1] with distance in (0, tmax).
    pub fn intersect(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        u0: f32,
        u1: f32,
    ) -> Option<CurveHit> {
        let piece = sub_curve(&self.cp, u0, u1);
        let frame = RayFrame::new(origin, dir, piece[3] - piece[0]);
        let cp = piece.map(|p| frame.point(p));
        let ray_len = dir.length();
        let z_max = ray_len * tmax;
        let max_width = self.width_at(u0).max(self.width_at(u1));
        if !overlaps_ray(&cp, 0.5 * max_width, z_max) {
            return None;
        }
        // Halve until the piece is within a twentieth of its width of a line.
        let mut l0 = 0.0f32;
        for i in 0..2 {
            let dd = (cp[i] - 2.0 * cp[i + 1] + cp[i + 2]).abs();
            l0 = l0.max(dd.max_element());
        }
        let eps = self.width[0].max(self.width[1]) * 0.05;
        let depth = if l0 > 0.0 && eps > 0.0 {
            let r = std::f32::consts::SQRT_2 * 6.0 * l0 / (8.0 * eps);
            ((libm::log2f(r.max(1.0)).floor() as i32) / 2).clamp(0, 10) as u32
        } else {
            0
        };
        let mut best: Option<(f32, f32, f32, f32)> = None;
        let query = Query {
            z_max,
            dir: dir / ray_len,
        };
        self.recurse(&cp, u0, u1, depth, &query, &mut best);
        let (z, u, v, _) = best?;
        Some(CurveHit {
            t: z / ray_len,
            u,
            v,
        })
    }

    /// Tests the piece `cp` (ray frame) spanning [u0, u1]; keeps the nearest hit in `best`
    /// as (distance along the ray, u, v, width there).
    fn recurse(
        &self,
        cp: &[Vec3A; 4],
        u0: f32,
        u1: f32,
        depth: u32,
        query: &Query,
        best: &mut Option<(f32, f32, f32, f32)>,
    ) {
        let Query { z_max, dir } = *query;
        if depth > 0 {
            let um = 0.5 * (u0 + u1);
            let [a, b] = halves(cp);
            for (half, lo, hi) in [(a, u0, um), (b, um, u1)] {
                let w = self.width_at(lo).max(self.width_at(hi));
                let limit = best.map_or(z_max, |b| b.0);
                if overlaps_ray(&half, 0.5 * w, limit) {
                    self.recurse(&half, lo, hi, depth - 1, query, best);
                }
            }
            return;
        }
        // The ray must pass between the perpendiculars at the piece's two ends.
        let edge0 = (cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x);
        let edge1 = (cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x);
        if edge0 < 0.0 || edge1 < 0.0 {
            return;
        }
        let chord = Vec2::new(cp[3].x - cp[0].x, cp[3].y - cp[0].y);
        let denom = chord.length_squared();
        if denom == 0.0 {
            return;
        }
        let w = (-Vec2::new(cp[0].x, cp[0].y)).dot(chord) / denom;
        let u = (u0 + (u1 - u0) * w).clamp(u0, u1);
        let mut width = self.width_at(u);
        if let Some(n) = self.ribbon_normal(u) {
            // A ribbon seen edge-on is thin.
            width *= n.dot(dir).abs();
        }
        let (pc, dpcdw) = evaluate(cp, w.clamp(0.0, 1.0));
        let dist2 = pc.x * pc.x + pc.y * pc.y;
        if dist2 > width * width * 0.25 {
            return;
        }
        // Rays leaving a curve ignore the ribbon they leave (see the module's notes).
        if pc.z <= width || pc.z > z_max {
            return;
        }
        if best.is_some_and(|b| pc.z >= b.0) {
            return;
        }
        let dist = dist2.sqrt();
        let edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
        let v = if edge > 0.0 {
            0.5 + dist / width
        } else {
            0.5 - dist / width
        };
        *best = Some((pc.z, u, v, width));
    }

    /// The hit record's geometry at (u, v) for a ray along `dir`: dp/du, dp/dv and the
    /// unit normal.
    pub fn shading(&self, dir: Vec3A, u: f32, v: f32) -> (Vec3A, Vec3A, Vec3A) {
        let (_, dpdu) = evaluate(&self.cp, u);
        let width = self.width_at(u);
        let dpdv = match (self.kind, self.ribbon_normal(u)) {
            (CurveType::Ribbon, Some(n)) => n.cross(dpdu).normalize_or_zero() * width,
            _ => {
                let frame = RayFrame::new(Vec3A::ZERO, dir, dpdu);
                let du = frame.vector(dpdu);
                let mut dv = Vec3A::new(-du.y, du.x, 0.0).normalize_or_zero() * width;
                if self.kind == CurveType::Cylinder {
                    // Turn across the width, -90° to 90°, to look round.
                    let theta = (-90.0 + 180.0 * v).to_radians();
                    dv = rotate(dv, du.normalize_or_zero(), -theta);
                }
                frame.to_world(dv)
            }
        };
        let mut n = dpdu.cross(dpdv).normalize_or_zero();
        if n == Vec3A::ZERO {
            n = -dir.normalize();
        }
        if self.flip {
            n = -n;
        }
        (dpdu, dpdv, n)
    }
}

/// The ray, as the recursive test needs it: how far it reaches along its unit direction.
#[derive(Clone, Copy)]
struct Query {
    z_max: f32,
    dir: Vec3A,
}

/// Rodrigues' rotation of `v` by `angle` about the unit `axis`.
fn rotate(v: Vec3A, axis: Vec3A, angle: f32) -> Vec3A {
    let (s, c) = libm::sincosf(angle);
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

/// Whether the bounds of `cp` (ray frame) grown by `half_width` meet the ray's segment
/// from z = 0 to `z_max` along the z axis.
fn overlaps_ray(cp: &[Vec3A; 4], half_width: f32, z_max: f32) -> bool {
    let lo = cp
        .iter()
        .fold(Vec3A::splat(f32::INFINITY), |a, p| a.min(*p))
        - half_width;
    let hi = cp
        .iter()
        .fold(Vec3A::splat(f32::NEG_INFINITY), |a, p| a.max(*p))
        + half_width;
    lo.x <= 0.0 && hi.x >= 0.0 && lo.y <= 0.0 && hi.y >= 0.0 && hi.z >= 0.0 && lo.z <= z_max
}

impl Geometry {
    /// The distance to curve piece `id` along the ray, or infinity.
    pub(super) fn curve_t(&self, origin: Vec3A, dir: Vec3A, id: u32, tmax: f32) -> f32 {
        let piece = &self.prims.curve_pieces[id as usize];
        let seg = &self.prims.curve_segments[piece.segment as usize];
        seg.intersect(origin, dir, tmax, piece.u0, piece.u1)
            .map_or(f32::INFINITY, |h| h.t)
    }

    pub(super) fn curve_hit(&self, ray: &Ray, t: f32, id: u32) -> SurfaceHit {
        let piece = &self.prims.curve_pieces[id as usize];
        let seg = &self.prims.curve_segments[piece.segment as usize];
        let hit = seg
            .intersect(
                ray.origin,
                ray.dir,
                t * (1.0 + 1e-5) + 1e-30,
                piece.u0,
                piece.u1,
            )
            .unwrap_or(CurveHit {
                t,
                u: 0.5 * (piece.u0 + piece.u1),
                v: 0.5,
            });
        let (dpdu, dpdv, n) = seg.shading(ray.dir, hit.u, hit.v);
        let p = ray.at(t);
        SurfaceHit {
            p,
            t,
            ng: n,
            ns: n,
            dpdu,
            dpdv,
            uv: Vec2::new(hit.u, hit.v),
            surface: seg.surface,
            light: None,
            offset: crate::math::surface_epsilon(p),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(width: f32, kind: CurveType) -> CurveSegment {
        CurveSegment {
            cp: [
                Vec3A::new(-1.0, 0.0, 0.0),
                Vec3A::new(-1.0 / 3.0, 0.0, 0.0),
                Vec3A::new(1.0 / 3.0, 0.0, 0.0),
                Vec3A::new(1.0, 0.0, 0.0),
            ],
            width: [width, width],
            normals: None,
            kind,
            surface: SurfaceInfo::PLAIN,
            flip: false,
        }
    }

    /// A straight flat curve of width w seen from above covers |y| < w/2 and nothing more,
    /// with v running across it from 0 to 1.
    #[test]
    fn a_flat_curve_is_as_wide_as_its_width() {
        let seg = straight(0.2, CurveType::Flat);
        let hit = |y: f32| seg.intersect(Vec3A::new(0.3, y, 5.0), -Vec3A::Z, 100.0, 0.0, 1.0);
        let h = hit(0.0).expect("the middle");
        assert!(
            (h.t - 5.0).abs() < 1e-4 && (h.u - 0.65).abs() < 1e-3,
            "{h:?}"
        );
        assert!((h.v - 0.5).abs() < 1e-3);
        assert!(hit(0.099).is_some() && hit(-0.099).is_some());
        assert!(hit(0.101).is_none() && hit(-0.101).is_none());
        let (a, b) = (hit(0.09).unwrap().v, hit(-0.09).unwrap().v);
        assert!((a - b).abs() > 0.85, "v spans the width: {a} {b}");
    }

    /// Evaluation and sub-curves agree: a piece's ends are the curve's points there.
    #[test]
    fn pieces_are_the_curve_between_their_parameters() {
        let cp = [
            Vec3A::new(0.0, 0.0, 0.0),
            Vec3A::new(1.0, 2.0, 0.0),
            Vec3A::new(2.0, -1.0, 1.0),
            Vec3A::new(3.0, 0.0, 0.0),
        ];
        let piece = sub_curve(&cp, 0.25, 0.75);
        assert!((piece[0] - evaluate(&cp, 0.25).0).length() < 1e-5);
        assert!((piece[3] - evaluate(&cp, 0.75).0).length() < 1e-5);
        assert!((evaluate(&piece, 0.5).0 - evaluate(&cp, 0.5).0).length() < 1e-5);
    }

    /// A cylinder curve's normal turns from one edge to the other; a flat curve's faces
    /// the ray.
    #[test]
    fn normals_face_the_ray_or_turn_across_the_width() {
        let flat = straight(0.2, CurveType::Flat);
        let (_, _, n) = flat.shading(-Vec3A::Z, 0.5, 0.8);
        assert!(n.z.abs() > 0.999, "{n}");
        let cyl = straight(0.2, CurveType::Cylinder);
        let (_, _, n0) = cyl.shading(-Vec3A::Z, 0.5, 0.01);
        let (_, _, n1) = cyl.shading(-Vec3A::Z, 0.5, 0.5);
        let (_, _, n2) = cyl.shading(-Vec3A::Z, 0.5, 0.99);
        assert!(n1.z.abs() > 0.999, "{n1}");
        assert!(n0.z.abs() < 0.1 && n2.z.abs() < 0.1, "{n0} {n2}");
        assert!(n0.dot(n2) < -0.9, "the edges face opposite ways: {n0} {n2}");
    }
}
