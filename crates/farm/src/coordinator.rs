//! The coordinator: an axum service that keeps jobs, scene bundles and finished tiles
//! durable in a data directory (SQLite plus tile files), lends tiles to workers under
//! leases, merges their EXRs and reports progress.
//!
//! State lives behind one std mutex (no lock is held across an await): the job store is
//! small, every handler's critical section is short, and SQLite wants one writer.

use crate::api::*;
use crate::bundle;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Path as UrlPath, Request, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use axum::{Json, Router};
use kiln_image::RgbBuffer;
use kiln_render::{TileRect, split_into_tiles};
use rusqlite::{Connection, params};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// Tiles a job gives up on after this many failed attempts.
pub const MAX_TILE_ATTEMPTS: u32 = 3;
/// A worker whose attempts fail this many times in a row gets no more leases.
pub const MAX_WORKER_FAILURES: u32 = 5;

#[derive(Debug, Clone)]
pub struct Config {
    pub data_dir: PathBuf,
    pub token: Option<String>,
    pub lease_ttl: Duration,
    pub max_scene_bytes: usize,
    pub max_tile_bytes: usize,
}

impl Config {
    pub fn new(data_dir: PathBuf) -> Config {
        Config {
            data_dir,
            token: None,
            lease_ttl: Duration::from_secs(20),
            max_scene_bytes: 2 << 30,
            max_tile_bytes: 256 << 20,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TileState {
    Pending,
    Leased(u64),
    Done,
}

struct Job {
    id: u64,
    spec: JobSpec,
    state: JobState,
    error: Option<String>,
    tiles: Vec<TileRect>,
    tile_state: Vec<TileState>,
    /// Tiles to lend next, in order; a tile may appear here after it stopped being
    /// pending (leases check), so lending never scans the whole job.
    queue: std::collections::VecDeque<usize>,
    attempts: Vec<u32>,
    failures: u32,
    done: u32,
    frame: RgbBuffer,
    spp: u32,
    started: Instant,
    samples_at_start: u64,
    merge_seconds: Option<f64>,
}

impl Job {
    fn samples_of(&self, i: usize) -> u64 {
        self.tiles[i].pixel_count() * self.spp as u64
    }

    fn status(&self) -> JobStatus {
        let samples_total: u64 = (0..self.tiles.len()).map(|i| self.samples_of(i)).sum();
        let samples_done: u64 = (0..self.tiles.len())
            .filter(|&i| self.tile_state[i] == TileState::Done)
            .map(|i| self.samples_of(i))
            .sum();
        let secs = self.started.elapsed().as_secs_f64().max(1e-3);
        let rate = samples_done.saturating_sub(self.samples_at_start) as f64 / secs;
        let progress = if samples_total == 0 {
            1.0
        } else {
            samples_done as f64 / samples_total as f64
        };
        JobStatus {
            id: self.id,
            state: self.state,
            width: self.frame.frame_width,
            height: self.frame.frame_height,
            tiles_total: self.tiles.len() as u32,
            tiles_done: self.done,
            samples_total,
            samples_done,
            progress,
            samples_per_second: rate,
            eta_seconds: (rate > 0.0 && self.state == JobState::Running)
                .then(|| (samples_total - samples_done) as f64 / rate),
            failures: self.failures,
            error: self.error.clone(),
            merge_seconds: self.merge_seconds,
        }
    }
}

struct LeaseState {
    job: u64,
    tile: usize,
    worker: String,
    deadline: Instant,
}

#[derive(Default)]
struct WorkerState {
    consecutive_failures: u32,
}

#[derive(Default)]
struct Metrics {
    leases_issued: u64,
    leases_expired: u64,
    tiles_accepted: u64,
    tiles_rejected: u64,
}

struct Inner {
    db: Connection,
    jobs: BTreeMap<u64, Job>,
    leases: HashMap<u64, LeaseState>,
    next_lease: u64,
    workers: HashMap<String, WorkerState>,
    metrics: Metrics,
}

/// The shared state handle: cheap to clone.
#[derive(Clone)]
pub struct Coordinator {
    inner: Arc<Mutex<Inner>>,
    config: Arc<Config>,
    events: broadcast::Sender<u64>,
}

/// An error with its HTTP status; the body is `{"error": message}`.
pub struct AppError(StatusCode, String);

impl AppError {
    fn new(status: StatusCode, message: impl Into<String>) -> AppError {
        AppError(status, message.into())
    }
}

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        if self.0.is_server_error() {
            tracing::error!("{}", self.1);
        }
        (self.0, Json(ApiError { error: self.1 })).into_response()
    }
}

fn internal(e: impl std::fmt::Display) -> AppError {
    AppError::new(
        StatusCode::INTERNAL_SERVER_ERROR,
        format!("internal error: {e}"),
    )
}

fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

impl Coordinator {
    /// Opens (or creates) the data directory and resumes every unfinished job in it.
    pub fn open(config: Config) -> Result<Coordinator, String> {
        let dir = &config.data_dir;
        std::fs::create_dir_all(dir.join("scenes"))
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        std::fs::create_dir_all(dir.join("jobs"))
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let db = Connection::open(dir.join("kiln.sqlite"))
            .map_err(|e| format!("cannot open the job store: {e}"))?;
        db.execute_batch(
            "PRAGMA journal_mode = WAL;
             PRAGMA synchronous = NORMAL;
             CREATE TABLE IF NOT EXISTS jobs (id INTEGER PRIMARY KEY, spec TEXT NOT NULL, state TEXT NOT NULL, error TEXT, idempotency_key TEXT UNIQUE);
             CREATE TABLE IF NOT EXISTS tiles (job INTEGER NOT NULL, idx INTEGER NOT NULL, exr BLOB NOT NULL, PRIMARY KEY (job, idx));",
        )
        .map_err(|e| format!("cannot set up the job store: {e}"))?;
        let (events, _) = broadcast::channel(1024);
        let coordinator = Coordinator {
            inner: Arc::new(Mutex::new(Inner {
                db,
                jobs: BTreeMap::new(),
                leases: HashMap::new(),
                next_lease: 1,
                workers: HashMap::new(),
                metrics: Metrics::default(),
            })),
            config: Arc::new(config),
            events,
        };
        coordinator.resume()?;
        Ok(coordinator)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // A panic while holding the lock poisons it; the state is still consistent
        // (every mutation is a few plain assignments), so carry on.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn scene_dir(&self, digest: &str) -> PathBuf {
        self.config.data_dir.join("scenes").join(digest)
    }

