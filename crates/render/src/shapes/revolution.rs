//! Surfaces of revolution (seed 003's glasses): a contour of points (r, z) in the
//! half-plane r ≥ 0 turned about the object-space z axis. Each pair of neighbouring points
//! sweeps a strip: a cone frustum in general, a cylinder where r is constant, a flat annulus
//! where z is. Strips are intersected exactly (one quadratic, or one plane), and each is cut
//! into sectors of at most 22.5° so their boxes stay tight (16 round trace the martini
//! glass 10% faster than 8 did, and 32 only 3% faster again); [`super::quadric`] places the
//! sectors in the world and the quadric BVH holds them, which is the hierarchy over the strips.
//!
//! Orientation: the normal faces to the right of the contour's direction of travel in the
//! (r, z) plane, so a contour that runs from the bottom of a solid up its outer side faces
//! outwards, as a sphere's does. Shading normals are interpolated along the strip between
//! per-point normals (given, or the strips' normals averaged at each point where the contour
//! turns by less than the crease angle) and turned about the axis, so the surface shades
//! smoothly in both directions.

use super::local::LocalPoint;
use crate::math::{phi_of, solve_quadratic};
use glam::{DVec3, Vec2, Vec3A};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};

/// One sector of one strip, in object space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Strip {
    /// The contour points the strip joins: (r, z), r ≥ 0.
    pub a: Vec2,
    pub b: Vec2,
    /// Unit shading normals in the (r, z) plane at `a` and at `b`.
    pub na: Vec2,
    pub nb: Vec2,
    /// The contour parameter (arc length over the whole contour's, in [0, 1]) at `a`, `b`.
    pub va: f32,
    pub vb: f32,
    /// The sector: φ from `phi0` to `phi1` (radians, within [0, phi_max]).
    pub phi0: f32,
    pub phi1: f32,
    /// The whole shape's φmax, for u = φ / φmax.
    pub phi_max: f32,
    /// (cos, sin) of `phi0` and of `phi1`: a point is in the sector when it lies left of the
    /// first and right of the second (no arctangent per candidate hit; neighbouring sectors
    /// share the vector, so the two tests at a seam are exact negations and leave no gap).
    pub edge0: Vec2,
    pub edge1: Vec2,
}

/// Relative slack on a strip's edges, so a ray through the seam between two strips (whose
/// hit points are computed from different equations) finds at least one of them.
const SEAM: f64 = 1e-7;

impl Strip {
    fn ends(&self) -> (f64, f64, f64, f64) {
        (
            f64::from(self.a.x),
            f64::from(self.a.y),
            f64::from(self.b.x),
            f64::from(self.b.y),
        )
    }

    fn is_flat(&self) -> bool {
        self.a.y == self.b.y
    }

