//! The coordinator: keeps jobs, scene bundles and finished tiles durable in a data
//! directory, lends tiles to workers under leases, merges their EXRs and reports progress.
//!
//! - [`Coordinator`] (here) is the cheap-clone handle every request works through; its
//!   methods are the operations, in `jobs.rs` (scenes, jobs, results: the client's side)
//!   and `lending.rs` (leases, heartbeats, uploads, failures: the workers' side).
//! - `http.rs` turns requests into those calls and errors into JSON responses.
//! - `listen.rs` holds the connections: a limit on how many, a header-read timeout, the
//!   open-file limit raised, and hyper's own error answers made JSON.
//! - `merge.rs` writes a finished job's frame without holding the lock.
//! - `prepass.rs` keeps what workers compute once per job and share (photon maps, SPPM
//!   passes) beside the scene bundle, and who is computing what.
//! - `job.rs` (one job's tiles and frame), `leases.rs` (the lease table and worker records)
//!   and `metrics.rs` (counters) are plain state; `store/` is the job store (a trait, and
//!   its SQLite and PostgreSQL back-ends with versioned migrations), `data_dir.rs` the data
//!   directory's files; `error.rs` names the failures.
//! - `leader.rs` opens the store the configuration names and, on one that several
//!   coordinators share, waits for the lead, renews it and notices when it is lost.

mod credentials;
mod data_dir;
mod denoised;
mod error;
mod http;
mod job;
mod jobs;
mod leader;
mod leases;
mod lending;
mod listen;
mod merge;
mod metrics;
mod objects;
mod prepass;
#[cfg(test)]
mod proptests;
mod store;
mod stored;
#[cfg(test)]
mod tests;
mod tls;
mod verify;
mod webhooks;

pub use error::{Error, PlanError, TileRejected};
pub use http::app;
pub use leader::{Candidate, stand_by};
pub use listen::MAX_HEAD_BYTES;
pub use store::StoreError;
pub use stored::Stored;
pub use tls::{TlsFiles, check as check_tls};

use crate::api::{JobState, JobStatus};
use data_dir::DataDir;
use job::Job;
use leases::{Leases, Workers};
use metrics::Metrics;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use store::JobStore;
use tokio::sync::broadcast;
use tokio::time::Instant;

/// Tiles a job gives up on after this many failed attempts.
pub const MAX_TILE_ATTEMPTS: u32 = 3;
/// Tiles a job gives up on after their renderers died (their leases expired) this many
/// times on one pass while the rest of the job went on. Workers die of their own too, and
/// chance must not fail a job: with one attempt in five lost, a tile of a thousand-tile
/// frame loses ten in a row about once in ten thousand frames.
pub const MAX_TILE_EXPIRIES: u32 = 10;
/// A worker whose attempts fail this many times in a row gets no more leases.
pub const MAX_WORKER_FAILURES: u32 = 5;

#[derive(Debug, Clone)]
pub struct Config {
    pub data_dir: PathBuf,
    pub token: Option<String>,
    pub lease_ttl: Duration,
    pub max_scene_bytes: usize,
    /// The largest shared pre-pass (photon maps, an SPPM pass) a worker may upload; 512 MiB
    /// by default (a map of ten million photons is some 400 MB).
    pub max_prepass_bytes: usize,
    /// The first wait before a merged frame that could not be written (a full disk) is
    /// written again; it doubles, to at most a minute.
    pub merge_retry: Duration,
    /// How many job submissions may load their scenes at once (each holds its scene in
    /// memory while it plans); the others wait their turn. 2 by default.
    pub max_plannings: usize,
    pub max_tile_bytes: usize,
    /// The most pixels a job's frame (its crop window) may hold: the frame is allocated
    /// when the job is created. 16384 x 16384 by default (3 GiB of float RGB).
    pub max_frame_pixels: u64,
    /// The most pixels a frame denoised for a preview may hold (denoising holds about 300
    /// bytes a pixel while it runs): 4096 x 4096 by default.
    pub max_denoised_pixels: u64,
    /// The pause before a failed webhook call is retried; it doubles after each failure,
    /// up to a minute.
    pub webhook_backoff: Duration,
    /// Connections open at once; one more is answered 503. 1,024 by default, fewer where
    /// the process may not open that many files.
    pub max_connections: usize,
    /// How long a connection may take to send a request's head, and so also how long a
    /// kept-alive connection may sit idle between requests: 30 s by default.
    pub header_timeout: Duration,
    /// Serve https with this certificate and key (PEM) rather than plain http.
    pub tls: Option<TlsFiles>,
    /// The job store: None for SQLite in the data directory, or a `postgres://` URL of a
    /// server that several coordinators may share.
    pub store: Option<String>,
    /// On a shared store, how this coordinator leads: it waits as a standby until the lead
    /// is free. Required with a `postgres://` store.
    pub candidate: Option<Candidate>,
    /// Scene bundles, pre-passes and merged frames also kept in this S3 bucket
    /// (`s3://bucket/prefix`), so that every coordinator of the farm finds them.
    pub objects: Option<String>,
}

