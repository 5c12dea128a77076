//! The render farm: merged images bit-identical to `kiln render`, surviving dead workers
//! and a dead coordinator, rejecting bad uploads, tokens and scenes.

use crate::util::{kiln, render, scene};
use kiln_farm::api::{JobSpec, JobState};
use kiln_farm::client::Client;
use kiln_farm::coordinator::{self, Config, Coordinator};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

pub fn farm(scene_path: &Path, dir: &Path, name: &str, args: &[&str]) -> Vec<u8> {
    let out = dir.join(format!("{name}.exr"));
    let o = kiln()
        .arg("farm")
        .arg(scene_path)
        .arg("-o")
        .arg(&out)
        .arg("-q")
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "kiln farm {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read(&out).unwrap()
}

#[test]
fn farm_images_are_bit_identical_to_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("materials/scene.pbrt");
    for tile in ["16", "37", "64"] {
        let direct = render(
            &path,
            dir.path(),
            &format!("direct{tile}"),
            &["--spp", "4", "--tile", tile],
        )
        .bytes;
        for workers in ["1", "3"] {
            let merged = farm(
                &path,
                dir.path(),
                &format!("farm{tile}-{workers}"),
                &[
                    "--spp",
                    "4",
                    "--tile",
                    tile,
                    "--workers",
                    workers,
                    "--threads-per-worker",
                    "1",
                ],
            );
            assert_eq!(merged, direct, "tile {tile}, {workers} workers");
        }
    }
}

/// Photon maps are built by every worker from the same seeds: a farm of three workers
/// merges the same bytes as `kiln render` for caustic maps (lens), a volume map (haze) and
/// SPPM (ball: `kiln render` runs each iteration over every tile at once, a worker over
/// the tile it leased).
#[test]
fn farm_images_with_photon_maps_are_bit_identical_to_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["media/lens", "media/haze", "photons/ball", "martini/scene"] {
        let path = scene(&format!("{name}.pbrt"));
        let name = name.replace('/', "-");
        let args = ["--spp", "4", "--resolution", "32x32", "--tile", "16"];
        let direct = render(&path, dir.path(), &format!("{name}-direct"), &args).bytes;
        let mut farm_args = args.to_vec();
        farm_args.extend(["--workers", "3", "--threads-per-worker", "1"]);
        let merged = farm(&path, dir.path(), &format!("{name}-farm"), &farm_args);
        assert_eq!(
            merged, direct,
            "{name}: the farm's image differs from kiln render's"
        );
    }
}

/// A child process that is killed when dropped, so a failing test leaves none behind.
pub(crate) struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl std::ops::Deref for Guard {
    type Target = Child;
    fn deref(&self) -> &Child {
        &self.0
    }
}

impl std::ops::DerefMut for Guard {
    fn deref_mut(&mut self) -> &mut Child {
        &mut self.0
    }
}

/// A coordinator process on a chosen port, and how to reach it.
struct CoordinatorProcess {
    child: Guard,
    url: String,
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn start_coordinator(data: &Path, port: u16) -> CoordinatorProcess {
    let mut child = kiln()
        .args([
            "coordinator",
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--lease-ttl",
            "1",
        ])
        .arg("--data-dir")
        .arg(data)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.contains("listening on"), "{line}");
    CoordinatorProcess {
        child: Guard(child),
        url: format!("http://127.0.0.1:{port}"),
    }
}

fn start_worker(url: &str, name: &str, cache: &Path, log: &Path) -> Guard {
    start_worker_with(url, name, cache, log, &[])
}

/// A one-thread `kiln worker` named `name`, with `extra` arguments, logging to `log`.
pub(crate) fn start_worker_with(
    url: &str,
    name: &str,
    cache: &Path,
    log: &Path,
    extra: &[&str],
) -> Guard {
    Guard(
        kiln()
            .args([
                "worker",
                "--coordinator",
                url,
                "--threads",
                "1",
                "--name",
                name,
            ])
            .args(extra)
            .arg("--cache-dir")
            .arg(cache)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap(),
    )
}

fn rendered_lines(log: &Path) -> usize {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .filter(|l| l.contains("rendered job"))
        .count()
}

