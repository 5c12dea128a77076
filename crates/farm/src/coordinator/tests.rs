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
    let mut config = Config::new(data.to_path_buf());
    config.token = token.map(String::from);
    config.lease_ttl = TTL;
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
    let response = app
        .clone()
        .oneshot(req.body(body.into()).unwrap())
        .await
        .unwrap();
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
    let spec = JobSpec {
        scene: bundle.digest,
        spp: Some(1),
        resolution: None,
        tile,
        seed: None,
    };
    let (status, body) = call(
        &f.app,
        "POST",
        "/v1/jobs",
        None,
        serde_json::to_vec(&spec).unwrap(),
    )
    .await;
    assert_eq!(
        status,
        StatusCode::CREATED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    json::<crate::api::JobCreated>(&body).id
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
    let response = app
        .clone()
        .oneshot(req.body(Body::from(exr)).unwrap())
        .await
        .unwrap();
    let status = response.status();
    let body = axum::body::to_bytes(response.into_body(), usize::MAX)
        .await
        .unwrap();
    (status, body)
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
    let mut tile = RgbBuffer::new(frame.0, frame.1, t.x0, t.y0, t.width, t.height);
    tile.pixels.iter_mut().for_each(|p| *p = [value; 3]);
    tile
}

fn exr(tile: &RgbBuffer) -> Vec<u8> {
    kiln_image::encode_exr(tile).unwrap()
}

#[tokio::test]
async fn requests_without_the_right_token_are_refused() {
    let f = farm(Some("s3cret"));
    for token in [None, Some("wrong"), Some("s3cret ")] {
        let (status, body) = call(&f.app, "GET", "/v1/jobs", token, Body::empty()).await;
        assert_eq!(status, StatusCode::UNAUTHORIZED, "token {token:?}");
        assert_eq!(error_of(&body), "missing or wrong bearer token");
    }
    // Workers are refused too, and nothing is lent.
    let (status, _) = call(&f.app, "POST", "/v1/leases", None, "{\"worker\": \"w\"}").await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    let (status, body) = call(&f.app, "GET", "/v1/jobs", Some("s3cret"), Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    assert!(json::<Vec<JobStatus>>(&body).is_empty());
    let (status, body) = call(
        &f.app,
        "GET",
        "/v1/openapi.json",
        Some("s3cret"),
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(body, include_str!("../openapi.json"));
    // Liveness needs no token.
    let (status, body) = call(&f.app, "GET", "/healthz", None, Body::empty()).await;
    assert_eq!((status, &body[..]), (StatusCode::OK, &b"ok\n"[..]));
}

#[tokio::test]
async fn malformed_bodies_and_ids_get_json_errors_that_say_what_is_wrong() {
    let f = farm(None);
    for (method, path, body, status, message) in [
        ("POST", "/v1/leases", "not json", 400, "bad request body: "),
        (
            "POST",
            "/v1/leases",
            "{\"name\": \"w\"}",
            400,
            "bad request body: missing field `worker`",
        ),
        (
            "POST",
            "/v1/jobs",
            "{\"scene\": 3}",
            400,
            "bad job: invalid type",
        ),
        (
            "POST",
            "/v1/leases/1/fail",
            "{}",
            400,
            "bad request body: missing field `reason`",
        ),
        ("GET", "/v1/jobs/abc", "", 400, "'abc' is not an id"),
        (
            "POST",
            "/v1/leases/xyz/heartbeat",
            "",
            400,
            "'xyz' is not an id",
        ),
        (
            "GET",
            "/v1/scenes/not-hex",
            "",
            400,
            "a digest is hexadecimal",
        ),
        (
            "GET",
            "/v1/scenes/abc123",
            "",
            404,
            "no scene with digest 'abc123'",
        ),
        ("GET", "/v1/jobs/99", "", 404, "no job 99"),
        ("GET", "/v1/nothing", "", 404, "no such route"),
        (
            "POST",
            "/v1/scenes",
            "KILNBDL1 nope",
            400,
            "corrupt bundle: ",
        ),
        (
            "POST",
            "/v1/jobs",
            "{\"scene\": \"abc\", \"tile\": 8}",
            422,
            "no scene with digest 'abc' was uploaded",
        ),
    ] {
        let (got, text) = call(&f.app, method, path, None, body).await;
        assert_eq!(got.as_u16(), status, "{method} {path}");
        let error = error_of(&text);
        assert!(error.starts_with(message), "{method} {path}: {error}");
    }
}

#[tokio::test]
async fn tiles_go_from_lease_to_upload_to_a_finished_job() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 16).await;
    let frame = (32, 16);
    let a = lease(&f.app, "w").await.expect("two tiles to lend");
    let b = lease(&f.app, "w").await.expect("two tiles to lend");
    assert_eq!((a.job, b.job), (job, job));
    assert_ne!(a.tile_index, b.tile_index);
    assert_eq!(a.ttl_ms, TTL.as_millis() as u64);
    assert!(lease(&f.app, "w").await.is_none(), "both tiles are lent");
    let (tile_a, tile_b) = (tile_of(&a, frame, 0.25), tile_of(&b, frame, 4.0));
    let (status, body) = upload(&f.app, b.lease, exr(&tile_b)).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.state, s.tiles_done, s.tiles_total),
        (JobState::Running, 1, 2)
    );
    assert_eq!(s.progress, 0.5);
    let (status, _) = upload(&f.app, a.lease, exr(&tile_a)).await;
    assert_eq!(status, StatusCode::OK);
    // The last upload is answered once the frame is written.
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.state, s.tiles_done, s.progress),
        (JobState::Done, 2, 1.0)
    );
    assert!(s.merge_seconds.is_some());
    let (status, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let mut expected = RgbBuffer::new(32, 16, 0, 0, 32, 16);
    expected.paste(&tile_a).unwrap();
    expected.paste(&tile_b).unwrap();
    assert_eq!(
        body,
        exr(&expected),
        "the merged EXR is the tiles' frame, byte for byte"
    );
    let m = metrics(&f.app).await;
    for line in [
        "kiln_leases_issued_total 2\n",
        "kiln_tiles_accepted_total 2\n",
        "kiln_jobs{state=\"done\"} 1\n",
        "kiln_leases_active 0\n",
    ] {
        assert!(m.contains(line), "{line} in\n{m}");
    }
    // The lease is spent: a heartbeat on it is a conflict.
    assert_eq!(heartbeat(&f.app, a.lease).await, StatusCode::CONFLICT);
}

