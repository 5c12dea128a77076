//! Microfacet roughness as a material holds it: fixed when the scene gives constants (the
//! distribution is built once), or evaluated from float textures at each hit.

use crate::bsdfs::TrowbridgeReitz;
use crate::textures::{FloatTexture, TextureEvalContext, Textures};
use kiln_scene::Roughness;

#[derive(Debug, Clone)]
pub enum RoughnessTexture {
    Fixed(TrowbridgeReitz),
    Textured {
        u: FloatTexture,
        v: FloatTexture,
        remap: bool,
    },
}

/// pbrt-v4's roughness-to-alpha remapping (`remaproughness`): alpha = sqrt(roughness).
fn alpha(r: f32, remap: bool) -> f32 {
    let r = r.max(0.0);
    if remap { r.sqrt() } else { r }
}

impl RoughnessTexture {
    pub fn new(r: &Roughness, textures: &Textures) -> RoughnessTexture {
        let (u, v) = (textures.float_value(&r.u), textures.float_value(&r.v));
        match (u.as_constant(), v.as_constant()) {
            (Some(u), Some(v)) => {
                RoughnessTexture::Fixed(TrowbridgeReitz::new(alpha(u, r.remap), alpha(v, r.remap)))
            }
            _ => RoughnessTexture::Textured {
                u,
                v,
                remap: r.remap,
            },
        }
    }

    /// A perfectly smooth surface.
    pub fn smooth() -> RoughnessTexture {
        RoughnessTexture::Fixed(TrowbridgeReitz::new(0.0, 0.0))
    }

    pub fn distribution(&self, ctx: &TextureEvalContext) -> TrowbridgeReitz {
        match self {
            RoughnessTexture::Fixed(d) => *d,
            RoughnessTexture::Textured { u, v, remap } => TrowbridgeReitz::new(
                alpha(u.evaluate(ctx), *remap),
                alpha(v.evaluate(ctx), *remap),
            ),
        }
    }

    /// Smooth everywhere (only a fixed distribution can promise it).
    pub fn is_smooth(&self) -> bool {
        matches!(self, RoughnessTexture::Fixed(d) if d.effectively_smooth())
    }

    pub fn is_textured(&self) -> bool {
        matches!(self, RoughnessTexture::Textured { .. })
    }
}
