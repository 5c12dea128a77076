//! Textures: values that vary over a surface, evaluated where a ray hits it, with pbrt-v4's
//! kinds and semantics.
//!
//! Materials hold their parameters as a [`FloatTexture`] or a [`SpectrumTexture`] and
//! evaluate them at each hit through a [`TextureEvalContext`], which carries the hit's
//! surface coordinates and its footprint (how far the point and (u, v) move from one pixel
//! to the next) so that image lookups can filter. A texture is a constant held inline, or a
//! node shared by every texture and material that refers to it; nodes refer to the textures
//! defined before them, so the graph has no cycles. Each kind lives in its own file:
//! [`mapping`] (uv, spherical, cylindrical, planar, solid), [`checkerboard`], [`dots`],
//! [`noise`] (Perlin noise, fBm, turbulence and the fbm, wrinkled, windy and marble
//! textures), [`image`] and [`mipmap`].
//!
//! Evaluating a texture never allocates. Textures know nothing of materials, lights or
//! integrators.

pub mod checkerboard;
pub mod dots;
pub mod image;
pub mod mapping;
pub mod mipmap;
pub mod noise;

use crate::math::{Color, rgb};
use crate::spectral::Wavelengths;
use glam::{Vec2, Vec3A};
use kiln_scene::{
    FloatTextureDesc, FloatValue, RgbValue, SpectrumTextureDesc, TextureDesc, TextureKind,
};
use std::ops::{Add, Mul};
use std::sync::Arc;

pub use checkerboard::Checkerboard;
pub use dots::Dots;
pub use image::ImageTexture;
pub use mapping::{Mapping2D, Mapping3D};
pub use noise::{Fbm, Marble, Windy, Wrinkled};

/// Where a texture is evaluated: the hit point, its geometric normal, its surface
/// coordinates and how they change from one pixel to the next (x and y on the film).
#[derive(Debug, Clone, Copy, Default)]
pub struct TextureEvalContext {
    pub p: Vec3A,
    pub n: Vec3A,
    pub uv: Vec2,
    pub dpdx: Vec3A,
    pub dpdy: Vec3A,
    pub dudx: f32,
    pub dudy: f32,
    pub dvdx: f32,
    pub dvdy: f32,
    /// The path's wavelengths in spectral mode (None: RGB), which colours become spectra at.
    pub waves: Option<Wavelengths>,
}

impl TextureEvalContext {
    /// The context at a point with surface derivatives `dpdu`, `dpdv`, whose footprint on
    /// the surface is `dpdx`, `dpdy`: (u, v)'s derivatives by least squares, as pbrt-v4's
    /// `ComputeDifferentials` finds them.
    pub fn with_footprint(
        p: Vec3A,
        n: Vec3A,
        uv: Vec2,
        dpdu: Vec3A,
        dpdv: Vec3A,
        dpdx: Vec3A,
        dpdy: Vec3A,
    ) -> TextureEvalContext {
        let (a00, a01, a11) = (dpdu.dot(dpdu), dpdu.dot(dpdv), dpdv.dot(dpdv));
        let inv_det = 1.0 / (a00 * a11 - a01 * a01);
        let inv_det = if inv_det.is_finite() { inv_det } else { 0.0 };
        let (b0x, b1x) = (dpdu.dot(dpdx), dpdv.dot(dpdx));
        let (b0y, b1y) = (dpdu.dot(dpdy), dpdv.dot(dpdy));
        let tidy = |d: f32| {
            if d.is_finite() {
                d.clamp(-1e8, 1e8)
            } else {
                0.0
            }
        };
        TextureEvalContext {
            p,
            n,
            uv,
            dpdx,
            dpdy,
            dudx: tidy((a11 * b0x - a01 * b1x) * inv_det),
            dvdx: tidy((a00 * b1x - a01 * b0x) * inv_det),
            dudy: tidy((a11 * b0y - a01 * b1y) * inv_det),
            dvdy: tidy((a00 * b1y - a01 * b0y) * inv_det),
            waves: None,
        }
    }