#[tokio::test(start_paused = true)]
async fn a_lease_expires_after_its_ttl_and_its_tile_is_lent_again() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 32).await;
    let first = lease(&f.app, "slow").await.expect("one tile");
    assert!(lease(&f.app, "other").await.is_none());
    // Just before the deadline a heartbeat renews the lease for another ttl.
    tokio::time::advance(TTL - Duration::from_millis(1)).await;
    f.c.expire_leases();
    assert_eq!(heartbeat(&f.app, first.lease).await, StatusCode::NO_CONTENT);
    tokio::time::advance(TTL).await;
    f.c.expire_leases();
    assert!(
        lease(&f.app, "other").await.is_none(),
        "due at the renewed deadline, not before"
    );
    tokio::time::advance(Duration::from_millis(1)).await;
    f.c.expire_leases();
    let again = lease(&f.app, "other")
        .await
        .expect("the expired tile is lent again");
    assert_eq!((again.job, again.tile_index), (job, first.tile_index));
    assert_ne!(again.lease, first.lease);
    assert_eq!(heartbeat(&f.app, first.lease).await, StatusCode::CONFLICT);
    assert!(
        metrics(&f.app)
            .await
            .contains("kiln_leases_expired_total 1\n")
    );
}

#[tokio::test(start_paused = true)]
async fn serve_s_expiry_loop_expires_leases_on_the_paused_clock() {
    let f = farm(None);
    submit(&f, 32, 16, 32).await;
    let expirer = tokio::spawn(super::expire_leases_every_tick(f.c.clone()));
    let first = lease(&f.app, "w").await.unwrap();
    // The loop ticks every ttl/4; sleeping on the paused clock (which jumps to each
    // timer) lets it run.
    tokio::time::sleep(TTL).await;
    assert!(
        lease(&f.app, "w").await.is_none(),
        "not expired at its deadline"
    );
    tokio::time::sleep(TTL / 2).await;
    let again = lease(&f.app, "w").await.expect("expired by the loop");
    assert_eq!(again.tile_index, first.tile_index);
    expirer.abort();
}

