//! The farm's HTTP API answering clients and workers: bad uploads refused and their tiles
//! lent again, shared pre-passes, tokens, limits and malformed requests, progress events,
//! and the health check.

use super::Farm;
use crate::util::{kiln, scene};
use kiln_farm::api::{JobSpec, JobState};
use kiln_farm::client::Client;
use std::time::{Duration, Instant};

#[test]
fn corrupt_uploads_are_rejected_and_the_tile_is_issued_again() {
    let farm = Farm::in_process(None);
    let (rt, client) = (&farm.rt, &farm.client);
    let id = farm.job("furnace/scene.pbrt", Some(1), None, 16);
    let lease = rt.block_on(client.lease("t")).unwrap().unwrap();
    let err = rt
        .block_on(client.upload_tile(lease.lease, b"garbage".to_vec()))
        .unwrap_err();
    assert_eq!(
        err.status(),
        Some(reqwest::StatusCode::BAD_REQUEST),
        "{err}"
    );
    let again = rt.block_on(client.lease("t")).unwrap().unwrap();
    assert_eq!(
        again.tile_index, lease.tile_index,
        "the rejected tile is issued again"
    );
    // A truncated EXR, and one with the wrong window, are rejected too.
    let mut tile = kiln_image::RgbBuffer::new(32, 32, again.tile.x0, again.tile.y0, 16, 16);
    tile.pixels.iter_mut().for_each(|p| *p = [1.0; 3]);
    let good = kiln_image::encode_exr(&tile).unwrap();
    let err = rt
        .block_on(client.upload_tile(again.lease, good[..good.len() / 2].to_vec()))
        .unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::BAD_REQUEST));
    let third = rt.block_on(client.lease("t")).unwrap().unwrap();
    assert_eq!(third.tile_index, lease.tile_index);
    let mut wrong = tile.clone();
    wrong.x0 += 1;
    let err = rt
        .block_on(client.upload_tile(third.lease, kiln_image::encode_exr(&wrong).unwrap()))
        .unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::BAD_REQUEST));
    // Three failed attempts fail the job, with the reason.
    let s = rt.block_on(client.status(id)).unwrap();
    assert_eq!(s.state, JobState::Failed);
    assert!(s.error.unwrap().contains("failed 3 times"));
}

