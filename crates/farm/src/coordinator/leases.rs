//! Leases: which worker holds which tile until when, and which workers may hold any.
//!
//! Time comes in from the caller as `now`; nothing here reads a clock, so expiry is a pure
//! function of the instants passed in. The coordinator passes `tokio::time::Instant::now()`,
//! which tests stop and move with `tokio::time::pause` and `advance`. This must never touch
//! jobs, the store or HTTP: the coordinator tells jobs what happened to their tiles.

use super::MAX_WORKER_FAILURES;
use crate::api::PassRange;
use std::collections::HashMap;
use std::time::Duration;
use tokio::time::Instant;

/// A tile lent to a worker.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Held {
    pub job: u64,
    pub tile: usize,
    pub pass: PassRange,
    pub worker: String,
    deadline: Instant,
}

/// The leases outstanding. Ids are never reused, across restarts too: an id is the
/// coordinator's epoch (how many times its store was opened) times 2^40 plus a count, so a
/// worker that still holds an id from before a restart names no lease granted after it.
/// (2^40 leases are seven years at 5,000 a second.)
pub(super) struct Leases {
    held: HashMap<u64, Held>,
    next: u64,
    ttl: Duration,
}

/// Lease ids per epoch.
const EPOCH_LEASES: u64 = 1 << 40;

impl Leases {
    /// Leases that last `ttl` from their grant or last renewal, with ids of `epoch`.
    pub fn new(ttl: Duration, epoch: u64) -> Leases {
        Leases {
            held: HashMap::new(),
            next: epoch * EPOCH_LEASES + 1,
            ttl,
        }
    }

    pub fn ttl(&self) -> Duration {
        self.ttl
    }

