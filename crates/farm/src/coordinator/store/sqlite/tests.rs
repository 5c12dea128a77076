//! The SQLite store's schema versions: a store written before versions existed opens with
//! everything in it, a newer one is refused. (What every store must do is in
//! `store/tests.rs`, run against both back-ends.)

use super::super::JobStore;
use super::super::WebhookOutcome;
use super::super::tests::{job, names, spec};
use super::SqliteStore;
use crate::api::JobState;

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