    /// A reflectance a texture gave in RGB, as the path sees it: that RGB, or its bounded
    /// spectrum at the path's wavelengths.
    #[inline]
    pub fn reflectance(&self, rgb: Color) -> Color {
        match &self.waves {
            None => rgb,
            Some(w) => w.albedo(rgb),
        }
    }

    /// An unbounded value (an index of refraction, an absorption) a texture gave in RGB,
    /// as the path sees it.
    #[inline]
    pub fn unbounded(&self, rgb: Color) -> Color {
        match &self.waves {
            None => rgb,
            Some(w) => w.unbounded(rgb),
        }
    }
}

/// What a texture evaluates to: a float or a colour.
pub trait TexValue: Copy + Add<Output = Self> + Mul<f32, Output = Self> + PartialEq {
    fn splat(v: f32) -> Self;
    /// A value from a colour (marble's spline).
    fn from_color(c: Color) -> Self;
    /// A value times another of its kind.
    fn times(self, other: Self) -> Self;
    /// A value from one texel's channels, as pbrt-v4's texel lookups give it (a float
    /// reads the first channel).
    fn from_texel(c: &[f32]) -> Self;
    /// A value from bilinearly interpolated channels, as pbrt-v4's bilinear lookups give it
    /// (a float reads grey, the average of RGB, or the alpha of RGBA).
    fn from_bilerp(c: &[f32]) -> Self;
    /// max(0, 1 − v): an inverted image value.
    fn inverted(self) -> Self;
    /// An image's value as pbrt-v4 returns it: colours clamped at zero, floats as they are.
    fn image_value(self) -> Self;
}

impl TexValue for f32 {
    fn splat(v: f32) -> f32 {
        v
    }
    fn from_color(c: Color) -> f32 {
        (c.x + c.y + c.z) / 3.0
    }
    fn times(self, other: f32) -> f32 {
        self * other
    }
    fn from_texel(c: &[f32]) -> f32 {
        c[0]
    }
    fn from_bilerp(c: &[f32]) -> f32 {
        match c.len() {
            3 => (c[0] + c[1] + c[2]) / 3.0,
            4 => c[3],
            _ => c[0],
        }
    }
    fn inverted(self) -> f32 {
        (1.0 - self).max(0.0)
    }
    fn image_value(self) -> f32 {
        self
    }
}

/// A colour from 1 to 4 channels: grey, or RGB (alpha ignored).
fn color_from_channels(c: &[f32]) -> Color {
    match c.len() {
        1 | 2 => Color::splat(c[0]),
        _ => crate::math::rgb3(c[0], c[1], c[2]),
    }
}

impl TexValue for Color {
    fn splat(v: f32) -> Color {
        Color::splat(v)
    }
    fn from_color(c: Color) -> Color {
        c
    }
    fn times(self, other: Color) -> Color {
        self * other
    }
    fn from_texel(c: &[f32]) -> Color {
        color_from_channels(c)
    }
    fn from_bilerp(c: &[f32]) -> Color {
        color_from_channels(c)
    }
    fn inverted(self) -> Color {
        (Color::ONE - self).max(Color::ZERO)
    }
    fn image_value(self) -> Color {
        self.max(Color::ZERO)
    }
}

/// A texture: a constant inline, or a shared node.
#[derive(Debug, Clone)]
pub enum Texture<V> {
    Constant(V),
    Node(Arc<Node<V>>),
}

/// A scalar texture.
pub type FloatTexture = Texture<f32>;
/// An RGB texture (linear sRGB).
pub type SpectrumTexture = Texture<Color>;

/// The kinds of texture that are not constants.
#[derive(Debug, Clone)]
pub enum Node<V> {
    Scale {
        tex: Texture<V>,
        scale: FloatTexture,
    },
    Mix {
        tex1: Texture<V>,
        tex2: Texture<V>,
        amount: FloatTexture,
    },
    DirectionMix {
        tex1: Texture<V>,
        tex2: Texture<V>,
        dir: Vec3A,
    },
    Checkerboard(Checkerboard<V>),
    Bilerp {
        mapping: Mapping2D,
        v: [Texture<V>; 4],
    },
    Dots(Dots<V>),
    Fbm(Fbm),
    Wrinkled(Wrinkled),
    Windy(Windy),
    Marble(Marble),
    Image(ImageTexture),
}