#[tokio::test(start_paused = true)]
async fn an_upload_under_an_expired_lease_is_kept_only_if_it_is_the_tile_kept() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 16).await;
    let frame = (32, 16);
    let late = lease(&f.app, "late").await.unwrap();
    tokio::time::advance(TTL + Duration::from_millis(1)).await;
    f.c.expire_leases();
    let on_time = lease(&f.app, "on-time").await.unwrap();
    assert_eq!(on_time.tile_index, late.tile_index, "lost tiles go first");
    let tile = tile_of(&late, frame, 1.5);
    // Before anyone delivered the tile, a late upload conflicts.
    let (status, body) = upload(&f.app, late.lease, exr(&tile)).await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert_eq!(
        error_of(&body),
        format!(
            "lease {} has expired or is unknown, and the tile differs from the one kept",
            late.lease
        )
    );
    let (status, _) = upload(&f.app, on_time.lease, exr(&tile)).await;
    assert_eq!(status, StatusCode::OK);
    // The same bytes late are fine (the worker finished anyway); other bytes are not.
    assert_eq!(
        upload(&f.app, late.lease, exr(&tile)).await.0,
        StatusCode::OK
    );
    let other = tile_of(&late, frame, 2.5);
    assert_eq!(
        upload(&f.app, late.lease, exr(&other)).await.0,
        StatusCode::CONFLICT
    );
    let (status, body) = upload(&f.app, late.lease, b"garbage".to_vec()).await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert_eq!(
        error_of(&body),
        format!("lease {} has expired or is unknown", late.lease)
    );
    // None of it counted as a failure or a second acceptance.
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.tiles_done, s.failures, s.state),
        (1, 0, JobState::Running)
    );
    assert!(
        metrics(&f.app)
            .await
            .contains("kiln_tiles_accepted_total 1\n")
    );
}

#[tokio::test]
async fn a_rejected_upload_counts_as_a_failed_attempt_and_the_tile_is_lent_again() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 32).await;
    let first = lease(&f.app, "w").await.unwrap();
    let mut nan = tile_of(&first, (32, 16), 1.0);
    nan.pixels[3] = [f32::NAN, 0.0, 0.0];
    let (status, body) = upload(&f.app, first.lease, exr(&nan)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "rejected tile: the tile has NaN or infinite pixels"
    );
    let second = lease(&f.app, "w").await.expect("lent again");
    assert_eq!(second.tile_index, first.tile_index);
    let mut wrong = tile_of(&second, (32, 16), 1.0);
    wrong.frame_width = 64;
    let (status, body) = upload(&f.app, second.lease, exr(&wrong)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("64x16 frame"),
        "{}",
        error_of(&body)
    );
    let s = job_status(&f.app, job).await;
    assert_eq!((s.failures, s.state), (2, JobState::Running));
    assert!(
        metrics(&f.app)
            .await
            .contains("kiln_tiles_rejected_total 2\n")
    );
}

#[tokio::test]
async fn internal_errors_are_answered_without_their_details() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 32).await;
    let l = lease(&f.app, "w").await.unwrap();
    assert_eq!(
        upload(&f.app, l.lease, exr(&tile_of(&l, (32, 16), 1.0)))
            .await
            .0,
        StatusCode::OK
    );
    let result = f.dir.path().join(format!("data/jobs/{job}/result.exr"));
    std::fs::remove_file(&result).unwrap();
    let path = format!("/v1/jobs/{job}/result.exr");
    let (status, body) = call(&f.app, "GET", &path, None, Body::empty()).await;
    assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
    assert_eq!(&body[..], br#"{"error":"internal error"}"#);
}

