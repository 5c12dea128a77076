//! The job store: what survives a restart besides the data directory's files. Jobs, every
//! kept tile pass's EXR (with its running sums and whose unchecked renders it holds),
//! workers set aside, webhook outcomes and counters.
//!
//! [`JobStore`] is the interface the coordinator keeps them through. [`SqliteStore`]
//! (`sqlite.rs`, an embedded SQLite file in the data directory) is the default;
//! [`PostgresStore`] (`postgres.rs`, `--store postgres://...`) is a server several
//! coordinators share, one leading (see [`Leadership`]). Both keep versioned migrations and
//! pass the same conformance test.
//! A store records and reads back: it never decides anything about jobs or leases, and keeps
//! no state in memory beyond its connection. Its errors are Kiln's own ([`StoreError`]), so
//! no driver's type reaches the coordinator's public errors.

mod postgres;
mod sqlite;
#[cfg(test)]
pub(super) mod tests;

pub(super) use postgres::PostgresStore;
pub(super) use sqlite::SqliteStore;

use crate::api::{JobSpec, JobState, Role};
use std::collections::BTreeSet;
use std::time::Duration;

/// Why the store could not do what it was asked: what it was doing, and the back-end's
/// reason, as text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct StoreError {
    message: String,
    /// The write was refused because another coordinator leads now.
    deposed: bool,
}

impl StoreError {
    pub(super) fn new(message: impl Into<String>) -> StoreError {
        StoreError {
            message: message.into(),
            deposed: false,
        }
    }

    /// A write refused by its epoch: this coordinator was deposed.
    pub(super) fn deposed(message: impl Into<String>) -> StoreError {
        StoreError {
            message: message.into(),
            deposed: true,
        }
    }

    /// Whether another coordinator leads now, so that this one must stop.
    pub fn is_deposed(&self) -> bool {
        self.deposed
    }
}

/// Who leads the coordinators that share a store.
#[derive(Debug, Clone, PartialEq)]
pub enum Leadership {
    /// This coordinator leads, under this epoch: every write it makes carries it. `after`
    /// is the coordinator that led before and the seconds since it last renewed the lead
    /// (infinite if it gave the lead up), when there was one.
    Leading {
        epoch: u64,
        after: Option<(String, f64)>,
    },
    /// Another does: its name, the address it serves on and its epoch.
    Led {
        holder: String,
        address: String,
        epoch: u64,
    },
}

/// A job as the store keeps it.
pub(super) struct StoredJob {
    pub id: u64,
    /// The job's spec, or why it cannot be read back.
    pub spec: Result<JobSpec, String>,
    pub state: JobState,
    pub error: Option<String>,
}

/// A tile pass as the store keeps it.
#[derive(Debug, Clone)]
pub(super) struct KeptTile {
    pub idx: usize,
    /// Samples per pixel its sums hold.
    pub samples: u32,
    pub exr: Vec<u8>,
    /// The workers whose unchecked renders its sums hold.
    pub unchecked_by: BTreeSet<String>,
    /// Kept before passes existed: a finished tile without running sums.
    pub legacy: bool,
}

/// What became of a job's webhook call since the job last ended, as the store keeps it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum WebhookOutcome {
    /// Not answered yet: called after a restart.
    Pending = 0,
    Delivered = 1,
    /// Every call failed: not called again after a restart.
    GaveUp = 2,
}

/// Everything the coordinator keeps durable about jobs. Every write is committed before it
/// returns. Used under the coordinator's lock, one caller at a time.
pub(super) trait JobStore: Send {
    /// Counts this opening of the store: 1 the first time, then one more at each restart,
    /// committed before it is returned. Lease ids carry it, so an id from before a restart
    /// never names a lease granted after it.
    fn next_epoch(&self) -> Result<u64, StoreError>;

    // Jobs.

    /// Every job, oldest first. A state the store does not know reads as failed; a record
    /// that cannot be read back is returned with `spec` as the reason, so that the job can
    /// be reported failed while the others resume.
    fn jobs(&self) -> Result<Vec<StoredJob>, StoreError>;
    /// The job created earlier under this idempotency key.
    fn job_with_key(&self, key: &str) -> Result<Option<u64>, StoreError>;
    /// Records a new running job; returns its id.
    fn insert_job(&self, spec: &JobSpec, key: Option<&str>) -> Result<u64, StoreError>;
    /// Records a job's changed spec (its passes stopped early or extended).
    fn set_spec(&self, job: u64, spec: &JobSpec) -> Result<(), StoreError>;
    fn set_state(&self, job: u64, state: JobState, error: Option<&str>) -> Result<(), StoreError>;

