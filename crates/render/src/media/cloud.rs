//! pbrt-v4's "cloud" medium density: fractal Perlin noise whose lookup is perturbed by the
//! noise's own gradient (wisps), thinning with height, in [0, 1].

use crate::textures::noise::noise;
use glam::Vec3A;

#[derive(Debug, Clone, Copy)]
pub struct Cloud {
    pub density: f32,
    pub wispiness: f32,
    pub frequency: f32,
}

/// The gradient of the noise by forward differences of 0.01, as pbrt-v4's `DNoise`.
fn dnoise(p: Vec3A) -> Vec3A {
    let delta = 0.01;
    let n = noise(p);
    Vec3A::new(
        noise(p + Vec3A::new(delta, 0.0, 0.0)),
        noise(p + Vec3A::new(0.0, delta, 0.0)),
        noise(p + Vec3A::new(0.0, 0.0, delta)),
    )
    .map(|v| (v - n) / delta)
}

impl Cloud {
    /// The density at `p` in the medium's own space (not its box).
    pub fn density_at(&self, p: Vec3A) -> f32 {
        let mut pp = self.frequency * p;
        if self.wispiness > 0.0 {
            let (mut omega, mut lambda) = (0.05 * self.wispiness, 10.0);
            for _ in 0..2 {
                pp += omega * dnoise(lambda * pp);
                omega *= 0.5;
                lambda *= 1.99;
            }
        }
        let mut d = 0.0;
        let (mut omega, mut lambda) = (0.5, 1.0);
        for _ in 0..5 {
            d += omega * noise(lambda * pp);
            omega *= 0.5;
            lambda *= 1.99;
        }
        let d = ((1.0 - p.y) * 4.5 * self.density * d).clamp(0.0, 1.0) + 2.0 * (0.5 - p.y).max(0.0);
        d.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense at the bottom, clear at the top, in [0, 1] everywhere, and varying between.
    #[test]
    fn cloud_density_thins_with_height() {
        let cloud = Cloud {
            density: 1.0,
            wispiness: 1.0,
            frequency: 5.0,
        };
        let mut values = Vec::new();
        for i in 0..400 {
            let p = Vec3A::new((i % 20) as f32 / 20.0, (i / 20) as f32 / 20.0, 0.37);
            let d = cloud.density_at(p);
            assert!((0.0..=1.0).contains(&d), "{d} at {p}");
            values.push((p.y, d));
        }
        // Below y = 0 the height term alone fills it; at y = 1 the noise term vanishes.
        assert_eq!(cloud.density_at(Vec3A::new(0.3, -0.1, 0.2)), 1.0);
        assert_eq!(cloud.density_at(Vec3A::new(0.3, 1.0, 0.2)), 0.0);
        let band = |lo: f32, hi: f32| {
            let v: Vec<f32> = values
                .iter()
                .filter(|(y, _)| *y >= lo && *y < hi)
                .map(|v| v.1)
                .collect();
            v.iter().sum::<f32>() / v.len() as f32
        };
        assert!(
            band(0.0, 0.3) > band(0.6, 0.95),
            "{} {}",
            band(0.0, 0.3),
            band(0.6, 0.95)
        );
        let mid: Vec<f32> = values
            .iter()
            .filter(|(y, _)| *y > 0.5 && *y < 0.8)
            .map(|v| v.1)
            .collect();
        assert!(
            mid.iter().any(|&d| d > 0.05) && mid.iter().any(|&d| d < 0.05),
            "{mid:?}"
        );
    }
}
