//! Several jobs at once: higher priority first, and jobs of equal priority taking turns.

use super::*;

#[tokio::test]
async fn higher_priority_first_then_equal_jobs_take_turns() {
    let f = farm(None);
    // Two jobs of two tiles each at priority 0, then one of one tile at priority 5.
    let a = submit(&f, 16, 8, 8).await;
    let b = submit(&f, 16, 8, 8).await;
    let c = submit_with(&f, 8, 8, 8, |s| s.priority = 5).await;
    assert_eq!(job_status(&f.app, c).await.priority, 5);
    let mut order = Vec::new();
    while let Some(l) = lease(&f.app, "w").await {
        order.push(l.job);
        let frame = if l.job == c { (8, 8) } else { (16, 8) };
        let (status, _) = upload(&f.app, l.lease, exr(&tile_of(&l, frame, 1.0))).await;
        assert_eq!(status, StatusCode::OK);
    }
    assert_eq!(order, [c, a, b, a, b], "priority first, then turns");
}

/// Jobs of equal priority in passes share several workers: while both have work, every
/// window of leases is split between them evenly, whichever worker asks.
#[tokio::test]
async fn equal_jobs_in_passes_share_several_workers_evenly() {
    let f = farm(None);
    // Four 8x8 tiles each, three passes: 12 tile passes a job.
    let a = submit_passes(&f, 32, 8, 8, Some(vec![1, 2, 3])).await;
    let b = submit_passes(&f, 32, 8, 8, Some(vec![1, 2, 3])).await;
    let workers = ["w1", "w2", "w3"];
    // Each worker holds a lease; they land and ask again in turn.
    let mut held: Vec<Lease> = Vec::new();
    for w in workers {
        held.push(lease(&f.app, w).await.unwrap());
    }
    let mut order: Vec<u64> = held.iter().map(|l| l.job).collect();
    let mut turn = 0;
    while !held.is_empty() {
        let l = held.remove(0);
        let (status, _) = upload(&f.app, l.lease, exr(&tile_of(&l, (32, 8), 1.0))).await;
        assert_eq!(status, StatusCode::OK);
        if let Some(next) = lease(&f.app, workers[turn % 3]).await {
            order.push(next.job);
            held.push(next);
        }
        turn += 1;
    }
    assert_eq!(order.len(), 24);
    // Both jobs had work for all but the last leases: each run of 2 is one of each.
    for (k, pair) in order[..20].chunks(2).enumerate() {
        assert!(
            pair.contains(&a) && pair.contains(&b),
            "leases {} and {}: {pair:?} in {order:?}",
            2 * k,
            2 * k + 1
        );
    }
    for job in [a, b] {
        let s = job_status(&f.app, job).await;
        assert_eq!((s.state, s.passes_done), (JobState::Done, 3));
    }
}

/// A job's rate, and so its ETA, counts from its first lease: time queued behind a job of
/// higher priority is not rendering time.
#[tokio::test(start_paused = true)]
async fn the_rate_and_eta_count_from_the_first_lease() {
    let f = farm(None);
    let first = submit_with(&f, 8, 8, 8, |s| s.priority = 1).await;
    // Two 8x8 tiles of 1 sample: 128 samples.
    let queued = submit(&f, 16, 8, 8).await;
    let l = lease(&f.app, "w").await.unwrap();
    assert_eq!(l.job, first);
    tokio::time::advance(Duration::from_secs(100)).await;
    let (status, _) = upload(&f.app, l.lease, exr(&tile_of(&l, (8, 8), 1.0))).await;
    assert_eq!(status, StatusCode::OK);
    let s = job_status(&f.app, queued).await;
    assert_eq!(
        (s.samples_per_second, s.eta_seconds),
        (0.0, None),
        "not started"
    );
    let l = lease(&f.app, "w").await.unwrap();
    assert_eq!(l.job, queued);
    tokio::time::advance(Duration::from_secs(4)).await;
    let (status, _) = upload(&f.app, l.lease, exr(&tile_of(&l, (16, 8), 1.0))).await;
    assert_eq!(status, StatusCode::OK);
    let s = job_status(&f.app, queued).await;
    assert_eq!(s.samples_done, 64);
    assert!(
        (s.samples_per_second - 16.0).abs() < 1e-3,
        "64 samples in the 4 s since its first lease, not in 104 s: {}",
        s.samples_per_second
    );
    let eta = s.eta_seconds.unwrap();
    assert!((eta - 4.0).abs() < 1e-3, "64 samples left at 16/s: {eta}");
}