/// Shared pre-passes (photon maps, SPPM passes): the first worker to claim a missing one
/// computes it and the others are told to wait; an upload must carry its bytes' SHA-256;
/// once stored, a claim says it is ready and a download gives the bytes back with their
/// digest. Bad names, names no job of the scene shares, uploads past the size limit and
/// unknown scenes are refused; no pre-pass is stored for them.
#[test]
fn shared_prepasses_are_claimed_once_verified_and_served() {
    use kiln_farm::api::PrepassClaim;
    let farm = Farm::configured(None, |c| c.max_prepass_bytes = 1 << 20);
    let (rt, client, url) = (&farm.rt, &farm.client, &farm.url);
    let digest = farm.upload(&scene("furnace/scene.pbrt"));
    // Before any job of the scene, no name is wanted.
    let spec = JobSpec {
        spp: Some(4),
        ..Farm::spec(&digest)
    };
    let prefix = kiln_farm::api::prepass_prefix(&spec.overrides());
    let name = format!("{prefix}-sppm-pass-0");
    let name = name.as_str();
    let err = rt
        .block_on(client.claim_prepass(&digest, name))
        .unwrap_err();
    assert_eq!(
        err.status(),
        Some(reqwest::StatusCode::BAD_REQUEST),
        "{err}"
    );
    assert!(
        err.to_string().contains("no job of this scene shares"),
        "{err}"
    );
    farm.create(&spec);
    assert_eq!(rt.block_on(client.prepass(&digest, name)).unwrap(), None);
    assert_eq!(
        rt.block_on(client.claim_prepass(&digest, name)).unwrap(),
        PrepassClaim::Yours
    );
    assert_eq!(
        rt.block_on(client.claim_prepass(&digest, name)).unwrap(),
        PrepassClaim::Theirs,
        "a second worker waits for the first"
    );
    // A claim given up (its upload failed) goes to the next worker that asks.
    rt.block_on(client.release_prepass(&digest, name)).unwrap();
    assert_eq!(
        rt.block_on(client.claim_prepass(&digest, name)).unwrap(),
        PrepassClaim::Yours
    );
    // Bytes damaged on the way (not the digest given) are refused and not kept.
    let bytes = b"photons".to_vec();
    let put = |body: Vec<u8>, sha: String| {
        rt.block_on(
            reqwest::Client::new()
                .put(format!("{url}/v1/scenes/{digest}/prepass/{name}"))
                .header("x-kiln-prepass-sha256", sha)
                .body(body)
                .send(),
        )
        .unwrap()
        .status()
    };
    let sha = kiln_farm::bundle::digest_of(&bytes);
    assert_eq!(put(b"photonz".to_vec(), sha.clone()), 400);
    assert_eq!(rt.block_on(client.prepass(&digest, name)).unwrap(), None);
    assert_eq!(put(bytes.clone(), sha), 204);
    assert_eq!(
        rt.block_on(client.claim_prepass(&digest, name)).unwrap(),
        PrepassClaim::Ready
    );
    assert_eq!(
        rt.block_on(client.prepass(&digest, name)).unwrap(),
        Some(bytes.clone())
    );
    // Names that are not file-safe, and scenes that were never uploaded.
    for bad in ["../../etc", "Photon", "a b", &"x".repeat(129)] {
        let err = rt.block_on(client.claim_prepass(&digest, bad)).unwrap_err();
        assert!(
            matches!(err.status(), Some(s) if s == 400 || s == 404),
            "{bad}: {err}"
        );
    }
    // Names no job of this scene shares: another job's inputs, another kind of pass.
    for unwanted in [
        "0123456789abcdef-sppm-pass-0".to_string(),
        format!("{prefix}-sppm-pass-01"),
        format!("{prefix}-secrets"),
        prefix.clone(),
    ] {
        let err = rt
            .block_on(client.upload_prepass(&digest, &unwanted, bytes.clone()))
            .unwrap_err();
        assert_eq!(
            err.status(),
            Some(reqwest::StatusCode::BAD_REQUEST),
            "{unwanted}"
        );
        assert_eq!(
            rt.block_on(client.prepass(&digest, &unwanted)).unwrap(),
            None
        );
    }
    assert!(
        rt.block_on(client.claim_prepass(&digest, &format!("{prefix}-photon-maps")))
            .is_ok()
    );
    // Past the limit (1 MiB here) an upload is refused while it streams, and nothing is
    // kept.
    let big = vec![7u8; (1 << 20) + 1];
    let pass1 = format!("{prefix}-sppm-pass-1");
    let err = rt
        .block_on(client.upload_prepass(&digest, &pass1, big))
        .unwrap_err();
    assert_eq!(
        err.status(),
        Some(reqwest::StatusCode::PAYLOAD_TOO_LARGE),
        "{err}"
    );
    assert_eq!(rt.block_on(client.prepass(&digest, &pass1)).unwrap(), None);
    let err = rt
        .block_on(client.upload_prepass(&"ab".repeat(32), name, bytes))
        .unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::NOT_FOUND), "{err}");
}

