//! The coordinator's connections under a crowd and under hostile clients: a limit on how
//! many are open (the one past it answered 503 in JSON), a header timeout that closes a
//! slow or idle connection, the open-file limit raised so a crowd meets that limit rather
//! than `EMFILE`, and HTTP's own errors (a head too large, a request that is not HTTP)
//! answered in JSON like every other.

use super::{Farm, free_port, start_coordinator_under};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// Connects to `url`'s host and port, with reads that give up after `limit`.
pub(super) fn connect(url: &str, limit: Duration) -> TcpStream {
    let stream = TcpStream::connect(url.trim_start_matches("http://")).unwrap();
    stream.set_read_timeout(Some(limit)).unwrap();
    stream
}

/// Sends `request` (written whole from another thread, as the server may answer before it
/// has read it all) and reads the answer until the server closes: (status, headers, body).
fn exchange(url: &str, request: Vec<u8>) -> (u16, String, String) {
    exchange_with(url, move |writer| {
        let _ = writer.write_all(&request);
    })
}

/// As [`exchange`], the request written by `send` (which may stop at the first error).
pub(super) fn exchange_with(
    url: &str,
    send: impl FnOnce(&mut TcpStream) + Send + 'static,
) -> (u16, String, String) {
    let mut stream = connect(url, Duration::from_secs(10));
    let mut writer = stream.try_clone().unwrap();
    let sending = std::thread::spawn(move || send(&mut writer));
    let mut answer = Vec::new();
    let _ = stream.read_to_end(&mut answer);
    sending.join().unwrap();
    let answer = String::from_utf8_lossy(&answer).into_owned();
    let (head, body) = answer
        .split_once("\r\n\r\n")
        .unwrap_or_else(|| panic!("no answer, or not HTTP: {answer:?}"));
    let status = head[9..12].parse().unwrap();
    (status, head.to_ascii_lowercase(), body.to_string())
}

/// The `error` of a JSON error body.
pub(super) fn error_of(headers: &str, body: &str) -> String {
    assert!(
        headers.contains("content-type: application/json"),
        "{headers}"
    );
    let json: serde_json::Value = serde_json::from_str(body).unwrap();
    json["error"].as_str().unwrap().to_string()
}

/// Waits until the server closes `stream` (a read gives end of file or a reset).
fn closed_by_server(mut stream: TcpStream) -> bool {
    let mut byte = [0u8; 1];
    !matches!(stream.read(&mut byte), Err(e) if e.kind() == std::io::ErrorKind::WouldBlock
        || e.kind() == std::io::ErrorKind::TimedOut)
}

#[test]
fn connections_past_the_limit_are_told_so_and_idle_ones_are_closed() {
    let farm = Farm::configured(None, |c| {
        c.max_connections = 4;
        c.header_timeout = Duration::from_millis(600);
    });
    let started = Instant::now();
    // Four connections: two kept alive after a request, two that never send one. The
    // listener takes connections in the order they were made, so the fifth is the one over.
    let idle: Vec<TcpStream> = (0..4)
        .map(|i| {
            let mut stream = connect(&farm.url, Duration::from_secs(10));
            if i < 2 {
                stream
                    .write_all(b"GET /healthz HTTP/1.1\r\nhost: kiln\r\n\r\n")
                    .unwrap();
                let mut answer = Vec::new();
                let mut buf = [0u8; 512];
                while !answer.ends_with(b"\r\n\r\nok\n") {
                    let n = stream.read(&mut buf).unwrap();
                    assert!(n > 0, "closed before answering");
                    answer.extend_from_slice(&buf[..n]);
                }
            }
            stream
        })
        .collect();

    let health = b"GET /healthz HTTP/1.1\r\nhost: kiln\r\nconnection: close\r\n\r\n".to_vec();
    let (status, headers, body) = exchange(&farm.url, health.clone());
    assert_eq!(status, 503, "{headers}\n{body}");
    assert!(headers.contains("retry-after: 1"), "{headers}");
    let error = error_of(&headers, &body);
    assert!(error.contains("4 connections open, its limit"), "{error}");

    // No head came on any of them within the header timeout: each is closed.
    for stream in idle {
        assert!(closed_by_server(stream), "an idle connection was left open");
    }
    let waited = started.elapsed();
    assert!(
        waited >= Duration::from_millis(500),
        "closed after {waited:?}"
    );
    let (status, _, body) = exchange(&farm.url, health);
    assert_eq!((status, body.as_str()), (200, "ok\n"));
}