    /// The ray parameter of the nearest hit in (tmin, tmax), or infinity.
    pub fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        let (r0, z0, r1, z1) = self.ends();
        let scale = r0.max(r1).max(z0.abs()).max(z1.abs()).max(1e-30);
        let slack = SEAM * scale;
        let (e0, e1) = (self.edge0.as_dvec2(), self.edge1.as_dvec2());
        let in_sector = |p: DVec3| e0.x * p.y - e0.y * p.x >= 0.0 && p.x * e1.y - p.y * e1.x >= 0.0;
        if self.is_flat() {
            if d.z == 0.0 {
                return f64::INFINITY;
            }
            let t = (z0 - o.z) / d.z;
            if !(t > tmin && t < tmax) {
                return f64::INFINITY;
            }
            let p = o + d * t;
            let r = (p.x * p.x + p.y * p.y).sqrt();
            let (lo, hi) = (r0.min(r1), r0.max(r1));
            return if r >= lo - slack && r <= hi + slack && in_sector(p) {
                t
            } else {
                f64::INFINITY
            };
        }
        // x² + y² = r(z)², with r(z) = r0 + k (z − z0) along the strip.
        let k = (r1 - r0) / (z1 - z0);
        let w = r0 + k * (o.z - z0);
        let wd = k * d.z;
        let a = d.x * d.x + d.y * d.y - wd * wd;
        let b = 2.0 * (o.x * d.x + o.y * d.y - w * wd);
        let c = o.x * o.x + o.y * o.y - w * w;
        let roots = if a.abs() <= 1e-12 * (d.x * d.x + d.y * d.y + wd * wd) {
            // The ray runs parallel to the cone's slant: one crossing.
            if b == 0.0 {
                return f64::INFINITY;
            }
            let t = -c / b;
            (t, t)
        } else {
            match solve_quadratic(a, b, c, b * b - 4.0 * a * c) {
                Some(r) => r,
                None => return f64::INFINITY,
            }
        };
        let (zlo, zhi) = (z0.min(z1) - slack, z0.max(z1) + slack);
        for t in [roots.0, roots.1] {
            if t <= tmin || t >= tmax {
                continue;
            }
            let p = o + d * t;
            // The cone's other nappe (r(z) < 0) lies beyond the strip's ends.
            if p.z >= zlo && p.z <= zhi && in_sector(p) {
                return t;
            }
        }
        f64::INFINITY
    }

    /// How far along the strip (0 at `a`, 1 at `b`) the point `p` lies.
    fn along(&self, p: Vec3A) -> f32 {
        let s = if self.is_flat() {
            let r = (p.x * p.x + p.y * p.y).sqrt();
            (r - self.a.x) / (self.b.x - self.a.x)
        } else {
            (p.z - self.a.y) / (self.b.y - self.a.y)
        };
        if s.is_finite() {
            s.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The surface at the point of the strip nearest `p`.
    pub fn local(&self, p: Vec3A) -> LocalPoint {
        let s = self.along(p);
        let phi = phi_of(f64::from(p.x), f64::from(p.y)) as f32;
        let phi = phi.clamp(self.phi0, self.phi1);
        let (sin, cos) = libm::sincosf(phi);
        let q = self.a.lerp(self.b, s);
        let p = Vec3A::new(q.x * cos, q.x * sin, q.y);
        let turn = |v: Vec2| Vec3A::new(v.x * cos, v.x * sin, v.y);
        let t = self.b - self.a;
        let n = turn(Vec2::new(t.y, -t.x).normalize_or(Vec2::Y));
        let ns = turn(self.na.lerp(self.nb, s)).normalize_or(n);
        let dv = self.vb - self.va;
        let dpdv = if dv > 0.0 { turn(t) / dv } else { turn(t) };
        LocalPoint {
            ns: (ns != n).then_some(ns),
            pdf: 0.0,
            p,
            n,
            dpdu: Vec3A::new(-self.phi_max * p.y, self.phi_max * p.x, 0.0),
            dpdv,
            uv: Vec2::new(phi / self.phi_max, self.va + s * dv),
        }
    }

    pub fn area(&self) -> f32 {
        0.5 * (self.phi1 - self.phi0) * (self.a.x + self.b.x) * (self.b - self.a).length()
    }

    /// A point uniformly distributed over the sector's area: along the strip with density
    /// proportional to the radius there, uniformly in φ.
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let (r0, r1) = (self.a.x, self.b.x);
        let root = (r0 * r0 + u.x * (r1 * r1 - r0 * r0)).max(0.0).sqrt();
        let s = if r0 + root > 0.0 {
            (u.x * (r0 + r1) / (r0 + root)).clamp(0.0, 1.0)
        } else {
            u.x
        };
        let q = self.a.lerp(self.b, s);
        let phi = self.phi0 + u.y * (self.phi1 - self.phi0);
        Vec3A::new(q.x * libm::cosf(phi), q.x * libm::sinf(phi), q.y)
    }

    /// Object-space bounds of the sector.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        let mut add = |r: f32, phi: f32, z: f32| {
            let p = Vec3A::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
            lo = lo.min(p);
            hi = hi.max(p);
        };
        for q in [self.a, self.b] {
            add(q.x, self.phi0, q.y);
            add(q.x, self.phi1, q.y);
        }
        let r_max = self.a.x.max(self.b.x);
        let mut axis = 0.0f64;
        while axis <= TAU {
            let phi = axis as f32;
            if phi > self.phi0 && phi < self.phi1 {
                add(r_max, phi, self.a.y);
            }
            axis += FRAC_PI_2;
        }
        // Room for the rounding of cos and sin, and for the seam slack.
        let pad =
            Vec3A::splat(1e-6 * r_max.max(self.a.y.abs()).max(self.b.y.abs()).max(1e-6) * 4.0);
        lo.z = self.a.y.min(self.b.y);
        hi.z = self.a.y.max(self.b.y);
        (lo - pad, hi + pad)
    }
}

/// The most strip sectors one contour may make: a file's point count decides it, and each
/// sector is a quadric record of a few hundred bytes.
pub const MAX_SECTORS: usize = 1 << 22;

/// A contour that cannot be turned into a surface.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourError(pub String);