impl Config {
    pub fn new(data_dir: PathBuf) -> Config {
        Config {
            data_dir,
            token: None,
            lease_ttl: Duration::from_secs(20),
            max_scene_bytes: 2 << 30,
            max_prepass_bytes: 512 << 20,
            merge_retry: Duration::from_secs(1),
            max_plannings: 2,
            max_tile_bytes: 256 << 20,
            max_frame_pixels: kiln_image::MAX_PIXELS,
            max_denoised_pixels: 1 << 24,
            webhook_backoff: Duration::from_secs(1),
            max_connections: 1024,
            header_timeout: Duration::from_secs(30),
            tls: None,
            store: None,
            candidate: None,
            objects: None,
        }
    }
}

/// The shared state handle: cheap to clone (one `Arc`), one per request.
#[derive(Clone)]
pub struct Coordinator {
    shared: Arc<Shared>,
}

struct Shared {
    config: Config,
    files: DataDir,
    /// The S3 bucket bundles, pre-passes and merged frames are also kept in, if any.
    objects: Option<objects::Objects>,
    /// A std mutex, not tokio's (as tokio's docs advise for short critical sections):
    /// every critical section is a few assignments and at most one small SQLite
    /// statement, and none is held across an `.await` (a std guard is not `Send`, so a
    /// handler or task that tried would not compile). Slow work (parsing scenes, decoding
    /// uploads, encoding and writing the merged frame or a preview) happens outside it.
    /// SQLite wants one writer, which this also gives it.
    state: Mutex<State>,
    /// Job ids whose status changed, for progress events.
    events: broadcast::Sender<u64>,
    /// Who is computing which shared pre-pass, and since when (`prepass.rs`). Apart from
    /// the state lock: claims touch nothing else.
    prepass_claims: Mutex<prepass::Claims>,
    /// Turns to plan a job (load its scene): [`Config::max_plannings`] at once.
    plannings: tokio::sync::Semaphore,
    /// The frames denoised last, and the turn to denoise one (`denoised.rs`).
    denoised: tokio::sync::Mutex<denoised::Denoised>,
    /// Tests hold a merge here to watch what other requests do meanwhile.
    #[cfg(test)]
    merge_hook: Mutex<Option<Box<dyn FnOnce() + Send>>>,
    /// Tests run this on the planning thread of every job planned.
    #[cfg(test)]
    plan_hook: Mutex<Option<Arc<dyn Fn() + Send + Sync>>>,
}

/// Everything the lock guards.
struct State {
    /// The job store (SQLite in the data directory, or a shared PostgreSQL server).
    store: Box<dyn JobStore>,
    jobs: BTreeMap<u64, Job>,
    leases: Leases,
    workers: Workers,
    metrics: Metrics,
    health: Health,
    /// The tokens issued.
    credentials: credentials::Credentials,
}