#[test]
fn a_head_sent_a_byte_at_a_time_is_cut_off_at_the_header_timeout() {
    let farm = Farm::configured(None, |c| c.header_timeout = Duration::from_millis(500));
    let stream = connect(&farm.url, Duration::from_secs(10));
    let mut writer = stream.try_clone().unwrap();
    let started = Instant::now();
    let trickle = std::thread::spawn(move || {
        writer.write_all(b"GET /healthz HTTP/1.1\r\n").unwrap();
        // A header a byte every 50 ms, for at most 10 s: it never ends by itself.
        for _ in 0..200 {
            std::thread::sleep(Duration::from_millis(50));
            if writer.write_all(b"x").is_err() {
                return;
            }
        }
    });
    assert!(closed_by_server(stream), "a slow head was never cut off");
    let waited = started.elapsed();
    assert!(
        waited >= Duration::from_millis(450) && waited < Duration::from_secs(5),
        "cut off after {waited:?}"
    );
    drop(trickle);
}

#[test]
fn heads_too_large_and_requests_that_are_not_http_are_answered_in_json() {
    let farm = Farm::in_process(None);
    let mut huge = b"GET /v1/jobs HTTP/1.1\r\nhost: kiln\r\nauthorization: Bearer ".to_vec();
    huge.extend(std::iter::repeat_n(b'a', 1 << 20));
    huge.extend_from_slice(b"\r\n\r\n");
    let (status, headers, body) = exchange(&farm.url, huge);
    assert_eq!(status, 431, "{headers}\n{body}");
    assert!(error_of(&headers, &body).contains("over 64 KiB"), "{body}");

    let broken = b"GET /healthz HTTP/1.1\r\nnot a header\r\n\r\n".to_vec();
    let (status, headers, body) = exchange(&farm.url, broken);
    assert_eq!(status, 400, "{headers}\n{body}");
    assert!(error_of(&headers, &body).contains("not HTTP/1.1"), "{body}");

    // The server goes on answering.
    let health = b"GET /healthz HTTP/1.1\r\nhost: kiln\r\nconnection: close\r\n\r\n".to_vec();
    let (status, _, body) = exchange(&farm.url, health);
    assert_eq!((status, body.as_str()), (200, "ok\n"));
}

#[test]
fn a_crowd_of_idle_connections_does_not_exhaust_the_coordinator_s_files() {
    // Started with a soft limit of 64 open files (the hard limit as it is): a coordinator
    // that kept 64 would fail to accept the crowd's connections, and then everyone's.
    let hard: u64 = String::from_utf8(
        std::process::Command::new("bash")
            .args(["-c", "ulimit -Hn"])
            .output()
            .unwrap()
            .stdout,
    )
    .unwrap()
    .trim()
    .parse()
    .unwrap_or(u64::MAX);
    if hard < 2048 {
        println!("SKIPPED: the hard limit on open files is {hard}, under 2048");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let coordinator = start_coordinator_under("ulimit -Sn 64", &dir.path().join("data"), port);
    // The limit is raised as the server starts, just after the line above.
    let files = || {
        let limits = std::fs::read_to_string(format!("/proc/{}/limits", coordinator.id())).ok()?;
        let line = limits.lines().find(|l| l.starts_with("Max open files"))?;
        let numbers: Vec<String> = line
            .split_whitespace()
            .skip(3)
            .take(2)
            .map(String::from)
            .collect();
        Some(numbers)
    };
    let waited = Instant::now();
    while files().is_some_and(|n| n[0] != n[1]) && waited.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    if let Some(numbers) = files() {
        assert_eq!(
            numbers[0], numbers[1],
            "the soft limit on open files was not raised"
        );
    }

    let url = format!("http://127.0.0.1:{port}");
    let crowd: Vec<TcpStream> = (0..300)
        .map(|_| connect(&url, Duration::from_secs(10)))
        .collect();
    let health = b"GET /healthz HTTP/1.1\r\nhost: kiln\r\nconnection: close\r\n\r\n".to_vec();
    let (status, _, body) = exchange(&url, health);
    assert_eq!((status, body.as_str()), (200, "ok\n"));
    drop(crowd);
}