impl<V: TexValue> Texture<V> {
    pub fn evaluate(&self, ctx: &TextureEvalContext) -> V {
        match self {
            Texture::Constant(v) => *v,
            Texture::Node(node) => node.evaluate(ctx),
        }
    }

    /// The texture's value if it is the same everywhere.
    pub fn as_constant(&self) -> Option<V> {
        match self {
            Texture::Constant(v) => Some(*v),
            Texture::Node(_) => None,
        }
    }
}

impl<V: TexValue> Node<V> {
    fn evaluate(&self, ctx: &TextureEvalContext) -> V {
        match self {
            Node::Scale { tex, scale } => {
                let s = scale.evaluate(ctx);
                if s == 0.0 {
                    V::splat(0.0)
                } else {
                    tex.evaluate(ctx) * s
                }
            }
            Node::Mix { tex1, tex2, amount } => {
                let a = amount.evaluate(ctx);
                mix(a, || tex1.evaluate(ctx), || tex2.evaluate(ctx))
            }
            Node::DirectionMix { tex1, tex2, dir } => {
                // pbrt-v4: the weight of tex1 is |n·dir|.
                let a = ctx.n.dot(*dir).abs();
                mix(1.0 - a, || tex1.evaluate(ctx), || tex2.evaluate(ctx))
            }
            Node::Checkerboard(c) => c.evaluate(ctx),
            Node::Bilerp { mapping, v } => {
                let st = mapping.map(ctx).st;
                let (s, t) = (st.x, st.y);
                v[0].evaluate(ctx) * ((1.0 - s) * (1.0 - t))
                    + v[1].evaluate(ctx) * ((1.0 - s) * t)
                    + v[2].evaluate(ctx) * (s * (1.0 - t))
                    + v[3].evaluate(ctx) * (s * t)
            }
            Node::Dots(d) => d.evaluate(ctx),
            Node::Fbm(f) => V::splat(f.evaluate(ctx)),
            Node::Wrinkled(w) => V::splat(w.evaluate(ctx)),
            Node::Windy(w) => V::splat(w.evaluate(ctx)),
            Node::Marble(m) => V::from_color(m.evaluate(ctx)),
            Node::Image(i) => i.evaluate(ctx),
        }
    }
}

/// (1 − a)·t1 + a·t2, evaluating only the inputs whose weight is not zero (pbrt-v4 does the
/// same, and it keeps an unused input from costing anything).
pub(crate) fn mix<V: TexValue>(a: f32, t1: impl FnOnce() -> V, t2: impl FnOnce() -> V) -> V {
    let v1 = if a != 1.0 { t1() } else { V::splat(0.0) };
    let v2 = if a != 0.0 { t2() } else { V::splat(0.0) };
    v1 * (1.0 - a) + v2 * a
}

/// A scene's textures, built from its description in definition order, each sharing the
/// nodes of those it refers to.
#[derive(Debug, Clone, Default)]
pub struct Textures {
    pub float: Vec<FloatTexture>,
    pub spectrum: Vec<SpectrumTexture>,
}

impl Textures {
    pub fn from_description(
        float: &[FloatTextureDesc],
        spectrum: &[SpectrumTextureDesc],
    ) -> Textures {
        let mut t = Textures::default();
        let mut mipmaps = MipMaps::default();
        for desc in float {
            let tex = build(desc, |v| t.float_value(v), &t, &mut mipmaps);
            t.float.push(tex);
        }
        for desc in spectrum {
            let tex = build(desc, |v| t.rgb_value(v), &t, &mut mipmaps);
            t.spectrum.push(tex);
        }
        t
    }

    /// The texture a float parameter stands for.
    pub fn float_value(&self, v: &FloatValue) -> FloatTexture {
        match v {
            FloatValue::Constant(c) => Texture::Constant(*c),
            FloatValue::Texture(id) => self.float[id.0 as usize].clone(),
        }
    }