/// Cuts the surface of revolution of `contour` (points (r, z)) swept through `phi_max`
/// radians into strip sectors. `normals` gives a shading normal per point; without them
/// neighbouring strips' normals are averaged at each point where the contour turns by less
/// than `crease` radians (so a rim or a foot's edge stays sharp). A contour whose last point
/// is its first is closed, and smoothed across that point too.
pub fn strips(
    contour: &[[f32; 2]],
    normals: Option<&[[f32; 2]]>,
    crease: f32,
    phi_max: f32,
) -> Result<Vec<Strip>, ContourError> {
    if contour.len() < 2 {
        return Err(ContourError(
            "a contour needs at least two points".to_string(),
        ));
    }
    if let Some(i) = contour
        .iter()
        .position(|p| !(p[0] >= 0.0 && p[0].is_finite() && p[1].is_finite()))
    {
        return Err(ContourError(format!(
            "contour point {i} is ({}, {}): every point needs a finite radius r ≥ 0 and a finite height",
            contour[i][0], contour[i][1]
        )));
    }
    if let Some(n) = normals
        && n.len() != contour.len()
    {
        return Err(ContourError(format!(
            "{} normals for {} contour points: give one per point",
            n.len(),
            contour.len()
        )));
    }
    let pts: Vec<Vec2> = contour.iter().map(|p| Vec2::from(*p)).collect();
    let segments = pts.len() - 1;
    let closed = pts[0] == pts[segments] && segments >= 2;
    // Each strip's own normal, and its length (zero-length strips are dropped below).
    let face: Vec<Option<Vec2>> = (0..segments)
        .map(|i| {
            let t = pts[i + 1] - pts[i];
            (t.length() > 0.0).then(|| Vec2::new(t.y, -t.x).normalize())
        })
        .collect();
    let lengths: Vec<f32> = (0..segments)
        .map(|i| (pts[i + 1] - pts[i]).length())
        .collect();
    let total: f32 = lengths.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Err(ContourError(
            "the contour's points all coincide".to_string(),
        ));
    }
    // The nearest strip with a normal before and after point j.
    let before = |j: usize| -> Option<Vec2> {
        (0..j).rev().find_map(|i| face[i]).or_else(|| {
            closed
                .then(|| (j..segments).rev().find_map(|i| face[i]))
                .flatten()
        })
    };
    let after = |j: usize| -> Option<Vec2> {
        (j..segments)
            .find_map(|i| face[i])
            .or_else(|| closed.then(|| (0..j).find_map(|i| face[i])).flatten())
    };
    let cos_crease = libm::cosf(crease);
    // Shading normal at point j seen from the strip on `side` (its own normal `own`).
    let vertex_normal = |j: usize, own: Vec2| -> Vec2 {
        if let Some(n) = normals {
            let v = Vec2::from(n[j]);
            return v.try_normalize().unwrap_or(own);
        }
        let ends = !closed && (j == 0 || j == segments);
        if ends {
            // A point on the axis is a pole: its normal is the axis, up or down.
            return if pts[j].x == 0.0 && own.y != 0.0 {
                Vec2::new(0.0, own.y.signum())
            } else {
                own
            };
        }
        match (before(j), after(j)) {
            (Some(p), Some(q)) if p.dot(q) >= cos_crease => (p + q).try_normalize().unwrap_or(own),
            _ => own,
        }
    };
    let sectors = ((f64::from(phi_max) / (FRAC_PI_4 / 2.0)).ceil() as usize).max(1);
    if segments.saturating_mul(sectors) > MAX_SECTORS {
        return Err(ContourError(format!(
            "a contour of {} points makes {} strip sectors, more than Kiln's limit of {MAX_SECTORS} (about {} GiB of primitives); use fewer points",
            contour.len(),
            segments.saturating_mul(sectors),
            (MAX_SECTORS * super::QUADRIC_BYTES) >> 30
        )));
    }
    let mut out = Vec::with_capacity(segments * sectors);
    let mut arc = 0.0f32;
    for i in 0..segments {
        let (va, vb) = (arc / total, (arc + lengths[i]) / total);
        arc += lengths[i];
        let Some(own) = face[i] else { continue };
        let (a, b) = (pts[i], pts[i + 1]);
        if a.x == 0.0 && b.x == 0.0 {
            // A strip along the axis sweeps no area.
            continue;
        }
        let (na, nb) = (vertex_normal(i, own), vertex_normal(i + 1, own));
        for k in 0..sectors {
            let phi0 = phi_max * k as f32 / sectors as f32;
            let phi1 = if k + 1 == sectors {
                phi_max
            } else {
                phi_max * (k + 1) as f32 / sectors as f32
            };
            let edge = |phi: f32| {
                let (sin, cos) = libm::sincosf(phi);
                Vec2::new(cos, sin)
            };
            out.push(Strip {
                edge0: edge(phi0),
                edge1: edge(phi1),
                a,
                b,
                na,
                nb,
                va,
                vb,
                phi0,
                phi1,
                phi_max,
            });
        }
    }
    if out.is_empty() {
        return Err(ContourError(
            "the contour sweeps no area (every strip lies on the axis)".to_string(),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    /// A unit sphere as a contour: `n` strips from the south pole up to the north pole.
    fn sphere(n: usize) -> Vec<[f32; 2]> {
        (0..=n)
            .map(|i| {
                let theta = PI * i as f32 / n as f32;
                [libm::sinf(theta).max(0.0), -libm::cosf(theta)]
            })
            .collect()
    }

    #[test]
    fn a_sphere_contour_faces_out_and_its_area_converges() {
        let s = strips(&sphere(400), None, 0.5, TAU as f32).unwrap();
        let area: f32 = s.iter().map(Strip::area).sum();
        assert!((area - 4.0 * PI).abs() < 1e-3 * 4.0 * PI, "{area}");
        for strip in &s {
            let p = strip.sample(Vec2::new(0.3, 0.6));
            let l = strip.local(p);
            assert!(l.n.dot(l.p) > 0.99, "{:?} {:?}", l.n, l.p);
            // The smooth normal of a sphere's contour is its position.
            let ns = l.ns.unwrap_or(l.n);
            assert!(ns.dot(l.p.normalize()) > 0.99999, "{ns:?} at {:?}", l.p);
        }
    }

    /// Every strip kind (frustum, cylinder, annulus, cone to the axis) is hit where a ray
    /// from outside along the normal reaches it, from both sides.
    #[test]
    fn samples_are_found_by_rays_from_both_sides() {
        let contour = [
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.5, 1.5],
            [0.2, 2.0],
            [0.0, 2.5],
        ];
        let s = strips(&contour, None, 0.1, 5.0).unwrap();
        for strip in &s {
            for i in 0..16 {
                let u = Vec2::new((i % 4) as f32 / 4.0 + 0.1, (i / 4) as f32 / 4.0 + 0.1);
                let p = strip.sample(u);
                let l = strip.local(p);
                assert!((l.p - p).length() < 1e-5);
                for side in [1.0f32, -1.0] {
                    let o = p + l.n * side * 0.01;
                    let o = DVec3::new(o.x.into(), o.y.into(), o.z.into());
                    let d = -l.n * side;
                    let d = DVec3::new(d.x.into(), d.y.into(), d.z.into());
                    let t = strip.intersect(o, d, 0.0, 1.0);
                    assert!((t - 0.01).abs() < 1e-5, "{strip:?} {t} at {p:?}");
                }
            }
        }
    }

    /// Uniform area sampling: the density along the strip follows the radius.
    #[test]
    fn sampling_is_uniform_by_area() {
        let s = strips(&[[0.1, 0.0], [2.0, 1.0]], None, 0.0, TAU as f32).unwrap()[0];
        let n = 20000;
        let mut low = 0;
        for i in 0..n {
            let p = s.sample(Vec2::new((i as f32 + 0.5) / n as f32, 0.5));
            if p.z < 0.5 {
                low += 1;
            }
        }
        // Area of the lower half over the whole: radii 0.1..1.05 against 0.1..2.0.
        let expect = (0.1 + 1.05) / (0.1 + 2.0) * 0.5;
        assert!((low as f32 / n as f32 - expect).abs() < 1e-3);
    }

    #[test]
    fn bad_contours_are_refused() {
        assert!(strips(&[[0.0, 0.0]], None, 0.5, 1.0).is_err());
        assert!(strips(&[[-1.0, 0.0], [1.0, 0.0]], None, 0.5, 1.0).is_err());
        assert!(strips(&[[0.0, 0.0], [0.0, 1.0]], None, 0.5, 1.0).is_err());
        assert!(strips(&[[1.0, 0.0], [1.0, 0.0]], None, 0.5, 1.0).is_err());
        assert!(strips(&[[1.0, 0.0], [1.0, 1.0]], Some(&[[1.0, 0.0]]), 0.5, 1.0).is_err());
        // More points than the sector limit allows is refused before anything is built.
        let many: Vec<[f32; 2]> = (0..=MAX_SECTORS / 16 + 1)
            .map(|i| [1.0, i as f32 * 1e-3])
            .collect();
        let err = strips(&many, None, 0.5, TAU as f32).unwrap_err();
        assert!(err.0.contains("more than Kiln's limit"), "{}", err.0);
    }

    /// The nearest hit of a ray on any of `strips`.
    fn nearest(strips: &[Strip], o: [f64; 3], d: [f64; 3]) -> f64 {
        let (o, d) = (DVec3::from(o), DVec3::from(d));
        strips
            .iter()
            .map(|s| s.intersect(o, d, 0.0, f64::INFINITY))
            .fold(f64::INFINITY, f64::min)
    }

    const VASE: [[f32; 2]; 11] = [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 0.5],
        [0.6, 0.5],
        [0.6, 1.0],
        [0.8, 1.2],
        [1.2, 1.5],
        [1.2, 2.0],
        [0.9, 2.1],
        [0.3, 2.2],
        [0.0, 2.2],
    ];

    /// Rays along the axis meet the flat ends and the poles at their centres, from outside
    /// and from inside.
    #[test]
    fn rays_along_the_axis_find_the_ends() {
        let vase = strips(&VASE, None, 0.5, TAU as f32).unwrap();
        assert!((nearest(&vase, [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]) - 1.0).abs() < 1e-6);
        assert!((nearest(&vase, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]) - 1.2).abs() < 1e-6);
        assert!((nearest(&vase, [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]) - 1.0).abs() < 1e-6);
        assert!((nearest(&vase, [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]) - 2.8).abs() < 1e-6);
        let ball = strips(&sphere(64), None, 0.5, TAU as f32).unwrap();
        assert!((nearest(&ball, [0.0, 0.0, -2.0], [0.0, 0.0, 1.0]) - 1.0).abs() < 1e-6);
        assert!((nearest(&ball, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]) - 1.0).abs() < 1e-6);
    }

    /// A ray grazing the widest cylinder just outside misses, just inside hits where the
    /// circle says; one along a flat strip's plane finds the wall it runs into; one down
    /// through the flat shoulder hits it.
    #[test]
    fn grazing_and_flat_rays() {
        let vase = strips(&VASE, None, 0.5, TAU as f32).unwrap();
        assert_eq!(
            nearest(&vase, [-5.0, 1.2001, 1.75], [1.0, 0.0, 0.0]),
            f64::INFINITY
        );
        let t = nearest(&vase, [-5.0, 1.199, 1.75], [1.0, 0.0, 0.0]);
        let want = 5.0 - (1.2f64 * 1.2 - 1.199 * 1.199).sqrt();
        assert!((t - want).abs() < 1e-4, "{t} vs {want}");
        // Exactly tangent: a hit at the tangent point or a miss, never a wrong distance.
        let t = nearest(&vase, [-5.0, 1.2, 1.75], [1.0, 0.0, 0.0]);
        assert!(t == f64::INFINITY || (t - 5.0).abs() < 1e-2, "{t}");
        // In the plane of the shoulder (z = 0.5): it meets the outer wall's top edge.
        let t = nearest(&vase, [-5.0, 0.0, 0.5], [1.0, 0.0, 0.0]);
        assert!((t - 4.0).abs() < 1e-4, "{t}");
        // Down through the shoulder's annulus.
        let t = nearest(&vase, [0.8, 0.0, 1.0], [0.0, 0.0, -1.0]);
        assert!((t - 0.5).abs() < 1e-6, "{t}");
        // Through the rim's seam between the cone and the cylinder.
        let d = DVec3::new(1.0, 0.0, 0.3).normalize();
        let t = nearest(&vase, [0.0, 0.0, 1.5 - 0.36], d.into());
        assert!(t.is_finite());
    }

    /// From inside a finely cut sphere every direction meets the surface once, where the
    /// sphere is, and the sectors' seams let nothing through.
    #[test]
    fn rays_from_inside_meet_the_surface_where_the_sphere_is() {
        let ball = strips(&sphere(2000), None, 0.5, TAU as f32).unwrap();
        let o = DVec3::new(0.1, -0.2, 0.3);
        for i in 0..500 {
            let u = Vec2::new((i as f32 * 0.618_034).fract(), (i as f32 + 0.5) / 500.0);
            let d = crate::sampling::uniform_sphere(u);
            let d = DVec3::new(d.x.into(), d.y.into(), d.z.into());
            let t = nearest(&ball, o.into(), d.into());
            let b = o.dot(d);
            let want = -b + (b * b - (o.length_squared() - 1.0)).sqrt();
            assert!((t - want).abs() < 1e-5, "{t} vs {want} along {d:?}");
        }
        // Along the sector seams exactly (φ a multiple of 45°).
        for k in 0..8 {
            let phi = std::f64::consts::FRAC_PI_4 * k as f64;
            let d = [libm::cos(phi), libm::sin(phi), 0.0];
            assert!(nearest(&ball, [0.0, 0.0, 0.0], d).is_finite(), "seam {k}");
        }
    }

    /// u is φ over φmax and v the arc length along the contour over its whole length; dp/du
    /// and dp/dv are the derivatives of the point in those parameters.
    #[test]
    fn uv_follow_angle_and_arc_length() {
        // Three strips of lengths 1, 1 and 2: v = 0, 0.25, 0.5, 1 at the points.
        let contour = [[1.0, 0.0], [1.0, 1.0], [2.0, 1.0], [2.0, 3.0]];
        let phi_max = 3.0;
        let s = strips(&contour, None, 0.0, phi_max).unwrap();
        for strip in &s {
            for u in [Vec2::new(0.2, 0.3), Vec2::new(0.8, 0.9)] {
                let p = strip.sample(u);
                let l = strip.local(p);
                let phi = phi_of(f64::from(p.x), f64::from(p.y)) as f32;
                assert!((l.uv.x - phi / phi_max).abs() < 1e-5);
                let v = if p.z < 1.0 - 1e-6 {
                    0.25 * p.z
                } else if (p.z - 1.0).abs() < 1e-6 {
                    0.25 + 0.25 * ((p.x * p.x + p.y * p.y).sqrt() - 1.0)
                } else {
                    0.5 + 0.25 * (p.z - 1.0)
                };
                assert!((l.uv.y - v).abs() < 1e-5, "v {} vs {v} at {p:?}", l.uv.y);
                // A small step in v moves the point by dp/dv times the step.
                let dv = 1e-3;
                let q = strip.local(p + l.dpdv * dv);
                assert!((q.uv.y - l.uv.y - dv).abs() < 1e-5, "{} {}", q.uv.y, l.uv.y);
                let du = 1e-3;
                let q = strip.local(p + l.dpdu * du);
                assert!((q.uv.x - l.uv.x - du).abs() < 1e-4);
            }
        }
    }

    /// Given normals are interpolated along each strip and turned about the axis; without
    /// them a sharp turn keeps each strip's own normal (a crease) and a gentle one is smoothed.
    #[test]
    fn shading_normals_are_given_or_smoothed_below_the_crease() {
        let contour = [[1.0, 0.0], [1.0, 1.0], [0.5, 1.5]];
        let given = [[1.0, -1.0], [1.0, 0.0], [1.0, 1.0]];
        let s = strips(&contour, Some(&given), 0.0, TAU as f32).unwrap();
        // Halfway up the cylinder (the first strip): the mean of the two unit normals, and
        // a quarter turn round, the same turned.
        let mid = (Vec2::new(1.0, -1.0).normalize() + Vec2::X).normalize();
        let l = s[0].local(Vec3A::new(1.0, 0.0, 0.5));
        let ns = l.ns.unwrap();
        assert!(
            (ns - Vec3A::new(mid.x, 0.0, mid.y)).length() < 1e-5,
            "{ns:?}"
        );
        let sector = s.iter().find(|k| k.phi0 <= 1.6 && k.phi1 >= 1.6).unwrap();
        let l = sector.local(Vec3A::new(0.0, 1.0, 0.5));
        assert!((l.ns.unwrap() - Vec3A::new(0.0, mid.x, mid.y)).length() < 1e-5);
        // The turn at (1, 1) is 45°: a crease at 30°, smooth at 60°.
        for (crease, smooth) in [(30f32, false), (60.0, true)] {
            let s = strips(&contour, None, crease.to_radians(), TAU as f32).unwrap();
            let at_top = s[0].local(Vec3A::new(1.0, 0.0, 1.0));
            let n = at_top.ns.unwrap_or(at_top.n);
            if smooth {
                let want = Vec3A::new(1.0 + 0.5f32.sqrt(), 0.0, 0.5f32.sqrt()).normalize();
                assert!((n - want).length() < 1e-5, "{n:?}");
            } else {
                assert!((n - Vec3A::X).length() < 1e-6, "{n:?}");
            }
        }
    }
}
