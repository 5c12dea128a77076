//! Verified workers through the app: checked tile passes held until a second worker's
//! render agrees, a worker two others contradict set aside with the reason, and what it
//! rendered unchecked rendered again.

use super::*;
use crate::coordinator::verify::is_checked;

/// Uploads `lease`'s tile, every pixel `value`, expecting it taken.
async fn land(app: &Router, lease: &Lease, value: f32) {
    let (status, body) = upload(app, lease.lease, exr(&tile_of(lease, (16, 8), value))).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
}

async fn workers(app: &Router) -> Vec<crate::api::WorkerStatus> {
    let (status, body) = call(app, "GET", "/v1/workers", None, Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    json(&body)
}

async fn result_pixels(app: &Router, job: u64) -> Vec<[f32; 3]> {
    let (status, body) = call(
        app,
        "GET",
        &format!("/v1/jobs/{job}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    kiln_image::decode_exr(&body).unwrap().pixels
}

#[tokio::test]
async fn a_worker_two_others_contradict_is_set_aside_and_honest_ones_never_are() {
    let f = farm(None);
    // Two 8x8 tiles, every pass checked.
    let job = submit_with(&f, 16, 8, 8, |s| s.verify = Some(1.0)).await;
    let a0 = lease(&f.app, "a").await.unwrap();
    land(&f.app, &a0, 1.0).await;
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.tiles_done, s.tile_passes_held),
        (0, 1),
        "held for a second render"
    );
    // a is not lent what it rendered: it gets the other tile, then nothing.
    let a1 = lease(&f.app, "a").await.unwrap();
    assert_ne!(a1.tile_index, a0.tile_index);
    land(&f.app, &a1, 1.0).await;
    assert!(lease(&f.app, "a").await.is_none());
    // b agrees on the first tile: kept, and counted verified.
    let b0 = lease(&f.app, "b").await.unwrap();
    assert_eq!(
        b0.tile_index, a1.tile_index,
        "the most recent held tile comes first"
    );
    land(&f.app, &b0, 1.0).await;
    let s = job_status(&f.app, job).await;
    assert_eq!((s.tiles_done, s.tile_passes_verified), (1, 1));
    // b disagrees on the other: held until c decides for a.
    let b1 = lease(&f.app, "b").await.unwrap();
    land(&f.app, &b1, 2.0).await;
    assert!(lease(&f.app, "b").await.is_none());
    let c1 = lease(&f.app, "c").await.unwrap();
    assert_eq!(c1.tile_index, b1.tile_index);
    land(&f.app, &c1, 1.0).await;
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.tile_passes_verified), (JobState::Done, 2));
    assert!(
        result_pixels(&f.app, job)
            .await
            .iter()
            .all(|p| *p == [1.0; 3])
    );
    let ws = workers(&f.app).await;
    let aside: Vec<_> = ws.iter().filter(|w| w.set_aside.is_some()).collect();
    assert_eq!(aside.len(), 1, "{ws:?}");
    assert_eq!(aside[0].name, "b");
    let why = aside[0].set_aside.as_deref().unwrap();
    assert!(
        why.contains("differs, bit for bit") && why.contains("a and c"),
        "{why}"
    );
    let (status, body) = call(
        &f.app,
        "POST",
        "/v1/leases",
        None,
        r#"{"worker": "b"}"#.to_string(),
    )
    .await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert!(error_of(&body).contains("set aside"), "{}", error_of(&body));
    assert!(
        metrics(&f.app)
            .await
            .contains("kiln_workers_set_aside_total 1")
    );
}

