//! pbrt-v4's "imagemap": an image looked up through a 2D mapping and a MIP map, scaled and
//! optionally inverted.

use super::mapping::Mapping2D;
use super::mipmap::MipMap;
use super::{TexValue, TextureEvalContext};
use glam::Vec2;
use kiln_scene::ImageFilter;
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct ImageTexture {
    pub mipmap: Arc<MipMap>,
    pub mapping: Mapping2D,
    pub filter: ImageFilter,
    pub max_anisotropy: f32,
    pub scale: f32,
    pub invert: bool,
}

impl ImageTexture {
    pub fn evaluate<V: TexValue>(&self, ctx: &TextureEvalContext) -> V {
        let c = self.mapping.map(ctx);
        // Images are stored top row first; t grows upwards. (pbrt-v4 flips t and leaves its
        // derivatives as they are; so does Kiln.)
        let st = Vec2::new(c.st.x, 1.0 - c.st.y);
        let v: V = self.mipmap.filter(
            self.filter,
            self.max_anisotropy,
            st,
            Vec2::new(c.dsdx, c.dtdx),
            Vec2::new(c.dsdy, c.dtdy),
        );
        let v = v * self.scale;
        if self.invert {
            v.inverted()
        } else {
            v.image_value()
        }
    }
}