    /// The EXR kept for a finished tile.
    fn kept_tile(inner: &Inner, job: u64, idx: usize) -> Option<Vec<u8>> {
        inner
            .db
            .query_row(
                "SELECT exr FROM tiles WHERE job = ?1 AND idx = ?2",
                params![job as i64, idx as i64],
                |r| r.get(0),
            )
            .ok()
    }

    fn result_path(&self, job: u64) -> PathBuf {
        self.config
            .data_dir
            .join("jobs")
            .join(job.to_string())
            .join("result.exr")
    }

    /// Loads a job's scene to learn its frame and tiles; errors are the parser's, with
    /// the data directory's prefix taken off file names.
    fn plan(&self, spec: &JobSpec) -> Result<(Vec<TileRect>, RgbBuffer, u32), String> {
        if spec.tile == 0 {
            return Err("tile must be at least 1".into());
        }
        let scenes = self.config.data_dir.join("scenes");
        let scene_file = bundle::cached_scene(&scenes, &spec.scene)
            .ok_or_else(|| format!("no scene with digest '{}' was uploaded", spec.scene))?;
        let prefix = format!("{}/", self.scene_dir(&spec.scene).display());
        let mut desc =
            kiln_scene::load_file(&scene_file).map_err(|e| e.to_string().replace(&prefix, ""))?;
        desc.apply_overrides(&spec.overrides())?;
        let f = &desc.film;
        let [x0, x1, y0, y1] = f.pixel_bounds;
        let frame = RgbBuffer::new(f.xresolution, f.yresolution, x0, y0, x1 - x0, y1 - y0);
        Ok((
            split_into_tiles(f.pixel_bounds, spec.tile),
            frame,
            desc.sampler.pixel_samples,
        ))
    }