/// A tile a worker rendered unchecked is rendered again when that worker is caught on a
/// checked one.
#[tokio::test]
async fn what_a_caught_worker_rendered_unchecked_is_rendered_again() {
    // A fraction that checks one of the two tiles' passes and not the other.
    let u = |t: usize| {
        (1..1000)
            .find(|&k| is_checked(k as f64 / 1000.0, t, 0))
            .unwrap()
    };
    let (checked, unchecked) = if u(0) < u(1) { (0, 1) } else { (1, 0) };
    let fraction = u(checked) as f64 / 1000.0;
    assert!(!is_checked(fraction, unchecked, 0));
    let f = farm(None);
    let job = submit_with(&f, 16, 8, 8, |s| s.verify = Some(fraction)).await;
    // The bad worker renders both tiles wrong: the unchecked one is kept at once.
    for _ in 0..2 {
        let l = lease(&f.app, "bad").await.unwrap();
        land(&f.app, &l, 9.0).await;
    }
    let s = job_status(&f.app, job).await;
    assert_eq!(s.tiles_done, 1, "the unchecked tile is kept");
    // Two honest workers contradict it on the checked tile.
    let g = lease(&f.app, "good").await.unwrap();
    assert_eq!(g.tile_index as usize, checked);
    land(&f.app, &g, 1.0).await;
    let h = lease(&f.app, "honest").await.unwrap();
    assert_eq!(h.tile_index as usize, checked);
    land(&f.app, &h, 1.0).await;
    // bad is set aside, and the tile it rendered unchecked starts again.
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let again = lease(&f.app, "good").await.unwrap();
    assert_eq!(again.tile_index as usize, unchecked);
    land(&f.app, &again, 1.0).await;
    let s = job_status(&f.app, job).await;
    assert_eq!(s.state, JobState::Done);
    assert!(
        result_pixels(&f.app, job)
            .await
            .iter()
            .all(|p| *p == [1.0; 3])
    );
    let ws = workers(&f.app).await;
    assert!(
        ws.iter()
            .all(|w| w.set_aside.is_some() == (w.name == "bad")),
        "{ws:?}"
    );
}

/// Catches `bad` on a one-tile job that checks every pass: `bad` renders it wrong, two
/// honest workers agree against it. Returns the job.
async fn catch(f: &Farm, bad: &str) -> u64 {
    let job = submit_with(f, 8, 8, 8, |s| {
        s.verify = Some(1.0);
        s.priority = 1;
    })
    .await;
    for (worker, value) in [(bad, 9.0), ("good", 1.0), ("honest", 1.0)] {
        let l = lease(&f.app, worker).await.unwrap();
        assert_eq!(l.job, job, "{worker} is lent the checking job first");
        let (status, body) = upload(&f.app, l.lease, exr(&tile_of(&l, (8, 8), value))).await;
        assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    }
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.tile_passes_verified), (JobState::Done, 1));
    job
}

