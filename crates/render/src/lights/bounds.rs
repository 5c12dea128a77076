//! What a light, or a cluster of lights, can send where ([`LightBounds`]), and how the
//! light hierarchy weighs it from a shading point: its bounds with what their importance
//! needs computed once ([`Cluster`]), and a node's two children
//! side by side in lanes ([`Pair`]), so that choosing between them is one pass of four-lane
//! operations rather than two computations, each full of square roots, divisions and
//! branches, one after the other.

use crate::simd::F4;
use glam::Vec3A;
use std::f32::consts::PI;

/// What a light, or a cluster of lights, can send where: a box holding the emitters, the
/// cone of their surface normals (axis `w`, half-angle theta_o) and the spread of emission
/// about each normal (theta_e), and their power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightBounds {
    pub lo: Vec3A,
    pub hi: Vec3A,
    pub w: Vec3A,
    /// Power, in the units the lights share (what [`Light::power`] gives or, for lights
    /// with a narrower cone, the power of an isotropic emitter of the same intensity).
    pub phi: f32,
    pub cos_o: f32,
    pub cos_e: f32,
    /// Emits on both sides of the normals.
    pub two_sided: bool,
}

impl LightBounds {
    /// An emitter that may send light in every direction from anywhere in the box.
    pub fn everywhere(lo: Vec3A, hi: Vec3A, phi: f32) -> LightBounds {
        LightBounds {
            lo,
            hi,
            w: Vec3A::Z,
            phi,
            cos_o: -1.0,
            cos_e: 0.0,
            two_sided: false,
        }
    }

    /// A one-sided (or two-sided) diffuse emitter whose normals all lie in the cone about
    /// `n` of half-angle acos(cos_o).
    pub fn diffuse(
        lo: Vec3A,
        hi: Vec3A,
        n: Vec3A,
        cos_o: f32,
        phi: f32,
        two_sided: bool,
    ) -> LightBounds {
        LightBounds {
            lo,
            hi,
            w: n,
            phi,
            cos_o,
            cos_e: 0.0,
            two_sided,
        }
    }

    pub(super) fn union(&self, b: &LightBounds) -> LightBounds {
        if self.phi == 0.0 {
            return *b;
        }
        if b.phi == 0.0 {
            return *self;
        }
        let (w, cos_o) = cone_union((self.w, self.cos_o), (b.w, b.cos_o));
        LightBounds {
            lo: self.lo.min(b.lo),
            hi: self.hi.max(b.hi),
            w,
            phi: self.phi + b.phi,
            cos_o,
            cos_e: self.cos_e.min(b.cos_e),
            two_sided: self.two_sided || b.two_sided,
        }
    }

    pub(super) fn centroid(&self) -> Vec3A {
        0.5 * (self.lo + self.hi)
    }

    /// How much light the emitters could send to a point `p` with normal `n` (zero for a
    /// point in a medium): their power over the squared distance, times the cosine of the
    /// smallest angle any emitter's direction can make with the way to `p` and, at a
    /// surface, the largest cosine its normal can make with the box. Zero only where no
    /// emitter in the bounds can light `p`.
    pub fn importance(&self, p: Vec3A, n: Vec3A) -> f32 {
        Cluster::new(self).importance(p, n)
    }

    /// The surface-area and orientation cost pbrt-v4 splits clusters by: power times the
    /// solid measure of the emission cone times the box's area, times how elongated the
    /// parent box is across the split axis.
    pub(super) fn cost(&self, parent_diag: Vec3A, axis: usize) -> f32 {
        let theta_o = libm::acosf(self.cos_o.clamp(-1.0, 1.0));
        let theta_e = libm::acosf(self.cos_e.clamp(-1.0, 1.0));
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = safe_sqrt(1.0 - self.cos_o * self.cos_o);
        let m_omega = 2.0 * PI * (1.0 - self.cos_o)
            + PI / 2.0
                * (2.0 * theta_w * sin_o
                    - libm::cosf(theta_o - 2.0 * theta_w)
                    - 2.0 * theta_o * sin_o
                    + self.cos_o);
        let kr = if parent_diag[axis] > 0.0 {
            parent_diag.max_element() / parent_diag[axis]
        } else {
            1.0
        };
        let d = self.hi - self.lo;
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        self.phi * m_omega * kr * area
    }
}