    fn new_job(&self, id: u64, spec: JobSpec, state: JobState) -> Result<Job, String> {
        let (tiles, frame, spp) = self.plan(&spec)?;
        let n = tiles.len();
        Ok(Job {
            id,
            spec,
            state,
            error: None,
            tiles,
            tile_state: vec![TileState::Pending; n],
            queue: (0..n).collect(),
            attempts: vec![0; n],
            failures: 0,
            done: 0,
            frame,
            spp,
            started: Instant::now(),
            samples_at_start: 0,
            merge_seconds: None,
        })
    }

    fn resume(&self) -> Result<(), String> {
        let rows: Vec<(u64, String, String, Option<String>)> = {
            let inner = self.lock();
            let mut stmt = inner
                .db
                .prepare("SELECT id, spec, state, error FROM jobs ORDER BY id")
                .map_err(|e| e.to_string())?;
            stmt.query_map([], |r| {
                Ok((r.get::<_, i64>(0)? as u64, r.get(1)?, r.get(2)?, r.get(3)?))
            })
            .map_err(|e| e.to_string())?
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?
        };
        for (id, spec, state, error) in rows {
            let spec: JobSpec =
                serde_json::from_str(&spec).map_err(|e| format!("job {id}: corrupt spec: {e}"))?;
            let state: JobState =
                serde_json::from_str(&format!("\"{state}\"")).unwrap_or(JobState::Failed);
            let mut job = match self.new_job(id, spec, state) {
                Ok(j) => j,
                Err(e) => {
                    tracing::warn!("job {id} cannot be resumed: {e}");
                    continue;
                }
            };
            job.error = error;
            let done: Vec<(usize, Vec<u8>)> = {
                let inner = self.lock();
                let mut stmt = inner
                    .db
                    .prepare("SELECT idx, exr FROM tiles WHERE job = ?1")
                    .map_err(|e| e.to_string())?;
                stmt.query_map([id as i64], |r| {
                    Ok((r.get::<_, i64>(0)? as usize, r.get::<_, Vec<u8>>(1)?))
                })
                .map_err(|e| e.to_string())?
                .filter_map(|r| r.ok())
                .collect()
            };
            for (idx, bytes) in done {
                if idx >= job.tiles.len() {
                    continue;
                }
                // A tile that cannot be read back is rendered again.
                let Ok(tile) = kiln_image::decode_exr(&bytes) else {
                    continue;
                };
                if job.frame.paste(&tile).is_err() {
                    continue;
                }
                job.tile_state[idx] = TileState::Done;
                job.done += 1;
            }
            job.samples_at_start = job.status().samples_done;
            if job.state == JobState::Running && job.done as usize == job.tiles.len() {
                self.finish(&mut job);
            }
            self.lock().jobs.insert(id, job);
        }
        Ok(())
    }

    /// Writes the merged frame and marks the job done.
    fn finish(&self, job: &mut Job) {
        let start = Instant::now();
        let result = kiln_image::encode_exr(&job.frame)
            .map_err(|e| e.to_string())
            .and_then(|bytes| {
                write_atomically(&self.result_path(job.id), &bytes).map_err(|e| e.to_string())
            });
        match result {
            Ok(()) => {
                job.state = JobState::Done;
                job.merge_seconds = Some(start.elapsed().as_secs_f64());
            }
            Err(e) => {
                job.state = JobState::Failed;
                job.error = Some(format!("cannot write the result: {e}"));
            }
        }
    }

    fn persist_state(inner: &Inner, job: &Job) {
        let state = serde_json::to_value(job.state)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default();
        if let Err(e) = inner.db.execute(
            "UPDATE jobs SET state = ?1, error = ?2 WHERE id = ?3",
            params![state, job.error, job.id as i64],
        ) {
            tracing::error!("cannot record job {}'s state: {e}", job.id);
        }
    }

