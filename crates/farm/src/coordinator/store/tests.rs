//! What every job store must do (`conformance`, written against the trait), run against
//! SQLite and PostgreSQL; and what only a shared store does: leading and fencing.
//!
//! The PostgreSQL tests need a server: `KILN_TEST_POSTGRES` is a URL whose user may create
//! databases (`.ci/run` starts one), and each test makes a database of its own. Without
//! it they print SKIPPED, unless `KILN_REQUIRE_POSTGRES` is set, when they fail.

use super::{JobStore, Leadership, PostgresStore, SqliteStore, StoredJob, WebhookOutcome};
use crate::api::{JobSpec, JobState, Role};
use std::collections::BTreeSet;
use std::time::Duration;

/// A URL of a new, empty database on the test server, named after `test`; None (with
/// SKIPPED printed) when there is no server to test against.
pub(in crate::coordinator) fn fresh_postgres(test: &str) -> Option<String> {
    let Some(admin) = std::env::var("KILN_TEST_POSTGRES")
        .ok()
        .filter(|u| !u.is_empty())
    else {
        assert!(
            std::env::var_os("KILN_REQUIRE_POSTGRES").is_none(),
            "{test}: KILN_REQUIRE_POSTGRES is set but KILN_TEST_POSTGRES names no server"
        );
        println!(
            "{test}: SKIPPED: no PostgreSQL server (set KILN_TEST_POSTGRES to a URL whose user may create databases)"
        );
        return None;
    };
    use std::sync::atomic::{AtomicU32, Ordering};
    static COUNT: AtomicU32 = AtomicU32::new(0);
    let name = format!(
        "kiln_test_{}_{}_{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed),
        test.chars()
            .filter(char::is_ascii_alphanumeric)
            .take(24)
            .collect::<String>()
    )
    .to_ascii_lowercase();
    let admin2 = admin.clone();
    let name2 = name.clone();
    // The blocking client must not run on a runtime's thread, and a test may be on one.
    std::thread::spawn(move || {
        let mut c = postgres::Client::connect(&admin2, postgres::NoTls)
            .unwrap_or_else(|e| panic!("KILN_TEST_POSTGRES: cannot connect: {e}"));
        c.batch_execute(&format!("CREATE DATABASE {name2}"))
            .unwrap_or_else(|e| panic!("cannot create the test database {name2}: {e}"));
    })
    .join()
    .expect("the test database is made");
    // The admin URL with its database replaced: postgres://user:pw@host:port/db?params
    let (base, query) = admin
        .split_once('?')
        .map_or((admin.as_str(), ""), |(b, q)| (b, q));
    let after_scheme = base.find("://").map_or(0, |i| i + 3);
    let base = match base[after_scheme..].find('/') {
        Some(slash) => &base[..after_scheme + slash],
        None => base,
    };
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{query}")
    };
    Some(format!("{base}/{name}{query}"))
}

pub(super) fn spec(scene: &str) -> JobSpec {
    JobSpec {
        spp: Some(16),
        resolution: Some((64, 32)),
        tile: 16,
        passes: Some(vec![4, 16]),
        verify: Some(0.5),
        priority: 2,
        webhook: Some("http://127.0.0.1:9/hook".into()),
        spectral: Some(false),
        ..JobSpec::new(scene)
    }
}

pub(super) fn names(n: &[&str]) -> BTreeSet<String> {
    n.iter().map(|s| s.to_string()).collect()
}

pub(super) fn job(jobs: &[StoredJob], id: u64) -> &StoredJob {
    jobs.iter().find(|j| j.id == id).expect("job kept")
}