fn submit(url: &str, scene_path: &Path, args: &[&str]) -> u64 {
    let o = kiln()
        .arg("submit")
        .arg(scene_path)
        .args(["--coordinator", url])
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .trim()
        .rsplit(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

fn wait_done(
    rt: &tokio::runtime::Runtime,
    client: &Client,
    id: u64,
    limit: Duration,
) -> kiln_farm::api::JobStatus {
    let start = Instant::now();
    loop {
        if let Ok(s) = rt.block_on(client.status(id))
            && s.state != JobState::Running
        {
            return s;
        }
        assert!(
            start.elapsed() < limit,
            "job {id} did not finish in {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

const SLOW_JOB: &[&str] = &["--spp", "64", "--resolution", "192x108", "--tile", "16"];

#[test]
fn a_killed_worker_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("mis/scene.pbrt");
    let direct = render(&path, dir.path(), "direct", &SLOW_JOB[..4]);
    let port = free_port();
    let mut coord = start_coordinator(&dir.path().join("data"), port);
    let (log_a, log_b) = (dir.path().join("a.log"), dir.path().join("b.log"));
    let mut a = start_worker(&coord.url, "a", &dir.path().join("cache"), &log_a);
    let id = submit(&coord.url, &path, SLOW_JOB);
    // Once worker a has rendered a tile, kill it mid-job; b arrives later and finishes.
    let start = Instant::now();
    while rendered_lines(&log_a) < 2 {
        assert!(start.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(10));
    }
    a.kill().unwrap();
    a.wait().unwrap();
    let mut b = start_worker(&coord.url, "b", &dir.path().join("cache"), &log_b);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let client = Client::new(&coord.url, None);
    let status = wait_done(&rt, &client, id, Duration::from_secs(120));
    assert_eq!(status.state, JobState::Done, "{status:?}");
    let merged = rt.block_on(client.result(id)).unwrap();
    assert_eq!(
        kiln_image::decode_exr(&merged).unwrap().pixels,
        direct.image.pixels
    );
    assert_eq!(merged, direct.bytes);
    b.kill().ok();
    coord.child.kill().ok();
}

#[test]
fn a_killed_coordinator_resumes_without_rendering_finished_tiles_again() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("mis/scene.pbrt");
    let direct = render(&path, dir.path(), "direct", &SLOW_JOB[..4]);
    let data = dir.path().join("data");
    let port = free_port();
    let mut coord = start_coordinator(&data, port);
    let log = dir.path().join("w.log");
    let mut w = start_worker(&coord.url, "w", &dir.path().join("cache"), &log);
    let id = submit(&coord.url, &path, SLOW_JOB);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let client = Client::new(&coord.url, None);
    let start = Instant::now();
    let before = loop {
        let s = rt.block_on(client.status(id)).unwrap();
        if s.tiles_done >= 10 {
            break s;
        }
        assert!(start.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(10));
    };
    coord.child.kill().unwrap();
    coord.child.wait().unwrap();
    let rendered_before = rendered_lines(&log);
    let mut coord = start_coordinator(&data, port);
    let resumed = rt.block_on(client.status(id)).unwrap();
    assert!(
        resumed.tiles_done >= before.tiles_done,
        "{} tiles were done, {} after the restart",
        before.tiles_done,
        resumed.tiles_done
    );
    let status = wait_done(&rt, &client, id, Duration::from_secs(120));
    assert_eq!(status.state, JobState::Done, "{status:?}");
    assert_eq!(rt.block_on(client.result(id)).unwrap(), direct.bytes);
    // Every tile kept before the restart stayed kept: only the rest (plus the tile the
    // worker held at the kill) were rendered afterwards.
    let rendered_after = rendered_lines(&log) - rendered_before;
    let left = (status.tiles_total - resumed.tiles_done) as usize;
    assert!(
        rendered_after <= left + 1,
        "{rendered_after} tiles rendered after the restart, {left} were left"
    );
    w.kill().ok();
    coord.child.kill().ok();
}

/// An in-process coordinator on a free port, for API tests.
pub(crate) fn in_process(rt: &tokio::runtime::Runtime, data: &Path, token: Option<&str>) -> String {
    let mut config = Config::new(data.to_path_buf());
    config.token = token.map(String::from);
    let c = Coordinator::open(config).unwrap();
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    rt.spawn(coordinator::serve(listener, c, std::future::pending()));
    url
}

/// Uploads one of the repository's scenes and creates a job for it; returns the job id.
fn new_job(
    rt: &tokio::runtime::Runtime,
    client: &Client,
    scene_file: &str,
    spp: Option<u32>,
    resolution: Option<(u32, u32)>,
    tile: u32,
) -> u64 {
    let bundle = kiln_farm::bundle::pack(&scene(scene_file)).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = JobSpec {
        scene: digest,
        spp,
        resolution,
        tile,
        seed: None,
        passes: None,
        verify: None,
        priority: 0,
        webhook: None,
    };
    rt.block_on(client.create_job(&spec, None)).unwrap()
}

#[test]
fn corrupt_uploads_are_rejected_and_the_tile_is_issued_again() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let id = new_job(&rt, &client, "furnace/scene.pbrt", Some(1), None, 16);
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
/// digest. Bad names and unknown scenes are refused; no pre-pass is stored for them.
#[test]
fn shared_prepasses_are_claimed_once_verified_and_served() {
    use kiln_farm::api::PrepassClaim;
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let bundle = kiln_farm::bundle::pack(&scene("furnace/scene.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let name = "0123456789abcdef-sppm-pass-0";
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
    let err = rt
        .block_on(client.upload_prepass(&"ab".repeat(32), name, bytes))
        .unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::NOT_FOUND), "{err}");
}

#[test]
fn tokens_limits_bad_requests_and_bad_scenes_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), Some("s3cret"));
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
    let client = Client::new(&url, Some("s3cret".into()));
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
                scene: digest,
                spp: None,
                resolution: None,
                tile: 8,
                seed: None,
                passes: None,
                verify: None,
                priority: 0,
                webhook: None,
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
        .args(["--coordinator", &url, "--token", "s3cret"])
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
        .args(["--coordinator", &url, "--token", "s3cret"])
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
    let good = kiln_farm::bundle::pack(&scene("furnace/scene.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(good.bytes)).unwrap();
    let spec = JobSpec {
        scene: digest,
        spp: Some(1),
        resolution: None,
        tile: 8,
        seed: None,
        passes: None,
        verify: None,
        priority: 0,
        webhook: None,
    };
    let a = rt.block_on(client.create_job(&spec, Some("k1"))).unwrap();
    let b = rt.block_on(client.create_job(&spec, Some("k1"))).unwrap();
    assert_eq!(a, b);
}

#[test]
fn progress_events_never_go_backwards_and_end_at_100_percent() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let id = new_job(&rt, &client, "mis/scene.pbrt", Some(8), Some((96, 54)), 16);
    let mut events = rt
        .block_on(reqwest::get(format!("{url}/v1/jobs/{id}/events")))
        .unwrap();
    let mut worker = start_worker(
        &url,
        "sse",
        &dir.path().join("cache"),
        &dir.path().join("w.log"),
    );
    let mut text = String::new();
    let start = Instant::now();
    while let Some(chunk) = rt.block_on(events.chunk()).unwrap() {
        text.push_str(&String::from_utf8_lossy(&chunk));
        assert!(start.elapsed() < Duration::from_secs(60));
    }
    worker.kill().ok();
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

#[test]
fn a_worker_that_keeps_failing_is_set_aside() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let id = new_job(&rt, &client, "furnace/scene.pbrt", Some(1), None, 8);
    // Five failures on five different tiles: no tile reaches three, so the job goes on...
    for _ in 0..kiln_farm::coordinator::MAX_WORKER_FAILURES {
        let lease = rt.block_on(client.lease("flaky")).unwrap().unwrap();
        rt.block_on(client.fail(lease.lease, "out of memory"))
            .unwrap();
        // Another worker takes the returned tile, so the next failure is on another one.
        let other = rt.block_on(client.lease("steady")).unwrap().unwrap();
        assert_eq!(other.tile_index, lease.tile_index);
    }
    assert_eq!(
        rt.block_on(client.status(id)).unwrap().state,
        JobState::Running
    );
    // ...but the worker is set aside.
    let err = rt.block_on(client.lease("flaky")).unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::FORBIDDEN), "{err}");
    assert!(err.to_string().contains("set aside"));
    assert!(rt.block_on(client.lease("steady")).unwrap().is_some());
}

