//! Coordinators sharing a PostgreSQL job store: a deposed leader stops serving and its
//! writes are refused; a stopping leader gives the lead up at once. (Failover between
//! processes, kill -9 included, is deploy/test-ha.sh's.)

use super::*;
use crate::coordinator::store::tests::fresh_postgres;

/// Runs `sql` on the database at `url`, as another coordinator (or an operator) would.
fn on_db(url: &str, sql: &str) {
    let (url, sql) = (url.to_string(), sql.to_string());
    std::thread::spawn(move || {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        c.batch_execute(&sql).unwrap();
    })
    .join()
    .unwrap();
}

fn lead_row(url: &str) -> (i64, String, bool) {
    let url = url.to_string();
    std::thread::spawn(move || {
        let mut c = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        let r = c
            .query_one(
                "SELECT epoch, holder, renewed < now() - interval '1 hour' FROM leader",
                &[],
            )
            .unwrap();
        (r.get(0), r.get(1), r.get(2))
    })
    .join()
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_deposed_coordinator_refuses_writes_and_stops_serving() {
    let Some(url) = fresh_postgres("deposed") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (c, app) = open_on(&dir.path().join("data"), None, Some(&url));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let served = tokio::spawn(crate::coordinator::serve(
        listener,
        c.clone(),
        std::future::pending(),
    ));
    // It leads and renews: a job is created.
    tokio::time::sleep(Duration::from_millis(400)).await;
    let f = Farm { dir, c, app };
    submit(&f, 32, 16, 16).await;
    let (epoch, holder, _) = lead_row(&url);
    assert_eq!(epoch, 1);
    // Another coordinator takes the lead while this one is paused (its epoch moves on).
    on_db(
        &url,
        "UPDATE leader SET epoch = epoch + 1, holder = 'usurper', renewed = now()",
    );
    // Its next write is refused by the store, and the request says the job store failed.
    let spec = JobSpec {
        resolution: Some((32, 16)),
        spp: Some(2),
        tile: 16,
        ..JobSpec::new(&upload_scene(&f, 32, 16).await)
    };
    let (status, body) = post_job(&f, &spec).await;
    assert_eq!(
        status,
        StatusCode::SERVICE_UNAVAILABLE,
        "{}",
        error_of(&body)
    );
    // Within a renewal period it notices and stops serving, saying why.
    let ended = tokio::time::timeout(Duration::from_secs(5), served)
        .await
        .expect("serving stops")
        .unwrap();
    let why = ended.unwrap_err().to_string();
    assert!(why.contains("deposed"), "{why}");
    assert_ne!(holder, "usurper");
    assert_eq!(lead_row(&url).1, "usurper", "the usurper keeps the lead");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stopping_leader_gives_up_the_lead() {
    let Some(url) = fresh_postgres("resign") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (c, _app) = open_on(&dir.path().join("data"), None, Some(&url));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let served = tokio::spawn(crate::coordinator::serve(listener, c, async {
        let _ = stopped.await;
    }));
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(!lead_row(&url).2, "the lead is fresh while it serves");
    stop.send(()).unwrap();
    served.await.unwrap().unwrap();
    assert!(
        lead_row(&url).2,
        "the lead is given up: a standby may take it at once"
    );
}