/// A job that ended with a worker's unchecked render in its frame runs again when that
/// worker is caught later, and ends with the honest frame; the worker stays set aside
/// across a restart of the coordinator, until an operator reinstates it.
#[tokio::test]
async fn a_done_job_holding_a_caught_workers_render_runs_again_and_set_aside_is_kept() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    let done = submit(&f, 16, 8, 8).await;
    let first = lease(&f.app, "bad").await.unwrap();
    land(&f.app, &first, 9.0).await;
    let second = lease(&f.app, "good").await.unwrap();
    land(&f.app, &second, 1.0).await;
    let s = job_status(&f.app, done).await;
    assert_eq!((s.state, s.notice), (JobState::Done, None));
    catch(&f, "bad").await;
    // The done job runs again: its result no longer counts, and it says why.
    let s = job_status(&f.app, done).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let notice = s.notice.unwrap();
    assert!(
        notice.contains("1 tiles are rendered again") && notice.contains("worker bad"),
        "{notice}"
    );
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{done}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT, "the result held bad's render");
    // A restart keeps both: the job runs on, and bad stays set aside.
    let Farm { dir: _dir, c, app } = f;
    drop((c, app));
    let (_c, app) = open(&data, None);
    let s = job_status(&app, done).await;
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 1));
    let ws = workers(&app).await;
    let bad = ws
        .iter()
        .find(|w| w.name == "bad")
        .expect("listed after a restart");
    assert!(
        bad.set_aside
            .as_deref()
            .unwrap()
            .contains("differs, bit for bit"),
        "{bad:?}"
    );
    let (status, _) = call(&app, "POST", "/v1/leases", None, r#"{"worker": "bad"}"#).await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    let again = lease(&app, "good").await.unwrap();
    assert_eq!((again.job, again.tile_index), (done, first.tile_index));
    land(&app, &again, 1.0).await;
    let s = job_status(&app, done).await;
    assert_eq!(s.state, JobState::Done);
    assert!(
        result_pixels(&app, done)
            .await
            .iter()
            .all(|p| *p == [1.0; 3])
    );
    // Reinstated, it is lent work again; reinstating a worker not set aside is a 404.
    let (status, body) = call(
        &app,
        "POST",
        "/v1/workers/bad/reinstate",
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let ws: Vec<crate::api::WorkerStatus> = json(&body);
    assert!(ws.iter().all(|w| w.set_aside.is_none()), "{ws:?}");
    let (status, _) = call(&app, "POST", "/v1/leases", None, r#"{"worker": "bad"}"#).await;
    assert_eq!(status, StatusCode::NO_CONTENT, "no work, but no refusal");
    let (status, body) = call(
        &app,
        "POST",
        "/v1/workers/good/reinstate",
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(error_of(&body).contains("no worker 'good' is set aside"));
    let (_c, app) = open(&data, None);
    assert!(workers(&app).await.iter().all(|w| w.set_aside.is_none()));
}

/// In a job of several passes, only the tiles whose sums hold a caught worker's renders
/// start again; the others keep their passes (though the store forgot their earlier
/// ones), wait for the restarted tiles, and the next merged pass is whole and honest.
#[tokio::test]
async fn only_the_tiles_a_caught_worker_touched_start_again_in_a_job_of_passes() {
    let f = farm(None);
    let job = submit_passes(&f, 16, 8, 8, Some(vec![1, 2, 3])).await;
    // Pass 0: bad renders tile 0, good tile 1; pass 1: good renders both. Merging pass 1
    // forgets pass 0's rows.
    let a = lease(&f.app, "bad").await.unwrap();
    let b = lease(&f.app, "good").await.unwrap();
    assert_eq!(
        (a.tile_index, a.pass.index, b.tile_index, b.pass.index),
        (0, 0, 1, 0)
    );
    land(&f.app, &a, 9.0).await;
    land(&f.app, &b, 1.0).await;
    for t in 0..2 {
        let l = lease(&f.app, "good").await.unwrap();
        assert_eq!((l.tile_index, l.pass.index), (t, 1));
        land(&f.app, &l, 1.0).await;
    }
    assert_eq!(job_status(&f.app, job).await.passes_done, 2);
    catch(&f, "bad").await;
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.passes_done), (JobState::Running, 0));
    assert!(s.notice.unwrap().contains("1 tiles"));
    // Tile 0 renders its three passes again; tile 1 renders only its last (one pass ahead
    // of tile 0 at most), and pass 1 is merged again once tile 0 is back at it.
    let mut lent = Vec::new();
    while let Some(l) = lease(&f.app, "good").await {
        lent.push((l.tile_index, l.pass.index));
        land(&f.app, &l, 1.0).await;
    }
    assert_eq!(lent, [(0, 0), (1, 2), (0, 1), (0, 2)]);
    let s = job_status(&f.app, job).await;
    assert_eq!((s.state, s.passes_done), (JobState::Done, 3));
    assert!(
        result_pixels(&f.app, job)
            .await
            .iter()
            .all(|p| *p == [1.0; 3])
    );
}

#[tokio::test]
async fn a_fraction_outside_0_to_1_is_refused() {
    let f = farm(None);
    let digest = upload_scene(&f, 8, 8).await;
    let body = format!(r#"{{"scene":"{}","verify":1.5}}"#, digest);
    let (status, text) = call(&f.app, "POST", "/v1/jobs", None, body).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(
        error_of(&text).contains("0 to 1, not 1.5"),
        "{}",
        error_of(&text)
    );
}
