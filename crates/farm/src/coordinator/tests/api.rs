//! The HTTP surface: tokens, malformed requests, JSON errors, job creation and its limits.

use super::*;

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
    assert_eq!(body, include_str!("../../openapi.json"));
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
            spp: Some(1),
            resolution,
            ..JobSpec::new(&scene)
        };
        let body = serde_json::to_vec(&spec).unwrap();
        let (status, body) = call(&f.app, "POST", "/v1/jobs", None, body).await;
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(error_of(&body).contains("51.5 GB"), "{}", error_of(&body));
    }
    assert_eq!(job_status(&f.app, 1).await.tiles_total, 1);
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
                spp: Some(1),
                tile: 8,
                ..JobSpec::new(&digest)
            };
            let key = key.clone();
            tokio::spawn(async move {
                let req = Request::builder()
                    .method("POST")
                    .uri("/v1/jobs")
                    .header("idempotency-key", key)
                    .body(Body::from(serde_json::to_vec(&spec).unwrap()))
                    .unwrap();
                send(&app, req).await
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
            spp: Some(1),
            tile: 8,
            ..JobSpec::new(&scene)
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

/// The dashboard's files are served without the token, with a content security policy;
/// its sign-in check answers 200 either way; a preview's exposure is checked.
#[tokio::test]
async fn the_dashboard_is_served_and_its_sign_in_checks_the_token() {
    let f = farm(Some("tok"));
    for (path, kind) in [
        ("/", "text/html"),
        ("/dashboard/app.js", "text/javascript"),
        ("/dashboard/app.css", "text/css"),
    ] {
        let req = Request::builder().uri(path).body(Body::empty()).unwrap();
        let r = f.app.clone().oneshot(req).await.unwrap();
        assert_eq!(r.status(), StatusCode::OK, "{path}");
        let h = r.headers();
        assert!(h[header::CONTENT_TYPE].to_str().unwrap().starts_with(kind));
        assert!(
            h[header::CONTENT_SECURITY_POLICY]
                .to_str()
                .unwrap()
                .contains("default-src 'self'")
        );
    }
    for (token, valid) in [("tok", true), ("tok2", false), ("", false), ("to", false)] {
        let body = format!(r#"{{"token":"{token}"}}"#);
        let (status, text) = call(&f.app, "POST", "/v1/token/check", None, body).await;
        assert_eq!(status, StatusCode::OK);
        let v: serde_json::Value = json(&text);
        assert_eq!(v["valid"], valid, "{token}");
    }
    let f = farm(None);
    let job = submit(&f, 8, 8, 8).await;
    for (q, ok) in [
        ("", true),
        ("?exposure=2.5", true),
        ("?exposure=abc", false),
        ("?exposure=99", false),
    ] {
        let path = format!("/v1/jobs/{job}/preview.png{q}");
        let (status, _) = call(&f.app, "GET", &path, None, Body::empty()).await;
        assert_eq!(status == StatusCode::OK, ok, "{q}: {status}");
    }
}

/// Tiles of one pixel on an 8192x8192 frame once made the coordinator allocate a gigabyte
/// for the plan and abort. The tile count is bounded before anything is planned: a 422
/// that says the limit and the smallest tile that fits, at once.
#[tokio::test]
async fn a_job_of_too_many_tiles_is_refused_before_it_is_planned() {
    let f = farm(None);
    let scene = upload_scene(&f, 8192, 8192).await;
    let spec = |tile: u32| JobSpec {
        spp: Some(1),
        tile,
        ..JobSpec::new(&scene)
    };
    let start = std::time::Instant::now();
    let (status, body) = call(
        &f.app,
        "POST",
        "/v1/jobs",
        None,
        serde_json::to_vec(&spec(1)).unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(
        error_of(&body),
        "tiles of 1 pixels cut this 8192x8192 render into 67108864 tiles; a job has at most 1048576: use tiles of at least 8 pixels"
    );
    assert!(start.elapsed() < std::time::Duration::from_secs(2));
    // The smallest tile it names is accepted.
    let (status, _) = call(
        &f.app,
        "POST",
        "/v1/jobs",
        None,
        serde_json::to_vec(&spec(8)).unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED);
}

/// Planning a job holds its scene in memory: at most `max_plannings` submissions plan at
/// once, the others wait their turn (six concurrent submissions with a 5 GiB include once
/// took 6.2 GB). Every submission is planned in the end.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn submissions_plan_a_few_at_a_time_and_the_rest_wait() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config::new(dir.path().join("data"));
    config.max_plannings = 2;
    let c = Coordinator::open(config).unwrap();
    let app = app(c.clone());
    let f = Farm { dir, c, app };
    use std::sync::Arc;
    let (now, most) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
    let (now2, most2) = (now.clone(), most.clone());
    *f.c.shared.plan_hook.lock().unwrap() = Some(Arc::new(move || {
        let n = now2.fetch_add(1, Ordering::SeqCst) + 1;
        most2.fetch_max(n, Ordering::SeqCst);
        std::thread::sleep(Duration::from_millis(100));
        now2.fetch_sub(1, Ordering::SeqCst);
    }));
    let scene = upload_scene(&f, 16, 8).await;
    let submissions = (0..6).map(|seed| {
        let spec = JobSpec {
            spp: Some(1),
            tile: 8,
            seed: Some(seed),
            ..JobSpec::new(&scene)
        };
        let app = f.app.clone();
        tokio::spawn(async move {
            call(
                &app,
                "POST",
                "/v1/jobs",
                None,
                serde_json::to_vec(&spec).unwrap(),
            )
            .await
            .0
        })
    });
    for s in submissions.collect::<Vec<_>>() {
        assert_eq!(s.await.unwrap(), StatusCode::CREATED);
    }
    assert_eq!(
        most.load(Ordering::SeqCst),
        2,
        "at most two planned at once"
    );
}
