//! Feature buffers: what a denoiser reads beside each pixel's radiance, kept in every render.
//!
//! Each camera sample notes its path's first non-specular vertex, seen through any mirrors
//! and glass on the way as denoisers expect (Intel Open Image Denoise's convention): that
//! vertex's reflectance (times what the specular bounces before it passed, at most 1), its
//! shading normal turned toward the path, and how far the path travelled to reach it. A
//! path that met no such vertex (it left the scene, reached a light, or ended among
//! specular surfaces) notes white, no normal and no depth. A pixel sums its samples' notes
//! by filter weight in sample order, as it sums its radiance ([`FeatureSums::add`]), so the
//! features are the same bytes for any tiling, thread count, pass split or worker; and with
//! the sums of squares of its radiance it gives the variance of its own value
//! (the sums'). The film module places these channels among a pixel's further ones.

use crate::math::Color;
use glam::Vec3A;

/// What one camera sample's path saw at its first non-specular vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feature {
    pub albedo: Color,
    /// The shading normal, facing where the path came from (zero: no surface).
    pub normal: Vec3A,
    /// The path's length to the vertex (zero: none).
    pub depth: f32,
}

impl Feature {
    /// What a path that met no non-specular vertex notes.
    pub const NOTHING: Feature = Feature {
        albedo: Color::ONE,
        normal: Vec3A::ZERO,
        depth: 0.0,
    };
}

/// The feature channels' names, sorted (as images hold them).
pub const FEATURE_CHANNELS: [&str; 10] = [
    "features.albedo.B",
    "features.albedo.G",
    "features.albedo.R",
    "features.depth",
    "features.normal.X",
    "features.normal.Y",
    "features.normal.Z",
    "features.variance.B",
    "features.variance.G",
    "features.variance.R",
];

/// One pixel's feature sums, filter-weighted in sample order. Kept in f32: features need
/// no more, and a farm's passes carry them (7 words a pixel rather than 14).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FeatureSums {
    pub albedo: [f32; 3],
    pub normal: [f32; 3],
    pub depth: f32,
}

impl FeatureSums {
    /// The 32-bit words [`FeatureSums::to_words`] gives.
    pub const WORDS: usize = 7;

    /// Adds a sample's feature with filter weight `w`.
    pub fn add(&mut self, f: &Feature, w: f32) {
        for c in 0..3 {
            self.albedo[c] += f.albedo[c] * w;
            self.normal[c] += f.normal[c] * w;
        }
        self.depth += f.depth * w;
    }

    /// Every sum, bit for bit.
    pub fn to_words(&self) -> [u32; Self::WORDS] {
        let [a, b, c] = self.albedo.map(f32::to_bits);
        let [x, y, z] = self.normal.map(f32::to_bits);
        [a, b, c, x, y, z, self.depth.to_bits()]
    }

    /// The sums [`FeatureSums::to_words`] gave these words for.
    pub fn from_words(w: &[u32]) -> FeatureSums {
        let f = |i: usize| f32::from_bits(w[i]);
        FeatureSums {
            albedo: [f(0), f(1), f(2)],
            normal: [f(3), f(4), f(5)],
            depth: f(6),
        }
    }
}

/// A pixel's feature channels, in [`FEATURE_CHANNELS`]' order, from its feature sums, the
/// sum of its samples' filter weights and the variance of its value
/// (the sums' `PixelSums::value_variance`): albedo and depth over the weight, the normal
/// normalised.
pub fn finish(f: &FeatureSums, weight: f64, variance: [f32; 3]) -> [f32; FEATURE_CHANNELS.len()] {
    let over = |v: f32| {
        if weight != 0.0 {
            (v as f64 / weight) as f32
        } else {
            0.0
        }
    };
    let len = f.normal.iter().map(|v| v * v).sum::<f32>().sqrt();
    let unit = |v: f32| if len > 0.0 { v / len } else { 0.0 };
    [
        over(f.albedo[2]),
        over(f.albedo[1]),
        over(f.albedo[0]),
        over(f.depth),
        unit(f.normal[0]),
        unit(f.normal[1]),
        unit(f.normal[2]),
        variance[2],
        variance[1],
        variance[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feature_channels_are_sorted() {
        let mut sorted = FEATURE_CHANNELS;
        sorted.sort();
        assert_eq!(sorted, FEATURE_CHANNELS);
    }
}
