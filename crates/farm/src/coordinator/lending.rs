//! The workers' side of the coordinator handle: tiles lent under leases, heartbeats,
//! uploads taken back and kept, and failed attempts. (Expiry is
//! `Coordinator::expire_leases`, beside the handle.)
//!
//! An upload is decoded and checked outside the lock, and acknowledged only after the
//! store has kept it. Nothing here speaks HTTP or reads a clock other than through
//! `Coordinator::now`.

use super::error::TileRejected;
use super::job::{Hold, Landed};
use super::store::{StoreError, WebhookOutcome};
use super::verify::{Candidate, MAX_CANDIDATES, Verdict};
use super::{Coordinator, Error, Health, State};
use crate::api::{JobState, Lease, LeaseRequest};
use crate::bundle;
use axum::body::Bytes;
use kiln_image::{RgbBuffer, Windows};
use tokio::time::Instant;

impl Coordinator {
    /// [`Coordinator::lease_for`] a worker that offers no tags and says nothing of its
    /// memory.
    pub fn lease(&self, worker: &str) -> Result<Option<Lease>, Error> {
        self.lease_for(&LeaseRequest::plain(worker))
    }

    /// Lends the worker that asks, offering its tags and memory, the next pending tile
    /// pass: of the running job of highest priority that has one, whose requirements the
    /// worker meets (every tag, the memory estimated) and whose worker cap it does not
    /// pass, sharing workers between jobs of equal priority; `None` if there is no work
    /// for it now.
    pub fn lease_for(&self, req: &LeaseRequest) -> Result<Option<Lease>, Error> {
        let (worker, tags) = (req.worker.as_str(), &req.tags);
        crate::api::check_worker_name(worker).map_err(Error::BadWorkerName)?;
        crate::api::check_tags(tags).map_err(Error::BadTags)?;
        let now = self.now();
        let mut state = self.lock();
        let state = &mut *state;
        if let Some(reason) = state.workers.set_aside_reason(worker) {
            return Err(Error::SetAside {
                worker: worker.to_string(),
                reason,
            });
        }
        state.workers.seen(worker, now);
        state.workers.declare(worker, tags, req.memory_mib);
        state.workers.geometry(worker, req.geometry);
        for job in state.settle_dependents() {
            self.notify(job);
        }
        let ttl = state.leases.ttl();
        // Higher priority first; among equals, the job lent to longest ago (lease ids only
        // grow), so jobs of one priority take turns, tile by tile; then the oldest.
        let mut order: Vec<(i32, u64, u64)> = state
            .jobs
            .values()
            .filter(|j| j.state == JobState::Running)
            .map(|j| (-j.spec.priority, j.last_lent, j.id))
            .collect();
        order.sort_unstable();
        for (_, _, id) in order {
            if !matches!(state.after_of(&state.jobs[&id]), super::After::Ready) {
                continue;
            }
            let job = state.jobs.get_mut(&id).expect("listed above");
            if !job.spec.requires.iter().all(|t| tags.contains(t))
                || req.memory_mib.is_some_and(|m| m < job.memory_mib)
                || at_worker_cap(&state.leases, id, job.spec.max_workers, worker)
            {
                continue;
            }
            let Some((tile, pass)) = job.next_pending(worker) else {
                continue;
            };
            let lease = state.leases.grant(job.id, tile, pass, worker, now);
            job.lend(tile, lease, now);
            job.last_lent = lease;
            state.metrics.leases_issued += 1;
            return Ok(Some(Lease {
                lease,
                job: job.id,
                spec: job.spec.clone(),
                tile_index: tile as u32,
                tile: job.rect(tile).into(),
                pass,
                ttl_ms: ttl.as_millis() as u64,
                frame: job.frame_of(tile) as u32,
            }));
        }
        Ok(None)
    }

    /// Renews a lease. A lease of a job that stopped running ends here, so its worker
    /// stops rendering.
    pub fn heartbeat(&self, lease: u64) -> Result<(), Error> {
        let now = self.now();
        let mut state = self.lock();
        let held = state
            .leases
            .renew(lease, now)
            .ok_or(Error::UnknownLease(lease))?;
        let (job, worker) = (held.job, held.worker.clone());
        state.workers.seen(&worker, now);
        if state
            .jobs
            .get(&job)
            .is_some_and(|j| j.state != JobState::Running)
        {
            state.leases.remove(lease);
            return Err(Error::JobEnded(job));
        }
        Ok(())
    }

