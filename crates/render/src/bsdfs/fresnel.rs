//! Fresnel reflectance of dielectric and conductor interfaces, and refraction.

use crate::math::Color;
use glam::Vec3A;

/// Refracts `wi` through a surface with normal `n` and relative IOR `eta`; returns (wt, eta actually crossed).
pub fn refract(wi: Vec3A, mut n: Vec3A, mut eta: f32) -> Option<(Vec3A, f32)> {
    let mut cos_i = n.dot(wi);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

/// Unpolarised Fresnel reflectance of a dielectric interface.
pub fn fresnel_dielectric(cos_i: f32, mut eta: f32) -> f32 {
    let mut cos_i = cos_i.clamp(-1.0, 1.0);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_parl * r_parl + r_perp * r_perp) / 2.0
}

#[derive(Debug, Clone, Copy)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    fn new(re: f32, im: f32) -> Complex {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn div(self, o: Complex) -> Complex {
        let d = o.re * o.re + o.im * o.im;
        Complex::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex::new(t1, t2)
        } else {
            Complex::new(t2.abs(), t1.copysign(self.im))
        }
    }
}

/// Fresnel reflectance of a conductor with complex IOR eta + i k, one channel.
fn fresnel_complex_1(cos_i: f32, eta: f32, k: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let eta = Complex::new(eta, k);
    let sin2_i = Complex::new(1.0 - cos_i * cos_i, 0.0);
    let sin2_t = sin2_i.div(eta.mul(eta));
    let cos_t = Complex::new(1.0, 0.0).sub(sin2_t).sqrt();
    let ci = Complex::new(cos_i, 0.0);
    let r_parl = eta.mul(ci).sub(cos_t).div(eta.mul(ci).add(cos_t));
    let r_perp = ci.sub(eta.mul(cos_t)).div(ci.add(eta.mul(cos_t)));
    (r_parl.norm() + r_perp.norm()) / 2.0
}

/// A conductor's Fresnel reflectance tabulated in RGB over cos θ from 0 to 1 (evenly
/// spaced), from its spectral eta and k (`kiln_scene::spectrum::conductor_fresnel_rgb`):
/// what the spectral reflectance looks like, where the Fresnel of RGB eta and k misses it.
#[derive(Debug, Clone)]
pub struct FresnelTable(Vec<Color>);

impl FresnelTable {
    /// From at least two entries.
    pub fn new(rgb: &[[f32; 3]]) -> FresnelTable {
        assert!(rgb.len() >= 2, "a Fresnel table needs two entries");
        FresnelTable(rgb.iter().map(|c| crate::math::rgb(*c)).collect())
    }

    /// The reflectance at `cos_i`, linearly interpolated.
    pub fn eval(&self, cos_i: f32) -> Color {
        let x = cos_i.clamp(0.0, 1.0) * (self.0.len() - 1) as f32;
        let i = (x as usize).min(self.0.len() - 2);
        let t = x - i as f32;
        self.0[i] * (1.0 - t) + self.0[i + 1] * t
    }
}

/// The Fresnel reflectance of each lane's complex index. An RGB colour's fourth lane (a copy
/// of the second) is copied, not computed again; a spectral lane equal to the second has the
/// same value anyway.
pub fn fresnel_complex(cos_i: f32, eta: Color, k: Color) -> Color {
    let y = fresnel_complex_1(cos_i, eta.y, k.y);
    let w = if eta.w == eta.y && k.w == k.y {
        y
    } else {
        fresnel_complex_1(cos_i, eta.w, k.w)
    };
    Color::new(
        fresnel_complex_1(cos_i, eta.x, k.x),
        y,
        fresnel_complex_1(cos_i, eta.z, k.z),
        w,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-4);
        assert_eq!(fresnel_dielectric(0.1, 1.0 / 1.5), 1.0);
        let f = fresnel_complex(1.0, Color::splat(1.5), Color::splat(0.0));
        assert!((f.x - 0.04).abs() < 1e-4);
    }
}
