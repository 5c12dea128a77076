//! pbrt-v4's "measured" material: a BRDF tabulated in the RGL format.

use crate::bsdfs::{Bsdf, MeasuredBxdf, MeasuredTables};
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct MeasuredMaterial {
    pub tables: Arc<MeasuredTables>,
}

impl MeasuredMaterial {
    pub fn bsdf(&self) -> Bsdf<'_> {
        Bsdf::Measured(MeasuredBxdf {
            tables: &self.tables,
        })
    }
}