    // Tile passes.

    /// A job's kept tile passes. Records that cannot be read are left out. Tiles kept
    /// before passes existed come as passes of `legacy_samples`.
    fn tiles(&self, job: u64, legacy_samples: u32) -> Result<Vec<KeptTile>, StoreError>;
    /// The EXR kept for a tile after `samples` samples.
    fn tile(&self, job: u64, idx: usize, samples: u32) -> Result<Option<Vec<u8>>, StoreError>;
    /// Whether `exr` is, byte for byte, one kept for the tile (any pass, or from before
    /// passes existed).
    fn holds_tile(&self, job: u64, idx: usize, exr: &[u8]) -> Result<bool, StoreError>;
    /// Keeps a tile's EXR after `samples` samples. The first one kept for a tile's pass
    /// stays.
    fn insert_tile(
        &self,
        job: u64,
        idx: usize,
        samples: u32,
        exr: &[u8],
        unchecked_by: &BTreeSet<String>,
    ) -> Result<(), StoreError>;
    /// Forgets every kept pass of the job's `tiles`: they are rendered again from nothing.
    fn drop_tiles(&self, job: u64, tiles: &[usize]) -> Result<(), StoreError>;
    /// Forgets a job's tile passes of fewer than `samples` samples: once every tile has done
    /// the pass of `samples`, nothing continues from them or pastes them again.
    fn drop_passes_before(&self, job: u64, samples: u32) -> Result<(), StoreError>;

    // Verification and webhooks.

    /// Counts a tile pass of the job that two workers agreed on.
    fn add_verified(&self, job: u64) -> Result<(), StoreError>;
    /// How many of the job's tile passes two workers agreed on.
    fn verified(&self, job: u64) -> Result<u64, StoreError>;
    /// What became of the job's webhook call since the job last ended.
    fn webhook(&self, job: u64) -> Result<WebhookOutcome, StoreError>;
    /// Records what became of the job's webhook call (or, with `Pending`, that it must be
    /// called again: the job runs again).
    fn set_webhook(&self, job: u64, outcome: WebhookOutcome) -> Result<(), StoreError>;

    // Workers.

    /// Records that `worker` is set aside for `reason` (the first reason stays), so that a
    /// restarted coordinator does not trust it again.
    fn set_aside(&self, worker: &str, reason: &str) -> Result<(), StoreError>;
    /// Forgets that `worker` was set aside (an operator reinstated it).
    fn reinstate(&self, worker: &str) -> Result<(), StoreError>;
    /// Every worker set aside, with the reason.
    fn set_aside_workers(&self) -> Result<Vec<(String, String)>, StoreError>;

    // Tokens.

    /// Records an issued token: its role, whose it is, and the SHA-256 of its secret (the
    /// secret itself is never stored). Returns its id.
    fn insert_token(&self, role: Role, name: &str, hash: &str) -> Result<u64, StoreError>;
    /// Marks a token revoked; returns whether there was such a token.
    fn revoke_token(&self, id: u64) -> Result<bool, StoreError>;
    /// Every token issued, revoked ones too.
    fn tokens(&self) -> Result<Vec<StoredToken>, StoreError>;

    // Leadership (a store only one coordinator opens needs none).

    /// Takes the lead for `holder` (serving at `address`) if no one holds it or its holder
    /// has not renewed it for `ttl`; from then on every write is fenced by the new epoch.
    /// Otherwise says who leads.
    fn lead(
        &self,
        _holder: &str,
        _address: &str,
        _ttl: Duration,
    ) -> Result<Leadership, StoreError> {
        Ok(Leadership::Leading {
            epoch: 0,
            after: None,
        })
    }
    /// Renews the lead; false when another coordinator has taken it.
    fn renew_lead(&self) -> Result<bool, StoreError> {
        Ok(true)
    }
    /// Gives the lead up (a coordinator stopping), so that a standby takes it at once.
    fn resign_lead(&self) -> Result<(), StoreError> {
        Ok(())
    }
}

/// An issued token as the store keeps it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct StoredToken {
    pub id: u64,
    pub role: Role,
    pub name: String,
    /// The SHA-256 of its secret, in hex.
    pub hash: String,
    pub revoked: bool,
}
