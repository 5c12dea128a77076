//! Participating media: homogeneous, and grids (densities, temperatures, emission) with
//! the lattice their samples sit on; phase functions; the media on each side of a surface.

use crate::error::Loc;
use crate::spectrum::Rgb;
use glam::DMat4;
use std::sync::Arc;

pub use crate::voxel_grid::VoxelGrid;

/// Index into [`SceneDescription::media`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MediumId(pub u32);

/// The media on the two sides of a surface; `None` is vacuum. Outside is the side its normal points to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MediumInterfaceDesc {
    pub inside: Option<MediumId>,
    pub outside: Option<MediumId>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MediumKind {
    /// Constant coefficients (per unit length, `scale` applied) and emission (`Lescale` applied).
    Homogeneous {
        sigma_a: Rgb,
        sigma_s: Rgb,
        le: Rgb,
        /// The shape of Le's spectrum, where it was given as one.
        le_spectrum: Option<crate::spectrum::EmissionSpectrum>,
        phase: PhaseDesc,
    },
    /// pbrt-v4's "uniformgrid", "rgbgrid" and "cloud": coefficients varying over the box
    /// `p0`..`p1` of the medium's own space (see [`GridDensity`]).
    Grid(Arc<GridMediumDesc>),
}

/// A phase function: Henyey-Greenstein (pbrt's), or Schlick's approximation of it
/// ("string phase" "schlick", a Kiln parameter) with the same asymmetry `g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PhaseDesc {
    HenyeyGreenstein { g: f32 },
    Schlick { g: f32 },
}

/// A heterogeneous medium. Grids are looked up as pbrt-v4's `SampledGrid` does: sample
/// (i, j, k) sits at the centre of voxel (i, j, k) of the box, values are interpolated
/// trilinearly, and samples outside the grid count as zero (so a field falls off over the
/// outer half voxel).
#[derive(Debug, Clone, PartialEq)]
pub struct GridMediumDesc {
    /// Per unit density and length, `scale` applied.
    pub sigma_a: Rgb,
    pub sigma_s: Rgb,
    pub phase: PhaseDesc,
    pub density: GridDensity,
    pub emission: GridEmission,
    pub p0: [f32; 3],
    pub p1: [f32; 3],
    /// The CTM when the medium was defined (pbrt's renderFromMedium).
    pub medium_to_world: DMat4,
    /// Where the grids' samples sit in the box.
    pub lattice: Lattice,
}

/// Where a grid medium's samples sit in its box `p0`..`p1`. Either way values are trilinear
/// between samples and zero beyond the grid's outermost ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lattice {
    /// pbrt-v4's `SampledGrid`: sample (i, j, k) of an nx·ny·nz grid at the centre of voxel
    /// (i, j, k) when the box is cut into nx·ny·nz voxels.
    Centred,
    /// At the integer points of a space the box maps into affinely (a NanoVDB grid's index
    /// space, shifted to put sample (0, 0, 0) at its origin): `to_samples` takes a point of
    /// the unit box (0..1 across `p0`..`p1`) there.
    Affine { to_samples: DMat4 },
}

/// What multiplies a grid medium's `sigma_a` and `sigma_s` at each point of its box.
#[derive(Debug, Clone, PartialEq)]
pub enum GridDensity {
    /// pbrt-v4's "uniformgrid": one density per voxel, for both coefficients.
    Scalar(VoxelGrid),
    /// pbrt-v4's "rgbgrid": an RGB value per voxel for each coefficient (the three grids
    /// are the channels); a coefficient without a grid is 1 everywhere, as in pbrt-v4.
    Rgb {
        sigma_a: Option<Box<[VoxelGrid; 3]>>,
        sigma_s: Option<Box<[VoxelGrid; 3]>>,
    },
    /// pbrt-v4's "cloud": a procedural density in [0, 1] from fractal noise, thinning with
    /// height (`density` scales the noise, `wispiness` perturbs its lookup, `frequency` is
    /// its scale).
    Cloud {
        density: f32,
        wispiness: f32,
        frequency: f32,
    },
}

/// Where a grid medium's emitted radiance Le comes from; the source term is sigma_a · Le.
#[derive(Debug, Clone, PartialEq)]
pub enum GridEmission {
    None,
    /// A constant colour times the `scale` grid ("Lescale": nx·ny·nz values, or one value
    /// as a 1x1x1 grid, pbrt's default).
    Constant {
        le: Rgb,
        /// The shape of Le's spectrum, where it was given as one.
        le_spectrum: Option<crate::spectrum::EmissionSpectrum>,
        scale: VoxelGrid,
    },
    /// The peak-normalised blackbody at (T − offset) · t_scale (none at or below 100 K),
    /// times `le_scale` and the `scale` grid where there is one (pbrt-v4's "uniformgrid" has
    /// a grid, its "nanovdb" a constant).
    Temperature {
        temperature: VoxelGrid,
        offset: f32,
        t_scale: f32,
        scale: Option<VoxelGrid>,
        le_scale: f32,
    },
    /// An RGB value per voxel (pbrt-v4's "rgbgrid" `Le`, the three grids its channels),
    /// times `scale`.
    Rgb {
        le: [VoxelGrid; 3],
        scale: f32,
    },
}

#[derive(Debug, Clone)]
pub struct MediumDesc {
    pub name: String,
    pub kind: MediumKind,
    pub loc: Loc,
}
