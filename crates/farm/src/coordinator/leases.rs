//! Leases: which worker holds which tile until when, and which workers may hold any.
//!
//! Time comes in from the caller as `now`; nothing here reads a clock, so expiry is a pure
//! function of the instants passed in. It must never touch jobs, the store or HTTP: the
//! coordinator tells jobs what happened to their tiles.

use super::MAX_WORKER_FAILURES;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// A tile lent to a worker.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Held {
    pub job: u64,
    pub tile: usize,
    pub worker: String,
    deadline: Instant,
}

/// The leases outstanding. Ids are never reused.
pub(super) struct Leases {
    held: HashMap<u64, Held>,
    next: u64,
    ttl: Duration,
}

impl Leases {
    /// Leases that last `ttl` from their grant or last renewal.
    pub fn new(ttl: Duration) -> Leases {
        Leases {
            held: HashMap::new(),
            next: 1,
            ttl,
        }
    }

    pub fn ttl(&self) -> Duration {
        self.ttl
    }

    /// Lends `tile` of `job` to `worker` until `now + ttl`; returns the lease's id.
    pub fn grant(&mut self, job: u64, tile: usize, worker: &str, now: Instant) -> u64 {
        let id = self.next;
        self.next += 1;
        self.held.insert(
            id,
            Held {
                job,
                tile,
                worker: worker.to_string(),
                deadline: now + self.ttl,
            },
        );
        id
    }

    pub fn get(&self, id: u64) -> Option<&Held> {
        self.held.get(&id)
    }

    /// Extends a lease to `now + ttl` (a heartbeat). `None` if it is unknown or has been
    /// expired by [`Leases::expire`].
    pub fn renew(&mut self, id: u64, now: Instant) -> Option<&Held> {
        let held = self.held.get_mut(&id)?;
        held.deadline = now + self.ttl;
        Some(held)
    }

    /// Ends a lease (its tile came back, failed, or its job ended).
    pub fn remove(&mut self, id: u64) -> Option<Held> {
        self.held.remove(&id)
    }

    /// Ends and returns every lease whose deadline is before `now`.
    pub fn expire(&mut self, now: Instant) -> Vec<(u64, Held)> {
        let expired: Vec<u64> = self
            .held
            .iter()
            .filter(|(_, h)| h.deadline < now)
            .map(|(id, _)| *id)
            .collect();
        expired
            .into_iter()
            .filter_map(|id| Some((id, self.held.remove(&id)?)))
            .collect()
    }

    pub fn len(&self) -> usize {
        self.held.len()
    }
}

/// Workers' records: how many of their attempts failed in a row.
#[derive(Default)]
pub(super) struct Workers {
    consecutive_failures: HashMap<String, u32>,
}

impl Workers {
    /// Whether the worker failed too often in a row to get more leases.
    pub fn is_set_aside(&self, worker: &str) -> bool {
        self.consecutive_failures
            .get(worker)
            .is_some_and(|&n| n >= MAX_WORKER_FAILURES)
    }

    pub fn seen(&mut self, worker: &str) {
        self.consecutive_failures
            .entry(worker.to_string())
            .or_default();
    }

    pub fn failed(&mut self, worker: &str) {
        *self
            .consecutive_failures
            .entry(worker.to_string())
            .or_default() += 1;
    }

    pub fn succeeded(&mut self, worker: &str) {
        if let Some(n) = self.consecutive_failures.get_mut(worker) {
            *n = 0;
        }
    }
}
