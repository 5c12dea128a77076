//! Jobs that start after others: nothing lent until those are done (or ended, as asked),
//! a status that says what the job waits for, a dependency that failed or was cancelled
//! failing or holding its dependents as they ask, and dependencies on jobs that do not
//! exist refused by name (so no circle of jobs can form).

use super::*;

#[tokio::test]
async fn a_job_is_lent_nothing_until_the_jobs_it_starts_after_are_done() {
    let f = farm(None);
    let frame = (32, 16);
    let first = submit(&f, 32, 16, 16).await;
    let second = submit_with(&f, 16, 16, 16, |s| s.after = vec![first]).await;
    let waiting = job_status(&f.app, second).await.waiting.expect("it waits");
    assert!(waiting.contains(&format!("job {first}")), "{waiting}");
    let a = lease(&f.app, "w").await.unwrap();
    let b = lease(&f.app, "w").await.unwrap();
    assert_eq!((a.job, b.job), (first, first));
    assert!(lease(&f.app, "w").await.is_none(), "the second waits");
    for l in [&a, &b] {
        let (status, _) = upload(&f.app, l.lease, exr(&tile_of(l, frame, 1.0))).await;
        assert_eq!(status, StatusCode::OK);
    }
    assert_eq!(job_status(&f.app, first).await.state, JobState::Done);
    assert_eq!(job_status(&f.app, second).await.waiting, None);
    assert_eq!(lease(&f.app, "w").await.unwrap().job, second);
}

#[tokio::test]
async fn a_cancelled_dependency_fails_or_holds_its_dependents_as_they_ask() {
    let f = farm(None);
    let first = submit(&f, 16, 16, 16).await;
    let fails = submit_with(&f, 16, 16, 16, |s| s.after = vec![first]).await;
    let holds = submit_with(&f, 16, 16, 16, |s| {
        s.after = vec![first];
        s.hold_on_failure = true;
    })
    .await;
    let ended = submit_with(&f, 16, 16, 16, |s| {
        s.after = vec![first];
        s.after_ended = true;
    })
    .await;
    let (status, _) = call(
        &f.app,
        "POST",
        &format!("/v1/jobs/{first}/cancel"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    // The next request for work settles them: the one that waits for any end is lent.
    assert_eq!(lease(&f.app, "w").await.unwrap().job, ended);
    let s = job_status(&f.app, fails).await;
    assert_eq!(s.state, JobState::Failed);
    let error = s.error.unwrap();
    assert!(
        error.contains(&format!("job {first}")) && error.contains("cancelled"),
        "{error}"
    );
    let s = job_status(&f.app, holds).await;
    assert_eq!(s.state, JobState::Running, "it holds");
    assert!(s.waiting.unwrap().contains("held"));
    assert!(lease(&f.app, "w").await.is_none(), "nothing else to lend");
    // The expiry loop settles them too, without a worker asking.
    let late = submit_with(&f, 16, 16, 16, |s| s.after = vec![first]).await;
    f.c.expire_leases();
    assert_eq!(job_status(&f.app, late).await.state, JobState::Failed);
}

#[tokio::test]
async fn jobs_to_start_after_that_do_not_exist_are_refused_by_name() {
    let f = farm(None);
    let scene = upload_scene(&f, 16, 16).await;
    let existing = submit(&f, 16, 16, 16).await;
    // An unknown job, this very job (the next id), and too many.
    for (after, names) in [
        (vec![existing, 99], "no job 99"),
        (vec![existing + 1], &*format!("no job {}", existing + 1)),
        (vec![existing; 65], "at most 64"),
    ] {
        let spec: JobSpec =
            serde_json::from_value(serde_json::json!({ "scene": scene, "spp": 1, "after": after }))
                .unwrap();
        assert_refused(&f, &spec, names).await;
    }
}
