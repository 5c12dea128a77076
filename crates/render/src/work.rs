//! What tracing a sample cost, counted as it goes: rays traced, and tracking walks through a
//! medium cut off at [`MAX_TRACKING_STEPS`]. Counting is deterministic (a function of the
//! sample), so a cut-off happens at the same sample on every machine.

/// The most tentative collisions one walk through a grid medium may visit. A medium whose
/// density is far too large (or a majorant far above the density it bounds) would
/// otherwise keep a ray walking for ever; a walk cut off here ends its path, and the
/// sample is reported so that the render fails with the reason.
pub const MAX_TRACKING_STEPS: u32 = 1 << 20;

/// What a sample cost so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Work {
    pub rays: u64,
    /// Tracking walks cut off at [`MAX_TRACKING_STEPS`].
    pub cut_walks: u64,
}
