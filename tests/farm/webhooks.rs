//! Webhooks through a real receiver: called when a job ends, retried, given up on, called
//! again for a job that runs again, and never again after a restart.

use super::{Farm, wait_for};
use crate::util::scene;
use kiln_farm::api::{JobSpec, JobState};
use std::time::Duration;

/// A job's webhook is called when it ends (done, failed or cancelled), with its status,
/// and retried with backoff until it answers 2xx; one that never answers is given up on
/// after its attempts, saying why. A job extended while the call for its end is on its way
/// is announced again when it ends again (the receiver holds that call until the test has
/// extended the job). What became of each call survives a restart: a restarted
/// coordinator calls none of them again.
#[test]
fn webhooks_are_called_when_a_job_ends_and_retried_until_they_answer() {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex};
    let mut farm = Farm::configured(None, |c| c.webhook_backoff = Duration::from_millis(20));
    // A receiver with four hooks: /hook fails its first two calls, /down every call, /slow
    // answers once `release` says so, /failed at once. Each call is kept as (event, body).
    type Calls = Arc<Mutex<HashMap<String, Vec<(String, serde_json::Value)>>>>;
    let calls: Calls = Arc::default();
    let seen = calls.clone();
    let (release, released) = tokio::sync::watch::channel(false);
    let hook = farm
        .rt
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
                let mut released = released.clone();
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
                            let _ = released.wait_for(|go| *go).await;
                            S::NO_CONTENT
                        }
                        _ => S::NO_CONTENT,
                    }
                }
            },
        ),
    );
    farm.rt
        .spawn(async move { axum::serve(hook, receiver).await });
    let calls_to = |name: &str| calls.lock().unwrap().get(name).cloned().unwrap_or_default();
    let (rt, client) = (&farm.rt, &farm.client);
    let digest = farm.upload(&scene("furnace/scene.pbrt"));
    let spec = |hook: &str| JobSpec {
        spp: Some(1),
        resolution: Some((16, 16)),
        tile: 16,
        webhook: Some(format!("{base}/{hook}")),
        ..JobSpec::new(&digest)
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
    let _w = farm.worker("w");
    // Extended while the call announcing its end is on its way.
    wait_for("a call to /slow", Duration::from_secs(60), || {
        !calls_to("slow").is_empty()
    });
    rt.block_on(client.extend(extended, &[72])).unwrap();
    release.send(true).unwrap();
    farm.wait_done(done, Duration::from_secs(60));
    let webhook_of = |id| rt.block_on(client.status(id)).unwrap().webhook;
    let settled = |id| {
        webhook_of(id)
            .is_some_and(|w: String| w.starts_with("delivered") || w.starts_with("gave up"))
    };
    wait_for(
        "every webhook delivered or given up on",
        Duration::from_secs(60),
        || {
            [done, cancelled, failed, extended].into_iter().all(settled)
                && farm.status(extended).state == JobState::Done
        },
    );
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
    // A restart calls none of them again, and says what became of each: once the
    // restarted coordinator's sweep has read every job's outcome from the store (each
    // status says so), no call was started, and none was made.
    let before: usize = calls.lock().unwrap().values().map(Vec::len).sum();
    farm.restart_in_process(|c| c.webhook_backoff = Duration::from_millis(20));
    let restarted = |id| farm.status(id).webhook;
    wait_for(
        "the restarted coordinator's webhook sweep",
        Duration::from_secs(30),
        || {
            [done, cancelled, failed, extended].into_iter().all(|id| {
                restarted(id).is_some_and(|w| w.ends_with("before the coordinator restarted"))
            })
        },
    );
    let after: usize = calls.lock().unwrap().values().map(Vec::len).sum();
    assert_eq!(
        before, after,
        "a webhook was called again after the restart"
    );
    let webhook_of = |id| farm.status(id).webhook.unwrap();
    assert_eq!(
        webhook_of(done),
        "delivered before the coordinator restarted"
    );
    assert_eq!(
        webhook_of(cancelled),
        "gave up after 8 calls before the coordinator restarted"
    );
}
