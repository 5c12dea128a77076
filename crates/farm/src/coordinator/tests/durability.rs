//! What survives and what is refused: merges off the lock, restarts, a damaged store, and bundles that try to reach outside themselves.

use super::*;
use crate::coordinator::store::JobStore;

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
    restart_keeps_tiles_and_merges(None).await;
}

#[tokio::test]
async fn a_restarted_coordinator_on_postgres_keeps_acknowledged_tiles_and_merges() {
    if let Some(url) = crate::coordinator::store::tests::fresh_postgres("restart") {
        restart_keeps_tiles_and_merges(Some(&url)).await;
    }
}

/// A job half rendered, its coordinator dropped and opened again on the same store.
async fn restart_keeps_tiles_and_merges(store: Option<&str>) {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let (c, app) = open_on(&data, None, store);
    let f = Farm { dir, c, app };
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
    let (c, app) = open_on(&data, None, store);
    let s = job_status(&app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let again = lease(&app, "w").await.unwrap();
    assert_eq!(again.tile_index, b.tile_index);
    assert!(lease(&app, "w").await.is_none());
    drop((c, app));
    // A coordinator that stopped after keeping the last tile, before writing the frame,
    // writes it when it starts.
    {
        let files = crate::coordinator::data_dir::DataDir::create(&data).unwrap();
        let kept = crate::coordinator::leader::open_store(store, &files.database()).unwrap();
        kept.insert_tile(
            job,
            b.tile_index as usize,
            b.pass.to,
            &exr(&tile_b),
            &Default::default(),
        )
        .unwrap();
    }
    let (_c, app) = open_on(&data, None, store);
    let s = job_status(&app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Done, 2));
    let path = format!("/v1/jobs/{job}/result.exr");
    let (status, body) = call(&app, "GET", &path, None, Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    let mut expected = RgbBuffer::new(32, 16, 0, 0, 32, 16).with_aovs(kiln_render::aov_names(None));
    expected.paste(&tile_a).unwrap();
    expected.paste(&tile_b).unwrap();
    assert_eq!(body, exr(&expected));
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
            spp: Some(1),
            resolution: Some((8, 8)),
            tile: 8,
            ..JobSpec::new(&bundle.digest)
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

/// Bundles whose entry names the file system would refuse (a file that is also a folder, a
/// name over 255 bytes, a NUL, a name twice, a folder's name, a path thousands of folders
/// deep) are the client's mistake: a 400 that says
/// which, never a 500 with the server's path, and nothing is left behind.
#[tokio::test]
async fn bundles_whose_names_cannot_be_files_are_refused() {
    let f = farm(None);
    let scene = b"WorldBegin\n".to_vec();
    let long = "n".repeat(300);
    let deep = "d/".repeat(30_000) + "f";
    for (names, words) in [
        (vec!["scene.pbrt", "d/"], "names a folder"),
        (vec!["scene.pbrt", deep.as_str()], "the most is 4096"),
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

/// A data directory from before passes: tiles kept in the old `tiles` table, without
/// running sums, resume as done (not rendered again); only the job's extension is refused,
/// saying why.
#[tokio::test]
async fn tiles_kept_before_passes_existed_resume_as_done() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let job = submit_with(&f, 16, 8, 8, |s| s.spp = Some(64)).await;
    let a = lease(&f.app, "w").await.unwrap();
    let mut old = tile_of(&a, (16, 8), 0.5);
    old.words = kiln_image::Words::default();
    let Farm { dir, c, app } = f;
    drop((c, app));
    let db = rusqlite::Connection::open(data.join("kiln.sqlite")).unwrap();
    db.execute(
        "INSERT INTO tiles (job, idx, exr) VALUES (?1, ?2, ?3)",
        rusqlite::params![job as i64, a.tile_index as i64, exr(&old)],
    )
    .unwrap();
    drop(db);
    let (_c, app) = open(&data, None);
    let s = job_status(&app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let b = lease(&app, "w").await.unwrap();
    assert_ne!(
        b.tile_index, a.tile_index,
        "the kept tile is not rendered again"
    );
    assert!(lease(&app, "w").await.is_none());
    let (status, _) = upload(&app, b.lease, exr(&tile_of(&b, (16, 8), 1.0))).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(job_status(&app, job).await.state, JobState::Done);
    let (status, body) = call(
        &app,
        "POST",
        &format!("/v1/jobs/{job}/extend"),
        None,
        r#"{"passes":[128]}"#.to_string(),
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert!(
        error_of(&body).contains("before passes existed"),
        "{}",
        error_of(&body)
    );
    drop(dir);
}

/// What a coordinator killed mid-write leaves (an upload streaming to disk, a bundle half
/// unpacked, a merged frame half written) is removed when the next one opens the data
/// directory; kept bundles and results are not touched.
#[tokio::test]
async fn leftovers_of_a_killed_coordinator_are_removed_at_the_next_start() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let job = submit_with(&f, 16, 8, 8, |_| {}).await;
    let scene = f.c.lock().jobs[&job].spec.scene.clone();
    let Farm { dir, c, app } = f;
    drop((c, app));
    let scenes = data.join("scenes");
    let leftovers = [
        scenes.join(".upload.4242.7"),
        scenes.join(format!(".{scene}.4242.3.tmp")),
        data.join("jobs")
            .join(job.to_string())
            .join("result.pass-0.tmp"),
    ];
    std::fs::create_dir_all(data.join("jobs").join(job.to_string())).unwrap();
    std::fs::write(&leftovers[0], b"half an upload").unwrap();
    std::fs::create_dir_all(leftovers[1].join("models")).unwrap();
    std::fs::write(&leftovers[2], b"").unwrap();
    let (_c, app) = open(&data, None);
    for l in &leftovers {
        assert!(!l.exists(), "{} is still there", l.display());
    }
    assert!(scenes.join(&scene).is_dir(), "the kept bundle was removed");
    let s = job_status(&app, job).await;
    assert_eq!(s.state, JobState::Running);
    drop(dir);
}

/// A merged frame that cannot be written (here its folder's name is taken by a file; a
/// full disk does the same) no longer fails the job for good: the job keeps running, its
/// status and /healthz say why (without the server's paths), the frame is written again
/// after a growing wait, and once it can be the job is done with its frame.
#[tokio::test(start_paused = true)]
async fn a_frame_that_cannot_be_written_is_written_again_later() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let job = submit(&f, 16, 8, 8).await;
    let blocker = data.join("jobs").join(job.to_string());
    std::fs::write(&blocker, b"in the way").unwrap();
    for _ in 0..2 {
        let l = lease(&f.app, "w").await.unwrap();
        let tile = tile_of(&l, (16, 8), 0.5);
        assert_eq!(upload(&f.app, l.lease, exr(&tile)).await.0, StatusCode::OK);
    }
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.state, s.tiles_done, s.passes_done),
        (JobState::Running, 2, 0)
    );
    let notice = s.notice.unwrap();
    assert!(
        notice.starts_with("pass 1 is complete, but its merged frame could not be written")
            && notice.contains("written again in 1 s"),
        "{notice}"
    );
    assert!(!notice.contains(&data.display().to_string()), "{notice}");
    let (_, health) = call(&f.app, "GET", "/healthz", None, Body::empty()).await;
    let health = String::from_utf8(health.to_vec()).unwrap();
    assert!(
        health.starts_with("ok, but merged frames cannot be written"),
        "{health}"
    );
    assert!(!health.contains(&data.display().to_string()), "{health}");
    // Still in the way a second later: the wait doubles.
    tokio::time::advance(Duration::from_millis(1001)).await;
    f.c.retry_merges();
    wait_until(|| {
        let c = f.c.clone();
        async move {
            c.status(job)
                .unwrap()
                .notice
                .unwrap_or_default()
                .contains("in 2 s")
        }
    })
    .await;
    // Out of the way: the next retry writes it, and the job is done.
    std::fs::remove_file(&blocker).unwrap();
    tokio::time::advance(Duration::from_millis(2001)).await;
    f.c.retry_merges();
    wait_until(|| {
        let c = f.c.clone();
        async move { c.status(job).unwrap().state == JobState::Done }
    })
    .await;
    let s = job_status(&f.app, job).await;
    assert_eq!((s.passes_done, s.notice), (1, None));
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let (_, health) = call(&f.app, "GET", "/healthz", None, Body::empty()).await;
    assert_eq!(&health[..], b"ok\n");
}

/// Polls `ready` on the paused clock (yielding to the merge's tasks) until it holds.
async fn wait_until<F: std::future::Future<Output = bool>>(ready: impl Fn() -> F) {
    for _ in 0..1000 {
        if ready().await {
            return;
        }
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    panic!("never became true");
}

/// A job's colour mode is pinned when it is planned: a scene that says nothing renders
/// spectrally (today's default) and its stored spec says so, before and after a restart,
/// so a later Kiln with another default would still render its remaining tiles as its
/// first; a job that asks for RGB keeps RGB.
#[tokio::test]
async fn a_jobs_colour_mode_is_pinned_when_it_is_planned() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let by_default = submit(&f, 16, 16, 16).await;
    let rgb = submit_with(&f, 16, 16, 16, |s| s.spectral = Some(false)).await;
    let modes = |leases: Vec<Lease>| {
        let mut m: Vec<(u64, Option<bool>)> = leases
            .into_iter()
            .map(|l| (l.job, l.spec.spectral))
            .collect();
        m.sort();
        m
    };
    let first = vec![
        lease(&f.app, "w").await.unwrap(),
        lease(&f.app, "w").await.unwrap(),
    ];
    assert_eq!(
        modes(first),
        vec![(by_default, Some(true)), (rgb, Some(false))]
    );
    let Farm { dir: _dir, c, app } = f;
    drop((c, app));
    {
        let files = crate::coordinator::data_dir::DataDir::create(&data).unwrap();
        let store = crate::coordinator::store::SqliteStore::open(&files.database()).unwrap();
        let stored = store.jobs().unwrap();
        let spec = |id: u64| stored.iter().find(|j| j.id == id).unwrap().spec.clone();
        assert_eq!(spec(by_default).unwrap().spectral, Some(true));
        assert_eq!(spec(rgb).unwrap().spectral, Some(false));
    }
}
