//! Textures: values that vary over a surface, evaluated where a ray hits it.
//!
//! Materials hold their parameters as textures and evaluate them at each hit through a
//! [`TextureEvalContext`]; [`FloatTexture`] and [`SpectrumTexture`] are the closed sets of
//! kinds, dispatched by `match`, one file per kind as kinds are added (pbrt-v4's image,
//! checkerboard, scale, mix, noise textures and the uv, spherical, cylindrical and planar
//! mappings). Only constants exist today, so every material evaluates to one BSDF.
//!
//! Textures know nothing of materials, lights or integrators.

use crate::math::Color;
use glam::{Vec2, Vec3A};

/// Where a texture is evaluated: the hit point and its surface coordinates.
#[derive(Debug, Clone, Copy)]
pub struct TextureEvalContext {
    pub p: Vec3A,
    pub uv: Vec2,
}

/// A scalar texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FloatTexture {
    Constant(f32),
}

impl FloatTexture {
    pub fn evaluate(&self, _ctx: &TextureEvalContext) -> f32 {
        match self {
            FloatTexture::Constant(v) => *v,
        }
    }

    /// The texture's value if it is the same everywhere.
    pub fn as_constant(&self) -> Option<f32> {
        match self {
            FloatTexture::Constant(v) => Some(*v),
        }
    }
}

/// An RGB texture (linear sRGB).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpectrumTexture {
    Constant(Color),
}

impl SpectrumTexture {
    pub fn evaluate(&self, _ctx: &TextureEvalContext) -> Color {
        match self {
            SpectrumTexture::Constant(c) => *c,
        }
    }

    /// The texture's value if it is the same everywhere.
    pub fn as_constant(&self) -> Option<Color> {
        match self {
            SpectrumTexture::Constant(c) => Some(*c),
        }
    }
}

impl From<&kiln_scene::RgbValue> for SpectrumTexture {
    fn from(v: &kiln_scene::RgbValue) -> SpectrumTexture {
        match v {
            kiln_scene::RgbValue::Constant(c) => SpectrumTexture::Constant(crate::math::rgb(*c)),
        }
    }
}
