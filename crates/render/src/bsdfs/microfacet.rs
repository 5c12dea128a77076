//! The anisotropic Trowbridge-Reitz (GGX) microfacet distribution, sampled by visible normals.

use glam::{Vec2, Vec3A};
use std::f32::consts::PI;

/// The anisotropic Trowbridge-Reitz (GGX) microfacet distribution.
#[derive(Debug, Clone, Copy)]
pub struct TrowbridgeReitz {
    pub alpha_x: f32,
    pub alpha_y: f32,
}

impl TrowbridgeReitz {
    pub fn new(alpha_x: f32, alpha_y: f32) -> TrowbridgeReitz {
        let mut d = TrowbridgeReitz { alpha_x, alpha_y };
        if !d.effectively_smooth() {
            // Very small alphas make D numerically unusable; pbrt clamps the same way.
            d.alpha_x = d.alpha_x.max(1e-4);
            d.alpha_y = d.alpha_y.max(1e-4);
        }
        d
    }

    /// pbrt-v4's regularisation: an alpha under 0.3 doubles, within [0.1, 0.3].
    pub fn regularize(&mut self) {
        for a in [&mut self.alpha_x, &mut self.alpha_y] {
            if *a < 0.3 {
                *a = (2.0 * *a).clamp(0.1, 0.3);
            }
        }
    }

    pub fn effectively_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < 1e-3
    }

    pub fn d(&self, wm: Vec3A) -> f32 {
        let cos2 = wm.z * wm.z;
        let sin2 = (1.0 - cos2).max(0.0);
        let tan2 = sin2 / cos2;
        if !tan2.is_finite() {
            return 0.0;
        }
        let cos4 = cos2 * cos2;
        if cos4 < 1e-16 {
            return 0.0;
        }
        let (cos2_phi, sin2_phi) = if sin2 > 0.0 {
            (wm.x * wm.x / sin2, wm.y * wm.y / sin2)
        } else {
            (1.0, 0.0)
        };
        let e = tan2
            * (cos2_phi / (self.alpha_x * self.alpha_x) + sin2_phi / (self.alpha_y * self.alpha_y));
        1.0 / (PI * self.alpha_x * self.alpha_y * cos4 * (1.0 + e) * (1.0 + e))
    }

    fn lambda(&self, w: Vec3A) -> f32 {
        let cos2 = w.z * w.z;
        let sin2 = (1.0 - cos2).max(0.0);
        let tan2 = sin2 / cos2;
        if !tan2.is_finite() {
            return 0.0;
        }
        let (cos2_phi, sin2_phi) = if sin2 > 0.0 {
            (w.x * w.x / sin2, w.y * w.y / sin2)
        } else {
            (1.0, 0.0)
        };
        let alpha2 =
            self.alpha_x * self.alpha_x * cos2_phi + self.alpha_y * self.alpha_y * sin2_phi;
        ((1.0 + alpha2 * tan2).sqrt() - 1.0) / 2.0
    }

    pub fn g1(&self, w: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    pub fn g(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals from direction `w`.
    pub fn pdf(&self, w: Vec3A, wm: Vec3A) -> f32 {
        if w.z == 0.0 {
            return 0.0;
        }
        self.g1(w) / w.z.abs() * self.d(wm) * w.dot(wm).abs()
    }

    /// Samples a visible normal (Heitz 2018).
    pub fn sample_wm(&self, w: Vec3A, u: Vec2) -> Vec3A {
        let mut wh = Vec3A::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            Vec3A::Z.cross(wh).normalize()
        } else {
            Vec3A::X
        };
        let t2 = wh.cross(t1);
        let r = u.x.sqrt();
        let theta = 2.0 * PI * u.y;
        let mut p = Vec2::new(r * libm::cosf(theta), r * libm::sinf(theta));
        let h = (1.0 - p.x * p.x).max(0.0).sqrt();
        let s = (1.0 + wh.z) / 2.0;
        p.y = (1.0 - s) * h + s * p.y;
        let pz = (1.0 - p.length_squared()).max(0.0).sqrt();
        let nh = p.x * t1 + p.y * t2 + pz * wh;
        Vec3A::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-6)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pbrt-v4's rule: an alpha under 0.3 doubles, held within [0.1, 0.3]; 0.3 and above
    /// stay; a smooth lobe becomes glossy.
    #[test]
    fn regularize_doubles_small_alphas_within_bounds() {
        let mut d = TrowbridgeReitz::new(0.0, 0.0);
        assert!(d.effectively_smooth());
        d.regularize();
        assert_eq!((d.alpha_x, d.alpha_y), (0.1, 0.1));
        assert!(!d.effectively_smooth());
        let mut d = TrowbridgeReitz::new(0.12, 0.2);
        d.regularize();
        assert_eq!((d.alpha_x, d.alpha_y), (0.24, 0.3));
        let mut d = TrowbridgeReitz::new(0.05, 0.5);
        d.regularize();
        assert_eq!((d.alpha_x, d.alpha_y), (0.1, 0.5));
    }
}