#[cfg(unix)]
#[test]
fn sigterm_lets_a_worker_finish_its_tile_and_leave() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let coord = start_coordinator(&dir.path().join("data"), port);
    let log = dir.path().join("w.log");
    let mut w = start_worker(&coord.url, "w", &dir.path().join("cache"), &log);
    let id = submit(&coord.url, &scene("mis/scene.pbrt"), SLOW_JOB);
    let start = Instant::now();
    while rendered_lines(&log) < 1 {
        assert!(start.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(10));
    }
    sigterm(&w);
    let status = wait_exit(&mut w, Duration::from_secs(30));
    assert!(status.success(), "{status:?}");
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains("stopped after"), "{text}");
    // Every tile it says it rendered was delivered: none is lost or held.
    let rt = tokio::runtime::Runtime::new().unwrap();
    let s = rt
        .block_on(Client::new(&coord.url, None).status(id))
        .unwrap();
    assert_eq!(s.tiles_done as usize, rendered_lines(&log), "{text}");
}

/// The headline scene, scenes/molten-glass (a 124k-face VolumeLight with a voxel grid),
/// through a local farm of two workers and through `kiln render`: the same bytes.
///
/// It renders a fifth of the 2880x1920 frame on each axis (18 x 12 tiles of 32 pixels):
/// the full frame would prove nothing more, since every tile is a pure function of
/// (scene, settings, pixel) whatever the split (determinism.rs), and the coordinator
/// assembles and encodes a frame of any size with the same code. The README's first
/// command renders the full frame.
#[test]
fn molten_glass_through_the_farm_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("molten-glass/scene.pbrt");
    let args = ["--spp", "1", "--resolution", "576x384", "--tile", "32"];
    let direct = render(&path, dir.path(), "direct", &args);
    assert_eq!((direct.image.width, direct.image.height), (576, 384));
    let merged = farm(
        &path,
        dir.path(),
        "farm",
        &[&args[..], &["--workers", "2", "--threads-per-worker", "1"]].concat(),
    );
    assert!(
        merged == direct.bytes,
        "the farm's frame differs from kiln render's"
    );
}