    /// Takes a leased tile's EXR back: checks it against the lease's tile, keeps it in the
    /// store, pastes it into the frame, and finishes the job if it was the last one. A
    /// corrupt or mismatched upload counts as a failed attempt. An upload under a lease that
    /// expired is accepted only if it is byte for byte the tile already kept.
    pub async fn upload_tile(&self, lease: u64, exr: Bytes, digest: &str) -> Result<(), Error> {
        let target = {
            let state = self.lock();
            state
                .leases
                .get(lease)
                .map(|h| (h.job, state.jobs[&h.job].spot(h.tile, h.pass)))
        };
        let Some((job, spot)) = target else {
            // Which tile was it? The upload's header says, and its bytes are compared with
            // the tile kept there: no pixel is decoded for a lease that is not live.
            let windows =
                kiln_image::read_exr_windows(&exr).map_err(|_| Error::UnknownLease(lease))?;
            return self
                .off_runtime(move |c| c.lock().judge_stale(lease, &windows, &exr))
                .await;
        };
        // The bytes are the worker's, or the tile is rendered again; and at most the tile's
        // own pixels are decoded, whatever the EXR's header claims.
        let checked = if bundle::digest_of(&exr).eq_ignore_ascii_case(digest.trim()) {
            kiln_image::decode_exr_limited(&exr, spot.pixels()).map_err(TileRejected::Decode)
        } else {
            Err(TileRejected::Digest)
        };
        let tile = match checked.and_then(|t| spot.check(&t).map(|()| t)) {
            Ok(t) => t,
            Err(why) => {
                {
                    let mut state = self.lock();
                    state.metrics.tiles_rejected += 1;
                    state.release_failed(lease, &format!("corrupt tile upload: {why}"));
                }
                self.notify(job);
                return Err(Error::RejectedTile(why));
            }
        };
        let now = self.now();
        let landed = self
            .off_runtime(move |c| c.lock().commit_tile(lease, &exr, tile, now))
            .await?;
        self.notify(job);
        // A pass's last tile's upload is answered once the frame is written (off the lock).
        if let Landed::Pass { index, pass, frame } = landed {
            self.merge(job, index, pass, frame).await;
        }
        Ok(())
    }

    /// The running sums the pass lent under `lease` continues: the tile's EXR after its
    /// previous pass, as its worker uploaded it.
    pub fn sums_for(&self, lease: u64) -> Result<Vec<u8>, Error> {
        let state = self.lock();
        let held = state.leases.get(lease).ok_or(Error::UnknownLease(lease))?;
        if held.pass.from == 0 {
            return Err(Error::NoSums(lease));
        }
        state
            .store
            .tile(held.job, held.tile, held.pass.from)?
            .ok_or(Error::NoSums(lease))
    }

    /// Records a failed attempt reported by the worker holding `lease`.
    pub fn fail_lease(&self, lease: u64, reason: &str) -> Result<(), Error> {
        let job = {
            let mut state = self.lock();
            let job = state
                .leases
                .get(lease)
                .map(|h| h.job)
                .ok_or(Error::UnknownLease(lease))?;
            state.release_failed(lease, reason);
            job
        };
        self.notify(job);
        Ok(())
    }
}