    /// Lends pass `pass` of `tile` of `job` to `worker` until `now + ttl`; returns the lease's id.
    pub fn grant(
        &mut self,
        job: u64,
        tile: usize,
        pass: PassRange,
        worker: &str,
        now: Instant,
    ) -> u64 {
        let id = self.next;
        self.next += 1;
        self.held.insert(
            id,
            Held {
                job,
                tile,
                pass,
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
            .filter_map(|id| Some((id, self.remove(id)?)))
            .collect()
    }

    pub fn len(&self) -> usize {
        self.held.len()
    }

    /// Ends every lease `which` picks; returns them.
    pub fn remove_where(&mut self, which: impl Fn(&Held) -> bool) -> Vec<(u64, Held)> {
        let ids: Vec<u64> = self
            .held
            .iter()
            .filter(|(_, h)| which(h))
            .map(|(&id, _)| id)
            .collect();
        ids.into_iter()
            .filter_map(|id| Some((id, self.remove(id)?)))
            .collect()
    }

    /// Every lease held, by id.
    pub fn iter(&self) -> impl Iterator<Item = (&u64, &Held)> {
        self.held.iter()
    }
}

/// One worker as the coordinator knows it.
#[derive(Debug, Clone, Default)]
pub(super) struct WorkerRecord {
    /// Failed attempts since its last success.
    pub consecutive_failures: u32,
    pub tiles_done: u64,
    pub failures: u64,
    /// When it last asked for work, renewed a lease or uploaded.
    pub last_seen: Option<Instant>,
    /// Why it gets no more leases, if it does not.
    pub set_aside: Option<String>,
    /// The tags it declared with its last request for work.
    pub tags: Vec<String>,
    /// The memory it offered then, in MiB (None: not said, taken as enough).
    pub memory_mib: Option<u64>,
    /// What its geometry cache had done, as it last said.
    pub geometry: Option<crate::api::GeometryCounts>,
}

/// Workers' records: what they did, when they were last heard from, and whether they are
/// set aside (too many failures in a row, or a render that disagreed with others').
#[derive(Default)]
pub(super) struct Workers {
    records: std::collections::BTreeMap<String, WorkerRecord>,
}

impl Workers {
    /// Why the worker gets no more leases: None if it does.
    pub fn set_aside_reason(&self, worker: &str) -> Option<String> {
        let r = self.records.get(worker)?;
        if let Some(why) = &r.set_aside {
            return Some(why.clone());
        }
        (r.consecutive_failures >= MAX_WORKER_FAILURES)
            .then(|| format!("it failed {MAX_WORKER_FAILURES} tiles in a row"))
    }

    #[cfg(test)]
    pub fn is_set_aside(&self, worker: &str) -> bool {
        self.set_aside_reason(worker).is_some()
    }

    fn record(&mut self, worker: &str) -> &mut WorkerRecord {
        self.records.entry(worker.to_string()).or_default()
    }

    pub fn seen(&mut self, worker: &str, now: Instant) {
        self.record(worker).last_seen = Some(now);
    }

    /// Notes what `worker` offered with a request for work: its tags and memory.
    pub fn declare(&mut self, worker: &str, tags: &[String], memory_mib: Option<u64>) {
        let r = self.record(worker);
        if r.tags != tags {
            r.tags = tags.to_vec();
        }
        r.memory_mib = memory_mib;
    }

    /// Notes what `worker`'s geometry cache has done, if it said.
    pub fn geometry(&mut self, worker: &str, counts: Option<crate::api::GeometryCounts>) {
        if counts.is_some() {
            self.record(worker).geometry = counts;
        }
    }

    /// Why no worker heard from can take a job that requires `tags` and `memory_mib` MiB,
    /// if none can: the required tags no worker has, that no one worker has them all, or
    /// that none with them offers the memory. None when some worker not set aside can, or
    /// the job requires no tag and no worker offers too little memory.
    pub fn none_can_take(&self, tags: &[String], memory_mib: u64) -> Option<String> {
        let able = self.records.values().filter(|r| r.set_aside.is_none());
        let has = |r: &WorkerRecord, t: &String| r.tags.contains(t);
        let tagged = able.clone().filter(|r| tags.iter().all(|t| has(r, t)));
        let enough = |r: &WorkerRecord| r.memory_mib.is_none_or(|m| m >= memory_mib);
        if tagged.clone().any(enough) {
            return None;
        }
        if let Some(most) = tagged.clone().filter_map(|r| r.memory_mib).max() {
            return Some(format!(
                "it needs about {memory_mib} MiB and the most a worker{} offers is {most} MiB (kiln worker --memory)",
                if tags.is_empty() {
                    ""
                } else {
                    " with its tags"
                }
            ));
        }
        if tags.is_empty() {
            // No worker heard from yet.
            return None;
        }
        let missing: Vec<&str> = tags
            .iter()
            .filter(|t| !able.clone().any(|r| has(r, t)))
            .map(String::as_str)
            .collect();
        Some(if missing.is_empty() {
            format!(
                "no worker has every tag it requires ({}), though each is some worker's",
                tags.join(", ")
            )
        } else {
            format!(
                "no worker has the tag{} {} it requires (kiln worker --tags)",
                if missing.len() == 1 { "" } else { "s" },
                missing.join(", ")
            )
        })
    }

    pub fn failed(&mut self, worker: &str) {
        let r = self.record(worker);
        r.consecutive_failures += 1;
        r.failures += 1;
    }

    pub fn succeeded(&mut self, worker: &str, now: Instant) {
        let r = self.record(worker);
        r.consecutive_failures = 0;
        r.tiles_done += 1;
        r.last_seen = Some(now);
    }

    /// Gives the worker no more leases, for `reason` (the first reason stays).
    pub fn set_aside(&mut self, worker: &str, reason: String) {
        self.record(worker).set_aside.get_or_insert(reason);
    }

    /// Trusts `worker` again: it was set aside, and an operator says it is fixed.
    pub fn reinstate(&mut self, worker: &str) {
        if let Some(r) = self.records.get_mut(worker) {
            r.set_aside = None;
            r.consecutive_failures = 0;
        }
    }

    /// Every worker seen, by name.
    pub fn iter(&self) -> impl Iterator<Item = (&String, &WorkerRecord)> {
        self.records.iter()
    }

    /// Forgets the workers last heard from before `before` (never heard from, for those
    /// only set aside) that are not set aside and hold no lease (`busy` says which do):
    /// workers come and go, and a record per name ever used must not pile up. Then, past
    /// [`MAX_WORKERS`] records, forgets the longest unheard of those it may. Returns how
    /// many it forgot.
    pub fn forget_unheard(&mut self, before: Instant, busy: impl Fn(&str) -> bool) -> usize {
        let n = self.records.len();
        let keep = |name: &String, r: &WorkerRecord| {
            r.set_aside.is_some() || busy(name) || r.last_seen.is_some_and(|t| t >= before)
        };
        self.records.retain(|name, r| keep(name, r));
        if self.records.len() > MAX_WORKERS {
            let mut idle: Vec<(Option<Instant>, String)> = self
                .records
                .iter()
                .filter(|(name, r)| r.set_aside.is_none() && !busy(name))
                .map(|(name, r)| (r.last_seen, name.clone()))
                .collect();
            idle.sort();
            let excess = self.records.len() - MAX_WORKERS;
            for (_, name) in idle.into_iter().take(excess) {
                self.records.remove(&name);
            }
        }
        n - self.records.len()
    }
}

/// The most workers the coordinator keeps records of (set-aside ones and ones holding a
/// lease are kept whatever their number).
pub const MAX_WORKERS: usize = 10_000;

/// How long a worker may stay silent before its record is forgotten (it comes back as new).
pub const FORGET_WORKERS_AFTER: Duration = Duration::from_secs(3600);

#[cfg(test)]
mod tests {
    const P: crate::api::PassRange = crate::api::PassRange {
        index: 0,
        from: 0,
        to: 1,
    };
    use super::*;

    const TTL: Duration = Duration::from_secs(20);
    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn a_lease_expires_only_after_its_deadline_and_renewals_move_it() {
        let t0 = Instant::now();
        let mut leases = Leases::new(TTL, 1);
        let a = leases.grant(7, 3, P, "w", t0);
        let b = leases.grant(7, 4, P, "w", t0 + 5 * TTL / 20);
        assert!(
            leases.expire(t0 + TTL).is_empty(),
            "due at t0 + ttl, not before"
        );
        let gone = leases.expire(t0 + TTL + MS);
        assert_eq!(gone.len(), 1);
        assert_eq!((gone[0].0, gone[0].1.job, gone[0].1.tile), (a, 7, 3));
        assert!(leases.get(a).is_none() && leases.renew(a, t0).is_none());
        // b was granted 5 s later; a heartbeat at 19 s gives it until 39 s.
        assert_eq!(leases.renew(b, t0 + 19 * TTL / 20).map(|h| h.tile), Some(4));
        assert!(leases.expire(t0 + TTL + TTL * 19 / 20).is_empty());
        assert_eq!(leases.expire(t0 + 2 * TTL).len(), 1);
        assert_eq!(leases.len(), 0);
    }

    #[test]
    fn lease_ids_are_never_reused() {
        let t0 = Instant::now();
        let mut leases = Leases::new(TTL, 1);
        let a = leases.grant(1, 0, P, "w", t0);
        assert!(leases.remove(a).is_some());
        assert!(leases.remove(a).is_none());
        let b = leases.grant(1, 0, P, "w", t0);
        assert!(b > a);
        leases.expire(t0 + 2 * TTL);
        assert!(leases.grant(1, 0, P, "w", t0) > b);
    }

    #[test]
    fn a_worker_is_set_aside_after_failures_in_a_row_only() {
        let mut workers = Workers::default();
        let t0 = Instant::now();
        workers.seen("w", t0);
        for _ in 1..MAX_WORKER_FAILURES {
            workers.failed("w");
        }
        workers.succeeded("w", t0);
        for _ in 1..MAX_WORKER_FAILURES {
            workers.failed("w");
        }
        assert!(
            !workers.is_set_aside("w"),
            "a success in between resets the count"
        );
        workers.failed("w");
        assert!(workers.is_set_aside("w"));
        assert!(!workers.is_set_aside("other"));
        workers.set_aside("v", "it disagreed".into());
        workers.set_aside("v", "later".into());
        assert_eq!(workers.set_aside_reason("v").unwrap(), "it disagreed");
    }
}