#[tokio::test]
async fn other_requests_are_answered_while_a_frame_is_merged() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 32).await;
    let l = lease(&f.app, "w").await.unwrap();
    // Hold the merge once it starts, until this test has looked around.
    let (started, merging) = tokio::sync::oneshot::channel();
    let (release, held) = std::sync::mpsc::channel::<()>();
    let (outcome, released) = std::sync::mpsc::channel::<bool>();
    f.c.on_next_merge(move || {
        started.send(()).unwrap();
        // Bounded, so a merge that blocks the requests below ends the test instead of
        // hanging it: they are then answered only after the timeout, and it fails.
        let in_time = held.recv_timeout(Duration::from_secs(5)).is_ok();
        outcome.send(in_time).unwrap();
    });
    let (app, last) = (f.app.clone(), exr(&tile_of(&l, (32, 16), 1.0)));
    let uploading = tokio::spawn(async move { upload(&app, l.lease, last).await });
    merging.await.unwrap();
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.state, s.tiles_done),
        (JobState::Running, 1),
        "the tile is kept and the job still running while its frame is written"
    );
    let preview = format!("/v1/jobs/{job}/preview.png");
    assert_eq!(
        call(&f.app, "GET", &preview, None, Body::empty()).await.0,
        StatusCode::OK
    );
    assert!(lease(&f.app, "w").await.is_none());
    let _ = release.send(());
    assert!(
        released.recv().unwrap(),
        "the requests above were answered while the merge was held"
    );
    assert_eq!(uploading.await.unwrap().0, StatusCode::OK);
    assert_eq!(job_status(&f.app, job).await.state, JobState::Done);
}

#[tokio::test]
async fn a_restarted_coordinator_keeps_acknowledged_tiles_and_merges_a_finished_job() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let job = submit(&f, 32, 16, 16).await;
    let a = lease(&f.app, "w").await.unwrap();
    let b = lease(&f.app, "w").await.unwrap();
    let (tile_a, tile_b) = (tile_of(&a, (32, 16), 3.0), tile_of(&b, (32, 16), 5.0));
    assert_eq!(
        upload(&f.app, a.lease, exr(&tile_a)).await.0,
        StatusCode::OK
    );
    let Farm { dir: _dir, c, app } = f;
    drop((c, app));
    // After a restart the acknowledged tile is still done; the other is lent again.
    let (c, app) = open(&data, None);
    let s = job_status(&app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let again = lease(&app, "w").await.unwrap();
    assert_eq!(again.tile_index, b.tile_index);
    assert!(lease(&app, "w").await.is_none());
    drop((c, app));
    // A coordinator that stopped after keeping the last tile, before writing the frame,
    // writes it when it starts.
    {
        let files = super::store::DataDir::create(&data).unwrap();
        let store = super::store::Store::open(&files).unwrap();
        store
            .insert_tile(job, b.tile_index as usize, &exr(&tile_b))
            .unwrap();
    }
    let (_c, app) = open(&data, None);
    let s = job_status(&app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Done, 2));
    let path = format!("/v1/jobs/{job}/result.exr");
    let (status, body) = call(&app, "GET", &path, None, Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    let mut expected = RgbBuffer::new(32, 16, 0, 0, 32, 16);
    expected.paste(&tile_a).unwrap();
    expected.paste(&tile_b).unwrap();
    assert_eq!(body, exr(&expected));
}