impl State {
    /// Keeps a checked tile uploaded under `lease`: in the store first (if that fails the
    /// lease stays, and expires), then in the job. A tile pass the job verifies is held
    /// until another worker's render agrees with it, and a worker whose render two others
    /// contradict is set aside. Returns what the upload did to the job (a pass it completed
    /// is merged by the caller). A lease that expired meanwhile is judged as a stale upload.
    fn commit_tile(
        &mut self,
        lease: u64,
        exr: &[u8],
        tile: RgbBuffer,
        now: Instant,
    ) -> Result<Landed, Error> {
        let Some(held) = self.leases.get(lease) else {
            return self
                .judge_stale(lease, &tile.windows(), exr)
                .map(|()| Landed::Nothing);
        };
        let (job_id, idx, pass, worker) = (held.job, held.tile, held.pass, held.worker.clone());
        let job = self.jobs.get_mut(&job_id).expect("leased jobs exist");
        if !job.expects(idx, pass.index) {
            // A pass the job no longer wants: it was stopped before it, or the tile starts
            // again. Nothing is kept.
            self.leases.remove(lease);
            job.lease_lost(idx, lease);
            self.workers.succeeded(&worker, now);
            return Ok(Landed::Nothing);
        }
        if !job.is_checked(idx, pass.index) {
            // Kept at once: the bytes as they came, no copy.
            let chain = job.unchecked_after(idx, &worker);
            let kept = self.store.insert_tile(job_id, idx, pass.to, exr, &chain);
            self.kept(job_id, kept)?;
            self.leases.remove(lease);
            self.metrics.tiles_accepted += 1;
            self.workers.succeeded(&worker, now);
            let job = self.jobs.get_mut(&job_id).expect("leased jobs exist");
            return job
                .complete_tile(idx, pass.index, &tile, chain)
                .map_err(Error::Image);
        }
        let render = Candidate {
            worker: worker.clone(),
            exr: exr.to_vec(),
            tile,
        };
        let (verdict, chain) = job.judge(idx, pass.index, render);
        let (render, agreeing, wrong) = match verdict {
            Verdict::Held => {
                self.leases.remove(lease);
                self.workers.succeeded(&worker, now);
                self.metrics.tiles_held += 1;
                return Ok(Landed::Nothing);
            }
            Verdict::Chaos => {
                let why =
                    format!("no two of {MAX_CANDIDATES} workers' renders of this tile pass agree");
                self.release_failed(lease, &why);
                return Ok(Landed::Nothing);
            }
            Verdict::Keep {
                render,
                agreeing,
                wrong,
            } => (render, agreeing, wrong),
        };
        let kept = self
            .store
            .insert_tile(job_id, idx, pass.to, &render.exr, &chain)
            .and_then(|()| self.store.add_verified(job_id));
        self.kept(job_id, kept)?;
        self.leases.remove(lease);
        self.metrics.tiles_accepted += 1;
        self.workers.succeeded(&worker, now);
        let job = self.jobs.get_mut(&job_id).expect("leased jobs exist");
        let mut landed = job
            .complete_tile(idx, pass.index, &render.tile, chain)
            .map_err(Error::Image)?;
        for w in wrong {
            let reason = format!(
                "its render of job {job_id} tile {idx} pass {} ({} samples) differs, bit for bit, from the render {} and {} agree on",
                pass.index, pass.to, agreeing[0], agreeing[1]
            );
            if self.set_aside(&w, reason).contains(&job_id) {
                // Its tiles start again: the pass this upload completed is not whole.
                landed = Landed::Nothing;
            }
        }
        Ok(landed)
    }

    /// Sets `worker` aside for `reason` (recorded in the store, so a restart keeps it so):
    /// it gets no more leases, the ones it holds end, its renders waiting to be compared
    /// are dropped, and every tile whose sums hold its unchecked renders is rendered again
    /// from nothing, in running jobs and in done ones, which run again (their result was
    /// not what the scene renders to, as far as anyone can tell; their webhook is called
    /// again when they end again). (A job is rebuilt from the store under the lock: slow
    /// for a big job, and rare.) Returns the jobs whose tiles start again.
    fn set_aside(&mut self, worker: &str, reason: String) -> Vec<u64> {
        tracing::warn!("worker {worker} is set aside: {reason}");
        if let Err(e) = self.store.set_aside(worker, &reason) {
            tracing::error!("cannot record that worker {worker} is set aside: {e}");
        }
        self.workers.set_aside(worker, reason.clone());
        self.metrics.workers_set_aside += 1;
        for (id, held) in self.leases.remove_where(|h| h.worker == worker) {
            if let Some(job) = self.jobs.get_mut(&held.job) {
                job.lease_lost(held.tile, id);
            }
        }
        let open: Vec<u64> = self
            .jobs
            .values()
            .filter(|j| matches!(j.state, JobState::Running | JobState::Done))
            .map(|j| j.id)
            .collect();
        let mut rebuilt = Vec::new();
        for id in open {
            let job = self.jobs.get_mut(&id).expect("listed above");
            job.forget_worker(worker);
            let tiles = job.tiles_unchecked_by(worker);
            if tiles.is_empty() {
                continue;
            }
            let (was_done, legacy) = (job.state == JobState::Done, job.last_samples());
            if was_done {
                // Recorded first: a job never runs again in memory only.
                let reopened = self
                    .store
                    .set_state(id, JobState::Running, None)
                    .and_then(|()| self.store.set_webhook(id, WebhookOutcome::Pending));
                if let Err(e) = reopened {
                    tracing::error!("job {id}: cannot run it again for {worker}'s tiles: {e}");
                    continue;
                }
                let job = self.jobs.get_mut(&id).expect("listed above");
                job.reopen();
            }
            let rows = self
                .store
                .drop_tiles(id, &tiles)
                .and_then(|()| self.store.tiles(id, legacy));
            let rows = match rows {
                Ok(rows) => rows,
                Err(e) => {
                    tracing::error!("job {id}: cannot render {worker}'s tiles again: {e}");
                    continue;
                }
            };
            for (lease, held) in self
                .leases
                .remove_where(|h| h.job == id && tiles.contains(&h.tile))
            {
                tracing::info!("lease {lease} ends: its tile {} starts again", held.tile);
            }
            let job = self.jobs.get_mut(&id).expect("listed above");
            job.rebuild(rows, &tiles);
            job.notice = Some(format!(
                "{} tiles are rendered again from nothing: their sums held renders of worker {worker}, set aside because {reason}",
                tiles.len()
            ));
            rebuilt.push(id);
            tracing::warn!(
                "job {id}: {} tiles holding {worker}'s unchecked renders start again",
                tiles.len()
            );
        }
        rebuilt
    }