/// Every operation of the store, written and read back.
fn conformance(store: &dyn JobStore) {
    let e1 = store.next_epoch().unwrap();
    assert_eq!(store.next_epoch().unwrap(), e1 + 1);

    // Jobs, and their idempotency keys.
    let a = store.insert_job(&spec("a"), Some("key-a")).unwrap();
    let b = store.insert_job(&spec("b"), None).unwrap();
    assert!(b > a);
    assert_eq!(store.job_with_key("key-a").unwrap(), Some(a));
    assert_eq!(store.job_with_key("key-b").unwrap(), None);
    assert!(store.insert_job(&spec("c"), Some("key-a")).is_err());
    let mut longer = spec("a");
    longer.passes = Some(vec![4, 16, 64]);
    store.set_spec(a, &longer).unwrap();
    store.set_state(b, JobState::Failed, Some("why")).unwrap();
    let jobs = store.jobs().unwrap();
    assert_eq!(jobs.iter().map(|j| j.id).collect::<Vec<_>>(), [a, b]);
    assert_eq!(job(&jobs, a).spec.as_ref().unwrap(), &longer);
    assert_eq!(job(&jobs, a).state, JobState::Running);
    assert_eq!(
        (job(&jobs, b).state, job(&jobs, b).error.as_deref()),
        (JobState::Failed, Some("why"))
    );

    // Tile passes: the first kept for a pass stays.
    store
        .insert_tile(a, 0, 4, b"t0p4", &names(&["w1"]))
        .unwrap();
    store.insert_tile(a, 0, 4, b"other", &names(&[])).unwrap();
    store
        .insert_tile(a, 0, 16, b"t0p16", &names(&["w1", "w2"]))
        .unwrap();
    store.insert_tile(a, 1, 4, b"t1p4", &names(&[])).unwrap();
    assert_eq!(store.tile(a, 0, 4).unwrap().as_deref(), Some(&b"t0p4"[..]));
    assert_eq!(store.tile(a, 0, 64).unwrap(), None);
    assert!(store.holds_tile(a, 0, b"t0p16").unwrap());
    assert!(!store.holds_tile(a, 1, b"t0p16").unwrap());
    let mut kept = store.tiles(a, 16).unwrap();
    kept.sort_by_key(|t| (t.idx, t.samples));
    let seen: Vec<_> = kept
        .iter()
        .map(|t| {
            (
                t.idx,
                t.samples,
                t.exr.clone(),
                t.unchecked_by.len(),
                t.legacy,
            )
        })
        .collect();
    assert_eq!(
        seen,
        [
            (0, 4, b"t0p4".to_vec(), 1, false),
            (0, 16, b"t0p16".to_vec(), 2, false),
            (1, 4, b"t1p4".to_vec(), 0, false),
        ]
    );
    store.drop_passes_before(a, 16).unwrap();
    assert_eq!(store.tiles(a, 16).unwrap().len(), 1);
    store.drop_tiles(a, &[0]).unwrap();
    assert!(store.tiles(a, 16).unwrap().is_empty());
    assert!(store.tiles(b, 16).unwrap().is_empty());

    // Verification counts and webhook outcomes, per job.
    assert_eq!(store.verified(a).unwrap(), 0);
    store.add_verified(a).unwrap();
    store.add_verified(a).unwrap();
    assert_eq!(
        (store.verified(a).unwrap(), store.verified(b).unwrap()),
        (2, 0)
    );
    assert_eq!(store.webhook(a).unwrap(), WebhookOutcome::Pending);
    store.set_webhook(a, WebhookOutcome::GaveUp).unwrap();
    store.set_webhook(b, WebhookOutcome::Delivered).unwrap();
    assert_eq!(store.webhook(a).unwrap(), WebhookOutcome::GaveUp);
    store.set_webhook(a, WebhookOutcome::Pending).unwrap();
    assert_eq!(store.webhook(a).unwrap(), WebhookOutcome::Pending);
    assert_eq!(store.webhook(b).unwrap(), WebhookOutcome::Delivered);
    assert_eq!(store.verified(a).unwrap(), 2, "a webhook leaves the count");

    // Workers set aside: the first reason stays.
    store.set_aside("w2", "first").unwrap();
    store.set_aside("w2", "second").unwrap();
    store.set_aside("w1", "other").unwrap();
    assert_eq!(
        store.set_aside_workers().unwrap(),
        [("w1".into(), "other".into()), ("w2".into(), "first".into())]
    );
    store.reinstate("w2").unwrap();
    assert_eq!(store.set_aside_workers().unwrap().len(), 1);

    // Tokens: kept by their hash, revoked by id.
    let t1 = store.insert_token(Role::Submitter, "alice", "h1").unwrap();
    let t2 = store.insert_token(Role::Worker, "w1", "h2").unwrap();
    assert!(t2 > t1);
    assert!(
        store.insert_token(Role::Admin, "x", "h1").is_err(),
        "a hash is kept once"
    );
    assert!(store.revoke_token(t1).unwrap());
    assert!(!store.revoke_token(t2 + 100).unwrap());
    let tokens = store.tokens().unwrap();
    assert_eq!(
        tokens
            .iter()
            .map(|t| (t.id, t.role, t.name.as_str(), t.hash.as_str(), t.revoked))
            .collect::<Vec<_>>(),
        [
            (t1, Role::Submitter, "alice", "h1", true),
            (t2, Role::Worker, "w1", "h2", false)
        ]
    );
}