/// A flipped bit in an uploaded tile (one the EXR decoder would accept) is caught by the
/// tile's digest: the upload is refused, the attempt counts as failed, the tile is lent
/// again, and the merged frame holds the worker's real pixels. An upload without a digest
/// is refused outright.
#[tokio::test]
async fn a_tile_damaged_on_the_way_is_refused_and_lent_again() {
    let f = farm(None);
    let job = submit(&f, 16, 16, 16).await;
    let first = lease(&f.app, "w").await.unwrap();
    let tile = tile_of(&first, (16, 16), 0.25);
    let good = exr(&tile);
    let digest = crate::bundle::digest_of(&good);
    // One flipped bit, the last one whose file still decodes, to other pixels.
    let damaged = (0..good.len() * 8)
        .rev()
        .map(|bit| {
            let mut d = good.clone();
            d[bit / 8] ^= 1 << (bit % 8);
            d
        })
        .find(|d| kiln_image::decode_exr(d).is_ok_and(|t| t.pixels != tile.pixels))
        .expect("some single-bit damage decodes to other pixels");
    let (status, body) = upload_with_digest(&f.app, first.lease, damaged, Some(&digest)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).contains("SHA-256"), "{}", error_of(&body));
    let (status, body) = upload_with_digest(&f.app, first.lease, good.clone(), None).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).contains("X-Kiln-Tile-SHA256"));
    // The damaged upload ended the lease; the tile is lent again and finishes the job.
    let again = lease(&f.app, "w").await.unwrap();
    assert_eq!(again.tile_index, first.tile_index);
    assert_eq!(upload(&f.app, again.lease, good).await.0, StatusCode::OK);
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.failures), (JobState::Done, 1));
    let (_, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(kiln_image::decode_exr(&body).unwrap().pixels, tile.pixels);
}

/// An EXR of a few hundred bytes whose header claims billions of pixels is refused, under
/// a live lease and under an unknown one, without decoding it; the coordinator goes on.
#[tokio::test]
async fn a_tile_claiming_a_huge_image_is_refused_without_decoding_it() {
    let f = farm(None);
    let job = submit(&f, 16, 16, 16).await;
    let held = lease(&f.app, "w").await.unwrap();
    let mut evil = exr(&tile_of(&held, (16, 16), 1.0));
    let name = b"dataWindow\0box2i\0";
    let at = evil.windows(name.len()).position(|w| w == name).unwrap() + name.len() + 4;
    evil[at + 8..at + 12].copy_from_slice(&99_999i32.to_le_bytes());
    evil[at + 12..at + 16].copy_from_slice(&99_999i32.to_le_bytes());
    assert!(evil.len() < 1000);
    for id in [held.lease, held.lease + 1000] {
        let (status, body) = upload(&f.app, id, evil.clone()).await;
        assert!(status.is_client_error(), "{status}: {}", error_of(&body));
    }
    assert_eq!(job_status(&f.app, job).await.state, JobState::Running);
    assert!(lease(&f.app, "w").await.is_some(), "the tile is lent again");
}

/// Lease ids are never reused, across restarts too: a worker still holding an id from
/// before a restart cannot heartbeat, upload to or fail a lease granted after it.
#[tokio::test]
async fn lease_ids_from_before_a_restart_name_no_new_lease() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    submit(&f, 32, 16, 16).await;
    let old = lease(&f.app, "old").await.unwrap();
    let Farm { dir: _dir, c, app } = f;
    drop((c, app));
    let (_c, app) = open(&data, None);
    let new = lease(&app, "new").await.unwrap();
    assert_ne!(new.lease, old.lease);
    let other = lease(&app, "new").await.unwrap();
    assert!(![new.lease, other.lease].contains(&old.lease));
    assert_eq!(heartbeat(&app, old.lease).await, StatusCode::CONFLICT);
    let tile = tile_of(&old, (32, 16), 1.0);
    assert_eq!(
        upload(&app, old.lease, exr(&tile)).await.0,
        StatusCode::CONFLICT
    );
    // The new leases are untouched.
    assert_eq!(heartbeat(&app, new.lease).await, StatusCode::NO_CONTENT);
    assert_eq!(heartbeat(&app, other.lease).await, StatusCode::NO_CONTENT);
}