/// What keeps the coordinator from keeping work right now (a full disk, a store that
/// refuses writes), as `/healthz` and the jobs' statuses say it. Each is logged once when
/// it starts and once when it ends, however many requests meet it meanwhile.
#[derive(Debug, Default)]
struct Health {
    /// Why the job store cannot write.
    store: Option<String>,
    /// Why a merged frame cannot be written to the data directory.
    files: Option<String>,
}

impl Health {
    /// Records `now` as what is wrong with `doing` (None: nothing), logging a change.
    fn note(slot: &mut Option<String>, doing: &str, now: Option<String>) {
        if *slot == now {
            return;
        }
        match &now {
            Some(why) => tracing::error!("{doing} fails: {why}; work waits until it can be kept"),
            None => tracing::info!("{doing} works again"),
        }
        *slot = now;
    }

    /// What `/healthz` says beyond being up.
    fn detail(&self) -> Vec<String> {
        let store = self
            .store
            .iter()
            .map(|w| format!("the job store cannot keep tiles: {w}"));
        let files = self
            .files
            .iter()
            .map(|w| format!("merged frames cannot be written: {w}"));
        store.chain(files).collect()
    }
}

impl Coordinator {
    /// Opens (or creates) the data directory and resumes every unfinished job in it.
    pub fn open(config: Config) -> Result<Coordinator, Error> {
        // On a shared store, a standby waits for the lead before it touches the data
        // directory (opening it clears a dead coordinator's leftovers).
        let shared = match config.store.as_deref() {
            Some(url) => {
                let store = leader::open_store(Some(url), std::path::Path::new(""))?;
                let me = config.candidate.as_ref().ok_or_else(|| {
                    StoreError::new("a shared job store needs a candidate to lead as".to_string())
                })?;
                leader::wait_for_lead(&*store, me)?;
                Some(store)
            }
            None => None,
        };
        let objects = match config.objects.as_deref() {
            Some(url) => Some(objects::Objects::open(url).map_err(Error::Objects)?),
            None => None,
        };
        let files = DataDir::create(&config.data_dir)?;
        let store = match shared {
            Some(store) => store,
            None => leader::open_store(None, &files.database())?,
        };
        // Merged frames whose jobs the store does not hold: the database (or its WAL) was
        // lost or replaced. Starting would hide those jobs for good; say so instead.
        let stored: std::collections::HashSet<u64> = store.jobs()?.iter().map(|j| j.id).collect();
        let lost: Vec<u64> = files
            .job_folders()?
            .into_iter()
            .filter(|id| !stored.contains(id))
            .collect();
        if !lost.is_empty() {
            return Err(Error::LostJobs(format!(
                "{}: the store has no record of jobs {lost:?}, whose frames are in jobs/: kiln.sqlite (or its -wal file) was truncated, deleted or replaced. Restore it, or move those folders out of jobs/ to start without them",
                config.data_dir.display()
            )));
        }
        let epoch = store.next_epoch()?;
        // Workers set aside stay so across restarts, until an operator reinstates them.
        let mut workers = Workers::default();
        for (name, reason) in store.set_aside_workers()? {
            workers.set_aside(&name, reason);
        }
        let credentials = credentials::Credentials::new(store.tokens()?);
        let (events, _) = broadcast::channel(1024);
        let plannings = tokio::sync::Semaphore::new(config.max_plannings.max(1));
        let coordinator = Coordinator {
            shared: Arc::new(Shared {
                state: Mutex::new(State {
                    store,
                    jobs: BTreeMap::new(),
                    leases: Leases::new(config.lease_ttl, epoch),
                    workers,
                    metrics: Metrics::default(),
                    health: Health::default(),
                    credentials,
                }),
                files,
                objects,
                config,
                events,
                prepass_claims: Mutex::new(prepass::Claims::default()),
                plannings,
                denoised: tokio::sync::Mutex::new(denoised::Denoised::default()),
                #[cfg(test)]
                merge_hook: Mutex::new(None),
                #[cfg(test)]
                plan_hook: Mutex::new(None),
            }),
        };
        coordinator.resume()?;
        Ok(coordinator)
    }