/// The smallest cone holding both cones (axis, cosine of the half-angle).
fn cone_union(a: (Vec3A, f32), b: (Vec3A, f32)) -> (Vec3A, f32) {
    let theta_a = libm::acosf(a.1.clamp(-1.0, 1.0));
    let theta_b = libm::acosf(b.1.clamp(-1.0, 1.0));
    let theta_d = libm::acosf(a.0.dot(b.0).clamp(-1.0, 1.0));
    if (theta_d + theta_b).min(PI) <= theta_a {
        return a;
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return b;
    }
    let theta_o = (theta_a + theta_d + theta_b) / 2.0;
    if theta_o >= PI {
        return (Vec3A::Z, -1.0);
    }
    let theta_r = theta_o - theta_a;
    let axis = a.0.cross(b.0);
    if axis.length_squared() == 0.0 {
        return (Vec3A::Z, -1.0);
    }
    let w = glam::Quat::from_axis_angle(axis.normalize().into(), theta_r) * glam::Vec3::from(a.0);
    (Vec3A::from(w).normalize(), libm::cosf(theta_o))
}

/// A [`LightBounds`] with what its importance needs computed once: the centre and squared
/// radius of the box's bounding sphere, the distance clamp, and the sine of the cone.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Cluster {
    center: Vec3A,
    radius2: f32,
    /// pbrt-v4 clamps the squared distance by half the diagonal's length (not squared);
    /// Kiln keeps its choice so that scenes shared with it sample alike.
    min_d2: f32,
    w: Vec3A,
    phi: f32,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    two_sided: bool,
}

impl Cluster {
    pub fn new(b: &LightBounds) -> Cluster {
        let half_diag = (b.hi - b.lo).length() / 2.0;
        Cluster {
            center: b.centroid(),
            radius2: half_diag * half_diag,
            min_d2: half_diag,
            w: b.w,
            phi: b.phi,
            cos_o: b.cos_o,
            sin_o: safe_sqrt(1.0 - b.cos_o * b.cos_o),
            cos_e: b.cos_e,
            two_sided: b.two_sided,
        }
    }

    /// See [`LightBounds::importance`].
    pub fn importance(&self, p: Vec3A, n: Vec3A) -> f32 {
        let d = p - self.center;
        let dist2 = d.length_squared();
        let wi = if dist2 > 0.0 {
            d / dist2.sqrt()
        } else {
            Vec3A::ZERO
        };
        let mut cos_w = self.w.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let sin_w = safe_sqrt(1.0 - cos_w * cos_w);
        // The cone of directions the box's bounding sphere subtends from p.
        let (cos_b, sin_b) = if dist2 < self.radius2 {
            (-1.0, 0.0)
        } else {
            let sin2 = self.radius2 / dist2;
            (safe_sqrt(1.0 - sin2), sin2.sqrt())
        };
        // theta' = max(0, theta_w - theta_o - theta_b), by its sine and cosine.
        let cos_x = cos_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
        let sin_x = sin_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
        let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_p / dist2.max(self.min_d2);
        if n != Vec3A::ZERO {
            let cos_i = n.dot(wi).abs();
            let sin_i = safe_sqrt(1.0 - cos_i * cos_i);
            importance *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
        }
        if importance > 0.0 && importance.is_finite() {
            importance
        } else {
            0.0
        }
    }
}

pub(super) fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// cos(max(0, a - b)) from the sines and cosines of a and b.
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// sin(max(0, a - b)) from the sines and cosines of a and b.
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

/// A node's two children's clusters, field by field: lane 0 the first, lane 1 the second
/// (in four-lane registers whose last two lanes compute on zeros and are dropped). Their importances come from one pass in which each lane
/// runs [`Cluster::importance`]'s IEEE operations in its order, its branches taken as
/// selections, so each is that function's value to the bit (the tests check it on random
/// and adversarial points).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Pair {
    cx: [f32; 2],
    cy: [f32; 2],
    cz: [f32; 2],
    radius2: [f32; 2],
    min_d2: [f32; 2],
    wx: [f32; 2],
    wy: [f32; 2],
    wz: [f32; 2],
    phi: [f32; 2],
    cos_o: [f32; 2],
    sin_o: [f32; 2],
    cos_e: [f32; 2],
    /// All bits set in the lanes of two-sided clusters.
    two_sided: [f32; 2],
}

