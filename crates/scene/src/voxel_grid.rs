//! A voxel grid of scalar values: what grid media, VolumeLights and their files hold.

/// A voxel grid of scalar values, x fastest: `values[(z * ny + y) * nx + x]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub values: Vec<f32>,
}