/// A medium too dense for tracking to cross (density 10^30 beside 0: the walk's steps
/// vanish below f32's precision) used to keep a worker tracking for ever, its lease alive
/// through heartbeats. Now each walk stops at its step limit, the worker fails the tile
/// with the reason, and after three attempts the job fails with it.
#[test]
fn a_medium_too_dense_to_track_fails_its_job_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = crate::util::write_scene(dir.path(), "dense.pbrt", crate::util::TOO_DENSE);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let bundle = kiln_farm::bundle::pack(&scene_path).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = JobSpec {
        scene: digest,
        spp: Some(1),
        resolution: None,
        tile: 8,
        seed: None,
        passes: None,
        verify: None,
        priority: 0,
        webhook: None,
    };
    let id = rt.block_on(client.create_job(&spec, None)).unwrap();
    let _worker = start_worker(
        &url,
        "w",
        &dir.path().join("cache"),
        &dir.path().join("w.log"),
    );
    let s = wait_done(&rt, &client, id, Duration::from_secs(60));
    assert_eq!(s.state, JobState::Failed);
    let error = s.error.unwrap();
    assert!(error.contains("tracking steps in a medium"), "{error}");
}

/// Sends SIGTERM to a child process (through `kill`, where there is no signal API).
fn sigterm(child: &Child) {
    let term = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
}

