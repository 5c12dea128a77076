//! Lending tiles: leases, heartbeats, expiry on the paused clock, uploads right, stale, damaged and hostile, and lease ids across restarts.

use super::*;

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
    let mut expected = RgbBuffer::new(32, 16, 0, 0, 32, 16).with_aovs(kiln_render::aov_names(None));
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
    let expirer = tokio::spawn(crate::coordinator::expire_leases_every_tick(f.c.clone()));
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
    // Before anyone delivered the tile, a late upload conflicts: the tile is lent again,
    // and that lease's upload is the one kept.
    let (status, body) = upload(&f.app, late.lease, exr(&tile)).await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert_eq!(
        error_of(&body),
        format!(
            "lease {} has expired and its tile is lent to another worker; this upload is not kept",
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
    // The expiry counted as one failed attempt; none of the late uploads counted as
    // another, or as a second acceptance.
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.tiles_done, s.failures, s.state),
        (1, 1, JobState::Running)
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

/// A tile without the further channels its frame keeps (a worker of an older Kiln, without
/// the denoiser's features) is refused by name as a failed attempt, not accepted to fail
/// the merge with an internal error.
#[tokio::test]
async fn a_tile_without_the_frames_channels_is_refused() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 32).await;
    let held = lease(&f.app, "w").await.unwrap();
    let mut bare = tile_of(&held, (32, 16), 1.0);
    bare.aovs = kiln_image::Aovs::default();
    let (status, body) = upload(&f.app, held.lease, exr(&bare)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("features.albedo.R"),
        "{}",
        error_of(&body)
    );
    let s = job_status(&f.app, job).await;
    assert_eq!((s.failures, s.state), (1, JobState::Running));
    let again = lease(&f.app, "w").await.expect("lent again");
    let (status, _) = upload(&f.app, again.lease, exr(&tile_of(&again, (32, 16), 1.0))).await;
    assert_eq!(status, StatusCode::OK);
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
    assert!(evil.len() < 4000, "{}", evil.len());
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

/// A worker's name is bounded (1 to 128 of letters, digits and . _ - : @): 20,000 lease
/// requests with distinct 10 KB names once grew the coordinator by 210 MB for good. Names
/// it cannot keep are a 400 that says so, and nothing is recorded for them.
#[tokio::test]
async fn worker_names_are_bounded_and_refused_names_leave_no_record() {
    let f = farm(None);
    for name in [
        "x".repeat(10_000),
        String::new(),
        "two words".into(),
        "a/b".into(),
        "caf\u{e9}".into(),
    ] {
        let body = serde_json::json!({ "worker": name }).to_string();
        let (status, body) = call(&f.app, "POST", "/v1/leases", None, body).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{name:.40}");
        let error = error_of(&body);
        assert!(error.contains("is not 1 to 128 of letters"), "{error}");
        assert!(error.len() < 200, "{error}");
    }
    assert!(lease(&f.app, "node-7.farm:2@rack_3").await.is_none());
    let (_, body) = call(&f.app, "GET", "/v1/workers", None, Body::empty()).await;
    let names: Vec<String> = json::<Vec<crate::api::WorkerStatus>>(&body)
        .into_iter()
        .map(|w| w.name)
        .collect();
    assert_eq!(names, ["node-7.farm:2@rack_3"]);
}

/// Workers come and go: one silent for an hour is forgotten, unless it holds a lease or is
/// set aside; it comes back as new when it asks again.
#[tokio::test(start_paused = true)]
async fn workers_silent_for_an_hour_are_forgotten_unless_set_aside_or_busy() {
    let f = farm(None);
    let names = |body: &[u8]| -> Vec<String> {
        json::<Vec<crate::api::WorkerStatus>>(body)
            .into_iter()
            .map(|w| w.name)
            .collect()
    };
    assert!(lease(&f.app, "gone").await.is_none());
    // A worker set aside, and one whose lease is kept alive by heartbeats.
    f.c.lock()
        .workers
        .set_aside("caught", "its render differed".into());
    submit_with(&f, 16, 8, 8, |s| s.spp = Some(1)).await;
    let held = lease(&f.app, "busy").await.unwrap();
    for _ in 0..6 * 60 + 6 {
        tokio::time::advance(Duration::from_secs(10)).await;
        assert_eq!(heartbeat(&f.app, held.lease).await, StatusCode::NO_CONTENT);
        f.c.expire_leases();
    }
    let (_, body) = call(&f.app, "GET", "/v1/workers", None, Body::empty()).await;
    assert_eq!(names(&body), ["busy", "caught"], "'gone' is forgotten");
    assert!(
        lease(&f.app, "gone").await.is_some(),
        "it comes back as new"
    );
}

