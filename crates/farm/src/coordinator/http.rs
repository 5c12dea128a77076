//! The coordinator's HTTP API: [`app`]'s routes, the bearer-token middleware (who the
//! request is from, and whether its role may call the route: `credentials.rs`), the
//! handlers (each job a submitter's own, each lease a worker's own), and how an [`Error`]
//! becomes a response.
//!
//! Handlers only parse requests, call the [`Coordinator`] handle and shape answers. They
//! must never touch SQLite, the data directory or the lock directly. Every error body is
//! `{"error": message}`: the client's mistakes with their own status and message, internal
//! failures logged here once and answered with a bare 500.

use super::credentials::{self, Principal};
use super::{Coordinator, Error};
use crate::api::*;
use axum::Extension;
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Path as UrlPath, Request, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use axum::{Json, Router};
use std::time::Duration;
use tokio::sync::broadcast;

/// The coordinator's HTTP routes.
pub fn app(c: Coordinator) -> Router {
    let max_tile = c.config().max_tile_bytes;
    let api = Router::new()
        // Streamed to disk, and limited as it streams (save_scene_stream).
        .route("/v1/scenes", post(upload_scene))
        .route("/v1/scenes/{digest}", get(download_scene))
        // Streamed to disk, and limited as it streams (save_prepass).
        .route(
            "/v1/scenes/{digest}/prepass/{name}",
            get(download_prepass).put(upload_prepass),
        )
        .route(
            "/v1/scenes/{digest}/prepass/{name}/claim",
            post(claim_prepass).delete(release_prepass),
        )
        .route("/v1/jobs", post(create_job).get(list_jobs))
        .route("/v1/jobs/{id}", get(get_job))
        .route("/v1/jobs/{id}/events", get(job_events))
        .route("/v1/jobs/{id}/result.exr", get(job_result))
        .route("/v1/jobs/{id}/preview.png", get(job_preview))
        .route("/v1/jobs/{id}/frames", get(job_frames))
        .route("/v1/jobs/{id}/frames/{frame}/result.exr", get(frame_result))
        .route(
            "/v1/jobs/{id}/frames/{frame}/preview.png",
            get(frame_preview),
        )
        .route("/v1/jobs/{id}/cancel", post(cancel_job))
        .route("/v1/jobs/{id}/stop", post(stop_job))
        .route("/v1/jobs/{id}/extend", post(extend_job))
        .route("/v1/workers", get(list_workers))
        .route("/v1/workers/{name}/reinstate", post(reinstate_worker))
        .route("/v1/tokens", post(issue_token).get(list_tokens))
        .route("/v1/tokens/{id}/revoke", post(revoke_token))
        .route("/v1/leases", post(lease))
        .route("/v1/leases/{id}/heartbeat", post(heartbeat))
        .route(
            "/v1/leases/{id}/tile",
            put(upload_tile).layer(DefaultBodyLimit::max(max_tile)),
        )
        .route("/v1/leases/{id}/fail", post(fail_lease))
        .route("/v1/leases/{id}/sums", get(lease_sums))
        .route("/v1/openapi.json", get(openapi))
        .route("/metrics", get(metrics))
        .route_layer(middleware::from_fn_with_state(c.clone(), require_token));
    Router::new()
        .route(
            "/healthz",
            get(|State(c): State<Coordinator>| async move { c.health() }),
        )
        // The dashboard's page and code hold no secrets: served without the token, which
        // the page asks for and sends with every API call.
        .route("/", get(dashboard_page))
        .route("/dashboard/app.js", get(dashboard_js))
        .route("/dashboard/app.css", get(dashboard_css))
        .route("/v1/token/check", post(check_token))
        .merge(api)
        .fallback(|| async { Error::NoRoute })
        .layer(middleware::map_response(json_errors))
        .with_state(c)
}

/// Every error answer is the documented JSON `{"error": ...}`: axum's own rejections (a
/// body over its limit, a method a route does not have) come as plain text, and are
/// rewritten here with their message.
async fn json_errors(response: Response) -> Response {
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, 4096)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let message = if text.is_empty() {
        status.canonical_reason().unwrap_or("error").to_lowercase()
    } else {
        text
    };
    let mut json = (status, Json(ApiError { error: message })).into_response();
    for (name, value) in &parts.headers {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            json.headers_mut().insert(name, value.clone());
        }
    }
    json
}