/// Waits for a child process to exit; panics after `limit`.
fn wait_exit(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        assert!(
            start.elapsed() < limit,
            "the process did not exit in {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until the worker's log holds `words`; panics after `limit`.
fn wait_for_log(log: &Path, words: &str, limit: Duration) -> String {
    let start = Instant::now();
    loop {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        if text.contains(words) {
            return text;
        }
        assert!(
            start.elapsed() < limit,
            "no '{words}' in {limit:?}:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until the coordinator at `url` has issued `n` leases.
fn wait_for_leases(rt: &tokio::runtime::Runtime, url: &str, n: u64) {
    let start = Instant::now();
    let want = format!("kiln_leases_issued_total {n}");
    loop {
        let text = rt
            .block_on(async { reqwest::get(format!("{url}/metrics")).await?.text().await })
            .unwrap_or_default();
        if text.lines().any(|l| l.trim() == want) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no lease {n}:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A tile that would take minutes (one 64x64 tile at 16,384 spp). Cancelling its job stops
/// the worker mid-tile: its next heartbeat is refused and the render stops between pixels.
/// A worker told twice to stop leaves at once and gives its tile back, which is lent
/// again straight away.
#[test]
fn cancel_and_a_second_sigterm_reach_a_worker_mid_tile() {
    const ONE_LONG_TILE: &[&str] = &["--spp", "16384", "--resolution", "64x64", "--tile", "64"];
    let dir = tempfile::tempdir().unwrap();
    let coord = start_coordinator(&dir.path().join("data"), free_port());
    let client = Client::new(&coord.url, None);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let log = dir.path().join("w.log");
    let _w = start_worker(&coord.url, "w", &dir.path().join("cache"), &log);
    let id = submit(&coord.url, &scene("mis/scene.pbrt"), ONE_LONG_TILE);
    wait_for_leases(&rt, &coord.url, 1);
    let start = Instant::now();
    rt.block_on(client.cancel(id)).unwrap();
    wait_for_log(&log, "abandoned part way", Duration::from_secs(10));
    assert!(start.elapsed() < Duration::from_secs(10));
    // Twice SIGTERM: the second stops the render, and the tile is given back. (Another
    // seed: the same settings again would be the cancelled job, as submits are idempotent.)
    let id = submit(
        &coord.url,
        &scene("mis/scene.pbrt"),
        &[ONE_LONG_TILE, &["--seed", "2"]].concat(),
    );
    let log2 = dir.path().join("w2.log");
    let mut w2 = start_worker(&coord.url, "w2", &dir.path().join("cache2"), &log2);
    wait_for_leases(&rt, &coord.url, 2);
    for _ in 0..2 {
        sigterm(&w2);
        std::thread::sleep(Duration::from_millis(200));
    }
    let status = wait_exit(&mut w2, Duration::from_secs(10));
    assert!(status.success(), "{status:?}");
    let s = rt.block_on(client.status(id)).unwrap();
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 0));
    assert!(s.failures >= 1, "the tile was given back: {s:?}");
    rt.block_on(client.cancel(id)).unwrap();
}

/// Chaos: jobs on a farm of three workers while a driver kills (SIGKILL) a random worker
/// or the coordinator at random moments and starts it again. No tile is lost: each job
/// ends done, its merged EXR byte-identical to `kiln render`'s. The kills follow a fixed
/// seed, so a failure can be replayed; the counts are printed. The second job runs in
/// progressive passes, so kills land between passes and in them.
#[test]
fn chaos_random_kills_of_workers_and_the_coordinator_lose_nothing() {
    const ROUNDS: u32 = 2;
    let dir = tempfile::tempdir().unwrap();
    let path = scene("mis/scene.pbrt");
    let data = dir.path().join("data");
    let port = free_port();
    let mut coord = start_coordinator(&data, port);
    let url = coord.url.clone();
    let worker = |i: usize, life: u32| {
        let name = format!("w{i}-{life}");
        let log = dir.path().join(format!("{name}.log"));
        start_worker(&url, &name, &dir.path().join(format!("cache{i}")), &log)
    };
    let mut lives = [0u32; 3];
    let mut workers: Vec<Guard> = (0..3).map(|i| worker(i, 0)).collect();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let client = Client::new(&url, None);
    // xorshift64*, seeded: the same kills at the same moments on every run.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = |n: u64| {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d) % n
    };
    let (mut worker_kills, mut coordinator_kills) = (0u32, 0u32);
    for round in 0..ROUNDS {
        let seed = (round + 1).to_string();
        let settings = [
            "--spp",
            "512",
            "--resolution",
            "192x108",
            "--seed",
            seed.as_str(),
        ];
        let direct = render(&path, dir.path(), &format!("direct{round}"), &settings);
        // The second round in passes: kills land between passes and in them.
        let passes: &[&str] = if round == 1 {
            &["--passes", "64,256,512"]
        } else {
            &[]
        };
        let id = submit(
            &url,
            &path,
            &[&settings[..], &["--tile", "16"], passes].concat(),
        );
        let start = Instant::now();
        loop {
            if let Ok(s) = rt.block_on(client.status(id))
                && s.state != JobState::Running
            {
                assert_eq!(s.state, JobState::Done, "{s:?}");
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(240),
                "round {round} did not finish"
            );
            std::thread::sleep(Duration::from_millis(150 + next(500)));
            match next(4) {
                3 => {
                    coord.child.kill().unwrap();
                    coord.child.wait().unwrap();
                    coord = start_coordinator(&data, port);
                    coordinator_kills += 1;
                }
                i => {
                    let i = i as usize;
                    workers[i].kill().unwrap();
                    workers[i].wait().unwrap();
                    lives[i] += 1;
                    workers[i] = worker(i, lives[i]);
                    worker_kills += 1;
                }
            }
        }
        let merged = rt.block_on(client.result(id)).unwrap();
        assert!(
            merged == direct.bytes,
            "round {round}: the merged frame differs"
        );
    }
    eprintln!(
        "chaos: {ROUNDS} rounds, {worker_kills} worker kills, {coordinator_kills} coordinator kills"
    );
    assert!(
        worker_kills >= ROUNDS && coordinator_kills >= 1,
        "too few kills to prove anything"
    );
}

/// `kiln health` (the container image's health check) exits 0 when a coordinator answers
/// /healthz, token or not, and 1 with the reason when nothing listens.
#[test]
fn kiln_health_tells_a_live_coordinator_from_none() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), Some("secret"));
    let ok = crate::util::kiln()
        .args(["health", "--coordinator", &url])
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

/// Progressive passes through real workers: whatever the schedule, tile size and worker
/// count, the frame after the last pass is `kiln render`'s at that many samples, byte for
/// byte (G-buffer channels too): each tile's pass continues the running sums the last
/// one uploaded, downloaded by whichever worker renders it.
#[test]
fn the_farm_in_passes_gives_the_bytes_of_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("materials/scene.pbrt");
    let base = ["--resolution", "48x32", "--threads-per-worker", "1"];
    let direct = render(
        &path,
        dir.path(),
        "direct",
        &["--spp", "6", "--resolution", "48x32", "--tile", "16"],
    )
    .bytes;
    for (passes, tile, workers) in [("1,3,6", "11", "2"), ("2,6", "7", "1"), ("6", "16", "2")] {
        let mut args = base.to_vec();
        args.extend(["--passes", passes, "--tile", tile, "--workers", workers]);
        let merged = farm(&path, dir.path(), &format!("p{tile}"), &args);
        assert!(
            merged == direct,
            "passes {passes}, tiles of {tile}, {workers} workers: not kiln render's bytes"
        );
    }
    let gb = crate::util::write_scene(dir.path(), "gb.pbrt", crate::gbuffer::SCENE);
    let direct = render(
        &gb,
        dir.path(),
        "gb-direct",
        &["--spp", "4", "--resolution", "24x16"],
    );
    let merged = farm(
        &gb,
        dir.path(),
        "gb-farm",
        &[
            "--passes",
            "1,4",
            "--tile",
            "9",
            "--resolution",
            "24x16",
            "--workers",
            "2",
        ],
    );
    assert!(merged == direct.bytes, "the G-buffer in passes differs");
    // Adaptive sampling: pixels stop at checkpoints by their own sums, whichever worker
    // and pass renders them; the coordinator checks no pixel took more than its pass.
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "Sampler \"sobol\" \"integer pixelsamples\" [ 16 ]",
        "Sampler \"sobol\" \"integer pixelsamples\" [ 16 ] \"float noisethreshold\" [ 0.05 ] \"integer minsamples\" [ 2 ]",
    );
    assert!(text.contains("noisethreshold"));
    let adaptive = crate::util::write_scene(dir.path(), "adaptive.pbrt", &text);
    let direct = render(
        &adaptive,
        dir.path(),
        "adaptive-direct",
        &["--spp", "16", "--resolution", "48x32"],
    );
    let plain = render(
        &adaptive,
        dir.path(),
        "adaptive-off",
        &[
            "--spp",
            "16",
            "--resolution",
            "48x32",
            "--noise-threshold",
            "0",
        ],
    );
    assert!(
        direct.bytes != plain.bytes,
        "adaptive sampling changed nothing"
    );
    let merged = farm(
        &adaptive,
        dir.path(),
        "adaptive-farm",
        &[
            "--passes",
            "2,5,8,16",
            "--tile",
            "11",
            "--resolution",
            "48x32",
            "--workers",
            "2",
        ],
    );
    assert!(
        merged == direct.bytes,
        "adaptive sampling in passes differs"
    );
}