    /// Loads every job in the store with the tiles it kept; a running job whose tiles are
    /// all kept is merged now.
    fn resume(&self) -> Result<(), Error> {
        let stored = self.lock().store.jobs()?;
        for s in stored {
            let id = s.id;
            let max_pixels = self.config().max_frame_pixels;
            let scenes = self.files().scenes();
            if let Ok(spec) = &s.spec {
                // A coordinator that took the lead on another host fetches the scene; an
                // object store that cannot be reached stops the start (it is tried again),
                // rather than failing jobs whose scenes are safe.
                self.ensure_bundle(&spec.scene)?;
            }
            let planned = match s.spec.clone() {
                Ok(spec) => Job::plan(&scenes, id, spec, s.state, max_pixels)
                    .map_err(|e| format!("it cannot be resumed: {e}")),
                Err(why) => Err(why),
            };
            let mut job = match planned {
                Ok(j) => j,
                Err(why) => {
                    // Kept in the list, failed with the reason, and the rest resume.
                    tracing::error!("job {id}: {why}");
                    let job = Job::damaged(id, s.spec.ok(), s.state, why);
                    let mut state = self.lock();
                    if job.state != s.state {
                        state.store.set_state(id, job.state, job.error.as_deref())?;
                    }
                    state.jobs.insert(id, job);
                    continue;
                }
            };
            job.error = s.error;
            let total = job.status(self.now()).passes.last().copied().unwrap_or(0);
            let (kept, verified) = {
                let state = self.lock();
                (state.store.tiles(id, total)?, state.store.verified(id)?)
            };
            job.restore(kept);
            job.verification.verified = verified;
            // The last complete pass is merged again: the coordinator may have stopped
            // before writing it. (A job that ended keeps its result as it is.)
            let merge = if job.state == JobState::Running {
                job.to_merge()
            } else {
                Vec::new()
            };
            self.lock().jobs.insert(id, job);
            for m in merge {
                self.merge_blocking(id, m.index, m.pass, &m.frame);
            }
        }
        Ok(())
    }

    pub fn config(&self) -> &Config {
        &self.shared.config
    }

    /// Runs `f`, work that may wait on the job store, on a blocking thread rather than one
    /// of the runtime's: a store on a server answers in a network round trip, or not at
    /// all for seconds while it is away.
    pub(super) async fn off_runtime<T: Send + 'static>(
        &self,
        f: impl FnOnce(&Coordinator) -> Result<T, Error> + Send + 'static,
    ) -> Result<T, Error> {
        let c = self.clone();
        tokio::task::spawn_blocking(move || f(&c)).await?
    }

    fn files(&self) -> &DataDir {
        &self.shared.files
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock poisons it; the state is still consistent
        // (every mutation is a few plain assignments), so carry on.
        self.shared.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The time leases and rates are measured in: tokio's clock, which tests pause and
    /// advance (outside a runtime, and in production, it is the system's monotonic clock).
    /// The only place the coordinator reads the time.
    fn now(&self) -> Instant {
        Instant::now()
    }

    fn notify(&self, job: u64) {
        let _ = self.shared.events.send(job);
    }

    fn subscribe(&self) -> broadcast::Receiver<u64> {
        self.shared.events.subscribe()
    }

    pub fn status(&self, id: u64) -> Option<JobStatus> {
        let now = self.now();
        let state = self.lock();
        state.jobs.get(&id).map(|j| state.status_of(j, now))
    }

    pub fn statuses(&self) -> Vec<JobStatus> {
        let now = self.now();
        let state = self.lock();
        state
            .jobs
            .values()
            .map(|j| state.status_of(j, now))
            .collect()
    }

    /// What `/healthz` says: "ok", and what keeps work from being kept, if anything.
    pub fn health(&self) -> String {
        let detail = self.lock().health.detail();
        if detail.is_empty() {
            "ok\n".into()
        } else {
            format!("ok, but {}\n", detail.join("; "))
        }
    }

    /// Returns expired leases' tiles to their jobs' queues (failing a job whose tile has
    /// now failed too often), and forgets workers long silent.
    pub fn expire_leases(&self) {
        let now = self.now();
        let failed = self.lock().expire_leases(now);
        for job in failed {
            self.notify(job);
        }
    }
}

