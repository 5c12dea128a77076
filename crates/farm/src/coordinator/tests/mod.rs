//! The coordinator through its HTTP app, without a socket: requests go straight into
//! [`app`] with `tower::ServiceExt::oneshot`, as axum's testing example does. Lease expiry
//! runs on tokio's paused clock (`start_paused`, `advance`), as mini-redis's tests do: no
//! test sleeps.
//!
//! Each test has its own data directory with a tiny scene (an environment light, no
//! geometry); tiles are made here, not rendered.

use super::{Config, Coordinator, app};
use crate::api::{ApiError, JobSpec, JobState, JobStatus, Lease};
use axum::Router;
use axum::body::{Body, Bytes};
use axum::http::{Request, StatusCode, header};
use kiln_image::RgbBuffer;
use std::path::Path;
use std::time::Duration;
use tower::ServiceExt;

mod after;
mod api;
mod denoised;
mod durability;
mod leading;
mod lending;
mod passes;
mod queue;
mod requirements;
mod roles;
mod shots;
mod verify;

const TTL: Duration = Duration::from_secs(20);

/// A coordinator on a fresh data directory, and its app.
struct Farm {
    dir: tempfile::TempDir,
    c: Coordinator,
    app: Router,
}

fn farm(token: Option<&str>) -> Farm {
    let dir = tempfile::tempdir().unwrap();
    let (c, app) = open(&dir.path().join("data"), token);
    Farm { dir, c, app }
}

fn open(data: &Path, token: Option<&str>) -> (Coordinator, Router) {
    open_on(data, token, None)
}

/// A coordinator on `data` with its job store on the PostgreSQL server of `store` (SQLite
/// in `data` when None). The lead lasts 0.3 s, so that a coordinator opened again after
/// one was dropped takes it over at once.
fn open_on(data: &Path, token: Option<&str>, store: Option<&str>) -> (Coordinator, Router) {
    let mut config = Config::new(data.to_path_buf());
    config.token = token.map(String::from);
    config.lease_ttl = TTL;
    if let Some(url) = store {
        config.store = Some(url.to_string());
        config.candidate = Some(super::Candidate::new(
            "http://test".into(),
            Duration::from_millis(300),
        ));
    }
    let c = Coordinator::open(config).unwrap();
    let app = app(c.clone());
    (c, app)
}

impl Coordinator {
    /// Runs `hook` on the merge's thread before the next merge encodes the frame.
    fn on_next_merge(&self, hook: impl FnOnce() + Send + 'static) {
        *self.shared.merge_hook.lock().unwrap() = Some(Box::new(hook));
    }

    pub(super) fn before_merge(&self) {
        let hook = self.shared.merge_hook.lock().unwrap().take();
        if let Some(hook) = hook {
            hook();
        }
    }
}

/// One request through the app: (status, body).
async fn call(
    app: &Router,
    method: &str,
    uri: &str,
    token: Option<&str>,
    body: impl Into<Body>,
) -> (StatusCode, Bytes) {
    let mut req = Request::builder().method(method).uri(uri);
    if let Some(t) = token {
        req = req.header(header::AUTHORIZATION, format!("Bearer {t}"));
    }
    send(app, req.body(body.into()).unwrap()).await
}

/// Sends a built request through the app: (status, body).
async fn send(app: &Router, req: Request<Body>) -> (StatusCode, Bytes) {
    let response = app.clone().oneshot(req).await.unwrap();
    let status = response.status();
    let body = axum::body::to_bytes(response.into_body(), usize::MAX)
        .await
        .unwrap();
    (status, body)
}

fn json<T: serde::de::DeserializeOwned>(body: &[u8]) -> T {
    serde_json::from_slice(body)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(body)))
}

/// The `{"error": ...}` message of an error response.
fn error_of(body: &[u8]) -> String {
    json::<ApiError>(body).error
}

/// Uploads a `width x height` scene and creates a job of `tile` px tiles; returns its id.
async fn submit(f: &Farm, width: u32, height: u32, tile: u32) -> u64 {
    submit_passes(f, width, height, tile, None).await
}

/// [`submit`] with a pass schedule.
async fn submit_passes(
    f: &Farm,
    width: u32,
    height: u32,
    tile: u32,
    passes: Option<Vec<u32>>,
) -> u64 {
    submit_with(f, width, height, tile, |s| {
        s.spp = passes.is_none().then_some(1);
        s.passes = passes;
    })
    .await
}

