//! pbrt-v4's "mix" material: at each intersection, one of two materials, the second with
//! probability `amount`. Which one is a pure function of the point (a hash of its
//! coordinates and of the two materials), as in pbrt-v4: the same bytes on any thread,
//! tile or machine, and a mixture of the two BSDFs in expectation.

use crate::textures::{FloatTexture, TextureEvalContext};
use glam::Vec3A;

#[derive(Debug, Clone)]
pub struct MixMaterial {
    /// Indices of the two materials in the scene's list.
    pub materials: [u32; 2],
    pub amount: FloatTexture,
}

impl MixMaterial {
    /// The material used at the point of `ctx`.
    pub fn choose(&self, ctx: &TextureEvalContext) -> u32 {
        let a = self.amount.evaluate(ctx);
        if a <= 0.0 {
            return self.materials[0];
        }
        if a >= 1.0 {
            return self.materials[1];
        }
        if a < hash(ctx.p, self.materials) {
            self.materials[0]
        } else {
            self.materials[1]
        }
    }
}

/// A number in [0, 1) from a point and two material indices (splitmix64 over their bits).
fn hash(p: Vec3A, materials: [u32; 2]) -> f32 {
    let mut h: u64 = 0x243f_6a88_85a3_08d3;
    let words = [
        p.x.to_bits() as u64,
        p.y.to_bits() as u64,
        p.z.to_bits() as u64,
        ((materials[0] as u64) << 32) | materials[1] as u64,
    ];
    for w in words {
        h ^= w;
        h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
        h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h ^= h >> 31;
    }
    (h >> 40) as f32 / (1u64 << 24) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::textures::Texture;

    #[test]
    fn the_second_material_is_chosen_with_probability_amount() {
        let m = MixMaterial {
            materials: [3, 7],
            amount: Texture::Constant(0.3),
        };
        let n = 100_000;
        let second = (0..n)
            .filter(|&i| {
                let ctx = TextureEvalContext {
                    p: Vec3A::new(i as f32 * 0.013, (i % 97) as f32, 1.0 / (i + 1) as f32),
                    ..Default::default()
                };
                m.choose(&ctx) == 7
            })
            .count();
        let f = second as f64 / n as f64;
        assert!((f - 0.3).abs() < 0.005, "{f}");
    }
}
