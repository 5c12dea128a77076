//! pbrt-v4's bilinear patch: the surface P(u, v) = lerp(u, lerp(v, p00, p01), lerp(v, p10, p11))
//! over the unit square, for the non-planar quads of `bilinearmesh` and `plymesh` (planar
//! ones stay two triangles, which are the same surface). Intersected as pbrt-v4 does (a
//! quadratic in u for the iso-line the ray meets, then v and t by determinants), sampled
//! by pbrt-v4's bilinear warp of the corners' area densities. [`super::quadric`] carries it
//! with the other shapes intersected in their own right; its object space is the world's.

use super::local::LocalPoint;
use crate::math::solve_quadratic;
use glam::{DVec3, Vec2, Vec3A};

#[derive(Debug, Clone, PartialEq)]
pub struct BilinearPatch {
    /// p00, p10, p01, p11.
    pub p: [Vec3A; 4],
    /// Per-corner shading normals, in the same order.
    pub n: Option<[Vec3A; 4]>,
    /// Per-corner texture coordinates, in the same order.
    pub uv: Option<[Vec2; 4]>,
    area: f32,
    /// The corners' area densities |dp/du x dp/dv|: the weights of the bilinear warp.
    weights: [f32; 4],
}

fn lerp3(t: f64, a: DVec3, b: DVec3) -> DVec3 {
    a + (b - a) * t
}

/// x in [0, 1] distributed in proportion to the line from a (at 0) to b (at 1).
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    if u == 0.0 && a == 0.0 {
        return 0.0;
    }
    let x = u * (a + b) / (a + (a * a + u * (b * b - a * a)).max(0.0).sqrt());
    x.min(1.0 - f32::EPSILON / 2.0)
}

