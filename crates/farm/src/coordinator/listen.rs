//! The coordinator's connections: how many may be open, how long one may take to send a
//! request's head or sit idle, and the answers HTTP itself gives (a head too large, a
//! request that is not HTTP) made JSON like every other.
//!
//! - [`serve_connections`] accepts while fewer than [`Limits::max_connections`] are open;
//!   one more is answered 503 and closed, so a client is told rather than left to time
//!   out in the kernel's queue. Each is served by hyper's HTTP/1.1 with a header-read
//!   timeout, which also ends a kept-alive connection idle that long between requests.
//!   With TLS (a [`TlsAcceptor`]) each connection's handshake comes first, within the same
//!   time; the 503 of a connection over the limit is then plain text a client cannot read,
//!   and it sees the connection closed.
//! - [`raise_fd_limit`] lifts the process's soft limit on open files to its hard limit, so
//!   the connection limit, not `EMFILE`, is what a crowd of clients meets.
//! - [`JsonAnswers`] wraps a connection's socket and rewrites the bodiless 400, 414 and 431
//!   that hyper writes on its own into `{"error": ...}` answers.
//!
//! This module knows nothing of jobs or the API: it takes the router whole.

use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::future::Future;
use std::io;
use std::pin::{Pin, pin};
use std::sync::Arc;
use std::task::{Context, Poll, ready};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Semaphore, watch};
use tokio_rustls::TlsAcceptor;

/// The largest request head (request line and headers) read; a larger one is answered 431.
pub const MAX_HEAD_BYTES: usize = 64 << 10;
/// Files the process keeps for itself beyond its connections: the store, the data
/// directory's files, webhook calls, the log.
const FILES_KEPT_BACK: u64 = 256;
/// How long a stopping server waits for requests in flight before it returns anyway.
const DRAIN: Duration = Duration::from_secs(10);
/// Connections over the limit being told so at once; more are closed without a word.
const MAX_REFUSING: usize = 64;

/// The limits [`serve_connections`] keeps.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Connections open at once.
    pub max_connections: usize,
    /// How long a connection may take to send a request's head, counted from when the
    /// server starts waiting for it (so also the longest a kept-alive connection may idle).
    pub header_timeout: Duration,
}

/// Raises the soft limit on open files to the hard limit (at most 2^20) and returns the
/// soft limit now in force, or `None` where there is none to read.
pub fn raise_fd_limit() -> Option<u64> {
    #[cfg(unix)]
    {
        use rustix::process::{Resource, getrlimit, setrlimit};
        let limit = getrlimit(Resource::Nofile);
        let hard = limit.maximum.unwrap_or(u64::MAX).min(1 << 20);
        let soft = limit.current.unwrap_or(u64::MAX);
        if soft >= hard {
            return Some(soft);
        }
        let raised = rustix::process::Rlimit {
            current: Some(hard),
            maximum: limit.maximum,
        };
        match setrlimit(Resource::Nofile, raised) {
            Ok(()) => Some(hard),
            Err(e) => {
                tracing::warn!("cannot raise the limit on open files from {soft}: {e}");
                Some(soft)
            }
        }
    }
    #[cfg(not(unix))]
    None
}

/// The connections the process can hold open with `open_files` files: all but a reserve,
/// or half where the limit is too small for the reserve.
pub fn connections_for(open_files: u64) -> usize {
    let usable = open_files
        .saturating_sub(FILES_KEPT_BACK)
        .max(open_files / 2)
        .max(1);
    usize::try_from(usable).unwrap_or(usize::MAX)
}