impl Pair {
    pub fn new(a: &Cluster, b: &Cluster) -> Pair {
        let lanes = |f: &dyn Fn(&Cluster) -> f32| [f(a), f(b)];
        Pair {
            cx: lanes(&|c| c.center.x),
            cy: lanes(&|c| c.center.y),
            cz: lanes(&|c| c.center.z),
            radius2: lanes(&|c| c.radius2),
            min_d2: lanes(&|c| c.min_d2),
            wx: lanes(&|c| c.w.x),
            wy: lanes(&|c| c.w.y),
            wz: lanes(&|c| c.w.z),
            phi: lanes(&|c| c.phi),
            cos_o: lanes(&|c| c.cos_o),
            sin_o: lanes(&|c| c.sin_o),
            cos_e: lanes(&|c| c.cos_e),
            two_sided: lanes(&|c| f32::from_bits(if c.two_sided { u32::MAX } else { 0 })),
        }
    }

    /// The two clusters' importances at `p` (normal `n`, zero in a medium): each
    /// [`Cluster::importance`] to the bit.
    #[inline(always)]
    pub fn importances(&self, p: Vec3A, n: Vec3A) -> (f32, f32) {
        let l = F4::load2;
        let (zero, one) = (F4::splat(0.0), F4::splat(1.0));
        let safe_sqrt = |x: F4| x.max(zero).sqrt();
        let dx = F4::splat(p.x).sub(l(&self.cx));
        let dy = F4::splat(p.y).sub(l(&self.cy));
        let dz = F4::splat(p.z).sub(l(&self.cz));
        // glam's dot: (x x' + y y') + z z'.
        let dist2 = dx.mul(dx).add(dy.mul(dy)).add(dz.mul(dz));
        let len = dist2.sqrt();
        let away = zero.lt_lanes(dist2);
        let wi = [dx, dy, dz].map(|d| away.select(d.div(len), zero));
        let dot = |a: [F4; 3]| a[0].mul(wi[0]).add(a[1].mul(wi[1])).add(a[2].mul(wi[2]));
        let cos_w = dot([l(&self.wx), l(&self.wy), l(&self.wz)]);
        let cos_w = l(&self.two_sided).select(cos_w.abs(), cos_w);
        let sin_w = safe_sqrt(one.sub(cos_w.mul(cos_w)));
        let (radius2, inside) = (l(&self.radius2), dist2.lt_lanes(l(&self.radius2)));
        let sin2 = radius2.div(dist2);
        let cos_b = inside.select(F4::splat(-1.0), safe_sqrt(one.sub(sin2)));
        let sin_b = inside.select(zero, sin2.sqrt());
        let (sin_o, cos_o) = (l(&self.sin_o), l(&self.cos_o));
        let cos_x = cos_sub_clamped_lanes(sin_w, cos_w, sin_o, cos_o);
        let sin_x = cos_o
            .lt_lanes(cos_w)
            .select(zero, sin_w.mul(cos_o).sub(cos_w.mul(sin_o)));
        let cos_p = cos_sub_clamped_lanes(sin_x, cos_x, sin_b, cos_b);
        let dark = cos_p.le_lanes(l(&self.cos_e));
        let min_d2 = l(&self.min_d2);
        // f32::max: a NaN clamp gives the distance (SSE's max would give the NaN).
        let clamped = min_d2.nan_lanes().select(dist2, dist2.max(min_d2));
        let mut importance = l(&self.phi).mul(cos_p).div(clamped);
        if n != Vec3A::ZERO {
            let cos_i = dot([F4::splat(n.x), F4::splat(n.y), F4::splat(n.z)]).abs();
            let sin_i = safe_sqrt(one.sub(cos_i.mul(cos_i)));
            importance = importance.mul(cos_sub_clamped_lanes(sin_i, cos_i, sin_b, cos_b));
        }
        let kept = zero.lt_lanes(importance);
        let finite = importance.abs().lt_lanes(F4::splat(f32::INFINITY));
        let out = dark
            .select(zero, kept.select(finite.select(importance, zero), zero))
            .store();
        (out[0], out[1])
    }
}

