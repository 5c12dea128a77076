//! The SQLite store: what every job store must do (`conformance`, written against the
//! trait so that another back-end can run it too), and its schema versions: a store written
//! before versions existed opens with everything in it, a newer one is refused.

use super::super::{JobStore, StoredJob, WebhookOutcome};
use super::SqliteStore;
use crate::api::{JobSpec, JobState};
use std::collections::BTreeSet;

fn spec(scene: &str) -> JobSpec {
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

fn names(n: &[&str]) -> BTreeSet<String> {
    n.iter().map(|s| s.to_string()).collect()
}

fn job(jobs: &[StoredJob], id: u64) -> &StoredJob {
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

/// The schema exactly as Kiln wrote it before its versions were counted (up to 8cf520a):
/// such a store is at user_version 0.
const SCHEMA_BEFORE_VERSIONS: &str = "PRAGMA journal_mode = WAL;
     PRAGMA synchronous = NORMAL;
     CREATE TABLE IF NOT EXISTS jobs (id INTEGER PRIMARY KEY, spec TEXT NOT NULL, state TEXT NOT NULL, error TEXT, idempotency_key TEXT UNIQUE);
     CREATE TABLE IF NOT EXISTS tiles (job INTEGER NOT NULL, idx INTEGER NOT NULL, exr BLOB NOT NULL, PRIMARY KEY (job, idx));
     CREATE TABLE IF NOT EXISTS tile_passes (job INTEGER NOT NULL, idx INTEGER NOT NULL, samples INTEGER NOT NULL, exr BLOB NOT NULL, unchecked_by TEXT NOT NULL DEFAULT '[]', PRIMARY KEY (job, idx, samples));
     CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
     CREATE TABLE IF NOT EXISTS set_aside (worker TEXT PRIMARY KEY, reason TEXT NOT NULL);";

#[test]
fn a_store_written_before_schema_versions_opens_with_everything_in_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kiln.sqlite");
    {
        let db = rusqlite::Connection::open(&path).unwrap();
        db.execute_batch(SCHEMA_BEFORE_VERSIONS).unwrap();
        let running = serde_json::to_string(&spec("a")).unwrap();
        let done = serde_json::to_string(&spec("b")).unwrap();
        db.execute_batch(&format!(
            "INSERT INTO jobs (id, spec, state, error, idempotency_key) VALUES (1, '{running}', 'running', NULL, 'k1');
             INSERT INTO jobs (id, spec, state, error, idempotency_key) VALUES (2, '{done}', 'done', NULL, NULL);
             INSERT INTO tile_passes (job, idx, samples, exr, unchecked_by) VALUES (1, 0, 4, x'0102', '[\"w1\"]');
             INSERT INTO tiles (job, idx, exr) VALUES (2, 3, x'0304');
             INSERT INTO meta (key, value) VALUES ('epoch', 7);
             INSERT INTO meta (key, value) VALUES ('verified:1', 5);
             INSERT INTO meta (key, value) VALUES ('webhook:2', 1);
             INSERT INTO meta (key, value) VALUES ('webhook:1', 2);
             INSERT INTO set_aside (worker, reason) VALUES ('bad', 'flipped bits');"
        ))
        .unwrap();
        let version: u32 = db
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .unwrap();
        assert_eq!(version, 0);
    }
    let store = SqliteStore::open(&path).unwrap();
    let jobs = store.jobs().unwrap();
    assert_eq!(jobs.len(), 2);
    assert_eq!(job(&jobs, 1).spec.as_ref().unwrap(), &spec("a"));
    assert_eq!(job(&jobs, 2).state, JobState::Done);
    assert_eq!(store.job_with_key("k1").unwrap(), Some(1));
    let kept = store.tiles(1, 16).unwrap();
    assert_eq!(kept.len(), 1);
    assert_eq!(
        (kept[0].idx, kept[0].samples, &kept[0].exr[..]),
        (0, 4, &[1u8, 2][..])
    );
    assert_eq!(kept[0].unchecked_by, names(&["w1"]));
    let legacy = store.tiles(2, 16).unwrap();
    assert_eq!(legacy.len(), 1);
    assert!(legacy[0].legacy && legacy[0].samples == 16 && legacy[0].idx == 3);
    assert_eq!(store.next_epoch().unwrap(), 8);
    assert_eq!(store.verified(1).unwrap(), 5);
    assert_eq!(store.verified(2).unwrap(), 0);
    assert_eq!(store.webhook(1).unwrap(), WebhookOutcome::GaveUp);
    assert_eq!(store.webhook(2).unwrap(), WebhookOutcome::Delivered);
    assert_eq!(
        store.set_aside_workers().unwrap(),
        [("bad".into(), "flipped bits".into())]
    );
    // The store is now at the latest version, with the per-job keys gone from meta.
    let (version, left): (u32, i64) = (
        store
            .db
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .unwrap(),
        store
            .db
            .query_row("SELECT COUNT(*) FROM meta WHERE key != 'epoch'", [], |r| {
                r.get(0)
            })
            .unwrap(),
    );
    assert_eq!((version, left), (SqliteStore::latest_version(), 0));
    drop(store);
    // Opened again, nothing is migrated twice.
    let store = SqliteStore::open(&path).unwrap();
    assert_eq!(store.verified(1).unwrap(), 5);
    assert_eq!(store.next_epoch().unwrap(), 9);
}

#[test]
fn a_store_from_a_newer_kiln_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kiln.sqlite");
    drop(SqliteStore::open(&path).unwrap());
    let newer = SqliteStore::latest_version() + 1;
    {
        let db = rusqlite::Connection::open(&path).unwrap();
        db.pragma_update(None, "user_version", newer).unwrap();
    }
    let err = SqliteStore::open(&path).err().expect("refused");
    let message = err.to_string();
    assert!(
        message.contains(&format!("schema version {newer}")) && message.contains("newer Kiln"),
        "{message}"
    );
}