/// A job whose frame would not fit in memory (65536 x 65536, from the request or from the
/// scene's Film) is refused with a message that says how large it is; nothing is
/// allocated for it and the coordinator goes on.
#[tokio::test]
async fn a_job_too_large_to_hold_is_refused_before_its_frame_is_allocated() {
    let f = farm(None);
    submit(&f, 8, 8, 8).await;
    let digest = f.c.lock().jobs.values().next().unwrap().spec.scene.clone();
    for (resolution, scene) in [
        (Some((65536, 65536)), digest.clone()),
        (None, String::new()),
    ] {
        let scene = if scene.is_empty() {
            // A scene whose Film itself asks for the huge frame.
            let dir = f.dir.path().join("huge-film");
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(
                dir.join("scene.pbrt"),
                "Film \"rgb\" \"integer xresolution\" [ 65536 ] \"integer yresolution\" [ 65536 ]\nWorldBegin\n",
            )
            .unwrap();
            let bundle = crate::bundle::pack(&dir.join("scene.pbrt")).unwrap();
            let (status, _) = call(&f.app, "POST", "/v1/scenes", None, bundle.bytes).await;
            assert_eq!(status, StatusCode::OK);
            bundle.digest
        } else {
            scene
        };
        let spec = JobSpec {
            scene,
            spp: Some(1),
            resolution,
            tile: 32,
            seed: None,
        };
        let body = serde_json::to_vec(&spec).unwrap();
        let (status, body) = call(&f.app, "POST", "/v1/jobs", None, body).await;
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(error_of(&body).contains("51.5 GB"), "{}", error_of(&body));
    }
    assert_eq!(job_status(&f.app, 1).await.tiles_total, 1);
}

/// A scene in a bundle may name only files inside the bundle: an Include of a server file
/// (absolute, or climbing out with `..`) is refused before the file is opened, and the
/// error quotes neither the file nor the coordinator's data path.
#[tokio::test]
async fn a_bundle_cannot_make_the_coordinator_read_its_files() {
    let f = farm(None);
    let secret = f.dir.path().join("secret.pbrt");
    std::fs::write(&secret, "this line is the server's secret\n").unwrap();
    for include in [
        secret.display().to_string(),
        "../../secret.pbrt".to_string(),
        "models/../../../secret.pbrt".to_string(),
    ] {
        let scene = format!("WorldBegin\nInclude \"{include}\"\n");
        let bundle = crate::bundle::encode(&[("scene.pbrt".into(), scene.into_bytes())]);
        let (status, _) = call(&f.app, "POST", "/v1/scenes", None, bundle.bytes).await;
        assert_eq!(status, StatusCode::OK);
        let spec = JobSpec {
            scene: bundle.digest,
            spp: Some(1),
            resolution: Some((8, 8)),
            tile: 8,
            seed: None,
        };
        let body = serde_json::to_vec(&spec).unwrap();
        let (status, body) = call(&f.app, "POST", "/v1/jobs", None, body).await;
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        let error = error_of(&body);
        assert!(error.contains("outside the scene's folder"), "{error}");
        assert!(error.starts_with("scene.pbrt:2:"), "{error}");
        assert!(!error.contains("server's secret"), "{error}");
        let data = f.dir.path().join("data").display().to_string();
        assert!(!error.contains(&data), "{error}");
    }
}

/// Answers axum makes itself (a body over its limit, a method a route lacks) are the
/// documented JSON error too.
#[tokio::test]
async fn every_error_answer_is_json() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config::new(dir.path().join("data"));
    config.max_tile_bytes = 1000;
    config.max_scene_bytes = 1000;
    let app = app(Coordinator::open(config).unwrap());
    for (method, uri, body) in [
        ("PUT", "/v1/leases/1/tile", vec![0u8; 5000]),
        ("POST", "/v1/scenes", vec![0u8; 5000]),
        ("DELETE", "/v1/jobs", Vec::new()),
        ("GET", "/v1/leases", Vec::new()),
    ] {
        let req = Request::builder()
            .method(method)
            .uri(uri)
            .header(crate::api::TILE_DIGEST_HEADER, "00")
            .body(Body::from(body))
            .unwrap();
        let response = app.clone().oneshot(req).await.unwrap();
        let status = response.status();
        assert!(status.is_client_error(), "{method} {uri}: {status}");
        assert_eq!(
            response.headers()[header::CONTENT_TYPE],
            "application/json",
            "{method} {uri}"
        );
        let body = axum::body::to_bytes(response.into_body(), usize::MAX)
            .await
            .unwrap();
        assert!(!error_of(&body).is_empty(), "{method} {uri}");
    }
    // The refused upload streamed to disk left nothing behind.
    let scenes = dir.path().join("data").join("scenes");
    assert_eq!(std::fs::read_dir(&scenes).unwrap().count(), 0);
}