    /// Returns expired leases' tiles to the queue.
    pub fn expire_leases(&self) {
        let now = Instant::now();
        let mut inner = self.lock();
        let expired: Vec<u64> = inner
            .leases
            .iter()
            .filter(|(_, l)| l.deadline < now)
            .map(|(id, _)| *id)
            .collect();
        for id in expired {
            if let Some(l) = inner.leases.remove(&id) {
                inner.metrics.leases_expired += 1;
                if let Some(job) = inner.jobs.get_mut(&l.job) {
                    if job.tile_state[l.tile] == TileState::Leased(id) {
                        job.tile_state[l.tile] = TileState::Pending;
                        // Lost tiles go first: a job finishes sooner without stragglers.
                        job.queue.push_front(l.tile);
                    }
                }
            }
        }
    }

    fn notify(&self, job: u64) {
        let _ = self.events.send(job);
    }

    pub fn status(&self, id: u64) -> Option<JobStatus> {
        self.lock().jobs.get(&id).map(Job::status)
    }
}

/// A buffer's data window.
fn data_window(b: &RgbBuffer) -> Rect {
    Rect {
        x0: b.x0,
        y0: b.y0,
        width: b.width,
        height: b.height,
    }
}

/// The coordinator's HTTP routes.
pub fn app(c: Coordinator) -> Router {
    let max_scene = c.config.max_scene_bytes;
    let max_tile = c.config.max_tile_bytes;
    let api = Router::new()
        .route(
            "/v1/scenes",
            post(upload_scene).layer(DefaultBodyLimit::max(max_scene)),
        )
        .route("/v1/scenes/{digest}", get(download_scene))
        .route("/v1/jobs", post(create_job).get(list_jobs))
        .route("/v1/jobs/{id}", get(get_job))
        .route("/v1/jobs/{id}/events", get(job_events))
        .route("/v1/jobs/{id}/result.exr", get(job_result))
        .route("/v1/jobs/{id}/preview.png", get(job_preview))
        .route("/v1/jobs/{id}/cancel", post(cancel_job))
        .route("/v1/leases", post(lease))
        .route("/v1/leases/{id}/heartbeat", post(heartbeat))
        .route(
            "/v1/leases/{id}/tile",
            put(upload_tile).layer(DefaultBodyLimit::max(max_tile)),
        )
        .route("/v1/leases/{id}/fail", post(fail_lease))
        .route("/v1/openapi.json", get(openapi))
        .route("/metrics", get(metrics))
        .route_layer(middleware::from_fn_with_state(c.clone(), require_token));
    Router::new()
        .route("/healthz", get(|| async { "ok\n" }))
        .merge(api)
        .fallback(|| async { AppError::new(StatusCode::NOT_FOUND, "no such route") })
        .with_state(c)
}

async fn require_token(
    State(c): State<Coordinator>,
    req: Request,
    next: Next,
) -> Result<Response, AppError> {
    if let Some(token) = &c.config.token {
        let ok = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| v.strip_prefix("Bearer ") == Some(token.as_str()));
        if !ok {
            return Err(AppError::new(
                StatusCode::UNAUTHORIZED,
                "missing or wrong bearer token",
            ));
        }
    }
    Ok(next.run(req).await)
}

async fn upload_scene(
    State(c): State<Coordinator>,
    body: Bytes,
) -> Result<Json<SceneUploaded>, AppError> {
    let digest = bundle::digest_of(&body);
    let scenes = c.config.data_dir.join("scenes");
    let digest2 = digest.clone();
    tokio::task::spawn_blocking(move || -> Result<(), AppError> {
        match bundle::unpack_into_cache(&body, &digest2, &scenes, true) {
            Ok(_) => Ok(()),
            Err(e @ bundle::BundleError::Corrupt(_)) => {
                Err(AppError::new(StatusCode::BAD_REQUEST, e.to_string()))
            }
            Err(e) => Err(internal(e)),
        }
    })
    .await
    .map_err(internal)??;
    Ok(Json(SceneUploaded { digest }))
}