/// Where a job stands with the jobs it starts after.
enum After {
    /// Every one is done (or ended, as the job asks): it may be lent.
    Ready,
    /// Why it waits.
    Waiting(String),
    /// Why it fails: one it waits on to be done failed or was cancelled.
    Failed(String),
}

impl State {
    /// A job's status, with what it waits for: the jobs it starts after, or a worker that
    /// can take it when none of those heard from can.
    fn status_of(&self, job: &Job, now: Instant) -> JobStatus {
        let mut status = job.status(now);
        if job.state == JobState::Running {
            status.waiting = match self.after_of(job) {
                After::Ready => self
                    .workers
                    .none_can_take(&job.spec.requires, job.memory_mib),
                After::Waiting(why) | After::Failed(why) => Some(why),
            };
        }
        status
    }

    /// Checks the jobs a new job is to start after: at most [`crate::api::MAX_AFTER`], each
    /// one that exists. (A job can wait only on jobs created before it, so no circle of
    /// jobs waiting on each other can form.)
    fn check_after(&self, after: &[u64]) -> Result<(), String> {
        if after.len() > crate::api::MAX_AFTER {
            return Err(format!(
                "{} jobs; a job starts after at most {}",
                after.len(),
                crate::api::MAX_AFTER
            ));
        }
        match after.iter().find(|id| !self.jobs.contains_key(id)) {
            Some(id) => Err(format!(
                "no job {id} (a job starts only after jobs created before it)"
            )),
            None => Ok(()),
        }
    }

    /// Where `job` stands with the jobs it starts after.
    fn after_of(&self, job: &Job) -> After {
        let spec = &job.spec;
        let mut waits = Vec::new();
        for id in &spec.after {
            let state = self.jobs.get(id).map_or(JobState::Failed, |j| j.state);
            match state {
                JobState::Done => {}
                JobState::Running => waits.push(format!("job {id}")),
                JobState::Failed | JobState::Cancelled if spec.after_ended => {}
                JobState::Failed | JobState::Cancelled => {
                    let why = format!("job {id}, which it starts after, {}", state.as_str());
                    if !spec.hold_on_failure {
                        return After::Failed(why);
                    }
                    waits.push(format!("{why} (held: cancel this job to end it)"));
                }
            }
        }
        if waits.is_empty() {
            return After::Ready;
        }
        let until = if spec.after_ended { "ended" } else { "done" };
        After::Waiting(format!("starts after {} ({until})", waits.join(", ")))
    }

    /// Fails the running jobs that start after a job that failed or was cancelled (unless
    /// they hold); returns them.
    fn settle_dependents(&mut self) -> Vec<u64> {
        let failing: Vec<(u64, String)> = self
            .jobs
            .values()
            .filter(|j| j.state == JobState::Running && !j.spec.after.is_empty())
            .filter_map(|j| match self.after_of(j) {
                After::Failed(why) => Some((j.id, why)),
                _ => None,
            })
            .collect();
        let mut failed = Vec::new();
        for (id, why) in failing {
            if self.jobs.get_mut(&id).is_some_and(|j| j.fail(why.clone())) {
                tracing::warn!("job {id} failed: {why}");
                self.persist(id);
                failed.push(id);
            }
        }
        failed
    }

    /// Records a job's state and error in the store. A failure is logged, not returned:
    /// the job goes on in memory, and a restart sees the state last recorded.
    fn persist(&self, id: u64) {
        let Some(job) = self.jobs.get(&id) else {
            return;
        };
        if let Err(e) = self.store.set_state(id, job.state, job.error.as_deref()) {
            tracing::error!("cannot record job {id}'s state: {e}");
        }
    }