/// Bundles whose entry names the file system would refuse (a file that is also a folder, a
/// name over 255 bytes, a NUL, a name twice) are the client's mistake: a 400 that says
/// which, never a 500 with the server's path, and nothing is left behind.
#[tokio::test]
async fn bundles_whose_names_cannot_be_files_are_refused() {
    let f = farm(None);
    let scene = b"WorldBegin\n".to_vec();
    let long = "n".repeat(300);
    for (names, words) in [
        (vec!["scene.pbrt", "a", "a/b"], "both a file and a folder"),
        (vec!["scene.pbrt", "a/b", "a"], "both a file and a folder"),
        (vec!["scene.pbrt", long.as_str()], "longer than 255 bytes"),
        (vec!["scene.pbrt", "x\0y"], "NUL"),
        (vec!["scene.pbrt", "m.ply", "m.ply"], "twice"),
    ] {
        let files: Vec<(String, Vec<u8>)> = names
            .iter()
            .map(|n| (n.to_string(), scene.clone()))
            .collect();
        let bundle = crate::bundle::encode(&files);
        let (status, body) = call(&f.app, "POST", "/v1/scenes", None, bundle.bytes).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{names:?}");
        let error = error_of(&body);
        assert!(error.contains(words), "{names:?}: {error}");
        assert!(
            !error.contains(&f.dir.path().display().to_string()),
            "{error}"
        );
    }
    // Nothing was kept: the scenes folder holds no entry, finished or temporary.
    let scenes = f.dir.path().join("data").join("scenes");
    let left: Vec<_> = std::fs::read_dir(&scenes)
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "{left:?}");
}

/// Submits racing with one Idempotency-Key make one job: every answer names it, none is a
/// 500 (the store's UNIQUE constraint once answered about four in ten of them).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn racing_submits_with_one_idempotency_key_make_one_job() {
    let f = farm(None);
    submit(&f, 8, 8, 8).await;
    let digest = f.c.lock().jobs.values().next().unwrap().spec.scene.clone();
    for round in 0..5 {
        let key = format!("retry-{round}");
        let requests = (0..8).map(|_| {
            let app = f.app.clone();
            let spec = JobSpec {
                scene: digest.clone(),
                spp: Some(1),
                resolution: None,
                tile: 8,
                seed: None,
            };
            let key = key.clone();
            tokio::spawn(async move {
                let req = Request::builder()
                    .method("POST")
                    .uri("/v1/jobs")
                    .header("idempotency-key", key)
                    .body(Body::from(serde_json::to_vec(&spec).unwrap()))
                    .unwrap();
                let response = app.oneshot(req).await.unwrap();
                let status = response.status();
                let body = axum::body::to_bytes(response.into_body(), usize::MAX)
                    .await
                    .unwrap();
                (status, body)
            })
        });
        let mut ids = Vec::new();
        for r in requests.collect::<Vec<_>>() {
            let (status, body) = r.await.unwrap();
            assert!(
                status == StatusCode::CREATED || status == StatusCode::OK,
                "{status}: {}",
                String::from_utf8_lossy(&body)
            );
            ids.push(json::<crate::api::JobCreated>(&body).id);
        }
        ids.dedup();
        assert_eq!(ids.len(), 1, "round {round}: {ids:?}");
    }
}

