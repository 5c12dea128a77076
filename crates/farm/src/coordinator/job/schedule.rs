//! A job's schedule: its passes (cumulative samples per pixel at the end of each), what its
//! tiles' running sums hold, and whether tiles kept before passes existed are in its frame.
//! Stopping after a pass and extending by more change it; nothing else does.

use super::super::error::PlanError;
use crate::api::{JobState, PassRange};
use kiln_render::SumsLayout;

/// The most passes a job may have.
pub const MAX_PASSES: usize = 64;

#[derive(Debug, Clone)]
pub(super) struct Schedule {
    /// Cumulative samples per pixel at the end of each pass, ascending.
    pub passes: Vec<u32>,
    /// Whether tiles carry running sums (every integrator but SPPM), and what those hold
    /// (G-buffer sums, adaptive sampling's): None for SPPM.
    pub sums: Option<SumsLayout>,
    /// Whether tiles kept before passes existed (without running sums) are in its frame.
    pub legacy: bool,
}

impl Schedule {
    /// How many passes the job has.
    pub fn len(&self) -> usize {
        self.passes.len()
    }

    /// Samples per pixel after `done` passes.
    pub fn samples_after(&self, done: u32) -> u32 {
        match done {
            0 => 0,
            d => self.passes[(d as usize - 1).min(self.passes.len() - 1)],
        }
    }

    /// The samples pass `pass` takes a tile from and to.
    pub fn range(&self, pass: u32) -> PassRange {
        PassRange {
            index: pass,
            from: self.samples_after(pass),
            to: self.passes[pass as usize],
        }
    }

    /// Samples per pixel at the end of the last pass.
    pub fn last_samples(&self) -> u32 {
        self.passes.last().copied().unwrap_or(0)
    }

    /// Samples per pixel at the end of pass `pass`.
    pub fn samples_of_pass(&self, pass: u32) -> u32 {
        self.passes[(pass as usize).min(self.passes.len() - 1)]
    }

    /// The schedule with `more` passes after its last, for a job in `state` created for
    /// `planned` samples per pixel, or why it cannot have them.
    pub fn extended(
        &self,
        more: &[u32],
        state: JobState,
        planned: Option<u32>,
    ) -> Result<Vec<u32>, PlanError> {
        let Some(last) = self.passes.last().copied() else {
            return Err(PlanError::Passes("this job has no tiles to extend".into()));
        };
        if self.legacy {
            return Err(PlanError::Passes(
                "this job was rendered before passes existed: its tiles keep no running sums to continue; submit a new job".into(),
            ));
        }
        if self.sums.is_none() {
            return Err(PlanError::Passes(
                "an SPPM job cannot be extended: its photon radius shrinks over all its iterations together".into(),
            ));
        }
        if !matches!(state, JobState::Running | JobState::Done) {
            return Err(PlanError::Passes(format!(
                "a {} job cannot be extended",
                state.as_str()
            )));
        }
        check_passes(more, last)?;
        let new_last = *more.last().expect("checked: not empty");
        // The renderer's footprint is the one the job was created with (its pinned spp).
        let planned = planned.unwrap_or(last);
        if kiln_render::texture_footprint(planned) != kiln_render::texture_footprint(new_last) {
            return Err(PlanError::Passes(format!(
                "a job created for {planned} samples per pixel cannot be extended to {new_last}: textures are filtered over a footprint that shrinks with the total up to 64 samples (as pbrt-v4 does), so its samples would not be those of a {new_last}-sample render; submit a new job"
            )));
        }
        if self.passes.len() + more.len() > MAX_PASSES {
            return Err(PlanError::Passes(format!(
                "a job has at most {MAX_PASSES} passes"
            )));
        }
        Ok(self.passes.iter().chain(more).copied().collect())
    }
}

/// Checks a schedule of cumulative sample counts: 1 to [`MAX_PASSES`] of them, ascending,
/// the first above `after`.
pub(super) fn check_passes(passes: &[u32], after: u32) -> Result<(), PlanError> {
    if passes.is_empty() || passes.len() > MAX_PASSES {
        return Err(PlanError::Passes(format!(
            "give 1 to {MAX_PASSES} passes, not {}",
            passes.len()
        )));
    }
    let mut prev = after;
    for &p in passes {
        if p <= prev {
            return Err(PlanError::Passes(format!(
                "passes are cumulative samples per pixel, each above the one before (and above {after}): {passes:?}"
            )));
        }
        prev = p;
    }
    Ok(())
}