async fn download_scene(
    State(c): State<Coordinator>,
    UrlPath(digest): UrlPath<String>,
) -> Result<Response, AppError> {
    if !bundle::is_digest(&digest) {
        return Err(AppError::new(
            StatusCode::BAD_REQUEST,
            "a digest is hexadecimal",
        ));
    }
    let bytes = tokio::fs::read(c.scene_dir(&digest).join(bundle::BUNDLE_FILE))
        .await
        .map_err(|_| {
            AppError::new(
                StatusCode::NOT_FOUND,
                format!("no scene with digest '{digest}'"),
            )
        })?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

async fn create_job(
    State(c): State<Coordinator>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, AppError> {
    let spec: JobSpec = serde_json::from_slice(&body)
        .map_err(|e| AppError::new(StatusCode::BAD_REQUEST, format!("bad job: {e}")))?;
    let key = headers
        .get("idempotency-key")
        .and_then(|v| v.to_str().ok())
        .map(String::from);
    if let Some(k) = &key {
        let inner = c.lock();
        let existing: Option<i64> = inner
            .db
            .query_row("SELECT id FROM jobs WHERE idempotency_key = ?1", [k], |r| {
                r.get(0)
            })
            .ok();
        if let Some(id) = existing {
            return Ok((StatusCode::OK, Json(JobCreated { id: id as u64 })).into_response());
        }
    }
    let c2 = c.clone();
    let spec2 = spec.clone();
    let planned = tokio::task::spawn_blocking(move || c2.new_job(0, spec2, JobState::Running))
        .await
        .map_err(internal)?
        .map_err(|e| AppError::new(StatusCode::UNPROCESSABLE_ENTITY, e))?;
    let id = {
        let mut inner = c.lock();
        let spec_json = serde_json::to_string(&spec).map_err(internal)?;
        inner
            .db
            .execute(
                "INSERT INTO jobs (spec, state, idempotency_key) VALUES (?1, 'running', ?2)",
                params![spec_json, key],
            )
            .map_err(internal)?;
        let id = inner.db.last_insert_rowid() as u64;
        let mut job = planned;
        job.id = id;
        std::fs::create_dir_all(c.config.data_dir.join("jobs").join(id.to_string()))
            .map_err(internal)?;
        inner.jobs.insert(id, job);
        id
    };
    c.notify(id);
    Ok((StatusCode::CREATED, Json(JobCreated { id })).into_response())
}

async fn list_jobs(State(c): State<Coordinator>) -> Json<Vec<JobStatus>> {
    Json(c.lock().jobs.values().map(Job::status).collect())
}

/// Ids in paths, parsed here so a bad one gets a JSON error like every other.
fn parse_id(text: &str) -> Result<u64, AppError> {
    text.parse()
        .map_err(|_| AppError::new(StatusCode::BAD_REQUEST, format!("'{text}' is not an id")))
}

/// JSON bodies, parsed here so malformed ones get a JSON error that says what is wrong.
fn parse_json<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, AppError> {
    serde_json::from_slice(body)
        .map_err(|e| AppError::new(StatusCode::BAD_REQUEST, format!("bad request body: {e}")))
}

fn not_found(id: u64) -> AppError {
    AppError::new(StatusCode::NOT_FOUND, format!("no job {id}"))
}

async fn get_job(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<JobStatus>, AppError> {
    let id = parse_id(&id)?;
    c.status(id).map(Json).ok_or_else(|| not_found(id))
}

async fn job_events(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, AppError> {
    let id = parse_id(&id)?;
    let first = c.status(id).ok_or_else(|| not_found(id))?;
    let mut rx = c.events.subscribe();
    let stream = async_stream(move |tx: tokio::sync::mpsc::Sender<Event>| async move {
        let mut last = first;
        let _ = tx
            .send(
                Event::default()
                    .event("progress")
                    .json_data(&last)
                    .unwrap_or_default(),
            )
            .await;
        while last.state == JobState::Running {
            let changed = tokio::time::timeout(Duration::from_secs(1), rx.recv()).await;
            if let Ok(Err(broadcast::error::RecvError::Closed)) = changed {
                break;
            }
            let Some(now) = c.status(id) else { break };
            if now != last {
                last = now;
                if tx
                    .send(
                        Event::default()
                            .event("progress")
                            .json_data(&last)
                            .unwrap_or_default(),
                    )
                    .await
                    .is_err()
                {
                    break;
                }
            }
        }
    });
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response())
}

/// A stream fed by a task through a channel (so handlers can write loops with await).
fn async_stream<F, Fut>(
    f: F,
) -> impl tokio_stream::Stream<Item = Result<Event, std::convert::Infallible>>
where
    F: FnOnce(tokio::sync::mpsc::Sender<Event>) -> Fut,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    tokio::spawn(f(tx));
    tokio_stream::StreamExt::map(tokio_stream::wrappers::ReceiverStream::new(rx), Ok)
}

async fn job_result(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, AppError> {
    let id = parse_id(&id)?;
    let status = c.status(id).ok_or_else(|| not_found(id))?;
    if status.state != JobState::Done {
        return Err(AppError::new(
            StatusCode::CONFLICT,
            format!("job {id} is {:?}, not done", status.state).to_lowercase(),
        ));
    }
    let bytes = tokio::fs::read(c.result_path(id)).await.map_err(internal)?;
    Ok(([(header::CONTENT_TYPE, "image/x-exr")], bytes).into_response())
}

async fn job_preview(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, AppError> {
    let id = parse_id(&id)?;
    let frame = c
        .lock()
        .jobs
        .get(&id)
        .map(|j| j.frame.clone())
        .ok_or_else(|| not_found(id))?;
    let png = tokio::task::spawn_blocking(move || kiln_image::encode_png(&frame, 0.0))
        .await
        .map_err(internal)?
        .map_err(internal)?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

async fn cancel_job(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<JobStatus>, AppError> {
    let id = parse_id(&id)?;
    let status = {
        let mut inner = c.lock();
        let inner = &mut *inner;
        let job = inner.jobs.get_mut(&id).ok_or_else(|| not_found(id))?;
        if job.state == JobState::Running {
            job.state = JobState::Cancelled;
            Coordinator::persist_state(inner, inner.jobs.get(&id).expect("present"));
        }
        inner.jobs[&id].status()
    };
    c.notify(id);
    Ok(Json(status))
}

async fn lease(State(c): State<Coordinator>, body: Bytes) -> Result<Response, AppError> {
    let req: LeaseRequest = parse_json(&body)?;
    let mut inner = c.lock();
    let inner = &mut *inner;
    if inner
        .workers
        .get(&req.worker)
        .is_some_and(|w| w.consecutive_failures >= MAX_WORKER_FAILURES)
    {
        return Err(AppError::new(
            StatusCode::FORBIDDEN,
            format!(
                "worker '{}' failed {MAX_WORKER_FAILURES} tiles in a row and is set aside",
                req.worker
            ),
        ));
    }
    inner.workers.entry(req.worker.clone()).or_default();
    for job in inner
        .jobs
        .values_mut()
        .filter(|j| j.state == JobState::Running)
    {
        let mut next = None;
        while let Some(t) = job.queue.pop_front() {
            if job.tile_state[t] == TileState::Pending {
                next = Some(t);
                break;
            }
        }
        let Some(tile) = next else { continue };
        let id = inner.next_lease;
        inner.next_lease += 1;
        job.tile_state[tile] = TileState::Leased(id);
        inner.leases.insert(
            id,
            LeaseState {
                job: job.id,
                tile,
                worker: req.worker.clone(),
                deadline: Instant::now() + c.config.lease_ttl,
            },
        );
        inner.metrics.leases_issued += 1;
        let lease = Lease {
            lease: id,
            job: job.id,
            spec: job.spec.clone(),
            tile_index: tile as u32,
            tile: job.tiles[tile].into(),
            ttl_ms: c.config.lease_ttl.as_millis() as u64,
        };
        return Ok(Json(lease).into_response());
    }
    Ok(StatusCode::NO_CONTENT.into_response())
}

async fn heartbeat(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<StatusCode, AppError> {
    let id = parse_id(&id)?;
    let ttl = c.config.lease_ttl;
    let mut inner = c.lock();
    let Some(l) = inner.leases.get_mut(&id) else {
        return Err(AppError::new(
            StatusCode::CONFLICT,
            format!("lease {id} has expired or is unknown"),
        ));
    };
    l.deadline = Instant::now() + ttl;
    let job = l.job;
    // A cancelled job's leases end: tell the worker to stop.
    if inner
        .jobs
        .get(&job)
        .is_some_and(|j| j.state != JobState::Running)
    {
        inner.leases.remove(&id);
        return Err(AppError::new(
            StatusCode::GONE,
            format!("job {job} is no longer running"),
        ));
    }
    Ok(StatusCode::NO_CONTENT)
}

async fn upload_tile(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
    body: Bytes,
) -> Result<Response, AppError> {
    let id = parse_id(&id)?;
    let (job_id, tile_idx, rect, frame_size) = {
        let inner = c.lock();
        match inner.leases.get(&id) {
            Some(l) => {
                let job = &inner.jobs[&l.job];
                (
                    l.job,
                    l.tile,
                    job.tiles[l.tile],
                    (job.frame.frame_width, job.frame.frame_height),
                )
            }
            // A stale lease: accepted only if identical to the tile already kept.
            None => return stale_upload(&inner, id, &body),
        }
    };
    let decoded = kiln_image::decode_exr(&body);
    let check = decoded.map_err(|e| e.to_string()).and_then(|t| {
        if (t.frame_width, t.frame_height) != frame_size || Rect::from(rect) != data_window(&t) {
            return Err(format!(
                "the EXR's windows ({}x{} frame, {}x{} at {},{}) are not the leased tile's",
                t.frame_width, t.frame_height, t.width, t.height, t.x0, t.y0
            ));
        }
        if t.pixels.iter().any(|p| p.iter().any(|v| !v.is_finite())) {
            return Err("the tile has NaN or infinite pixels".into());
        }
        Ok(t)
    });
    let tile = match check {
        Ok(t) => t,
        Err(e) => {
            let mut inner = c.lock();
            inner.metrics.tiles_rejected += 1;
            release_failed(&mut inner, id, &format!("corrupt tile upload: {e}"));
            drop(inner);
            c.notify(job_id);
            return Err(AppError::new(
                StatusCode::BAD_REQUEST,
                format!("rejected tile: {e}"),
            ));
        }
    };
    {
        let mut inner = c.lock();
        let inner = &mut *inner;
        let Some(lease) = inner.leases.remove(&id) else {
            // Expired while we checked it: judge it as a stale upload.
            return stale_upload(inner, id, &body);
        };
        inner.metrics.tiles_accepted += 1;
        if let Some(w) = inner.workers.get_mut(&lease.worker) {
            w.consecutive_failures = 0;
        }
        inner
            .db
            .execute(
                "INSERT OR IGNORE INTO tiles (job, idx, exr) VALUES (?1, ?2, ?3)",
                params![job_id as i64, tile_idx as i64, &body[..]],
            )
            .map_err(internal)?;
        let job = inner.jobs.get_mut(&job_id).expect("leased jobs exist");
        if job.tile_state[tile_idx] != TileState::Done {
            job.frame.paste(&tile).map_err(internal)?;
            job.tile_state[tile_idx] = TileState::Done;
            job.done += 1;
        }
        if job.state == JobState::Running && job.done as usize == job.tiles.len() {
            c.finish(job);
            let job = &inner.jobs[&job_id];
            Coordinator::persist_state(inner, job);
        }
    }
    c.notify(job_id);
    Ok(StatusCode::OK.into_response())
}

fn stale_upload(inner: &Inner, id: u64, body: &[u8]) -> Result<Response, AppError> {
    // Which tile was it? The upload carries its own windows.
    let Ok(t) = kiln_image::decode_exr(body) else {
        return Err(AppError::new(
            StatusCode::CONFLICT,
            format!("lease {id} has expired or is unknown"),
        ));
    };
    for job in inner.jobs.values() {
        if (job.frame.frame_width, job.frame.frame_height) != (t.frame_width, t.frame_height) {
            continue;
        }
        if let Some(idx) = job
            .tiles
            .iter()
            .position(|&r| Rect::from(r) == data_window(&t))
        {
            if job.tile_state[idx] == TileState::Done
                && Coordinator::kept_tile(inner, job.id, idx).is_some_and(|kept| kept == body)
            {
                return Ok(StatusCode::OK.into_response());
            }
        }
    }
    Err(AppError::new(
        StatusCode::CONFLICT,
        format!("lease {id} has expired or is unknown, and the tile differs from the one kept"),
    ))
}

/// Ends a lease whose attempt failed: the tile goes back to the queue, or fails its job.
fn release_failed(inner: &mut Inner, lease: u64, reason: &str) {
    let Some(l) = inner.leases.remove(&lease) else {
        return;
    };
    let w = inner.workers.entry(l.worker.clone()).or_default();
    w.consecutive_failures += 1;
    let Some(job) = inner.jobs.get_mut(&l.job) else {
        return;
    };
    job.failures += 1;
    job.attempts[l.tile] += 1;
    job.tile_state[l.tile] = TileState::Pending;
    job.queue.push_front(l.tile);
    if job.attempts[l.tile] >= MAX_TILE_ATTEMPTS && job.state == JobState::Running {
        job.state = JobState::Failed;
        let t = job.tiles[l.tile];
        job.error = Some(format!(
            "tile {} ({}x{} at {},{}) failed {} times; last: {reason}",
            l.tile, t.width, t.height, t.x0, t.y0, MAX_TILE_ATTEMPTS
        ));
        let id = job.id;
        Coordinator::persist_state(inner, &inner.jobs[&id]);
    }
}

async fn fail_lease(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
    body: Bytes,
) -> Result<StatusCode, AppError> {
    let id = parse_id(&id)?;
    let f: Failure = parse_json(&body)?;
    let job = {
        let mut inner = c.lock();
        let job = inner.leases.get(&id).map(|l| l.job).ok_or_else(|| {
            AppError::new(
                StatusCode::CONFLICT,
                format!("lease {id} has expired or is unknown"),
            )
        })?;
        release_failed(&mut inner, id, &f.reason);
        job
    };
    c.notify(job);
    Ok(StatusCode::NO_CONTENT)
}

async fn metrics(State(c): State<Coordinator>) -> Response {
    let inner = c.lock();
    let m = &inner.metrics;
    let mut text = String::new();
    text.push_str("# HELP kiln_leases_issued_total Tile leases issued.\n# TYPE kiln_leases_issued_total counter\n");
    text.push_str(&format!("kiln_leases_issued_total {}\n", m.leases_issued));
    text.push_str("# HELP kiln_leases_expired_total Leases that expired without a result.\n# TYPE kiln_leases_expired_total counter\n");
    text.push_str(&format!("kiln_leases_expired_total {}\n", m.leases_expired));
    text.push_str("# HELP kiln_tiles_accepted_total Tile results accepted.\n# TYPE kiln_tiles_accepted_total counter\n");
    text.push_str(&format!("kiln_tiles_accepted_total {}\n", m.tiles_accepted));
    text.push_str("# HELP kiln_tiles_rejected_total Tile uploads rejected as corrupt.\n# TYPE kiln_tiles_rejected_total counter\n");
    text.push_str(&format!("kiln_tiles_rejected_total {}\n", m.tiles_rejected));
    text.push_str("# HELP kiln_jobs Jobs by state.\n# TYPE kiln_jobs gauge\n");
    for state in ["running", "done", "failed", "cancelled"] {
        let n = inner
            .jobs
            .values()
            .filter(|j| {
                serde_json::to_value(j.state)
                    .ok()
                    .and_then(|v| v.as_str().map(String::from))
                    .as_deref()
                    == Some(state)
            })
            .count();
        text.push_str(&format!("kiln_jobs{{state=\"{state}\"}} {n}\n"));
    }
    text.push_str(
        "# HELP kiln_leases_active Leases outstanding.\n# TYPE kiln_leases_active gauge\n",
    );
    text.push_str(&format!("kiln_leases_active {}\n", inner.leases.len()));
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

async fn openapi() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        include_str!("openapi.json"),
    )
        .into_response()
}

/// Serves `app` on a bound listener until `shutdown` resolves, expiring leases meanwhile.
pub async fn serve(
    listener: tokio::net::TcpListener,
    c: Coordinator,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let expirer = c.clone();
    let tick = (c.config.lease_ttl / 4).max(Duration::from_millis(50));
    let task = tokio::spawn(async move {
        loop {
            tokio::time::sleep(tick).await;
            expirer.expire_leases();
        }
    });
    let result = axum::serve(listener, app(c))
        .with_graceful_shutdown(shutdown)
        .await;
    task.abort();
    result
}