impl Error {
    /// The status a client gets for this error.
    fn status(&self) -> StatusCode {
        match self {
            Error::Unauthorized => StatusCode::UNAUTHORIZED,
            Error::TooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            Error::NoRoute
            | Error::UnknownScene(_)
            | Error::UnknownJob(_)
            | Error::UnknownFrame { .. }
            | Error::UnknownToken(_)
            | Error::NotSetAside(_)
            | Error::UnknownPrepass(_)
            | Error::NoSums(_) => StatusCode::NOT_FOUND,
            Error::BadId(_)
            | Error::BadBody(_)
            | Error::BadJob(_)
            | Error::BadBundle(_)
            | Error::BadDigest
            | Error::BadExposure
            | Error::BadDenoise
            | Error::NoTileDigest
            | Error::BadPrepassName
            | Error::UnwantedPrepass(_)
            | Error::BadWorkerName(_)
            | Error::BadTags(_)
            | Error::BadToken(_)
            | Error::PrepassDigest
            | Error::BrokenUpload(_)
            | Error::RejectedTile(_) => StatusCode::BAD_REQUEST,
            Error::Unplannable(_) => StatusCode::UNPROCESSABLE_ENTITY,
            Error::NotDone { .. }
            | Error::NoResult(_)
            | Error::Passes { .. }
            | Error::UnknownLease(_)
            | Error::StaleTile(_)
            | Error::Relent(_)
            | Error::Denoise(_)
            | Error::DenoiseTooLarge { .. } => StatusCode::CONFLICT,
            Error::SetAside { .. } | Error::Forbidden(_) => StatusCode::FORBIDDEN,
            Error::JobEnded(_) => StatusCode::GONE,
            // The store is away (a server restarting, a full disk) or this coordinator no
            // longer leads: the same request may succeed later, here or at the leader.
            Error::Store(_) | Error::Objects(_) => StatusCode::SERVICE_UNAVAILABLE,
            Error::LostJobs(_)
            | Error::Io { .. }
            | Error::Unpack(_)
            | Error::Image(_)
            | Error::Task(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

impl IntoResponse for Error {
    fn into_response(self) -> Response {
        let status = self.status();
        let message = if let Error::Store(e) = &self {
            tracing::error!("{self}");
            if e.is_deposed() {
                "this coordinator no longer leads: ask the others".to_string()
            } else {
                "the job store cannot be used right now: try again (the coordinator's log says why)"
                    .to_string()
            }
        } else if let Error::Objects(_) = &self {
            tracing::error!("{self}");
            "the object store cannot be used right now: try again (the coordinator's log says why)"
                .to_string()
        } else if status.is_server_error() {
            // The details are for the operator's log, not for clients.
            tracing::error!("{self}");
            "internal error".to_string()
        } else {
            self.to_string()
        };
        (status, Json(ApiError { error: message })).into_response()
    }
}

/// Who the request is from (the admin for a coordinator without a token; else the bearer
/// token's owner, or 401), and whether that role may call the route (403 if not); the
/// principal goes on to the handler.
async fn require_token(
    State(c): State<Coordinator>,
    mut req: Request,
    next: Next,
) -> Result<Response, Error> {
    let who = match &c.config().token {
        None => Principal::admin(),
        Some(_) => {
            let given = req
                .headers()
                .get(header::AUTHORIZATION)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.strip_prefix("Bearer "));
            given
                .and_then(|g| c.principal(g))
                .ok_or(Error::Unauthorized)?
        }
    };
    let (method, path) = (req.method().as_str(), req.uri().path());
    if !credentials::may(who.role, method, path) {
        return Err(Error::Forbidden(format!(
            "a {} token may not {method} {}",
            who.role.as_str(),
            path.chars().take(200).collect::<String>()
        )));
    }
    req.extensions_mut().insert(who);
    Ok(next.run(req).await)
}

/// Job `id` as `who` may see it: a submitter sees only its own (another's is answered as no
/// such job, so ids say nothing of others' work).
fn own_job(c: &Coordinator, who: &Principal, id: u64) -> Result<u64, Error> {
    if who.role == Role::Submitter && c.job_owner(id)?.as_deref() != Some(who.name.as_str()) {
        return Err(Error::UnknownJob(id));
    }
    Ok(id)
}

/// Lease `lease` as `who` may touch it: a worker's credential only its own leases.
fn own_lease(c: &Coordinator, who: &Principal, lease: u64) -> Result<u64, Error> {
    if who.role == Role::Worker
        && let Some(holder) = c.lease_holder(lease)
        && holder != who.name
    {
        return Err(Error::Forbidden(format!(
            "lease {lease} is another worker's, not {}'s",
            who.name
        )));
    }
    Ok(lease)
}

/// The dashboard's sign-in: whether a token is the coordinator's, answered 200 either way
/// (`{"valid": bool}`), so that a mistyped token is a message, not a failed request.
async fn check_token(State(c): State<Coordinator>, body: Bytes) -> Result<Response, Error> {
    #[derive(serde::Deserialize)]
    struct Given {
        token: String,
    }
    let given: Given = parse_json(&body)?;
    let who = match &c.config().token {
        None => Some(Principal::admin()),
        Some(_) => c.principal(&given.token),
    };
    Ok(Json(TokenCheck {
        valid: who.is_some(),
        role: who.as_ref().map(|w| w.role),
        name: who.map(|w| w.name),
    })
    .into_response())
}

/// Ids in paths, parsed here so a bad one gets a JSON error like every other.
fn parse_id(text: &str) -> Result<u64, Error> {
    text.parse().map_err(|_| Error::BadId(text.to_string()))
}

/// JSON bodies, parsed here so malformed ones get a JSON error that says what is wrong.
fn parse_json<T: serde::de::DeserializeOwned>(body: &[u8]) -> Result<T, Error> {
    serde_json::from_slice(body).map_err(Error::BadBody)
}

async fn upload_scene(
    State(c): State<Coordinator>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<Json<SceneUploaded>, Error> {
    let body = refuse_declared_over(&headers, body, c.config().max_scene_bytes)?;
    let digest = c.save_scene_stream(body).await?;
    Ok(Json(SceneUploaded { digest }))
}

async fn download_scene(
    State(c): State<Coordinator>,
    UrlPath(digest): UrlPath<String>,
) -> Result<Response, Error> {
    let bundle = c.scene_bundle(&digest).await?;
    Ok(send_file(bundle, "application/octet-stream", None))
}

/// Refuses an upload whose declared length is over `limit` before a byte of it is stored
/// (one that declares none, or lies, is still stopped at the limit as it streams). The
/// refused body is read and dropped for a while meanwhile, as web servers do before they
/// close: a client that sends its whole body before it reads the answer (as most HTTP
/// libraries do) would otherwise see its connection reset instead of the 413.
fn refuse_declared_over(
    headers: &HeaderMap,
    body: axum::body::Body,
    limit: usize,
) -> Result<axum::body::Body, Error> {
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    match declared {
        Some(n) if n > limit as u64 => {
            tokio::spawn(linger(body));
            Err(Error::TooLarge { limit })
        }
        _ => Ok(body),
    }
}

/// How long a refused upload's body is read and dropped before its connection is closed.
const LINGER: std::time::Duration = std::time::Duration::from_secs(10);

/// Reads `body` and drops what it reads, until it ends or [`LINGER`] has passed.
async fn linger(body: axum::body::Body) {
    use tokio_stream::StreamExt;
    let mut stream = body.into_data_stream();
    let drain = async { while let Some(Ok(_)) = stream.next().await {} };
    let _ = tokio::time::timeout(LINGER, drain).await;
}

/// A job's shared pre-pass (photon maps, an SPPM pass), as a worker uploaded it, with the
/// SHA-256 of its bytes.
async fn download_prepass(
    State(c): State<Coordinator>,
    UrlPath((digest, name)): UrlPath<(String, String)>,
) -> Result<Response, Error> {
    let (prepass, sha) = c.prepass(&digest, &name).await?;
    let sha = (header::HeaderName::from_static(PREPASS_DIGEST_HEADER), sha);
    Ok(send_file(prepass, "application/octet-stream", Some(sha)))
}

async fn upload_prepass(
    State(c): State<Coordinator>,
    UrlPath((digest, name)): UrlPath<(String, String)>,
    headers: HeaderMap,
    body: axum::body::Body,
) -> Result<StatusCode, Error> {
    let body = refuse_declared_over(&headers, body, c.config().max_prepass_bytes)?;
    let sha = headers
        .get(PREPASS_DIGEST_HEADER)
        .and_then(|v| v.to_str().ok())
        .ok_or(Error::PrepassDigest)?
        .to_string();
    c.save_prepass(&digest, &name, body, &sha).await?;
    Ok(StatusCode::NO_CONTENT)
}

async fn claim_prepass(
    State(c): State<Coordinator>,
    UrlPath((digest, name)): UrlPath<(String, String)>,
) -> Result<Json<PrepassClaimAnswer>, Error> {
    let claim = c
        .off_runtime(move |c| c.claim_prepass(&digest, &name))
        .await?;
    Ok(Json(PrepassClaimAnswer { claim }))
}

async fn release_prepass(
    State(c): State<Coordinator>,
    UrlPath((digest, name)): UrlPath<(String, String)>,
) -> Result<StatusCode, Error> {
    c.release_prepass(&digest, &name)?;
    Ok(StatusCode::NO_CONTENT)
}

async fn create_job(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, Error> {
    let mut spec: JobSpec = serde_json::from_slice(&body).map_err(Error::BadJob)?;
    // Whose job it is is the token's to say, not the body's.
    spec.owner = (who.role == Role::Submitter).then(|| who.name.clone());
    let key = headers
        .get("idempotency-key")
        .and_then(|v| v.to_str().ok())
        .map(String::from);
    let (id, created) = c.create_job(spec, key).await?;
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(JobCreated { id })).into_response())
}

async fn list_jobs(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
) -> Json<Vec<JobStatus>> {
    let mut all = c.statuses();
    if who.role == Role::Submitter {
        all.retain(|j| j.owner.as_deref() == Some(who.name.as_str()));
    }
    Json(all)
}

async fn list_workers(State(c): State<Coordinator>) -> Json<Vec<WorkerStatus>> {
    Json(c.worker_statuses())
}

/// Issues a token (POST /v1/tokens): its secret is in this answer only.
async fn issue_token(
    State(c): State<Coordinator>,
    body: Bytes,
) -> Result<(StatusCode, Json<TokenIssued>), Error> {
    let req: TokenRequest = parse_json(&body)?;
    let issued = c.off_runtime(move |c| c.issue_token(&req)).await?;
    Ok((StatusCode::CREATED, Json(issued)))
}

async fn list_tokens(State(c): State<Coordinator>) -> Json<Vec<TokenInfo>> {
    Json(c.tokens())
}

/// Revokes a token (POST /v1/tokens/{id}/revoke): refused from the next request on.
async fn revoke_token(
    State(c): State<Coordinator>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<TokenInfo>, Error> {
    let id = parse_id(&id)?;
    c.off_runtime(move |c| c.revoke_token(id)).await.map(Json)
}

/// Trusts a worker set aside again (POST /v1/workers/{name}/reinstate).
async fn reinstate_worker(
    State(c): State<Coordinator>,
    UrlPath(name): UrlPath<String>,
) -> Result<Json<Vec<WorkerStatus>>, Error> {
    c.off_runtime(move |c| c.reinstate(&name)).await?;
    Ok(Json(c.worker_statuses()))
}

async fn get_job(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<JobStatus>, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    c.status(id).map(Json).ok_or(Error::UnknownJob(id))
}

async fn job_events(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    let first = c.status(id).ok_or(Error::UnknownJob(id))?;
    let mut rx = c.subscribe();
    let stream = async_stream(move |tx: tokio::sync::mpsc::Sender<Event>| async move {
        let progress = |s: &JobStatus| {
            Event::default()
                .event("progress")
                .json_data(s)
                .unwrap_or_default()
        };
        let mut last = first;
        let _ = tx.send(progress(&last)).await;
        while last.state == JobState::Running {
            let changed = tokio::time::timeout(Duration::from_secs(1), rx.recv()).await;
            if let Ok(Err(broadcast::error::RecvError::Closed)) = changed {
                break;
            }
            let Some(now) = c.status(id) else { break };
            if now != last {
                last = now;
                if tx.send(progress(&last)).await.is_err() {
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
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    let result = c.result(id).await?;
    Ok(send_file(result, "image/x-exr", None))
}

/// Answers with a kept file, read from disk a quarter of a megabyte at a time as the
/// client takes it: a bundle, a pre-pass or a frame may be gigabytes, and as many clients
/// may download them at once.
fn send_file(
    stored: super::Stored,
    content_type: &'static str,
    extra: Option<(header::HeaderName, String)>,
) -> Response {
    use tokio::io::AsyncReadExt;
    let super::Stored { mut file, len } = stored;
    let (chunks, body) = tokio::sync::mpsc::channel::<std::io::Result<Bytes>>(4);
    tokio::spawn(async move {
        let mut left = len;
        while left > 0 {
            let mut buf = vec![0u8; (256 << 10).min(left) as usize];
            let chunk = match file.read(&mut buf).await {
                Ok(0) => Err(std::io::ErrorKind::UnexpectedEof.into()),
                Ok(n) => {
                    buf.truncate(n);
                    left -= n as u64;
                    Ok(Bytes::from(buf))
                }
                Err(e) => Err(e),
            };
            let failed = chunk.is_err();
            // A client that went away drops the body, and the file is closed.
            if chunks.send(chunk).await.is_err() || failed {
                return;
            }
        }
    });
    let body = axum::body::Body::from_stream(tokio_stream::wrappers::ReceiverStream::new(body));
    let mut response = ([(header::CONTENT_TYPE, content_type)], body).into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_LENGTH, header::HeaderValue::from(len));
    if let Some((name, value)) = extra
        && let Ok(value) = header::HeaderValue::from_str(&value)
    {
        headers.insert(name, value);
    }
    response
}

/// `?exposure=` for a preview: stops, -20 to 20 (0 by default); `?denoise=1` (or true)
/// for the frame denoised by Kiln's built-in denoiser.
#[derive(Debug, serde::Deserialize)]
struct PreviewQuery {
    #[serde(default)]
    exposure: f32,
    #[serde(default)]
    denoise: Option<String>,
}

/// Whether `?denoise=` asks for the denoised frame: 1 or true, 0 or false.
fn denoise_of(value: Option<&str>) -> Result<bool, Error> {
    match value {
        None | Some("0" | "false") => Ok(false),
        Some("1" | "true") => Ok(true),
        Some(_) => Err(Error::BadDenoise),
    }
}

async fn job_preview(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
    query: Result<axum::extract::Query<PreviewQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    let (exposure, denoise) = exposure_of(query)?;
    let png = c.frame_preview(id, 0, exposure, denoise).await?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

/// The exposure a preview asks for (a number of stops from -20 to 20), and whether
/// denoised.
fn exposure_of(
    query: Result<axum::extract::Query<PreviewQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<(f32, bool), Error> {
    match query {
        Ok(q) if q.exposure.is_finite() && q.exposure.abs() <= 20.0 => {
            Ok((q.exposure, denoise_of(q.denoise.as_deref())?))
        }
        _ => Err(Error::BadExposure),
    }
}

/// Each frame's progress (GET /v1/jobs/{id}/frames).
async fn job_frames(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<Vec<FrameStatus>>, Error> {
    c.frames(own_job(&c, &who, parse_id(&id)?)?).map(Json)
}

/// A frame's id and index from the path, each a number.
fn parse_frame(id: &str, frame: &str) -> Result<(u64, u32), Error> {
    let frame = frame.parse().map_err(|_| Error::BadId(frame.to_string()))?;
    Ok((parse_id(id)?, frame))
}

/// A frame's merged EXR (GET /v1/jobs/{id}/frames/{frame}/result.exr).
async fn frame_result(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath((id, frame)): UrlPath<(String, String)>,
) -> Result<Response, Error> {
    let (id, frame) = parse_frame(&id, &frame)?;
    own_job(&c, &who, id)?;
    let result = c.frame_result(id, frame).await?;
    Ok(send_file(result, "image/x-exr", None))
}

/// A frame so far as a PNG (GET /v1/jobs/{id}/frames/{frame}/preview.png).
async fn frame_preview(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath((id, frame)): UrlPath<(String, String)>,
    query: Result<axum::extract::Query<PreviewQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Response, Error> {
    let (id, frame) = parse_frame(&id, &frame)?;
    own_job(&c, &who, id)?;
    let (exposure, denoise) = exposure_of(query)?;
    let png = c.frame_preview(id, frame, exposure, denoise).await?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

async fn cancel_job(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<JobStatus>, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    c.off_runtime(move |c| c.cancel(id)).await.map(Json)
}

/// Ends a job after the pass in progress (POST /v1/jobs/{id}/stop).
async fn stop_job(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<JobStatus>, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    c.off_runtime(move |c| c.stop_after_pass(id))
        .await
        .map(Json)
}

async fn extend_job(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
    body: Bytes,
) -> Result<Json<JobStatus>, Error> {
    let id = own_job(&c, &who, parse_id(&id)?)?;
    let e: Extend = parse_json(&body)?;
    c.off_runtime(move |c| c.extend(id, &e.passes))
        .await
        .map(Json)
}

/// The tile EXR a lease's pass continues from, with its SHA-256.
async fn lease_sums(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<Response, Error> {
    let id = own_lease(&c, &who, parse_id(&id)?)?;
    let bytes = c.off_runtime(move |c| c.sums_for(id)).await?;
    let sha = crate::bundle::digest_of(&bytes);
    Ok((
        [
            (header::CONTENT_TYPE, "image/x-exr".to_string()),
            (header::HeaderName::from_static(TILE_DIGEST_HEADER), sha),
        ],
        bytes,
    )
        .into_response())
}

async fn lease(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    body: Bytes,
) -> Result<Response, Error> {
    let req: LeaseRequest = parse_json(&body)?;
    // A worker's credential is its name: it asks for work as itself or not at all.
    if who.role == Role::Worker && req.worker != who.name {
        return Err(Error::Forbidden(format!(
            "this credential is worker {}'s; it may not ask for work under another name",
            who.name
        )));
    }
    Ok(match c.off_runtime(move |c| c.lease_for(&req)).await? {
        Some(lease) => Json(lease).into_response(),
        None => StatusCode::NO_CONTENT.into_response(),
    })
}

async fn heartbeat(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
) -> Result<StatusCode, Error> {
    let id = own_lease(&c, &who, parse_id(&id)?)?;
    c.off_runtime(move |c| c.heartbeat(id)).await?;
    Ok(StatusCode::NO_CONTENT)
}

async fn upload_tile(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<StatusCode, Error> {
    let id = own_lease(&c, &who, parse_id(&id)?)?;
    let digest = headers
        .get(TILE_DIGEST_HEADER)
        .and_then(|v| v.to_str().ok())
        .ok_or(Error::NoTileDigest)?;
    c.upload_tile(id, body, digest).await?;
    Ok(StatusCode::OK)
}

async fn fail_lease(
    State(c): State<Coordinator>,
    Extension(who): Extension<Principal>,
    UrlPath(id): UrlPath<String>,
    body: Bytes,
) -> Result<StatusCode, Error> {
    let id = own_lease(&c, &who, parse_id(&id)?)?;
    let f: Failure = parse_json(&body)?;
    c.off_runtime(move |c| c.fail_lease(id, &f.reason)).await?;
    Ok(StatusCode::NO_CONTENT)
}

async fn metrics(State(c): State<Coordinator>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        c.metrics_text(),
    )
        .into_response()
}

/// Security headers for the dashboard: its own code and styles only, images from the
/// object URLs its code makes, calls to this coordinator only.
const DASHBOARD_CSP: &str = "default-src 'self'; img-src 'self' blob: data:; script-src 'self'; style-src 'self'; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'";

fn dashboard_file(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CONTENT_SECURITY_POLICY, DASHBOARD_CSP),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn dashboard_page() -> Response {
    dashboard_file(
        "text/html; charset=utf-8",
        include_str!("../dashboard/index.html"),
    )
}

async fn dashboard_js() -> Response {
    dashboard_file(
        "text/javascript; charset=utf-8",
        include_str!("../dashboard/app.js"),
    )
}

async fn dashboard_css() -> Response {
    dashboard_file(
        "text/css; charset=utf-8",
        include_str!("../dashboard/app.css"),
    )
}

async fn openapi() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        include_str!("../openapi.json"),
    )
        .into_response()
}