impl BilinearPatch {
    pub fn new(p: [Vec3A; 4], n: Option<[Vec3A; 4]>, uv: Option<[Vec2; 4]>) -> BilinearPatch {
        let mut patch = BilinearPatch {
            p,
            n,
            uv,
            area: 0.0,
            weights: [0.0; 4],
        };
        patch.weights = [
            patch.jacobian(0.0, 0.0),
            patch.jacobian(1.0, 0.0),
            patch.jacobian(0.0, 1.0),
            patch.jacobian(1.0, 1.0),
        ];
        // The area by a fixed 32 x 32 midpoint rule (the same on every machine).
        let k = 32;
        let mut sum = 0.0f64;
        for i in 0..k {
            for j in 0..k {
                let (u, v) = ((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                sum += f64::from(patch.jacobian(u, v));
            }
        }
        patch.area = (sum / f64::from(k * k)) as f32;
        patch
    }

    /// Whether the four corners lie in one plane, up to `tolerance` of the patch's size: such
    /// a quad is two triangles.
    pub fn is_planar(p: [Vec3A; 4], tolerance: f32) -> bool {
        let [p00, p10, p01, p11] = p;
        let n = (p10 - p00).cross(p01 - p00) + (p11 - p10).cross(p11 - p01);
        let size = (p11 - p00).length().max((p10 - p01).length());
        if n.length_squared() == 0.0 || size == 0.0 {
            return true;
        }
        let n = n.normalize();
        [p10, p01, p11]
            .iter()
            .all(|q| (*q - p00).dot(n).abs() <= tolerance * size)
    }

    fn corners(&self) -> [DVec3; 4] {
        self.p.map(|c| DVec3::from(c.to_array().map(f64::from)))
    }

    fn point(&self, u: f32, v: f32) -> Vec3A {
        let [p00, p10, p01, p11] = self.p;
        let a = p00.lerp(p01, v);
        let b = p10.lerp(p11, v);
        a.lerp(b, u)
    }

    fn derivatives(&self, u: f32, v: f32) -> (Vec3A, Vec3A) {
        let [p00, p10, p01, p11] = self.p;
        (
            p10.lerp(p11, v) - p00.lerp(p01, v),
            p01.lerp(p11, u) - p00.lerp(p10, u),
        )
    }

    /// |dp/du x dp/dv|: world area per unit of (u, v).
    fn jacobian(&self, u: f32, v: f32) -> f32 {
        let (du, dv) = self.derivatives(u, v);
        du.cross(dv).length()
    }

    /// The ray parameter of the hit in (tmin, tmax), or infinity (pbrt-v4's
    /// IntersectBilinearPatch, in f64).
    pub fn intersect(&self, o: DVec3, d: DVec3, tmin: f64, tmax: f64) -> f64 {
        let [p00, p10, p01, p11] = self.corners();
        let a = (p10 - p00).cross(p01 - p11).dot(d);
        let c = (p00 - o).cross(d).dot(p01 - p00);
        let b = (p10 - o).cross(d).dot(p11 - p10) - (a + c);
        let (u1, u2) = if a == 0.0 {
            if b == 0.0 {
                return f64::INFINITY;
            }
            (-c / b, -c / b)
        } else {
            match solve_quadratic(a, b, c, b * b - 4.0 * a * c) {
                Some(roots) => roots,
                None => return f64::INFINITY,
            }
        };
        let mut best = f64::INFINITY;
        for (k, u) in [u1, u2].into_iter().enumerate() {
            if !(0.0..=1.0).contains(&u) || (k == 1 && u == u1) {
                continue;
            }
            let uo = lerp3(u, p00, p10);
            let ud = lerp3(u, p01, p11) - uo;
            let deltao = uo - o;
            let perp = d.cross(ud);
            let p2 = perp.length_squared();
            if p2 == 0.0 {
                continue;
            }
            let v = deltao.dot(d.cross(perp));
            let t = deltao.dot(ud.cross(perp));
            if (0.0..=p2).contains(&v) {
                let t = t / p2;
                if t > tmin && t < tmax && t < best {
                    best = t;
                }
            }
        }
        best
    }

    /// The patch parameters (u, v) of the point of the patch nearest `p` (Newton steps on
    /// the least-squares distance, from the middle).
    fn params_of(&self, p: Vec3A) -> (f32, f32) {
        let [p00, p10, p01, p11] = self.corners();
        let target = DVec3::from(p.to_array().map(f64::from));
        let (mut u, mut v) = (0.5f64, 0.5f64);
        for _ in 0..12 {
            let q = lerp3(u, lerp3(v, p00, p01), lerp3(v, p10, p11));
            let du = lerp3(v, p10, p11) - lerp3(v, p00, p01);
            let dv = lerp3(u, p01, p11) - lerp3(u, p00, p10);
            let r = target - q;
            let (a, b, c) = (du.dot(du), du.dot(dv), dv.dot(dv));
            let det = a * c - b * b;
            if det.abs() < 1e-300 {
                break;
            }
            let (ru, rv) = (du.dot(r), dv.dot(r));
            let (su, sv) = ((c * ru - b * rv) / det, (a * rv - b * ru) / det);
            u = (u + su).clamp(0.0, 1.0);
            v = (v + sv).clamp(0.0, 1.0);
            if su.abs() + sv.abs() < 1e-12 {
                break;
            }
        }
        (u as f32, v as f32)
    }

    /// The surface at (the point nearest) `p`, as pbrt-v4's bilinear patch interaction
    /// gives it: dp/du and dp/dv, re-expressed in the texture coordinates when the mesh has
    /// them (keeping the orientation), the normal cross(dp/du, dp/dv), and the shading
    /// normal interpolated from the corners'.
    pub fn local(&self, p: Vec3A) -> LocalPoint {
        let (u, v) = self.params_of(p);
        let (mut dpdu, mut dpdv) = self.derivatives(u, v);
        let mut st = Vec2::new(u, v);
        if let Some([uv00, uv10, uv01, uv11]) = self.uv {
            st = uv00.lerp(uv01, v).lerp(uv10.lerp(uv11, v), u);
            let dstdu = uv10.lerp(uv11, v) - uv00.lerp(uv01, v);
            let dstdv = uv01.lerp(uv11, u) - uv00.lerp(uv10, u);
            let inv = |x: f32| if x.abs() < 1e-8 { 0.0 } else { 1.0 / x };
            let (duds, dudt) = (inv(dstdu.x), inv(dstdu.y));
            let (dvds, dvdt) = (inv(dstdv.x), inv(dstdv.y));
            let dpds = dpdu * duds + dpdv * dvds;
            let mut dpdt = dpdu * dudt + dpdv * dvdt;
            if dpds.cross(dpdt) != Vec3A::ZERO {
                if dpdu.cross(dpdv).dot(dpds.cross(dpdt)) < 0.0 {
                    dpdt = -dpdt;
                }
                dpdu = dpds;
                dpdv = dpdt;
            }
        }
        // cross(dp/du, dp/dv); the quadric flips it as the mesh's orientation says and
        // turns it to the shading normal's side.
        let mut n = dpdu.cross(dpdv).normalize_or_zero();
        if n == Vec3A::ZERO {
            let (du, dv) = self.derivatives(u, v);
            n = du.cross(dv).normalize_or(Vec3A::Z);
        }
        let ns = self.n.and_then(|[n00, n10, n01, n11]| {
            let s = n00
                .lerp(n01, v)
                .lerp(n10.lerp(n11, v), u)
                .normalize_or_zero();
            (s != Vec3A::ZERO).then_some(s)
        });
        let j = self.jacobian(u, v);
        LocalPoint {
            p: self.point(u, v),
            n,
            ns,
            dpdu,
            dpdv,
            uv: st,
            pdf: if j > 0.0 {
                self.param_pdf(u, v) / j
            } else {
                0.0
            },
        }
    }

    /// The density of (u, v) under [`BilinearPatch::sample`].
    fn param_pdf(&self, u: f32, v: f32) -> f32 {
        let w = self.weights;
        let total = w.iter().sum::<f32>();
        if total == 0.0 {
            return 1.0;
        }
        4.0 * ((1.0 - u) * (1.0 - v) * w[0]
            + u * (1.0 - v) * w[1]
            + (1.0 - u) * v * w[2]
            + u * v * w[3])
            / total
    }

    /// A point on the patch, its (u, v) drawn by the bilinear warp of the corners' area
    /// densities (nearly uniform by area); its density per unit area is [`LocalPoint::pdf`].
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let w = self.weights;
        let v = sample_linear(u.y, w[0] + w[1], w[2] + w[3]);
        let s = sample_linear(u.x, w[0] + (w[2] - w[0]) * v, w[1] + (w[3] - w[1]) * v);
        self.point(s, v)
    }

    pub fn area(&self) -> f32 {
        self.area
    }

    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        let [a, b, c, d] = self.p;
        (a.min(b).min(c).min(d), a.max(b).max(c).max(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn saddle() -> BilinearPatch {
        BilinearPatch::new(
            [
                Vec3A::new(0.0, 0.0, 0.0),
                Vec3A::new(1.0, 0.0, 0.5),
                Vec3A::new(0.0, 1.0, 0.5),
                Vec3A::new(1.0, 1.2, 0.0),
            ],
            None,
            None,
        )
    }

    /// Rays aimed at points of the surface hit them, at the distance aimed at, and the hit's
    /// parameters give the point back.
    #[test]
    fn rays_hit_the_saddle_where_aimed() {
        let patch = saddle();
        assert!(!BilinearPatch::is_planar(patch.p, 1e-4));
        for i in 0..50 {
            let (u, v) = (
                (i % 7) as f32 / 6.0 * 0.98 + 0.01,
                (i / 7) as f32 / 7.0 * 0.98 + 0.01,
            );
            let target = patch.point(u, v);
            let o = Vec3A::new(0.3 + 0.01 * i as f32, -0.4, 3.0);
            let d = (target - o).normalize();
            let t = patch.intersect(
                DVec3::from(o.to_array().map(f64::from)),
                DVec3::from(d.to_array().map(f64::from)),
                0.0,
                100.0,
            );
            let hit = o + d * t as f32;
            assert!(
                hit.distance(target) < 2e-4 || t < (target - o).length() as f64 - 1e-4,
                "{i}: {hit} vs {target}"
            );
            let l = patch.local(target);
            assert!(l.p.distance(target) < 1e-5, "{} vs {target}", l.p);
            assert!((l.uv - Vec2::new(u, v)).length() < 1e-4);
        }
    }

    /// The sampling density integrates to 1 over the patch, and the samples' mean position
    /// is the area-weighted centroid.
    #[test]
    fn sampling_density_is_normalised() {
        let patch = saddle();
        let k = 64;
        let (mut total, mut mean, mut centroid) = (0.0f64, Vec3A::ZERO, Vec3A::ZERO);
        for i in 0..k {
            for j in 0..k {
                let u = Vec2::new((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                let q = patch.sample(u);
                let l = patch.local(q);
                // E[1 / pdf] over the samples is the area.
                total += 1.0 / f64::from(l.pdf);
                mean += q;
                let (du, dv) = patch.derivatives(u.x, u.y);
                centroid += patch.point(u.x, u.y) * du.cross(dv).length();
            }
        }
        let n = (k * k) as f32;
        let area = total / f64::from(n);
        assert!(
            (area / f64::from(patch.area()) - 1.0).abs() < 2e-3,
            "{area} vs {}",
            patch.area()
        );
        let centroid = centroid / n / patch.area();
        // Sampling by the bilinear warp is nearly uniform by area.
        assert!(
            (mean / n).distance(centroid) < 0.02,
            "{} vs {centroid}",
            mean / n
        );
    }
}
