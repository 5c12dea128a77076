//! pbrt-v4's "dots": polka dots of radius 0.35 in some unit cells of (s, t), placed and
//! kept by Perlin noise. Not filtered (pbrt-v4 does not filter it either).

use super::mapping::Mapping2D;
use super::noise::noise2;
use super::{TexValue, Texture, TextureEvalContext};

#[derive(Debug, Clone)]
pub struct Dots<V> {
    pub mapping: Mapping2D,
    /// The value inside a dot.
    pub in_dot: Texture<V>,
    /// The value between dots.
    pub between: Texture<V>,
}

impl<V: TexValue> Dots<V> {
    /// The texture of a scene's `inside` and `outside` parameters. pbrt-v4 hands them to its
    /// texture swapped, so that a point inside a dot shows `outside`; scenes were made
    /// looking at that, and Kiln draws them the same.
    pub fn new(mapping: &kiln_scene::Mapping2D, inside: Texture<V>, outside: Texture<V>) -> Self {
        Dots {
            mapping: Mapping2D::from_description(mapping),
            in_dot: outside,
            between: inside,
        }
    }

    pub fn evaluate(&self, ctx: &TextureEvalContext) -> V {
        let st = self.mapping.map(ctx).st;
        if in_dot(st.x, st.y) {
            self.in_dot.evaluate(ctx)
        } else {
            self.between.evaluate(ctx)
        }
    }
}

fn in_dot(s: f32, t: f32) -> bool {
    let (sc, tc) = ((s + 0.5).floor(), (t + 0.5).floor());
    if noise2(sc + 0.5, tc + 0.5) <= 0.0 {
        return false;
    }
    const RADIUS: f32 = 0.35;
    let max_shift = 0.5 - RADIUS;
    let cs = sc + max_shift * noise2(sc + 1.5, tc + 2.8);
    let ct = tc + max_shift * noise2(sc + 4.5, tc + 9.8);
    (s - cs) * (s - cs) + (t - ct) * (t - ct) < RADIUS * RADIUS
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn dots_cover_some_cells_and_are_round() {
        let mut cells_with_dots = 0;
        let mut covered = 0usize;
        let n = 40;
        for ci in 0..n {
            for cj in 0..n {
                let (s0, t0) = (ci as f32, cj as f32);
                let mut inside = 0;
                for i in 0..10 {
                    for j in 0..10 {
                        let s = s0 - 0.5 + (i as f32 + 0.5) / 10.0;
                        let t = t0 - 0.5 + (j as f32 + 0.5) / 10.0;
                        inside += in_dot(s, t) as usize;
                    }
                }
                if inside > 0 {
                    cells_with_dots += 1;
                    // A dot of radius 0.35 covers π·0.35² ≈ 38% of its cell.
                    assert!((25..=50).contains(&inside), "{inside} at {ci},{cj}");
                    covered += inside;
                }
            }
        }
        assert!(cells_with_dots > n * n / 5 && cells_with_dots < n * n * 4 / 5);
        let _ = covered;
        let d = Dots::new(
            &kiln_scene::Mapping2D::Uv {
                su: 1.0,
                sv: 1.0,
                du: 0.0,
                dv: 0.0,
            },
            Texture::Constant(1.0f32),
            Texture::Constant(0.0f32),
        );
        let ctx = TextureEvalContext {
            uv: Vec2::new(0.5, 0.5),
            ..Default::default()
        };
        let v = d.evaluate(&ctx);
        assert!(v == 0.0 || v == 1.0);
    }
}
