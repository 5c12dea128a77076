//! Textures as a scene describes them (pbrt-v4's `Texture` directive): what each kind is
//! made of, with its parameters read, defaulted and validated, and its transforms already
//! in world space. Evaluating them is the renderer's business.
//!
//! A texture is float or spectrum (pbrt-v4 keeps the two kinds and their names apart); a
//! material parameter that may vary over a surface is a [`FloatValue`] or an [`RgbValue`]:
//! a constant, or a reference to a texture defined earlier.

use crate::error::Loc;
use crate::spectrum::Rgb;
use glam::{DMat4, DVec3};
use std::path::PathBuf;
use std::sync::Arc;

/// Index into [`SceneDescription::float_textures`](crate::SceneDescription::float_textures).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FloatTextureId(pub u32);

/// Index into [`SceneDescription::spectrum_textures`](crate::SceneDescription::spectrum_textures).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SpectrumTextureId(pub u32);

/// A scalar that may vary over a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FloatValue {
    Constant(f32),
    Texture(FloatTextureId),
}

/// A linear-sRGB colour that may vary over a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RgbValue {
    Constant(Rgb),
    Texture(SpectrumTextureId),
}

impl FloatValue {
    pub fn as_constant(&self) -> Option<f32> {
        match self {
            FloatValue::Constant(v) => Some(*v),
            FloatValue::Texture(_) => None,
        }
    }
}

impl RgbValue {
    pub fn as_constant(&self) -> Option<Rgb> {
        match self {
            RgbValue::Constant(v) => Some(*v),
            RgbValue::Texture(_) => None,
        }
    }
}

/// How a surface point becomes 2D texture coordinates (s, t).
#[derive(Debug, Clone, PartialEq)]
pub enum Mapping2D {
    /// (su·u + du, sv·v + dv) from the shape's (u, v).
    Uv { su: f32, sv: f32, du: f32, dv: f32 },
    /// The direction from the texture space's origin: (θ/π, φ/2π).
    Spherical { texture_from_world: DMat4 },
    /// About texture space's z axis: ((π + atan2(y, x)) / 2π, z).
    Cylindrical { texture_from_world: DMat4 },
    /// Projection onto two texture-space vectors: (ds + p·vs, dt + p·vt).
    Planar {
        texture_from_world: DMat4,
        vs: DVec3,
        vt: DVec3,
        ds: f32,
        dt: f32,
    },
}

/// A checkerboard is 2D (through a [`Mapping2D`]) or solid (in texture space).
#[derive(Debug, Clone, PartialEq)]
pub enum CheckerMapping {
    Planar(Mapping2D),
    Solid { texture_from_world: DMat4 },
}

/// How lookups outside [0, 1]² find a texel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageWrap {
    Repeat,
    Clamp,
    /// Zero outside the image.
    Black,
    /// pbrt-v4's equal-area octahedral layout of a sphere of directions.
    OctahedralSphere,
}

/// How an image lookup filters over the footprint of a pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFilter {
    Point,
    Bilinear,
    Trilinear,
    Ewa,
}

/// How the integer values of an 8- or 16-bit image map to linear values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColorEncoding {
    Linear,
    Srgb,
    Gamma(f32),
}

impl ColorEncoding {
    /// The linear value of an encoded value in [0, 1].
    pub fn to_linear(self, v: f32) -> f32 {
        match self {
            ColorEncoding::Linear => v,
            ColorEncoding::Srgb => {
                if v <= 0.04045 {
                    v / 12.92
                } else {
                    libm::powf((v + 0.055) / 1.055, 2.4)
                }
            }
            ColorEncoding::Gamma(g) => libm::powf(v.max(0.0), g),
        }
    }
}

/// A decoded image, row-major, top row first, `channels` values per pixel (1: grey, 3: RGB,
/// 4: RGBA). 8-bit images keep their bytes and their encoding, as pbrt-v4 keeps them (a
/// quarter of the memory of floats; lookups decode them through a table); everything else
/// is linear floats.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureImage {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub data: ImageData,
    /// The file it was read from (for messages).
    pub path: PathBuf,
}

#[derive(Debug, Clone, PartialEq)]
pub enum ImageData {
    /// Encoded bytes; alpha (the fourth channel) is encoded too, as pbrt-v4 does.
    U8 {
        bytes: Vec<u8>,
        encoding: ColorEncoding,
    },
    F32(Vec<f32>),
}

impl TextureImage {
    /// The linear value of channel `c` at pixel (x, y), which must be inside the image.
    pub fn channel(&self, x: u32, y: u32, c: u32) -> f32 {
        let i =
            (y as usize * self.width as usize + x as usize) * self.channels as usize + c as usize;
        match &self.data {
            ImageData::U8 { bytes, encoding } => encoding.to_linear(bytes[i] as f32 / 255.0),
            ImageData::F32(v) => v[i],
        }
    }
}

/// pbrt-v4's "imagemap".
#[derive(Debug, Clone, PartialEq)]
pub struct ImageTextureDesc {
    pub image: Arc<TextureImage>,
    pub mapping: Mapping2D,
    pub filter: ImageFilter,
    pub max_anisotropy: f32,
    pub wrap: ImageWrap,
    pub scale: f32,
    pub invert: bool,
}

/// The kinds of texture; `V` is [`FloatValue`] for float textures and [`RgbValue`] for
/// spectrum textures. The parser accepts each kind for the texture types pbrt-v4 does (fbm,
/// wrinkled and windy are float only, marble spectrum only).
#[derive(Debug, Clone, PartialEq)]
pub enum TextureKind<V> {
    Constant(V),
    Scale {
        tex: V,
        scale: FloatValue,
    },
    /// (1 − amount)·tex1 + amount·tex2.
    Mix {
        tex1: V,
        tex2: V,
        amount: FloatValue,
    },
    /// |n·dir|·tex1 + (1 − |n·dir|)·tex2, `dir` a world-space unit vector.
    DirectionMix {
        tex1: V,
        tex2: V,
        dir: DVec3,
    },
    Checkerboard {
        mapping: CheckerMapping,
        tex1: V,
        tex2: V,
    },
    /// Bilinear interpolation of four values over (s, t).
    Bilerp {
        mapping: Mapping2D,
        v00: V,
        v01: V,
        v10: V,
        v11: V,
    },
    /// Polka dots of `inside` on `outside`, placed by noise.
    Dots {
        mapping: Mapping2D,
        inside: V,
        outside: V,
    },
    /// Fractional Brownian motion of Perlin noise in texture space.
    Fbm {
        texture_from_world: DMat4,
        octaves: u32,
        roughness: f32,
    },
    /// Turbulence: fBm of |noise|.
    Wrinkled {
        texture_from_world: DMat4,
        octaves: u32,
        roughness: f32,
    },
    /// pbrt's wind-over-water pattern.
    Windy {
        texture_from_world: DMat4,
    },
    /// Perlin's marble: a spline of colours driven by turbulence.
    Marble {
        texture_from_world: DMat4,
        octaves: u32,
        roughness: f32,
        scale: f32,
        variation: f32,
    },
    Image(ImageTextureDesc),
}

#[derive(Debug, Clone, PartialEq)]
pub struct TextureDesc<V> {
    pub name: String,
    pub kind: TextureKind<V>,
    pub loc: Loc,
}

pub type FloatTextureDesc = TextureDesc<FloatValue>;
pub type SpectrumTextureDesc = TextureDesc<RgbValue>;