/// A job stopped after a pass ends with that pass's whole frame; extended, it renders on
/// from there to `kiln render`'s bytes at the new count, the workers continuing the sums the
/// coordinator kept. Every pass is rendered with the footprint of the job's last pass, so a
/// pass of fewer than 64 samples (where pbrt-v4's texture footprint still narrows) is the
/// first samples of the longer render: `kiln render --spp N --footprint-spp LAST`, and on
/// this textured scene not `kiln render --spp N`.
#[test]
fn a_job_stopped_after_a_pass_and_extended_is_kiln_render_at_each_count() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let bundle = kiln_farm::bundle::pack(&scene("textures/scene.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let render_at = |spp: u32, footprint: Option<u32>| {
        let mut args = ["--spp", &spp.to_string(), "--resolution", "24x16"]
            .map(String::from)
            .to_vec();
        if let Some(f) = footprint {
            args.extend(["--footprint-spp".to_string(), f.to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        render(
            &scene("textures/scene.pbrt"),
            dir.path(),
            &format!("d{spp}-{footprint:?}"),
            &args,
        )
        .bytes
    };
    // Stopped mid-run, after its first pass merged, and at once, before any tile.
    for stop_at_once in [false, true] {
        let spec = JobSpec {
            scene: digest.clone(),
            spp: None,
            resolution: Some((24, 16)),
            tile: 8,
            seed: None,
            passes: Some(vec![16, 64, 72, 80, 88, 96]),
            verify: None,
            priority: 0,
            webhook: None,
        };
        let id = rt.block_on(client.create_job(&spec, None)).unwrap();
        if stop_at_once {
            rt.block_on(client.stop_after_pass(id)).unwrap();
        }
        let _worker = start_worker(
            &url,
            &format!("p{stop_at_once}"),
            &dir.path().join("cache"),
            &dir.path().join(format!("p{stop_at_once}.log")),
        );
        let start = Instant::now();
        while rt.block_on(client.status(id)).unwrap().passes_done == 0 {
            assert!(start.elapsed() < Duration::from_secs(120), "no pass merged");
            std::thread::sleep(Duration::from_millis(20));
        }
        rt.block_on(client.stop_after_pass(id)).unwrap();
        let s = wait_done(&rt, &client, id, Duration::from_secs(120));
        assert_eq!(s.state, JobState::Done);
        let stopped = s.samples_per_pixel_done;
        assert!(
            stopped < 96,
            "the job ran on to {stopped} samples after its stop"
        );
        if stop_at_once {
            assert_eq!(
                stopped, 16,
                "stopped before any tile, it ran past its first pass"
            );
        }
        assert_eq!(s.passes.last(), Some(&stopped));
        let result = rt.block_on(client.result(id)).unwrap();
        assert!(
            result == render_at(stopped, Some(96)),
            "stopped at {stopped}: not kiln render --footprint-spp 96's bytes"
        );
        if stopped < 64 {
            assert!(
                result != render_at(stopped, None),
                "this scene's textures should see the footprint of {stopped} samples"
            );
        } else {
            assert!(
                result == render_at(stopped, None),
                "stopped at {stopped}: not kiln render's bytes"
            );
        }
        let s = rt.block_on(client.extend(id, &[stopped + 8, 104])).unwrap();
        assert_eq!(s.state, JobState::Running);
        let s = wait_done(&rt, &client, id, Duration::from_secs(120));
        assert_eq!((s.state, s.samples_per_pixel_done), (JobState::Done, 104));
        let result = rt.block_on(client.result(id)).unwrap();
        assert!(
            result == render_at(104, None),
            "extended to 104: not kiln render's bytes"
        );
    }
}

/// Verified workers on real processes: a worker started in a fault-injection mode (it
/// flips the lowest bit of some pixels it uploads) is caught on its first tile and set
/// aside with the reason, two honest workers finish the job with `kiln render`'s bytes,
/// and no honest worker is ever flagged, here or on a job of honest workers alone.
#[test]
fn verification_catches_a_worker_that_flips_bits_and_never_an_honest_one() {
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let url = in_process(&rt, &dir.path().join("data"), None);
    let client = Client::new(&url, None);
    let path = scene("materials/scene.pbrt");
    let bundle = kiln_farm::bundle::pack(&path).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = |passes: Vec<u32>| JobSpec {
        scene: digest.clone(),
        spp: None,
        resolution: Some((48, 32)),
        tile: 16,
        seed: None,
        passes: Some(passes),
        verify: Some(1.0),
        priority: 0,
        webhook: None,
    };
    let workers = |rt: &tokio::runtime::Runtime| -> Vec<kiln_farm::api::WorkerStatus> {
        let http = reqwest::Client::new();
        rt.block_on(async {
            http.get(format!("{url}/v1/workers"))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap()
        })
    };
    // Honest workers alone: every tile pass verified, nobody set aside.
    let honest_job = rt
        .block_on(client.create_job(&spec(vec![2, 4]), None))
        .unwrap();
    let cache = dir.path().join("cache");
    let honest_workers = |names: std::ops::Range<usize>| -> Vec<Guard> {
        names
            .map(|i| {
                let log = dir.path().join(format!("h{i}.log"));
                start_worker(&url, &format!("h{i}"), &cache, &log)
            })
            .collect()
    };
    let mut honest = honest_workers(0..2);
    let s = wait_done(&rt, &client, honest_job, Duration::from_secs(120));
    assert_eq!(s.state, JobState::Done, "{s:?}");
    assert_eq!(
        s.tile_passes_verified,
        6 * 2,
        "every tile pass of 6 tiles x 2 passes"
    );
    assert!(workers(&rt).iter().all(|w| w.set_aside.is_none()));
    // Now a bad worker takes the first tiles of a new job before the honest ones come.
    for w in &mut honest {
        w.kill().unwrap();
        w.wait().unwrap();
    }
    let job = rt
        .block_on(client.create_job(&spec(vec![3]), None))
        .unwrap();
    let bad_log = dir.path().join("bad.log");
    let mut bad = start_worker_with(
        &url,
        "bad",
        &cache,
        &bad_log,
        &["--inject-fault", "flip-low-bit"],
    );
    let start = Instant::now();
    while rendered_lines(&bad_log) == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the bad worker rendered nothing"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let _honest = honest_workers(2..4);
    let s = wait_done(&rt, &client, job, Duration::from_secs(120));
    assert_eq!(s.state, JobState::Done, "{s:?}");
    let direct = render(
        &path,
        dir.path(),
        "direct",
        &["--spp", "3", "--resolution", "48x32"],
    );
    let merged = rt.block_on(client.result(job)).unwrap();
    assert!(
        merged == direct.bytes,
        "the verified job is not kiln render's bytes"
    );
    let ws = workers(&rt);
    for w in &ws {
        match w.name.as_str() {
            "bad" => {
                let why = w.set_aside.as_deref().expect("the bad worker is set aside");
                assert!(why.contains("differs, bit for bit"), "{why}");
            }
            name => assert!(w.set_aside.is_none(), "honest {name} was flagged: {w:?}"),
        }
    }
    // Refused, the bad worker leaves with the reason.
    let status = wait_exit(&mut bad, Duration::from_secs(30));
    assert!(!status.success());
    let log = std::fs::read_to_string(&bad_log).unwrap();
    assert!(log.contains("set aside"), "{log}");
}

/// A job's webhook is called when it ends (done, failed or cancelled), with its status,
/// and retried with backoff until it answers 2xx; one that never answers is given up on
/// after its attempts, saying why. A job extended while the call for its end is on its way
/// is announced again when it ends again. What became of each call survives a restart: a
/// restarted coordinator calls none of them again.
#[test]
fn webhooks_are_called_when_a_job_ends_and_retried_until_they_answer() {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex};
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    // A receiver with four hooks: /hook fails its first two calls, /down every call, /slow
    // answers after 700 ms, /failed at once. Each call is kept as (event, body).
    type Calls = Arc<Mutex<HashMap<String, Vec<(String, serde_json::Value)>>>>;
    let calls: Calls = Arc::default();
    let seen = calls.clone();
    let hook = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let base = format!("http://{}", hook.local_addr().unwrap());
    let receiver = axum::Router::new().route(
        "/{name}",
        axum::routing::post(
            move |axum::extract::Path(name): axum::extract::Path<String>,
                  headers: axum::http::HeaderMap,
                  body: axum::Json<serde_json::Value>| {
                let seen = seen.clone();
                async move {
                    let event = headers
                        .get("x-kiln-event")
                        .and_then(|v| v.to_str().ok())
                        .unwrap_or("")
                        .to_string();
                    let n = {
                        let mut calls = seen.lock().unwrap();
                        let list = calls.entry(name.clone()).or_default();
                        list.push((event, body.0));
                        list.len()
                    };
                    use axum::http::StatusCode as S;
                    match name.as_str() {
                        "hook" if n <= 2 => S::INTERNAL_SERVER_ERROR,
                        "down" => S::INTERNAL_SERVER_ERROR,
                        "slow" => {
                            tokio::time::sleep(Duration::from_millis(700)).await;
                            S::NO_CONTENT
                        }
                        _ => S::NO_CONTENT,
                    }
                }
            },
        ),
    );
    rt.spawn(async move { axum::serve(hook, receiver).await });
    let calls_to = |name: &str| calls.lock().unwrap().get(name).cloned().unwrap_or_default();
    let serve = |rt: &tokio::runtime::Runtime| {
        let mut config = Config::new(dir.path().join("data"));
        config.webhook_backoff = Duration::from_millis(20);
        let c = Coordinator::open(config).unwrap();
        let listener = rt
            .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
            .unwrap();
        let url = format!("http://{}", listener.local_addr().unwrap());
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let server = rt.spawn(coordinator::serve(listener, c, async move {
            let _ = stopped.await;
        }));
        (url, stop, server)
    };
    let (url, stop, server) = serve(&rt);
    let client = Client::new(&url, None);
    let bundle = kiln_farm::bundle::pack(&scene("furnace/scene.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = |hook: &str| JobSpec {
        scene: digest.clone(),
        spp: Some(1),
        resolution: Some((16, 16)),
        tile: 16,
        seed: None,
        passes: None,
        verify: None,
        priority: 0,
        webhook: Some(format!("{base}/{hook}")),
    };
    let bad = JobSpec {
        webhook: Some("ftp://x/".into()),
        ..spec("hook")
    };
    let err = rt.block_on(client.create_job(&bad, None)).unwrap_err();
    assert!(err.to_string().contains("not an http(s) URL"), "{err}");
    // A job that fails: its one tile fails three times.
    let failed = rt
        .block_on(client.create_job(&spec("failed"), None))
        .unwrap();
    for _ in 0..3 {
        let l = rt.block_on(client.lease("broken")).unwrap().unwrap();
        assert_eq!(l.job, failed);
        rt.block_on(client.fail(l.lease, "broken on purpose"))
            .unwrap();
    }
    assert_eq!(
        rt.block_on(client.status(failed)).unwrap().state,
        JobState::Failed
    );
    let done = rt.block_on(client.create_job(&spec("hook"), None)).unwrap();
    let cancelled = rt.block_on(client.create_job(&spec("down"), None)).unwrap();
    rt.block_on(client.cancel(cancelled)).unwrap();
    let extended = rt
        .block_on(client.create_job(
            &JobSpec {
                spp: None,
                passes: Some(vec![64]),
                ..spec("slow")
            },
            None,
        ))
        .unwrap();
    let _w = start_worker(
        &url,
        "w",
        &dir.path().join("cache"),
        &dir.path().join("w.log"),
    );
    // Extended while the call announcing its end is on its way.
    let start = Instant::now();
    while calls_to("slow").is_empty() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no call to /slow"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    rt.block_on(client.extend(extended, &[72])).unwrap();
    wait_done(&rt, &client, done, Duration::from_secs(60));
    let webhook_of = |id| rt.block_on(client.status(id)).unwrap().webhook;
    let settled = |id| {
        webhook_of(id)
            .is_some_and(|w: String| w.starts_with("delivered") || w.starts_with("gave up"))
    };
    let start = Instant::now();
    while ![done, cancelled, failed, extended].into_iter().all(settled)
        || rt.block_on(client.status(extended)).unwrap().state != JobState::Done
    {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{:?} {:?} {:?} {:?}",
            webhook_of(done),
            webhook_of(cancelled),
            webhook_of(failed),
            webhook_of(extended)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(
        webhook_of(done).as_deref(),
        Some("delivered after 3 call(s)")
    );
    let hook = calls_to("hook");
    assert_eq!(
        hook.len(),
        3,
        "two failures, then one answer: no more calls"
    );
    for (event, body) in &hook {
        assert_eq!(event, "job.done");
        assert_eq!(
            (&body["id"], &body["state"]),
            (&done.into(), &"done".into())
        );
    }
    let why = webhook_of(cancelled).unwrap();
    assert!(
        why.contains("gave up after 8 calls") && why.contains("500"),
        "{why}"
    );
    let down = calls_to("down");
    assert_eq!(down.len(), 8);
    assert!(
        down.iter()
            .all(|(e, b)| e == "job.cancelled" && b["id"] == cancelled)
    );
    let failed_calls = calls_to("failed");
    assert_eq!(failed_calls.len(), 1);
    assert_eq!(failed_calls[0].0, "job.failed");
    assert_eq!(failed_calls[0].1["state"], "failed");
    assert!(
        failed_calls[0].1["error"]
            .as_str()
            .is_some_and(|e| e.contains("broken on purpose")),
        "{:?}",
        failed_calls[0].1
    );
    // The call for the first end was answered after the extension: the second end was
    // announced by a call of its own.
    let slow = calls_to("slow");
    assert_eq!(slow.len(), 2, "{slow:?}");
    let spp: Vec<_> = slow
        .iter()
        .map(|(_, b)| b["samples_per_pixel_done"].clone())
        .collect();
    assert_eq!(spp, [64, 72]);
    assert_eq!(
        webhook_of(extended).as_deref(),
        Some("delivered after 1 call(s)")
    );
    // A restart calls none of them again, and says what became of each.
    stop.send(()).unwrap();
    rt.block_on(server).unwrap().unwrap();
    let before: usize = calls.lock().unwrap().values().map(Vec::len).sum();
    let (url, _stop, _server) = serve(&rt);
    let client = Client::new(&url, None);
    std::thread::sleep(Duration::from_millis(2500));
    let after: usize = calls.lock().unwrap().values().map(Vec::len).sum();
    assert_eq!(
        before, after,
        "a webhook was called again after the restart"
    );
    let webhook_of = |id| rt.block_on(client.status(id)).unwrap().webhook.unwrap();
    assert_eq!(
        webhook_of(done),
        "delivered before the coordinator restarted"
    );
    assert_eq!(
        webhook_of(cancelled),
        "gave up after 8 calls before the coordinator restarted"
    );
}