/// Damage to the store or the data directory is reported, and the rest serves: a job whose
/// record is unreadable, or whose scene bundle was deleted, is listed failed with the
/// reason (a finished one keeps its frame); a store that lost jobs whose frames are on
/// disk refuses to start, saying so, instead of starting empty.
#[tokio::test]
async fn damage_is_reported_and_the_rest_of_the_coordinator_serves() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let done = submit(&f, 8, 8, 8).await;
    let l = lease(&f.app, "w").await.unwrap();
    assert_eq!(
        upload(&f.app, l.lease, exr(&tile_of(&l, (8, 8), 1.0)))
            .await
            .0,
        StatusCode::OK
    );
    let running = submit(&f, 16, 8, 8).await;
    let damaged = submit(&f, 24, 8, 8).await;
    let healthy = submit(&f, 32, 8, 8).await;
    let scene_of = |job: u64| f.c.lock().jobs[&job].spec.scene.clone();
    let (done_scene, running_scene) = (scene_of(done), scene_of(running));
    let Farm { dir, c, app } = f;
    drop((c, app));
    // The finished job's and the running job's bundles vanish; one record is garbled.
    for digest in [&done_scene, &running_scene] {
        std::fs::remove_dir_all(data.join("scenes").join(digest)).unwrap();
    }
    let db = rusqlite::Connection::open(data.join("kiln.sqlite")).unwrap();
    db.execute(
        "UPDATE jobs SET spec = '{not json' WHERE id = ?1",
        [damaged as i64],
    )
    .unwrap();
    drop(db);
    let (_c, app) = open(&data, None);
    let s = job_status(&app, done).await;
    assert_eq!(s.state, JobState::Done);
    let (status, _) = call(
        &app,
        "GET",
        &format!("/v1/jobs/{done}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "a finished job keeps its frame");
    let s = job_status(&app, running).await;
    assert_eq!(s.state, JobState::Failed);
    assert!(s.error.unwrap().contains("no scene with digest"));
    let s = job_status(&app, damaged).await;
    assert_eq!(s.state, JobState::Failed);
    assert!(s.error.unwrap().contains("record in the store is damaged"));
    let s = job_status(&app, healthy).await;
    assert_eq!(s.state, JobState::Running);
    assert!(lease(&app, "w").await.is_some(), "the healthy job is lent");
    drop((_c, app));
    // The store is replaced by an empty one: the finished job's frame is on disk, so the
    // coordinator refuses to start, naming the job.
    std::fs::remove_file(data.join("kiln.sqlite")).unwrap();
    for side in ["kiln.sqlite-wal", "kiln.sqlite-shm"] {
        let _ = std::fs::remove_file(data.join(side));
    }
    let mut config = Config::new(data.clone());
    config.lease_ttl = TTL;
    let err = Coordinator::open(config)
        .err()
        .expect("it refuses to start")
        .to_string();
    assert!(
        err.contains(&format!("no record of jobs [{done}]")),
        "{err}"
    );
    drop(dir);
}

/// A job's scene is a digest of an uploaded bundle, nothing else: a path, even one that
/// names a folder with a scene marker, is no scene.
#[tokio::test]
async fn a_job_scene_must_be_a_digest() {
    let f = farm(None);
    submit(&f, 8, 8, 8).await;
    let digest = f.c.lock().jobs.values().next().unwrap().spec.scene.clone();
    for scene in [
        format!("{digest}/.."),
        format!("../scenes/{digest}"),
        "..".to_string(),
        "/etc".to_string(),
        digest.to_uppercase() + "x",
    ] {
        let spec = JobSpec {
            scene: scene.clone(),
            spp: Some(1),
            resolution: None,
            tile: 8,
            seed: None,
        };
        let body = serde_json::to_vec(&spec).unwrap();
        let (status, body) = call(&f.app, "POST", "/v1/jobs", None, body).await;
        assert!(status.is_client_error(), "{scene}: {status}");
        assert!(
            error_of(&body).contains("no scene"),
            "{scene}: {}",
            error_of(&body)
        );
    }
}
