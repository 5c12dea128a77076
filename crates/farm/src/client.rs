//! HTTP calls to a coordinator, for `kiln submit`, `kiln farm` and workers.
//!
//! A farm with standby coordinators is given as several URLs, comma separated: only the
//! leader listens, so a request whose connection cannot be made is sent again to the next
//! URL (each tried once), and the client keeps to the one that answered.
//!
//! A coordinator serving https (`--tls-cert`) is trusted through the certificates in the
//! PEM file `KILN_TLS_CA` names (its own self-signed certificate, or the farm's CA); no
//! other root is trusted, and without it an https coordinator is refused.

use crate::api::*;
use crate::trust::TLS_CA_VAR;
use reqwest::{Method, RequestBuilder, StatusCode};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The leader a standby coordinator's answer names (a 503 with `X-Kiln-Leader`).
fn standby_leader(resp: &reqwest::Response) -> Option<String> {
    if resp.status() != StatusCode::SERVICE_UNAVAILABLE {
        return None;
    }
    let leader = resp.headers().get(LEADER_HEADER)?;
    Some(leader.to_str().ok()?.trim_end_matches('/').to_string())
}

/// `http://a:7878, http://b:7878/` as its URLs, trimmed and without trailing slashes.
fn bases(list: &str) -> Arc<Vec<String>> {
    let mut all: Vec<String> = list
        .split(',')
        .map(|b| {
            // As reqwest writes it (a host in lower case, a default port dropped), so that a
            // request's URL starts with its coordinator's.
            let b = b.trim();
            reqwest::Url::parse(b)
                .map_or_else(|_| b.to_string(), |u| u.as_str().to_string())
                .trim_end_matches('/')
                .to_string()
        })
        .filter(|b| !b.is_empty())
        .collect();
    if all.is_empty() {
        all.push(String::new());
    }
    Arc::new(all)
}

#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("cannot reach the coordinator: {0}")]
    Http(#[from] reqwest::Error),
    #[error("the coordinator answered {status}: {message}")]
    Api { status: StatusCode, message: String },
    /// The client could not be set up (the file of certificates to trust).
    #[error("{0}")]
    Setup(String),
}

impl ClientError {
    pub fn status(&self) -> Option<StatusCode> {
        match self {
            ClientError::Api { status, .. } => Some(*status),
            ClientError::Http(_) | ClientError::Setup(_) => None,
        }
    }
}

pub type Result<T> = std::result::Result<T, ClientError>;

#[derive(Clone)]
pub struct Client {
    http: reqwest::Client,
    /// The coordinators' URLs, without a trailing slash; `current` indexes the one in use.
    bases: Arc<Vec<String>>,
    current: Arc<AtomicUsize>,
    /// Whether the coordinator in use has answered as the leader since the client last
    /// moved: until it has, a request is preceded by a health check, so that no body (a
    /// scene bundle of gigabytes) is sent to a standby, which answers before reading it.
    confirmed: Arc<AtomicBool>,
    token: Option<String>,
    /// Why the client cannot send anything (its certificates could not be read): every
    /// request fails with it.
    broken: Option<String>,
}

impl Client {
    /// A client of the coordinator at `base`, trusting for https the certificates in the
    /// file `KILN_TLS_CA` names, if it names one.
    pub fn new(base: &str, token: Option<String>) -> Client {
        let ca = std::env::var_os(TLS_CA_VAR).map(|path| {
            std::fs::read(&path).map_err(|e| {
                format!(
                    "cannot read {TLS_CA_VAR}={}: {e}",
                    std::path::Path::new(&path).display()
                )
            })
        });
        match ca {
            Some(Err(why)) => Client::broken(base, token, why),
            Some(Ok(pem)) => Client::with_ca(base, token, Some(&pem)),
            None => Client::with_ca(base, token, None),
        }
    }