#[test]
fn tokens_limits_bad_requests_and_bad_scenes_get_clear_errors() {
    let farm = Farm::in_process(Some("s3cret"));
    let (rt, url, dir) = (&farm.rt, &farm.url, &farm.dir);
    let http = reqwest::Client::new();
    let get = |path: &str, token: Option<&str>| {
        let mut r = http.get(format!("{url}{path}"));
        if let Some(t) = token {
            r = r.bearer_auth(t);
        }
        rt.block_on(r.send()).unwrap().status()
    };
    assert_eq!(get("/healthz", None), 200);
    assert_eq!(get("/v1/jobs", None), 401);
    assert_eq!(get("/v1/jobs", Some("wrong")), 401);
    assert_eq!(get("/v1/jobs", Some("s3cret")), 200);
    assert_eq!(get("/v1/jobs/99", Some("s3cret")), 404);
    assert_eq!(get("/metrics", Some("s3cret")), 200);
    assert_eq!(get("/v1/openapi.json", Some("s3cret")), 200);
    let client = Client::new(url, Some("s3cret".into()));
    // A corrupt bundle, a malformed job, and a scene that does not parse.
    let err = rt
        .block_on(client.upload_scene(b"KILNBDL1 nope".to_vec()))
        .unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::BAD_REQUEST));
    let r = rt
        .block_on(
            http.post(format!("{url}/v1/jobs"))
                .bearer_auth("s3cret")
                .body("{\"scene\": 3}")
                .send(),
        )
        .unwrap();
    assert_eq!(r.status(), 400);
    assert!(rt.block_on(r.text()).unwrap().contains("\"error\""));
    let bad = dir.path().join("bad");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("scene.pbrt"), "WorldBegin\nShape \"sphere\"\n").unwrap();
    let mut bundle = kiln_farm::bundle::pack(&bad.join("scene.pbrt"))
        .unwrap()
        .bytes;
    // Corrupt the scene text inside a well-formed bundle: the coordinator's parser names it.
    let at = bundle.windows(6).position(|w| w == b"sphere").unwrap();
    bundle[at..at + 6].copy_from_slice(b"sphore");
    let digest = rt.block_on(client.upload_scene(bundle)).unwrap();
    let err = rt
        .block_on(client.create_job(
            &JobSpec {
                tile: 8,
                ..Farm::spec(&digest)
            },
            None,
        ))
        .unwrap_err();
    assert_eq!(
        err.status(),
        Some(reqwest::StatusCode::UNPROCESSABLE_ENTITY)
    );
    assert!(
        err.to_string().contains("scene.pbrt:2") && err.to_string().contains("sphore"),
        "{err}"
    );
    // kiln submit checks the scene before uploading, with the parser's file and line.
    let o = kiln()
        .args(["submit"])
        .arg(bad.join("scene.pbrt"))
        .args(["--coordinator", url, "--token", "s3cret"])
        .output()
        .unwrap();
    assert!(o.status.success());
    std::fs::write(
        bad.join("scene.pbrt"),
        "WorldBegin\nShape \"sphere\" \"float radius\" [ 1\n",
    )
    .unwrap();
    let o = kiln()
        .args(["submit"])
        .arg(bad.join("scene.pbrt"))
        .args(["--coordinator", url, "--token", "s3cret"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("scene.pbrt:2"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Malformed worker requests and ids get JSON errors too.
    for (method, path, body, status) in [
        ("POST", "/v1/leases", "not json", 400),
        ("GET", "/v1/jobs/abc", "", 400),
        ("POST", "/v1/leases/xyz/heartbeat", "", 400),
        ("GET", "/v1/nothing", "", 404),
    ] {
        let m = reqwest::Method::from_bytes(method.as_bytes()).unwrap();
        let r = rt
            .block_on(
                http.request(m, format!("{url}{path}"))
                    .bearer_auth("s3cret")
                    .body(body)
                    .send(),
            )
            .unwrap();
        assert_eq!(r.status(), status, "{method} {path}");
        let text = rt.block_on(r.text()).unwrap();
        assert!(text.starts_with("{\"error\":"), "{method} {path}: {text}");
    }
    // A retried submit with the same Idempotency-Key makes one job.
    let spec = JobSpec {
        spp: Some(1),
        tile: 8,
        ..Farm::spec(&farm.upload(&scene("furnace/scene.pbrt")))
    };
    let a = rt.block_on(client.create_job(&spec, Some("k1"))).unwrap();
    let b = rt.block_on(client.create_job(&spec, Some("k1"))).unwrap();
    assert_eq!(a, b);
}

#[test]
fn progress_events_never_go_backwards_and_end_at_100_percent() {
    let farm = Farm::in_process(None);
    let (rt, url) = (&farm.rt, &farm.url);
    let id = farm.job("mis/scene.pbrt", Some(8), Some((96, 54)), 16);
    let mut events = rt
        .block_on(reqwest::get(format!("{url}/v1/jobs/{id}/events")))
        .unwrap();
    let mut worker = farm.worker("sse");
    let mut text = String::new();
    let start = Instant::now();
    while let Some(chunk) = rt.block_on(events.chunk()).unwrap() {
        text.push_str(&String::from_utf8_lossy(&chunk));
        assert!(start.elapsed() < Duration::from_secs(60));
    }
    worker.kill();
    let statuses: Vec<kiln_farm::api::JobStatus> = text
        .lines()
        .filter_map(|l| l.strip_prefix("data:"))
        .map(|d| serde_json::from_str(d.trim()).unwrap())
        .collect();
    assert!(statuses.len() >= 2, "{text}");
    for pair in statuses.windows(2) {
        assert!(pair[1].progress >= pair[0].progress && pair[1].tiles_done >= pair[0].tiles_done);
    }
    let last = statuses.last().unwrap();
    assert_eq!(
        (last.state, last.progress, last.tiles_done),
        (JobState::Done, 1.0, last.tiles_total)
    );
}

/// `kiln health` (the container image's health check) exits 0 when a coordinator answers
/// /healthz, token or not, and 1 with the reason when nothing listens.
#[test]
fn kiln_health_tells_a_live_coordinator_from_none() {
    let farm = Farm::in_process(Some("secret"));
    let url = &farm.url;
    let ok = crate::util::kiln()
        .args(["health", "--coordinator", url])
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let closed = format!("http://{}", listener.local_addr().unwrap());
    drop(listener);
    let down = crate::util::kiln()
        .args(["health", "--coordinator", &closed, "--timeout", "2"])
        .output()
        .unwrap();
    assert_eq!(down.status.code(), Some(1));
    let err = String::from_utf8_lossy(&down.stderr);
    assert!(
        err.contains("is not healthy") && err.contains(&closed),
        "{err}"
    );
}