    /// The texture a colour parameter stands for.
    pub fn rgb_value(&self, v: &RgbValue) -> SpectrumTexture {
        match v {
            RgbValue::Constant(c) => Texture::Constant(rgb(*c)),
            RgbValue::Texture(id) => self.spectrum[id.0 as usize].clone(),
        }
    }
}

/// MIP maps by image and wrap mode: one per image however many textures use it.
#[derive(Default)]
struct MipMaps(
    Vec<(
        Arc<kiln_scene::TextureImage>,
        kiln_scene::ImageWrap,
        Arc<mipmap::MipMap>,
    )>,
);

impl MipMaps {
    fn get(
        &mut self,
        image: &Arc<kiln_scene::TextureImage>,
        wrap: kiln_scene::ImageWrap,
    ) -> Arc<mipmap::MipMap> {
        if let Some((_, _, m)) = self
            .0
            .iter()
            .find(|(i, w, _)| Arc::ptr_eq(i, image) && *w == wrap)
        {
            return m.clone();
        }
        let m = Arc::new(mipmap::MipMap::new(image, wrap));
        self.0.push((image.clone(), wrap, m.clone()));
        m
    }
}

fn build<V: TexValue, D>(
    desc: &TextureDesc<D>,
    value: impl Fn(&D) -> Texture<V>,
    t: &Textures,
    mipmaps: &mut MipMaps,
) -> Texture<V> {
    let node = match &desc.kind {
        TextureKind::Constant(v) => return value(v),
        TextureKind::Scale { tex, scale } => Node::Scale {
            tex: value(tex),
            scale: t.float_value(scale),
        },
        TextureKind::Mix { tex1, tex2, amount } => Node::Mix {
            tex1: value(tex1),
            tex2: value(tex2),
            amount: t.float_value(amount),
        },
        TextureKind::DirectionMix { tex1, tex2, dir } => Node::DirectionMix {
            tex1: value(tex1),
            tex2: value(tex2),
            dir: dir.as_vec3().into(),
        },
        TextureKind::Checkerboard {
            mapping,
            tex1,
            tex2,
        } => Node::Checkerboard(Checkerboard::new(mapping, value(tex1), value(tex2))),
        TextureKind::Bilerp {
            mapping,
            v00,
            v01,
            v10,
            v11,
        } => Node::Bilerp {
            mapping: Mapping2D::from_description(mapping),
            v: [value(v00), value(v01), value(v10), value(v11)],
        },
        TextureKind::Dots {
            mapping,
            inside,
            outside,
        } => Node::Dots(Dots::new(mapping, value(inside), value(outside))),
        TextureKind::Fbm {
            texture_from_world,
            octaves,
            roughness,
        } => Node::Fbm(Fbm {
            mapping: Mapping3D::new(texture_from_world),
            octaves: *octaves,
            roughness: *roughness,
        }),
        TextureKind::Wrinkled {
            texture_from_world,
            octaves,
            roughness,
        } => Node::Wrinkled(Wrinkled {
            mapping: Mapping3D::new(texture_from_world),
            octaves: *octaves,
            roughness: *roughness,
        }),
        TextureKind::Windy { texture_from_world } => Node::Windy(Windy {
            mapping: Mapping3D::new(texture_from_world),
        }),
        TextureKind::Marble {
            texture_from_world,
            octaves,
            roughness,
            scale,
            variation,
        } => Node::Marble(Marble {
            mapping: Mapping3D::new(texture_from_world),
            octaves: *octaves,
            roughness: *roughness,
            scale: *scale,
            variation: *variation,
        }),
        TextureKind::Image(desc) => Node::Image(ImageTexture {
            mipmap: mipmaps.get(&desc.image, desc.wrap),
            mapping: Mapping2D::from_description(&desc.mapping),
            filter: desc.filter,
            max_anisotropy: desc.max_anisotropy,
            scale: desc.scale,
            invert: desc.invert,
        }),
    };
    Texture::Node(Arc::new(node))
}