#[test]
fn sqlite_does_what_a_job_store_must() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kiln.sqlite");
    conformance(&SqliteStore::open(&path).unwrap());
    // Everything was committed: a store opened again reads it back.
    let again = SqliteStore::open(&path).unwrap();
    assert_eq!(again.jobs().unwrap().len(), 2);
    assert_eq!(again.verified(1).unwrap(), 2);
}

#[test]
fn postgres_does_what_a_job_store_must() {
    let Some(url) = fresh_postgres("conformance") else {
        return;
    };
    conformance(&PostgresStore::open(&url).unwrap());
    // Everything was committed, and opening it again migrates nothing twice.
    let again = PostgresStore::open(&url).unwrap();
    assert_eq!(again.jobs().unwrap().len(), 2);
    assert_eq!(again.verified(1).unwrap(), 2);
    assert_eq!(again.tokens().unwrap().len(), 2);
}

#[test]
fn a_deposed_leader_cannot_write() {
    let Some(url) = fresh_postgres("fencing") else {
        return;
    };
    let ttl = Duration::from_millis(300);
    let a = PostgresStore::open(&url).unwrap();
    let b = PostgresStore::open(&url).unwrap();
    assert_eq!(
        a.lead("a", "http://a", ttl).unwrap(),
        Leadership::Leading {
            epoch: 1,
            after: None
        }
    );
    let job = a.insert_job(&spec("x"), None).unwrap();
    // While a renews, b stands by and is told who leads.
    assert!(a.renew_lead().unwrap());
    assert_eq!(
        b.lead("b", "http://b", ttl).unwrap(),
        Leadership::Led {
            holder: "a".into(),
            address: "http://a".into(),
            epoch: 1
        }
    );
    // a stops renewing (its process stalled, or lost the network): b takes the lead.
    std::thread::sleep(ttl + Duration::from_millis(200));
    // It says whom it took the lead from, and how long that one had been silent.
    match b.lead("b", "http://b", ttl).unwrap() {
        Leadership::Leading {
            epoch: 2,
            after: Some((before, silent)),
        } => assert!(
            before == "a" && (0.3..5.0).contains(&silent),
            "{before} {silent}"
        ),
        other => panic!("b should lead at epoch 2: {other:?}"),
    }
    // a comes back: every write it tries is refused by its epoch, and says so.
    let refused = a
        .set_state(job, JobState::Failed, Some("stale"))
        .unwrap_err();
    assert!(refused.is_deposed(), "{refused}");
    assert!(
        refused.to_string().contains("b took the lead at epoch 2"),
        "{refused}"
    );
    assert!(
        a.insert_tile(job, 0, 4, b"late", &names(&[]))
            .unwrap_err()
            .is_deposed()
    );
    assert!(!a.renew_lead().unwrap(), "its renewal finds the lead gone");
    // Nothing a wrote after it was deposed is there; b writes.
    assert_eq!(b.jobs().unwrap()[0].state, JobState::Running);
    assert!(b.tiles(job, 4).unwrap().is_empty());
    b.set_state(job, JobState::Done, None).unwrap();
    assert_eq!(
        a.jobs().unwrap()[0].state,
        JobState::Done,
        "a may still read"
    );
}

#[test]
fn a_postgres_store_from_a_newer_kiln_is_refused() {
    let Some(url) = fresh_postgres("newer") else {
        return;
    };
    drop(PostgresStore::open(&url).unwrap());
    let url2 = url.clone();
    std::thread::spawn(move || {
        let mut c = postgres::Client::connect(&url2, postgres::NoTls).unwrap();
        c.batch_execute("UPDATE kiln_schema SET version = version + 1")
            .unwrap();
    })
    .join()
    .unwrap();
    let message = PostgresStore::open(&url)
        .err()
        .expect("refused")
        .to_string();
    assert!(message.contains("newer Kiln"), "{message}");
}

#[test]
fn an_unreachable_server_is_a_clear_error_without_the_password() {
    // Port 1 on loopback: nothing listens, so the connection is refused at once.
    let started = std::time::Instant::now();
    let message = PostgresStore::open("postgres://kiln:hunter2@127.0.0.1:1/farm")
        .err()
        .expect("refused")
        .to_string();
    assert!(message.contains("127.0.0.1:1/farm"), "{message}");
    assert!(!message.contains("hunter2"), "{message}");
    assert!(started.elapsed() < Duration::from_secs(10));
    let message = PostgresStore::open("postgres://[::1")
        .err()
        .unwrap()
        .to_string();
    assert!(message.contains("not a PostgreSQL URL"), "{message}");
}
