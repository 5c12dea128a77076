//! pbrt-v4's "measured" material: a BRDF tabulated in the RGL format.

use crate::bsdfs::{Bsdf, MeasuredBxdf, MeasuredTables};
use crate::spectral::Wavelengths;
use std::sync::Arc;

#[derive(Debug, Clone)]
pub struct MeasuredMaterial {
    pub tables: Arc<MeasuredTables>,
}

impl MeasuredMaterial {
    /// The BRDF, at a spectral path's `waves` if given.
    pub fn bsdf(&self, waves: Option<&Wavelengths>) -> Bsdf<'_> {
        Bsdf::Measured(MeasuredBxdf {
            tables: &self.tables,
            lambda: waves.map(|w| w.lambda),
        })
    }
}