    /// A client of the coordinator at `base`, trusting for https the certificates in `pem`
    /// (none: https is refused).
    pub fn with_ca(base: &str, token: Option<String>, pem: Option<&[u8]>) -> Client {
        crate::trust::install_provider();
        let roots = match pem.map(reqwest::Certificate::from_pem_bundle) {
            None => Vec::new(),
            Some(Ok(roots)) if !roots.is_empty() => roots,
            Some(_) => {
                let why = format!("{TLS_CA_VAR} holds no PEM certificate");
                return Client::broken(base, token, why);
            }
        };
        // A connection that cannot be made in 10 s fails (the caller backs off and asks
        // again) rather than waiting out the kernel's retries, about two minutes; requests
        // themselves have no limit, as a tile or a bundle may take long to send. A pooled
        // connection is given up after 20 s idle, before the coordinator closes it (30 s
        // by default), so a request is not sent down a connection being closed.
        let built = reqwest::Client::builder()
            .connect_timeout(std::time::Duration::from_secs(10))
            .pool_idle_timeout(std::time::Duration::from_secs(20))
            .tls_certs_only(roots)
            .build();
        match built {
            Ok(http) => Client {
                http,
                bases: bases(base),
                current: Arc::new(AtomicUsize::new(0)),
                confirmed: Arc::new(AtomicBool::new(false)),
                token,
                broken: None,
            },
            Err(e) => Client::broken(base, token, format!("cannot set up the HTTP client: {e}")),
        }
    }

    /// A client that fails every request for `why`.
    fn broken(base: &str, token: Option<String>, why: String) -> Client {
        crate::trust::install_provider();
        Client {
            http: reqwest::Client::builder()
                .tls_certs_only(Vec::new())
                .build()
                .unwrap_or_default(),
            bases: bases(base),
            current: Arc::new(AtomicUsize::new(0)),
            confirmed: Arc::new(AtomicBool::new(false)),
            token,
            broken: Some(why),
        }
    }

    /// The URL of the coordinator in use.
    fn base(&self) -> &str {
        &self.bases[self.current.load(Ordering::Relaxed) % self.bases.len()]
    }

    fn req(&self, method: Method, path: &str) -> RequestBuilder {
        let r = self.http.request(method, format!("{}{path}", self.base()));
        match &self.token {
            Some(t) => r.bearer_auth(t),
            None => r,
        }
    }

    /// Sends and turns non-2xx answers into `ClientError::Api` with the server's message.
    async fn send(&self, r: RequestBuilder) -> Result<reqwest::Response> {
        if let Some(why) = &self.broken {
            return Err(ClientError::Setup(why.clone()));
        }
        let mut req = r.build()?;
        if self.bases.len() > 1 && !self.confirmed.load(Ordering::Relaxed) {
            self.find_leader().await;
            let used = self.current.load(Ordering::Relaxed) % self.bases.len();
            let url = req.url().as_str().to_string();
            if let Some((_, rest)) = self.base_of(&url)
                && let Ok(u) = reqwest::Url::parse(&format!("{}{rest}", self.bases[used]))
            {
                *req.url_mut() = u;
            }
        }
        // Each other coordinator is tried once when one cannot be reached or stands by (a
        // body that cannot be sent twice, a stream, is not sent again: the next call goes
        // there). A standby's answer names the leader, which is tried next if listed.
        for _ in 1..self.bases.len() {
            let spare = req.try_clone();
            // The coordinator this request is for (another task may have moved the client
            // on since it was built).
            let used = self
                .base_of(req.url().as_str())
                .map(|(i, _)| i)
                .unwrap_or_else(|| self.current.load(Ordering::Relaxed) % self.bases.len());
            let why = match self.http.execute(req).await {
                Ok(resp) => match standby_leader(&resp) {
                    Some(leader) => {
                        let listed = self.bases.iter().position(|b| *b == leader);
                        (
                            format!("it stands by, and {leader} leads"),
                            listed,
                            Ok(resp),
                        )
                    }
                    None => {
                        self.confirmed.store(true, Ordering::Relaxed);
                        return self.check(resp).await;
                    }
                },
                Err(e) if e.is_connect() => (e.to_string(), None, Err(e)),
                Err(e) => return Err(e.into()),
            };
            let (why, listed, outcome) = why;
            let next = listed.unwrap_or((used + 1) % self.bases.len());
            let _ = self
                .current
                .compare_exchange(used, next, Ordering::Relaxed, Ordering::Relaxed);
            self.confirmed.store(false, Ordering::Relaxed);
            tracing::info!(
                "coordinator {}: {why}; trying {}",
                self.bases[used],
                self.bases[next]
            );
            let Some(mut again) = spare else {
                return match outcome {
                    Ok(resp) => self.check(resp).await,
                    Err(e) => Err(e.into()),
                };
            };
            let url = again.url().as_str().to_string();
            let rest = self.base_of(&url).map_or("", |(_, rest)| rest);
            match reqwest::Url::parse(&format!("{}{rest}", self.bases[next])) {
                Ok(u) => *again.url_mut() = u,
                Err(_) => {
                    return match outcome {
                        Ok(resp) => self.check(resp).await,
                        Err(e) => Err(e.into()),
                    };
                }
            }
            req = again;
        }
        let resp = self.http.execute(req).await?;
        self.check(resp).await
    }

