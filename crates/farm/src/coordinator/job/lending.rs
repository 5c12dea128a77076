//! Lending a job's tiles: how many passes each tile has done, which lease renders its next,
//! the queue of tiles to lend next, the tiles parked two passes ahead of the slowest, and
//! the failed attempts. Tiles run at most one pass ahead of the slowest: every tile's pass
//! p is lent before any tile's pass p + 2.

use std::collections::VecDeque;

pub(super) struct Lending {
    /// Per tile: how many passes it has done.
    pub done: Vec<u32>,
    /// Per tile: the lease rendering its next pass.
    pub lent: Vec<Option<u64>>,
    /// Tiles whose next pass may be lent, in order; a tile may sit here after it stopped
    /// being lendable (lending checks), so lending never scans the whole job.
    queue: VecDeque<usize>,
    /// Tiles two passes ahead of the slowest, waiting for it.
    parked: Vec<usize>,
    /// Every tile, in the order they are first lent in.
    order: Vec<usize>,
    /// Failed attempts at each tile's current pass.
    attempts: Vec<u32>,
    /// The workers whose leases on each tile's current pass expired, in order.
    expired: Vec<Vec<String>>,
    /// Per tile: its leases on this pass that expired in a row with no pass of any of the
    /// job's tiles done between them.
    stalled: Vec<u32>,
    /// Per tile: `finished` when its last lease expired.
    finished_at_expiry: Vec<u64>,
    /// Passes done by all the job's tiles together since it was planned or restored.
    finished: u64,
    pub failures: u32,
}

/// What an expired lease on a tile's pass adds up to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expiries {
    /// Leases of the tile's pass that expired in a row while the rest of the job did
    /// nothing: the scene, not bad luck, is what kills its renderers.
    pub stalled: u32,
    /// Leases of the tile's pass that expired, whatever the rest of the job did.
    pub total: u32,
}

impl Lending {
    /// The tiles `order` lists (each of 0 to its length once), none started, all queued in
    /// that order.
    pub fn new(order: Vec<usize>) -> Lending {
        let tiles = order.len();
        Lending {
            done: vec![0; tiles],
            lent: vec![None; tiles],
            queue: order.iter().copied().collect(),
            order,
            parked: Vec::new(),
            attempts: vec![0; tiles],
            expired: vec![Vec::new(); tiles],
            stalled: vec![0; tiles],
            finished_at_expiry: vec![0; tiles],
            finished: 0,
            failures: 0,
        }
    }

    /// Passes done by all the job's tiles together since it was planned or restored.
    pub fn finished(&self) -> u64 {
        self.finished
    }

    /// The pass the slowest tile is on: every tile has done this many passes.
    pub fn frontier(&self) -> u32 {
        self.done.iter().copied().min().unwrap_or(0)
    }

    /// The next tile to lend, taken off the queue, of a job of `passes` passes; tiles
    /// `skip` says are not for this worker (a checked pass it has rendered already) stay
    /// queued, at the front.
    pub fn next(&mut self, passes: usize, skip: impl Fn(usize, u32) -> bool) -> Option<usize> {
        let frontier = self.frontier();
        let mut not_for_this_one = Vec::new();
        let found = loop {
            let Some(t) = self.queue.pop_front() else {
                break None;
            };
            let d = self.done[t];
            if self.lent[t].is_some() || d as usize >= passes {
                continue;
            }
            if d > frontier + 1 {
                self.parked.push(t);
                continue;
            }
            if skip(t, d) {
                not_for_this_one.push(t);
                continue;
            }
            break Some(t);
        };
        for t in not_for_this_one.into_iter().rev() {
            self.queue.push_front(t);
        }
        found
    }

    /// `tile` is not lent any more and goes to the front of the queue (a job finishes
    /// sooner without stragglers).
    pub fn give_back(&mut self, tile: usize) {
        self.lent[tile] = None;
        self.queue.push_front(tile);
    }

    /// `lease` ended without a result: if it still holds `tile`, the tile is given back.
    pub fn lease_lost(&mut self, tile: usize, lease: u64) {
        if self.lent[tile] == Some(lease) {
            self.give_back(tile);
        }
    }

    /// `worker`'s `lease` on `tile` expired (the worker died, hung or lost its link): if it
    /// still holds the tile, the tile is given back and the expiry is counted. Returns the
    /// tile's expiries on this pass if it did.
    pub fn lease_expired(&mut self, tile: usize, lease: u64, worker: &str) -> Option<Expiries> {
        if self.lent[tile] != Some(lease) {
            return None;
        }
        self.give_back(tile);
        self.expired[tile].push(worker.to_string());
        self.failures += 1;
        let progressed = self.finished != self.finished_at_expiry[tile];
        self.stalled[tile] = if progressed || self.stalled[tile] == 0 {
            1
        } else {
            self.stalled[tile] + 1
        };
        self.finished_at_expiry[tile] = self.finished;
        Some(Expiries {
            stalled: self.stalled[tile],
            total: self.expired[tile].len() as u32,
        })
    }

    /// The workers whose leases on `tile`'s current pass expired, each named once.
    pub fn expired_on(&self, tile: usize) -> Vec<&str> {
        let mut names: Vec<&str> = Vec::new();
        for w in &self.expired[tile] {
            if !names.contains(&w.as_str()) {
                names.push(w);
            }
        }
        names
    }

    /// An attempt at `tile` failed: it is given back; returns its failed attempts at this
    /// pass.
    pub fn attempt_failed(&mut self, tile: usize) -> u32 {
        self.failures += 1;
        self.attempts[tile] += 1;
        self.give_back(tile);
        self.attempts[tile]
    }

    /// `tile` did its pass: it moves on, and back to the end of the queue unless that was
    /// the last of the job's `passes`.
    pub fn advance(&mut self, tile: usize, passes: usize) {
        self.done[tile] += 1;
        self.finished += 1;
        self.attempts[tile] = 0;
        self.expired[tile].clear();
        self.stalled[tile] = 0;
        self.lent[tile] = None;
        if (self.done[tile] as usize) < passes {
            self.queue.push_back(tile);
        }
    }

    /// The slowest tile moved on: the tiles waiting for it may go on.
    pub fn release_parked(&mut self) {
        self.queue.extend(self.parked.drain(..));
    }

    /// Every tile with passes left and no lease queued afresh, in order (after `lent` was
    /// reset, for a restore, or with more passes).
    pub fn requeue(&mut self, passes: usize) {
        self.queue = self
            .order
            .iter()
            .copied()
            .filter(|&i| (self.done[i] as usize) < passes && self.lent[i].is_none())
            .collect();
    }

    /// No tile lent, none parked, every unfinished tile queued: as after a restart.
    pub fn reset(&mut self, passes: usize) {
        self.lent = vec![None; self.done.len()];
        self.parked.clear();
        self.requeue(passes);
    }
}