/// Uploads a `width x height` scene (an environment light, no geometry); returns its
/// digest.
async fn upload_scene(f: &Farm, width: u32, height: u32) -> String {
    let scene = f.dir.path().join(format!("scene-{width}x{height}"));
    std::fs::create_dir_all(&scene).unwrap();
    std::fs::write(
        scene.join("scene.pbrt"),
        format!(
            "Film \"rgb\" \"integer xresolution\" [ {width} ] \"integer yresolution\" [ {height} ]\nWorldBegin\nLightSource \"infinite\"\n"
        ),
    )
    .unwrap();
    let bundle = crate::bundle::pack(&scene.join("scene.pbrt")).unwrap();
    let (status, body) = call(&f.app, "POST", "/v1/scenes", None, bundle.bytes).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    bundle.digest
}

/// [`submit`] with the spec changed by `edit`.
async fn submit_with(
    f: &Farm,
    width: u32,
    height: u32,
    tile: u32,
    edit: impl FnOnce(&mut JobSpec),
) -> u64 {
    let mut spec = JobSpec {
        spp: Some(1),
        tile,
        ..JobSpec::new(&upload_scene(f, width, height).await)
    };
    edit(&mut spec);
    let (status, body) = post_job(f, &spec).await;
    assert_eq!(
        status,
        StatusCode::CREATED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    json::<crate::api::JobCreated>(&body).id
}

/// POSTs `spec` as a new job: (status, body).
async fn post_job(f: &Farm, spec: &JobSpec) -> (StatusCode, Bytes) {
    call(
        &f.app,
        "POST",
        "/v1/jobs",
        None,
        serde_json::to_vec(spec).unwrap(),
    )
    .await
}

/// Asserts that `spec` is refused as unplannable with a message holding `names`, and that
/// no job was created for it.
async fn assert_refused(f: &Farm, spec: &JobSpec, names: &str) {
    let before = call(&f.app, "GET", "/v1/jobs", None, Body::empty()).await.1;
    let (status, body) = post_job(f, spec).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(error_of(&body).contains(names), "{}", error_of(&body));
    let after = call(&f.app, "GET", "/v1/jobs", None, Body::empty()).await.1;
    assert_eq!(
        json::<Vec<JobStatus>>(&before).len(),
        json::<Vec<JobStatus>>(&after).len(),
        "nothing was created"
    );
}

async fn lease(app: &Router, worker: &str) -> Option<Lease> {
    let (status, body) = call(
        app,
        "POST",
        "/v1/leases",
        None,
        format!("{{\"worker\": \"{worker}\"}}"),
    )
    .await;
    match status {
        StatusCode::OK => Some(json(&body)),
        StatusCode::NO_CONTENT => None,
        s => panic!("lease: {s} {}", String::from_utf8_lossy(&body)),
    }
}

async fn job_status(app: &Router, job: u64) -> JobStatus {
    let (status, body) = call(app, "GET", &format!("/v1/jobs/{job}"), None, Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    json(&body)
}

/// Uploads `exr` under `lease` with its digest, as a worker does.
async fn upload(app: &Router, lease: u64, exr: Vec<u8>) -> (StatusCode, Bytes) {
    let digest = crate::bundle::digest_of(&exr);
    upload_with_digest(app, lease, exr, Some(&digest)).await
}

async fn upload_with_digest(
    app: &Router,
    lease: u64,
    exr: Vec<u8>,
    digest: Option<&str>,
) -> (StatusCode, Bytes) {
    let mut req = Request::builder()
        .method("PUT")
        .uri(format!("/v1/leases/{lease}/tile"));
    if let Some(d) = digest {
        req = req.header(crate::api::TILE_DIGEST_HEADER, d);
    }
    send(app, req.body(Body::from(exr)).unwrap()).await
}

async fn heartbeat(app: &Router, lease: u64) -> StatusCode {
    let path = format!("/v1/leases/{lease}/heartbeat");
    call(app, "POST", &path, None, Body::empty()).await.0
}

async fn metrics(app: &Router) -> String {
    let (status, body) = call(app, "GET", "/metrics", None, Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    String::from_utf8(body.to_vec()).unwrap()
}

/// The tile a lease asks for, every pixel `value`, in a `frame` sized frame.
fn tile_of(lease: &Lease, frame: (u32, u32), value: f32) -> RgbBuffer {
    let t = lease.tile;
    // The further channels every render keeps (the denoiser's features; their values are
    // the worker's business too).
    let mut tile = RgbBuffer::new(frame.0, frame.1, t.x0, t.y0, t.width, t.height)
        .with_aovs(kiln_render::aov_names(None));
    tile.pixels.iter_mut().for_each(|p| *p = [value; 3]);
    // The running sums its pass must carry (their values are the worker's business).
    let mut sums = kiln_render::TileSums::empty(t.into(), kiln_render::SumsLayout::default());
    sums.samples = lease.pass.to;
    tile.words = kiln_image::Words {
        names: kiln_render::TileSums::word_names(kiln_render::SumsLayout::default()),
        values: sums.to_words(),
    };
    tile
}

fn exr(tile: &RgbBuffer) -> Vec<u8> {
    kiln_image::encode_exr(tile).unwrap()
}