    /// An upload under an unknown or expired lease: fine if it is the very tile already
    /// kept for its place (a worker whose lease expired finished anyway), else a conflict.
    fn judge_stale(&self, lease: u64, tile: &Windows, exr: &[u8]) -> Result<(), Error> {
        let mut relent = false;
        for job in self.jobs.values() {
            // One tile per frame of a shot has these windows.
            for idx in job.find_tiles(tile) {
                if self.store.holds_tile(job.id, idx, exr)? {
                    return Ok(());
                }
                relent |= !job.is_finished(idx);
            }
        }
        Err(if relent {
            Error::Relent(lease)
        } else {
            Error::StaleTile(lease)
        })
    }

    /// Notes how keeping a tile of `job` in the store went. A failure (a full disk) holds
    /// the job back, said in its status and the coordinator's health and logged once; the
    /// worker is answered with an error and keeps its render to upload again. A success
    /// after failures lets the job go.
    fn kept(&mut self, job: u64, result: Result<(), StoreError>) -> Result<(), Error> {
        let trouble = result.as_ref().err().map(ToString::to_string);
        let was_in_trouble = self.health.store.is_some();
        Health::note(
            &mut self.health.store,
            "keeping tiles in the job store",
            trouble.clone(),
        );
        if let Some(j) = self.jobs.get_mut(&job) {
            match &trouble {
                Some(why) => {
                    j.held_back.insert(
                        Hold::Store,
                        format!("the job store cannot keep its tiles ({why}): workers keep their renders and upload them again"),
                    );
                }
                None => {
                    j.held_back.remove(&Hold::Store);
                }
            }
        }
        if trouble.is_none() && was_in_trouble {
            // Every job waiting on the store may go on.
            for j in self.jobs.values_mut() {
                j.held_back.remove(&Hold::Store);
            }
        }
        Ok(result?)
    }

    /// Ends a lease whose attempt failed: the tile goes back to the queue, or fails its job.
    fn release_failed(&mut self, lease: u64, reason: &str) {
        let Some(held) = self.leases.remove(lease) else {
            return;
        };
        self.workers.failed(&held.worker);
        let Some(job) = self.jobs.get_mut(&held.job) else {
            return;
        };
        if job.attempt_failed(held.tile, reason) {
            self.persist(held.job);
        }
    }
}

/// Whether job `job`, capped at `cap` workers, has its most workers holding its leases
/// without `worker` (a worker already holding one may take more).
fn at_worker_cap(leases: &super::leases::Leases, job: u64, cap: Option<u32>, worker: &str) -> bool {
    let Some(cap) = cap else {
        return false;
    };
    let mut holders = std::collections::BTreeSet::new();
    for (_, held) in leases.iter().filter(|(_, h)| h.job == job) {
        if held.worker == worker {
            return false;
        }
        holders.insert(held.worker.as_str());
    }
    holders.len() >= cap as usize
}