/// [`cos_sub_clamped`] in each lane.
#[inline(always)]
fn cos_sub_clamped_lanes(sin_a: F4, cos_a: F4, sin_b: F4, cos_b: F4) -> F4 {
    cos_b
        .lt_lanes(cos_a)
        .select(F4::splat(1.0), cos_a.mul(cos_b).add(sin_a.mul(sin_b)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A number in [0, 1) from a counter (a 32-bit mix).
    fn unit(k: &mut u32) -> f32 {
        *k = k.wrapping_add(0x9e37_79b9);
        let mut h = *k;
        h ^= h >> 16;
        h = h.wrapping_mul(0x85eb_ca6b);
        h ^= h >> 13;
        h = h.wrapping_mul(0xc2b2_ae35);
        h ^= h >> 16;
        (h >> 8) as f32 / (1u32 << 24) as f32
    }

    fn vector(k: &mut u32, scale: f32) -> Vec3A {
        Vec3A::new(unit(k) - 0.5, unit(k) - 0.5, unit(k) - 0.5) * scale
    }

    fn bounds(k: &mut u32) -> LightBounds {
        let lo = vector(k, 8.0);
        // Some boxes are points, some flat, some of zero power or a cone of every way.
        let size = match (unit(k) * 4.0) as u32 {
            0 => Vec3A::ZERO,
            1 => Vec3A::new(unit(k), 0.0, unit(k)),
            _ => Vec3A::new(unit(k), unit(k), unit(k)) * 3.0,
        };
        let w = vector(k, 2.0).try_normalize().unwrap_or(Vec3A::Z);
        let cos = |k: &mut u32| match (unit(k) * 5.0) as u32 {
            0 => 1.0,
            1 => -1.0,
            2 => 0.0,
            _ => unit(k) * 2.0 - 1.0,
        };
        LightBounds {
            lo,
            hi: lo + size,
            w,
            phi: if unit(k) < 0.05 { 0.0 } else { unit(k) * 100.0 },
            cos_o: cos(k),
            cos_e: cos(k),
            two_sided: unit(k) < 0.5,
        }
    }

    fn assert_same(pair: &Pair, a: &Cluster, b: &Cluster, p: Vec3A, n: Vec3A) {
        let (x, y) = pair.importances(p, n);
        let (want_x, want_y) = (a.importance(p, n), b.importance(p, n));
        assert_eq!(
            (x.to_bits(), y.to_bits()),
            (want_x.to_bits(), want_y.to_bits()),
            "at {p} normal {n}: lanes {x} {y}, scalar {want_x} {want_y}\n{a:?}\n{b:?}"
        );
    }

    /// Both lanes give [`Cluster::importance`] to the bit: random clusters and points, and
    /// the points where its branches turn (inside the bounding sphere, at the centre, on
    /// the cone's edge) or its numbers are not finite.
    #[test]
    fn pair_equals_each_cluster_bit_for_bit() {
        let mut k = 7u32;
        let mut nonzero = 0;
        for _ in 0..20_000 {
            let (ba, bb) = (bounds(&mut k), bounds(&mut k));
            let (a, b) = (Cluster::new(&ba), Cluster::new(&bb));
            let pair = Pair::new(&a, &b);
            let normals = [
                Vec3A::ZERO,
                vector(&mut k, 2.0).normalize_or_zero(),
                vector(&mut k, 3.0),
                -a.w,
            ];
            let points = [
                vector(&mut k, 30.0),
                ba.lo + (ba.hi - ba.lo) * unit(&mut k),
                a.center,
                b.center,
                a.center + a.w * a.radius2.sqrt(),
                a.center + a.w * 1e-20,
                Vec3A::new(f32::NAN, 0.0, 1.0),
                Vec3A::new(f32::INFINITY, 2.0, 1.0),
                Vec3A::splat(1e30),
            ];
            for p in points {
                for n in normals {
                    assert_same(&pair, &a, &b, p, n);
                    nonzero += (a.importance(p, n) > 0.0) as u32;
                }
            }
        }
        // The points reach both outcomes.
        assert!(nonzero > 100_000, "{nonzero}");
        // A cluster whose clamp is not a number: f32::max keeps the distance.
        let mut odd = Cluster::new(&LightBounds::everywhere(Vec3A::ZERO, Vec3A::ONE, 10.0));
        odd.min_d2 = f32::NAN;
        let pair = Pair::new(&odd, &odd);
        let far = Vec3A::new(20.0, 1.0, 0.0);
        assert!(odd.importance(far, Vec3A::ZERO) > 0.0);
        assert_same(&pair, &odd, &odd, far, Vec3A::ZERO);
        assert_same(&pair, &odd, &odd, odd.center, Vec3A::X);
    }
}
