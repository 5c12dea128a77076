//! pbrt-v4's "thindielectric": a thin slab such as a window pane.

use crate::bsdfs::{Bsdf, ThinDielectricBxdf};

#[derive(Debug, Clone)]
pub struct ThinDielectricMaterial {
    pub eta: f32,
}

impl ThinDielectricMaterial {
    pub fn bsdf(&self) -> Bsdf<'static> {
        Bsdf::ThinDielectric(ThinDielectricBxdf { eta: self.eta })
    }
}