    /// Expires what is due at `now`, and settles the jobs that start after others; returns
    /// the jobs that failed for it.
    fn expire_leases(&mut self, now: Instant) -> Vec<u64> {
        let mut failed = self.settle_dependents();
        for (id, held) in self.leases.expire(now) {
            self.metrics.leases_expired += 1;
            if let Some(job) = self.jobs.get_mut(&held.job)
                && job.lease_expired(held.tile, id, &held.worker)
            {
                tracing::warn!(
                    "job {} failed: {}",
                    held.job,
                    job.error.as_deref().unwrap_or_default()
                );
                self.persist(held.job);
                failed.push(held.job);
            }
        }
        let before = now.checked_sub(leases::FORGET_WORKERS_AFTER).unwrap_or(now);
        let busy: std::collections::HashSet<&str> =
            self.leases.iter().map(|(_, h)| h.worker.as_str()).collect();
        self.workers.forget_unheard(before, |w| busy.contains(w));
        failed
    }
}

/// Serves [`app`] on a bound listener until `shutdown` resolves, expiring leases and
/// calling webhooks meanwhile. It first raises the process's open-file limit as far as
/// it may, and holds no more connections than the files it then has allow.
pub async fn serve(
    listener: tokio::net::TcpListener,
    c: Coordinator,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let mut limits = listen::Limits {
        max_connections: c.config().max_connections,
        header_timeout: c.config().header_timeout,
    };
    if let Some(files) = listen::raise_fd_limit() {
        let fit = listen::connections_for(files);
        if fit < limits.max_connections {
            tracing::warn!(
                "{files} open files allowed: holding at most {fit} connections, not {}",
                limits.max_connections
            );
            limits.max_connections = fit;
        }
    }
    let tls = match &c.config().tls {
        Some(files) => Some(tls::acceptor(files).map_err(std::io::Error::other)?),
        None => None,
    };
    let task = tokio::spawn(expire_leases_every_tick(c.clone()));
    let hooks = tokio::spawn(webhooks::deliver_webhooks_forever(c.clone()));
    // On a shared store, the lead is renewed meanwhile; losing it stops the serving.
    let (lost_tx, lost_rx) = tokio::sync::oneshot::channel::<String>();
    let lead = c
        .config()
        .candidate
        .clone()
        .filter(|_| c.config().store.is_some());
    let renewal = lead.map(|me| {
        let c = c.clone();
        tokio::spawn(async move {
            let _ = lost_tx.send(leader::keep_lead(c, me).await);
        })
    });
    let lost = Arc::new(Mutex::new(None::<String>));
    let lost_slot = lost.clone();
    let stop = async move {
        tokio::select! {
            () = shutdown => {}
            Ok(why) = lost_rx => {
                tracing::error!("deposed: {why}; this coordinator stops serving");
                *lost_slot.lock().unwrap_or_else(|p| p.into_inner()) = Some(why);
            }
        }
    };
    let c2 = c.clone();
    let result = listen::serve_connections(listener, app(c), limits, tls, stop).await;
    task.abort();
    hooks.abort();
    let leading = renewal.is_some();
    if let Some(r) = renewal {
        r.abort();
    }
    let deposed = lost.lock().unwrap_or_else(|p| p.into_inner()).take();
    match deposed {
        Some(why) => Err(std::io::Error::other(format!("deposed: {why}"))),
        None => {
            if leading {
                // Stopping: a standby may take the lead now rather than after its TTL.
                let resigned =
                    tokio::task::spawn_blocking(move || c2.lock().store.resign_lead()).await;
                if let Ok(Err(e)) = resigned {
                    tracing::warn!("cannot give up the lead: {e}");
                }
            }
            result
        }
    }
}

/// Expires leases every quarter of their ttl (but no more often than every 50 ms), forever.
async fn expire_leases_every_tick(c: Coordinator) {
    let tick = (c.config().lease_ttl / 4).max(Duration::from_millis(50));
    loop {
        tokio::time::sleep(tick).await;
        // Off the runtime's threads: expiring may write to the job store.
        let c = c.clone();
        let _ = tokio::task::spawn_blocking(move || {
            c.expire_leases();
            c.retry_merges();
        })
        .await;
    }
}
