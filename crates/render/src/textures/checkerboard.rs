//! pbrt-v4's "checkerboard": two textures alternating over unit cells of (s, t) or of
//! texture space, filtered in closed form: the checker function convolved with a tent as
//! wide as the pixel footprint, so that a plane receding to the horizon fades to the
//! average of its two textures instead of aliasing.

use super::mapping::{Mapping2D, Mapping3D};
use super::{TexValue, Texture, TextureEvalContext, mix};
use kiln_scene::CheckerMapping;

#[derive(Debug, Clone)]
pub enum CheckerSpace {
    Planar(Mapping2D),
    Solid(Mapping3D),
}

#[derive(Debug, Clone)]
pub struct Checkerboard<V> {
    pub space: CheckerSpace,
    /// On cells whose coordinates' floors sum to an even number.
    pub tex1: Texture<V>,
    pub tex2: Texture<V>,
}

impl<V: TexValue> Checkerboard<V> {
    pub fn new(mapping: &CheckerMapping, tex1: Texture<V>, tex2: Texture<V>) -> Self {
        let space = match mapping {
            CheckerMapping::Planar(m) => CheckerSpace::Planar(Mapping2D::from_description(m)),
            CheckerMapping::Solid { texture_from_world } => {
                CheckerSpace::Solid(Mapping3D::new(texture_from_world))
            }
        };
        Checkerboard { space, tex1, tex2 }
    }

    pub fn evaluate(&self, ctx: &TextureEvalContext) -> V {
        let w = self.weight(ctx);
        mix(w, || self.tex1.evaluate(ctx), || self.tex2.evaluate(ctx))
    }

    /// The filtered weight of `tex2`: 0 inside a `tex1` cell, 1 inside a `tex2` cell.
    pub fn weight(&self, ctx: &TextureEvalContext) -> f32 {
        match &self.space {
            CheckerSpace::Planar(m) => {
                let c = m.map(ctx);
                let ds = 1.5 * c.dsdx.abs().max(c.dsdy.abs());
                let dt = 1.5 * c.dtdx.abs().max(c.dtdy.abs());
                0.5 - filtered(c.st.x, ds) * filtered(c.st.y, dt) / 2.0
            }
            CheckerSpace::Solid(m) => {
                let c = m.map(ctx);
                let r = 1.5 * c.dpdx.abs().max(c.dpdy.abs());
                0.5 - filtered(c.p.x, r.x) * filtered(c.p.y, r.y) * filtered(c.p.z, r.z) / 2.0
            }
        }
    }
}

/// The 1D checker function (+1 on [2k, 2k+1), -1 on [2k+1, 2k+2)) averaged under a tent of
/// half-width `r` centred at `x`: exact ±1 when the tent stays inside one cell, otherwise
/// the second difference of the function's second antiderivative.
fn filtered(x: f32, r: f32) -> f32 {
    if (x - r).floor() == (x + r).floor() {
        return 1.0 - 2.0 * ((x.floor() as i64 & 1) as f32);
    }
    // The second antiderivative of the checker function.
    let d = |x: f32| {
        let y = x / 2.0 - (x / 2.0).floor() - 0.5;
        x / 2.0 + y * (1.0 - 2.0 * y.abs())
    };
    (d(x + r) - 2.0 * d(x) + d(x - r)) / (r * r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;
    use kiln_scene::Mapping2D as Desc;

    fn board() -> Checkerboard<f32> {
        let uv = CheckerMapping::Planar(Desc::Uv {
            su: 4.0,
            sv: 4.0,
            du: 0.0,
            dv: 0.0,
        });
        Checkerboard::new(&uv, Texture::Constant(0.9), Texture::Constant(0.1))
    }

    fn at(uv: Vec2, d: f32) -> TextureEvalContext {
        TextureEvalContext {
            uv,
            dudx: d,
            dvdy: d,
            ..Default::default()
        }
    }

    #[test]
    fn cells_alternate_when_the_footprint_is_small() {
        let b = board();
        assert_eq!(b.evaluate(&at(Vec2::new(0.1, 0.1), 0.0)), 0.9);
        assert_eq!(b.evaluate(&at(Vec2::new(0.3, 0.1), 0.0)), 0.1);
        assert_eq!(b.evaluate(&at(Vec2::new(0.3, 0.3), 0.001)), 0.9);
    }

    #[test]
    fn a_wide_footprint_averages_the_two_textures() {
        // The mean of a checkerboard is its two values averaged; so is its heavily filtered value.
        let b = board();
        for uv in [
            Vec2::new(0.13, 0.71),
            Vec2::new(0.5, 0.5),
            Vec2::new(0.01, 0.99),
        ] {
            let v = b.evaluate(&at(uv, 3.0));
            assert!((v - 0.5).abs() < 0.02, "{v} at {uv}");
        }
    }

    #[test]
    fn the_filtered_integral_matches_brute_force() {
        // The closed form against a numerical tent-weighted average of the checker function.
        let checker = |x: f32| if x.floor() as i64 & 1 == 0 { 1.0 } else { -1.0 };
        for (x, r) in [(0.3f32, 0.5f32), (1.7, 0.9), (-2.2, 1.3), (5.05, 0.2)] {
            let n = 20_000;
            let (mut sum, mut wsum) = (0.0f64, 0.0f64);
            for i in 0..n {
                let t = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                let w = 1.0 - t.abs();
                sum += w * checker(x + r * t as f32);
                wsum += w;
            }
            let want = sum / wsum;
            let got = filtered(x, r) as f64;
            assert!((got - want).abs() < 1e-3, "x {x} r {r}: {got} vs {want}");
        }
    }
}