/// Serves `router` on `listener` within `limits` until `shutdown` resolves; then stops
/// accepting, lets the requests in flight finish (for up to ten seconds) and returns.
pub async fn serve_connections(
    listener: TcpListener,
    router: Router,
    limits: Limits,
    tls: Option<TlsAcceptor>,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> io::Result<()> {
    let max = limits.max_connections.clamp(1, Semaphore::MAX_PERMITS);
    let open = Arc::new(Semaphore::new(max));
    let refusing = Arc::new(Semaphore::new(MAX_REFUSING));
    let (stop, stopping) = watch::channel(false);
    let mut shutdown = pin!(shutdown);
    let mut last_accept_error = None;
    loop {
        let (stream, _) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(e) => {
                    accept_failed(&e, &mut last_accept_error).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        match open.clone().try_acquire_owned() {
            Ok(permit) => {
                let (router, stopping, tls) = (router.clone(), stopping.clone(), tls.clone());
                tokio::spawn(async move {
                    let timeout = limits.header_timeout;
                    match tls {
                        None => serve_one(stream, router, timeout, stopping).await,
                        // The handshake has the head's time limit too.
                        Some(tls) => {
                            match tokio::time::timeout(timeout, tls.accept(stream)).await {
                                Ok(Ok(secured)) => {
                                    serve_one(secured, router, timeout, stopping).await
                                }
                                Ok(Err(e)) => tracing::debug!("TLS handshake failed: {e}"),
                                Err(_) => tracing::debug!("TLS handshake timed out"),
                            }
                        }
                    }
                    drop(permit);
                });
            }
            Err(_) => {
                if let Ok(permit) = refusing.clone().try_acquire_owned() {
                    tokio::spawn(async move {
                        refuse(stream, max).await;
                        drop(permit);
                    });
                }
            }
        }
    }
    drop(listener);
    let _ = stop.send(true);
    let all = u32::try_from(max).unwrap_or(u32::MAX);
    let _ = tokio::time::timeout(DRAIN, open.acquire_many(all)).await;
    Ok(())
}

/// Waits out an accept that failed: a connection reset before it was taken needs no wait,
/// but out of files (or memory) the listener would fail again at once. Logged once per
/// kind of failure, not once per try.
async fn accept_failed(e: &io::Error, last: &mut Option<io::ErrorKind>) {
    use io::ErrorKind::*;
    if matches!(e.kind(), ConnectionAborted | ConnectionReset | Interrupted) {
        return;
    }
    if *last != Some(e.kind()) {
        tracing::error!("cannot accept a connection (trying again every 100 ms): {e}");
        *last = Some(e.kind());
    }
    tokio::time::sleep(Duration::from_millis(100)).await;
}

/// Serves one connection until it closes, its head is late, or the server stops (then
/// its request in flight finishes first).
async fn serve_one<S: AsyncRead + AsyncWrite + Unpin + Send + 'static>(
    stream: S,
    router: Router,
    header_timeout: Duration,
    mut stopping: watch::Receiver<bool>,
) {
    let io = TokioIo::new(JsonAnswers::new(stream));
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(header_timeout)
        .max_header_size(MAX_HEAD_BYTES);
    let mut conn = pin!(http.serve_connection(io, TowerToHyperService::new(router)));
    tokio::select! {
        done = conn.as_mut() => {
            if let Err(e) = done {
                tracing::debug!("connection ended: {e}");
            }
        }
        () = async { drop(stopping.wait_for(|stop| *stop).await) } => {
            conn.as_mut().graceful_shutdown();
            let _ = conn.await;
        }
    }
}

/// Answers a connection over the limit with a JSON 503, after reading what it sent in its
/// first second (so closing does not reset it before the answer is read).
async fn refuse(mut stream: TcpStream, max: usize) {
    let mut head = vec![0u8; 16 << 10];
    let mut read = 0;
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        while read < head.len() && !head[..read].windows(4).any(|w| w == b"\r\n\r\n") {
            match stream.read(&mut head[read..]).await {
                Ok(0) | Err(_) => break,
                Ok(n) => read += n,
            }
        }
    })
    .await;
    let message =
        format!("the coordinator has {max} connections open, its limit: try again in a moment");
    let answer = json_answer("503 Service Unavailable", &message, &["retry-after: 1"]);
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        stream.write_all(&answer).await?;
        stream.shutdown().await
    })
    .await;
}

/// A whole HTTP/1.1 answer whose body is `{"error": message}`, closing the connection.
fn json_answer(status_line: &str, message: &str, extra: &[&str]) -> Vec<u8> {
    let body = serde_json::json!({ "error": message }).to_string();
    let mut head = format!(
        "HTTP/1.1 {status_line}\r\ncontent-type: application/json\r\n\
         content-length: {}\r\nconnection: close\r\n",
        body.len()
    );
    for line in extra {
        head.push_str(line);
        head.push_str("\r\n");
    }
    head.push_str("\r\n");
    let mut answer = head.into_bytes();
    answer.extend_from_slice(body.as_bytes());
    answer
}

