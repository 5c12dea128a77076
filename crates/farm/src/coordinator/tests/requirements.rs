//! What a job asks of its workers: the tags it requires (lent only to workers that offer
//! every one, and a status that says why no worker takes it), the memory its scene is
//! estimated to need, and a cap on how many workers hold its leases at once; and
//! requirements that are not tags, refused.

use super::*;
use crate::api::{LeaseRequest, WorkerStatus};

/// A lease for `worker`, which offers `tags`.
async fn lease_tagged(app: &Router, worker: &str, tags: &[&str]) -> Option<Lease> {
    lease_offering(app, worker, tags, None).await
}

/// A lease for `worker`, which offers `tags` and `memory_mib`.
async fn lease_offering(
    app: &Router,
    worker: &str,
    tags: &[&str],
    memory_mib: Option<u64>,
) -> Option<Lease> {
    let req = LeaseRequest {
        geometry: None,
        worker: worker.into(),
        tags: tags.iter().map(|t| t.to_string()).collect(),
        memory_mib,
    };
    let (status, body) = call(
        app,
        "POST",
        "/v1/leases",
        None,
        serde_json::to_vec(&req).unwrap(),
    )
    .await;
    match status {
        StatusCode::OK => Some(json(&body)),
        StatusCode::NO_CONTENT => None,
        s => panic!("lease: {s} {}", String::from_utf8_lossy(&body)),
    }
}

fn tags(list: &[&str]) -> Vec<String> {
    list.iter().map(|t| t.to_string()).collect()
}

#[tokio::test]
async fn a_job_is_lent_only_to_workers_with_every_tag_it_requires() {
    let f = farm(None);
    let job = submit_with(&f, 32, 16, 16, |s| s.requires = tags(&["gpu", "big-mem"])).await;
    // Before any worker is heard from, none has the tags.
    let s = job_status(&f.app, job).await;
    let waiting = s.waiting.expect("no worker can take it");
    assert!(waiting.contains("gpu, big-mem"), "{waiting}");
    assert!(lease_tagged(&f.app, "plain", &[]).await.is_none());
    assert!(lease_tagged(&f.app, "half", &["gpu"]).await.is_none());
    let waiting = job_status(&f.app, job).await.waiting.expect("still none");
    assert!(
        waiting.contains("big-mem") && !waiting.contains("gpu"),
        "names only what no worker has: {waiting}"
    );
    // Two workers with one tag each: each tag is someone's, but no one has both.
    assert!(
        lease_tagged(&f.app, "other-half", &["big-mem"])
            .await
            .is_none()
    );
    let waiting = job_status(&f.app, job).await.waiting.expect("still none");
    assert!(waiting.contains("every tag"), "{waiting}");
    let l = lease_tagged(&f.app, "full", &["x", "big-mem", "gpu"])
        .await
        .expect("a worker with every tag takes it");
    assert_eq!(l.job, job);
    assert_eq!(job_status(&f.app, job).await.waiting, None);
    // A job that requires nothing goes to any worker, and the untagged one takes it
    // while the tagged job still has a tile.
    let free = submit(&f, 32, 16, 16).await;
    assert_eq!(lease_tagged(&f.app, "plain", &[]).await.unwrap().job, free);
    // The workers list shows what each declared.
    let (_, body) = call(&f.app, "GET", "/v1/workers", None, Body::empty()).await;
    let workers: Vec<WorkerStatus> = json(&body);
    let full = workers.iter().find(|w| w.name == "full").unwrap();
    assert_eq!(full.tags, tags(&["x", "big-mem", "gpu"]));
}

#[tokio::test]
async fn a_job_goes_only_to_workers_that_offer_the_memory_its_scene_needs() {
    let f = farm(None);
    let job = submit(&f, 32, 16, 16).await;
    // The tiny scene's estimate is the process's own share.
    let need = job_status(&f.app, job).await.memory_mib;
    assert_eq!(need, 16);
    assert!(
        lease_offering(&f.app, "small", &[], Some(8))
            .await
            .is_none()
    );
    let waiting = job_status(&f.app, job)
        .await
        .waiting
        .expect("no worker has the memory");
    assert!(
        waiting.contains("16 MiB") && waiting.contains("8 MiB"),
        "{waiting}"
    );
    let l = lease_offering(&f.app, "big", &[], Some(16))
        .await
        .expect("enough");
    assert_eq!(l.job, job);
    assert_eq!(job_status(&f.app, job).await.waiting, None);
    // A worker that says nothing of its memory is taken at its word.
    assert!(lease_offering(&f.app, "silent", &[], None).await.is_some());
    let (_, body) = call(&f.app, "GET", "/v1/workers", None, Body::empty()).await;
    let workers: Vec<WorkerStatus> = json(&body);
    let small = workers.iter().find(|w| w.name == "small").unwrap();
    assert_eq!(small.memory_mib, Some(8));
}

#[tokio::test]
async fn a_capped_job_is_lent_to_at_most_its_workers_at_once() {
    let f = farm(None);
    let frame = (48, 16);
    let job = submit_with(&f, 48, 16, 16, |s| s.max_workers = Some(1)).await;
    let a = lease_tagged(&f.app, "a", &[]).await.expect("three tiles");
    assert!(
        lease_tagged(&f.app, "b", &[]).await.is_none(),
        "a second worker passes the cap"
    );
    let a2 = lease_tagged(&f.app, "a", &[])
        .await
        .expect("its worker takes more");
    assert_eq!((a.job, a2.job), (job, job));
    for l in [&a, &a2] {
        let (status, _) = upload(&f.app, l.lease, exr(&tile_of(l, frame, 1.0))).await;
        assert_eq!(status, StatusCode::OK);
    }
    // With no lease held, another worker may take the last tile.
    let b = lease_tagged(&f.app, "b", &[])
        .await
        .expect("the cap is free");
    assert_eq!(b.job, job);
    assert!(lease_tagged(&f.app, "a", &[]).await.is_none(), "all lent");
    // Without the cap, two workers share a job.
    let free = submit(&f, 48, 16, 16).await;
    assert_eq!(lease_tagged(&f.app, "c", &[]).await.unwrap().job, free);
    assert_eq!(lease_tagged(&f.app, "d", &[]).await.unwrap().job, free);
}

#[tokio::test]
async fn requirements_that_are_not_tags_are_refused_by_name() {
    let f = farm(None);
    let scene = upload_scene(&f, 16, 16).await;
    for (edit, names) in [
        (
            Box::new(|s: &mut JobSpec| s.requires = tags(&["gpu", "Big Mem"]))
                as Box<dyn Fn(&mut JobSpec)>,
            "'Big Mem'",
        ),
        (
            Box::new(|s: &mut JobSpec| s.max_workers = Some(0)),
            "max_workers",
        ),
    ] {
        let mut spec: JobSpec =
            serde_json::from_value(serde_json::json!({ "scene": scene, "spp": 1 })).unwrap();
        edit(&mut spec);
        assert_refused(&f, &spec, names).await;
    }
    // A worker's tags the same way.
    let (status, body) = call(
        &f.app,
        "POST",
        "/v1/leases",
        None,
        r#"{"worker": "w", "tags": ["ok", "no/slash"]}"#,
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("'no/slash'"),
        "{}",
        error_of(&body)
    );
}