    /// Which of the coordinators `url` is addressed to, and the rest of it (its path and
    /// query, from the `/` on).
    fn base_of<'u>(&self, url: &'u str) -> Option<(usize, &'u str)> {
        self.bases.iter().enumerate().find_map(|(i, b)| {
            let rest = url.strip_prefix(b.as_str())?;
            (rest.is_empty() || rest.starts_with('/') || rest.starts_with('?')).then_some((i, rest))
        })
    }

    /// Moves to the first coordinator, from the one in use on, that answers its health
    /// check as the leader (or to the leader a standby names); stays put if none does.
    async fn find_leader(&self) {
        let start = self.current.load(Ordering::Relaxed) % self.bases.len();
        for k in 0..self.bases.len() {
            let i = (start + k) % self.bases.len();
            let Ok(resp) = self
                .http
                .get(format!("{}/healthz", self.bases[i]))
                .send()
                .await
            else {
                continue;
            };
            let found = match standby_leader(&resp) {
                Some(leader) => self.bases.iter().position(|b| *b == leader),
                None if resp.status().is_success() => Some(i),
                None => None,
            };
            if let Some(found) = found {
                self.current.store(found, Ordering::Relaxed);
                return;
            }
        }
    }

    /// An answer, or its non-2xx status as `ClientError::Api` with the server's message.
    async fn check(&self, resp: reqwest::Response) -> Result<reqwest::Response> {
        let status = resp.status();
        if status.is_success() {
            return Ok(resp);
        }
        let text = resp.text().await.unwrap_or_default();
        let message = serde_json::from_str::<ApiError>(&text)
            .map(|e| e.error)
            .unwrap_or(text);
        Err(ClientError::Api { status, message })
    }

    /// Whether the coordinator answers its health check (`GET /healthz`, no token needed).
    pub async fn healthz(&self) -> Result<()> {
        self.send(self.http.get(format!("{}/healthz", self.base())))
            .await
            .map(|_| ())
    }

    pub async fn upload_scene(&self, bytes: Vec<u8>) -> Result<String> {
        let r = self
            .send(self.req(Method::POST, "/v1/scenes").body(bytes))
            .await?;
        Ok(r.json::<SceneUploaded>().await?.digest)
    }

    pub async fn download_scene(&self, digest: &str) -> Result<Vec<u8>> {
        Ok(self
            .send(self.req(Method::GET, &format!("/v1/scenes/{digest}")))
            .await?
            .bytes()
            .await?
            .to_vec())
    }

    pub async fn create_job(&self, spec: &JobSpec, idempotency_key: Option<&str>) -> Result<u64> {
        let mut r = self.req(Method::POST, "/v1/jobs").json(spec);
        if let Some(k) = idempotency_key {
            r = r.header("Idempotency-Key", k);
        }
        Ok(self.send(r).await?.json::<JobCreated>().await?.id)
    }

    /// Cancels a job: its tiles are lent no more, and workers rendering one stop.
    pub async fn cancel(&self, job: u64) -> Result<JobStatus> {
        let r = self
            .send(self.req(Method::POST, &format!("/v1/jobs/{job}/cancel")))
            .await?;
        Ok(r.json().await?)
    }

    /// Ends a job after the pass in progress: its result is that pass's whole frame.
    pub async fn stop_after_pass(&self, job: u64) -> Result<JobStatus> {
        let r = self
            .send(self.req(Method::POST, &format!("/v1/jobs/{job}/stop")))
            .await?;
        Ok(r.json().await?)
    }

    /// Adds passes (cumulative samples per pixel) after a job's last.
    pub async fn extend(&self, job: u64, passes: &[u32]) -> Result<JobStatus> {
        let body = Extend {
            passes: passes.to_vec(),
        };
        let r = self
            .send(
                self.req(Method::POST, &format!("/v1/jobs/{job}/extend"))
                    .json(&body),
            )
            .await?;
        Ok(r.json().await?)
    }

    /// The tile EXR a lease's pass continues from; None if its bytes are not those the
    /// coordinator's digest header gives (damaged on the way).
    pub async fn lease_sums(&self, lease: u64) -> Result<Option<Vec<u8>>> {
        let r = self
            .send(self.req(Method::GET, &format!("/v1/leases/{lease}/sums")))
            .await?;
        let sha = r
            .headers()
            .get(TILE_DIGEST_HEADER)
            .and_then(|v| v.to_str().ok())
            .map(str::to_ascii_lowercase);
        let bytes = r.bytes().await?.to_vec();
        Ok((sha.as_deref() == Some(crate::bundle::digest_of(&bytes).as_str())).then_some(bytes))
    }

    pub async fn status(&self, job: u64) -> Result<JobStatus> {
        Ok(self
            .send(self.req(Method::GET, &format!("/v1/jobs/{job}")))
            .await?
            .json()
            .await?)
    }

    /// Every job the coordinator knows.
    pub async fn jobs(&self) -> Result<Vec<JobStatus>> {
        Ok(self
            .send(self.req(Method::GET, "/v1/jobs"))
            .await?
            .json()
            .await?)
    }

    /// Every worker the coordinator has heard from, with what it renders now.
    pub async fn workers(&self) -> Result<Vec<crate::api::WorkerStatus>> {
        Ok(self
            .send(self.req(Method::GET, "/v1/workers"))
            .await?
            .json()
            .await?)
    }

    pub async fn result(&self, job: u64) -> Result<Vec<u8>> {
        Ok(self
            .send(self.req(Method::GET, &format!("/v1/jobs/{job}/result.exr")))
            .await?
            .bytes()
            .await?
            .to_vec())
    }

    /// Issues a token (admin only): its secret is in the answer only.
    pub async fn issue_token(
        &self,
        req: &crate::api::TokenRequest,
    ) -> Result<crate::api::TokenIssued> {
        Ok(self
            .send(self.req(Method::POST, "/v1/tokens").json(req))
            .await?
            .json()
            .await?)
    }

    /// Every token issued, without secrets (admin only).
    pub async fn tokens(&self) -> Result<Vec<crate::api::TokenInfo>> {
        Ok(self
            .send(self.req(Method::GET, "/v1/tokens"))
            .await?
            .json()
            .await?)
    }

    /// Revokes token `id` (admin only).
    pub async fn revoke_token(&self, id: u64) -> Result<crate::api::TokenInfo> {
        let path = format!("/v1/tokens/{id}/revoke");
        Ok(self
            .send(self.req(Method::POST, &path))
            .await?
            .json()
            .await?)
    }

    /// Each frame's progress (one for a job of one frame).
    pub async fn frames(&self, job: u64) -> Result<Vec<crate::api::FrameStatus>> {
        Ok(self
            .send(self.req(Method::GET, &format!("/v1/jobs/{job}/frames")))
            .await?
            .json()
            .await?)
    }

    /// Frame `frame`'s merged EXR.
    pub async fn frame_result(&self, job: u64, frame: u32) -> Result<Vec<u8>> {
        let path = format!("/v1/jobs/{job}/frames/{frame}/result.exr");
        Ok(self
            .send(self.req(Method::GET, &path))
            .await?
            .bytes()
            .await?
            .to_vec())
    }

    pub async fn lease(&self, worker: &str) -> Result<Option<Lease>> {
        self.lease_for(&LeaseRequest::plain(worker)).await
    }

    /// A lease for the worker that `req` names, offering its tags and memory.
    pub async fn lease_for(&self, req: &LeaseRequest) -> Result<Option<Lease>> {
        let r = self
            .send(self.req(Method::POST, "/v1/leases").json(req))
            .await?;
        if r.status() == StatusCode::NO_CONTENT {
            return Ok(None);
        }
        Ok(Some(r.json().await?))
    }

    pub async fn heartbeat(&self, lease: u64) -> Result<()> {
        self.send(self.req(Method::POST, &format!("/v1/leases/{lease}/heartbeat")))
            .await
            .map(|_| ())
    }

    pub async fn upload_tile(&self, lease: u64, exr: Vec<u8>) -> Result<()> {
        self.send(
            self.req(Method::PUT, &format!("/v1/leases/{lease}/tile"))
                .header(TILE_DIGEST_HEADER, crate::bundle::digest_of(&exr))
                .body(exr),
        )
        .await
        .map(|_| ())
    }

    /// A job's shared pre-pass, if stored; its bytes are checked against the SHA-256 the
    /// coordinator gives (None for bytes damaged on the way: compute it instead).
    pub async fn prepass(&self, scene: &str, name: &str) -> Result<Option<Vec<u8>>> {
        if let Some(why) = &self.broken {
            return Err(ClientError::Setup(why.clone()));
        }
        let r = self
            .req(Method::GET, &format!("/v1/scenes/{scene}/prepass/{name}"))
            .send()
            .await?;
        if r.status() == StatusCode::NOT_FOUND {
            return Ok(None);
        }
        let r = self.check(r).await?;
        let sha = r
            .headers()
            .get(PREPASS_DIGEST_HEADER)
            .and_then(|v| v.to_str().ok())
            .map(str::to_ascii_lowercase);
        let bytes = r.bytes().await?.to_vec();
        Ok((sha.as_deref() == Some(crate::bundle::digest_of(&bytes).as_str())).then_some(bytes))
    }

    pub async fn claim_prepass(&self, scene: &str, name: &str) -> Result<PrepassClaim> {
        let r = self
            .send(self.req(
                Method::POST,
                &format!("/v1/scenes/{scene}/prepass/{name}/claim"),
            ))
            .await?;
        Ok(r.json::<PrepassClaimAnswer>().await?.claim)
    }

    pub async fn release_prepass(&self, scene: &str, name: &str) -> Result<()> {
        self.send(self.req(
            Method::DELETE,
            &format!("/v1/scenes/{scene}/prepass/{name}/claim"),
        ))
        .await
        .map(|_| ())
    }

    pub async fn upload_prepass(&self, scene: &str, name: &str, bytes: Vec<u8>) -> Result<()> {
        self.send(
            self.req(Method::PUT, &format!("/v1/scenes/{scene}/prepass/{name}"))
                .header(PREPASS_DIGEST_HEADER, crate::bundle::digest_of(&bytes))
                .body(bytes),
        )
        .await
        .map(|_| ())
    }

    pub async fn fail(&self, lease: u64, reason: &str) -> Result<()> {
        self.send(
            self.req(Method::POST, &format!("/v1/leases/{lease}/fail"))
                .json(&Failure {
                    reason: reason.into(),
                }),
        )
        .await
        .map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::Client;

    /// Only the leader of several coordinators listens: a client given them all finds it,
    /// and keeps to it.
    #[tokio::test]
    async fn a_client_of_several_coordinators_finds_the_one_that_answers() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let live = format!("http://{}", listener.local_addr().unwrap());
        let app = axum::Router::new().route("/healthz", axum::routing::get(|| async { "ok" }));
        tokio::spawn(async move { axum::serve(listener, app).await });
        // Port 1 on loopback: nothing listens there.
        let dead = "http://127.0.0.1:1";
        let client = Client::new(&format!("{dead}/, {live}"), None);
        assert_eq!(client.base(), dead);
        client.healthz().await.unwrap();
        assert_eq!(client.base(), live);
        client.healthz().await.unwrap();
        assert_eq!(client.base(), live);
        // One coordinator that cannot be reached is an error, as before.
        let alone = Client::new(dead, None);
        assert!(alone.healthz().await.is_err());
    }

    /// A standby's answer names the leader: a client given both moves to it, whichever
    /// order they come in.
    #[tokio::test]
    async fn a_client_moves_from_a_standby_to_the_leader_it_names() {
        use crate::coordinator::{Candidate, stand_by};
        let leading = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let leader = format!("http://{}", leading.local_addr().unwrap());
        let app = axum::Router::new()
            .route("/healthz", axum::routing::get(|| async { "ok" }))
            .route(
                "/v1/scenes",
                axum::routing::post(|body: axum::body::Bytes| async move {
                    axum::Json(serde_json::json!({ "digest": body.len().to_string() }))
                }),
            )
            .layer(axum::extract::DefaultBodyLimit::disable());
        tokio::spawn(async move { axum::serve(leading, app).await });
        let standing = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let standby = format!("http://{}", standing.local_addr().unwrap());
        let me = Candidate::new(standby.clone(), std::time::Duration::from_secs(5));
        tokio::spawn(stand_by(standing, me.clone(), std::future::pending()));
        // No leader known yet: a 503 that says so.
        let err = Client::new(&standby, None).healthz().await.unwrap_err();
        assert_eq!(err.status(), Some(reqwest::StatusCode::SERVICE_UNAVAILABLE));
        assert!(
            err.to_string().contains("no coordinator leads yet"),
            "{err}"
        );
        *me.leader.lock().unwrap() = Some(("c1".into(), leader.clone()));
        let err = Client::new(&standby, None).healthz().await.unwrap_err();
        assert!(
            err.to_string().contains(&format!("leads at {leader}")),
            "{err}"
        );
        // Given both, a client goes to the leader the standby names.
        let client = Client::new(&format!("{standby},{leader}"), None);
        client.healthz().await.unwrap();
        assert_eq!(client.base(), leader);
        let client = Client::new(&format!("{leader},{standby}"), None);
        client.healthz().await.unwrap();
        assert_eq!(client.base(), leader);
        // A large body goes to the leader too.
        let client = Client::new(&format!("{standby},{leader}"), None);
        let big = vec![7u8; 64 << 20];
        assert_eq!(
            client.upload_scene(big).await.unwrap(),
            (64u32 << 20).to_string()
        );
        assert_eq!(client.base(), leader);

        // A standby answers before reading a body and closes the connection, so an upload
        // sent to it may die of a broken pipe before its answer is read (seen in CI): the
        // client asks who leads before it sends a body to a coordinator not yet heard as the
        // leader. This one reads the head and closes without a word, every time, so a body
        // sent to it always fails.
        let rude = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let rude_url = format!("http://{}", rude.local_addr().unwrap());
        tokio::spawn(async move {
            use tokio::io::AsyncReadExt;
            loop {
                let Ok((mut socket, _)) = rude.accept().await else {
                    return;
                };
                let mut head = [0u8; 512];
                let _ = socket.read(&mut head).await;
                drop(socket);
            }
        });
        let client = Client::new(&format!("{rude_url},{leader}"), None);
        let big = vec![7u8; 64 << 20];
        assert_eq!(
            client.upload_scene(big).await.unwrap(),
            (64u32 << 20).to_string()
        );
        assert_eq!(client.base(), leader);
    }
}