/// What hyper answers on its own, before the router sees a request: the head of one of
/// these, with no content type and nothing after it, is hyper's (every answer of the
/// router's has a JSON or other typed body). Returns the JSON answer to write instead.
fn rewritten(written: &[u8]) -> Option<Vec<u8>> {
    let end = written.windows(4).position(|w| w == b"\r\n\r\n")?;
    if end + 4 != written.len() {
        return None;
    }
    let head = std::str::from_utf8(&written[..end]).ok()?;
    let mut lines = head.split("\r\n");
    let status_line = lines.next()?.strip_prefix("HTTP/1.1 ")?;
    if lines.any(|l| l.to_ascii_lowercase().starts_with("content-type:")) {
        return None;
    }
    let message = match status_line.get(..3)? {
        "400" => "the request is not HTTP/1.1: its request line or a header cannot be read",
        "414" => "the request's path is too long",
        "431" => "the request's head (its request line and headers) is over 64 KiB",
        _ => return None,
    };
    Some(json_answer(status_line, message, &[]))
}

/// A connection's socket whose writes of hyper's own answers are [`rewritten`] as JSON.
/// It does not offer vectored writes, so hyper writes each answer's head from the start
/// of one buffer.
pub struct JsonAnswers<S> {
    inner: S,
    /// A rewritten answer not yet all written, and how much of it is.
    pending: Vec<u8>,
    sent: usize,
}

impl<S> JsonAnswers<S> {
    pub fn new(inner: S) -> JsonAnswers<S> {
        JsonAnswers {
            inner,
            pending: Vec::new(),
            sent: 0,
        }
    }
}

impl<S: AsyncWrite + Unpin> JsonAnswers<S> {
    /// Writes what is left of a rewritten answer.
    fn poll_pending(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.sent < self.pending.len() {
            let n = ready!(Pin::new(&mut self.inner).poll_write(cx, &self.pending[self.sent..]))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.sent += n;
        }
        self.pending.clear();
        self.sent = 0;
        Poll::Ready(Ok(()))
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for JsonAnswers<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for JsonAnswers<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        ready!(this.poll_pending(cx))?;
        if let Some(answer) = rewritten(buf) {
            this.pending = answer;
            // Taken whole: what is left is written before anything else, or at flush.
            if let Poll::Ready(Err(e)) = this.poll_pending(cx) {
                return Poll::Ready(Err(e));
            }
            return Poll::Ready(Ok(buf.len()));
        }
        Pin::new(&mut this.inner).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.poll_pending(cx))?;
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.poll_pending(cx))?;
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hyper_s_own_answers_are_made_json_and_the_router_s_are_left_alone() {
        let hyper_431 = b"HTTP/1.1 431 Request Header Fields Too Large\r\n\
                          content-length: 0\r\ndate: Fri, 27 Nov 2026 10:00:00 GMT\r\n\r\n";
        let answer = String::from_utf8(rewritten(hyper_431).unwrap()).unwrap();
        assert!(
            answer.starts_with("HTTP/1.1 431 Request Header Fields Too Large\r\n"),
            "{answer}"
        );
        assert!(
            answer.contains("content-type: application/json\r\n"),
            "{answer}"
        );
        let body = answer.split("\r\n\r\n").nth(1).unwrap();
        let length: usize = answer
            .lines()
            .find_map(|l| l.strip_prefix("content-length: "))
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(length, body.len());
        let json: serde_json::Value = serde_json::from_str(body).unwrap();
        assert!(json["error"].as_str().unwrap().contains("64 KiB"), "{json}");

        let bad = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n\r\n";
        assert!(rewritten(bad).is_some());
        // The router's answers: typed, or with a body, or not an error hyper writes.
        let typed = b"HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\n\
                      content-length: 0\r\n\r\n";
        assert!(rewritten(typed).is_none());
        let with_body = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 2\r\n\r\n{}";
        assert!(rewritten(with_body).is_none());
        let ok = b"HTTP/1.1 200 OK\r\ncontent-length: 0\r\n\r\n";
        assert!(rewritten(ok).is_none());
        assert!(rewritten(b"HTTP/1.1 431 Request Header").is_none());
    }

    #[test]
    fn connections_leave_files_for_the_rest_of_the_process() {
        assert_eq!(connections_for(20_000), 19_744);
        assert_eq!(connections_for(1024), 768);
        assert_eq!(connections_for(64), 32);
        assert_eq!(connections_for(0), 1);
    }
}