/// A scene that kills every worker that renders it: three expired leases on its tile in a
/// row, with nothing else of the job done, fail the job with the reason (whoever the
/// workers were, the same one restarting included), instead of killing workers for ever.
/// No worker is blamed, and another job goes on.
#[tokio::test(start_paused = true)]
async fn a_tile_whose_renderers_die_fails_its_job_and_blames_no_worker() {
    let f = farm(None);
    let poison = submit_with(&f, 8, 8, 8, |s| s.priority = 1).await;
    let other = submit(&f, 16, 8, 8).await;
    for worker in ["a", "b", "a"] {
        let l = lease(&f.app, worker).await.unwrap();
        assert_eq!(l.job, poison, "the higher priority goes first");
        tokio::time::advance(TTL + Duration::from_millis(1)).await;
        f.c.expire_leases();
    }
    let s = job_status(&f.app, poison).await;
    assert_eq!((s.state, s.failures), (JobState::Failed, 3));
    let error = s.error.unwrap();
    assert_eq!(
        error,
        "3 renderers in a row died, hung or lost their link rendering tile 0 (8x8 at 0,0) while no tile of the job was done; leases of a, b expired on this pass, the last a's: a scene that crashes or hangs its renderer does this"
    );
    // No worker is set aside, and the other job's tiles are lent.
    let (_, body) = call(&f.app, "GET", "/v1/workers", None, Body::empty()).await;
    for w in json::<Vec<crate::api::WorkerStatus>>(&body) {
        assert!(w.set_aside.is_none(), "{w:?}");
    }
    let l = lease(&f.app, "a").await.unwrap();
    assert_eq!(l.job, other);
    assert_eq!(job_status(&f.app, other).await.state, JobState::Running);
}

/// Workers that die of their own while the job goes on (a machine lost, an operator's
/// kill) cost the job nothing until one tile has lost MAX_TILE_EXPIRIES renderers on one
/// pass: a scene that kills only on that tile. Three expiries of one tile with tiles done
/// between them do not fail the job (they did, before: random kills of a farm's workers
/// failed a healthy job).
#[tokio::test(start_paused = true)]
async fn renderers_that_die_while_the_job_goes_on_fail_it_only_past_the_expiry_limit() {
    let f = farm(None);
    let job = submit(&f, 128, 8, 8).await;
    let frame = (128, 8);
    let mut tile = None;
    for i in 0..crate::coordinator::MAX_TILE_EXPIRIES {
        let doomed = lease(&f.app, &format!("dies-{i}")).await.unwrap();
        assert_eq!(*tile.get_or_insert(doomed.tile_index), doomed.tile_index);
        // Another worker finishes a tile meanwhile.
        let good = lease(&f.app, "good").await.unwrap();
        let (status, _) = upload(&f.app, good.lease, exr(&tile_of(&good, frame, 1.0))).await;
        assert_eq!(status, StatusCode::OK);
        tokio::time::advance(TTL + Duration::from_millis(1)).await;
        f.c.expire_leases();
        let s = job_status(&f.app, job).await;
        if i + 1 < crate::coordinator::MAX_TILE_EXPIRIES {
            assert_eq!((s.state, s.failures), (JobState::Running, i + 1), "{s:?}");
        } else {
            assert_eq!(s.state, JobState::Failed);
            let error = s.error.unwrap();
            assert!(
                error.starts_with(
                    "10 renderers died, hung or lost their link rendering tile 0 (8x8 at 0,0) while the rest of the job went on; leases of dies-0, dies-1,"
                ),
                "{error}"
            );
        }
    }
}

/// The last tile left (or the slowest, the others a pass ahead and waiting for it), once the
/// job's other tiles were done: renderers dying on it three times in a row do not fail the
/// job, since nothing else could have been done meanwhile and renderers did finish this
/// scene; only the limit of expiries whatever the job did applies. (A chaos test that kills
/// workers failed a healthy job on its last tile.)
#[tokio::test(start_paused = true)]
async fn renderers_that_die_on_the_last_tile_fail_the_job_only_past_the_expiry_limit() {
    let f = farm(None);
    let job = submit(&f, 16, 8, 8).await;
    let good = lease(&f.app, "good").await.unwrap();
    let (status, _) = upload(&f.app, good.lease, exr(&tile_of(&good, (16, 8), 1.0))).await;
    assert_eq!(status, StatusCode::OK);
    for i in 0..crate::coordinator::MAX_TILE_EXPIRIES {
        let doomed = lease(&f.app, &format!("dies-{i}")).await.unwrap();
        assert_ne!(doomed.tile_index, good.tile_index);
        tokio::time::advance(TTL + Duration::from_millis(1)).await;
        f.c.expire_leases();
        let s = job_status(&f.app, job).await;
        if i + 1 < crate::coordinator::MAX_TILE_EXPIRIES {
            assert_eq!((s.state, s.failures), (JobState::Running, i + 1), "{s:?}");
        } else {
            assert_eq!(s.state, JobState::Failed);
            let error = s.error.unwrap();
            assert!(error.starts_with("10 renderers died"), "{error}");
        }
    }
}
