//! The job store in an embedded SQLite file (`kiln.sqlite` in the data directory): one
//! connection, one writer, used under the coordinator's lock.
//!
//! The schema is versioned (SQLite's `user_version`): [`MIGRATIONS`] lists every change in
//! order, and opening a store applies those it lacks, each in a transaction with its version
//! number, so a crash mid-upgrade leaves the store at the last whole version. A store
//! written by a newer Kiln, at a version this one does not know, is refused rather than
//! misread. Stores written before versions existed are at version 0 with version 1's tables
//! already there: version 1 creates only what is missing.

use super::{JobStore, KeptTile, StoreError, StoredJob, StoredToken, WebhookOutcome};
use crate::api::{JobSpec, JobState, Role};
use rusqlite::{Connection, OptionalExtension, params};
use std::collections::BTreeSet;
use std::path::Path;

/// One change to the schema: the version it brings the store to, and its SQL.
struct Migration {
    version: u32,
    sql: &'static str,
}

/// Every schema change, oldest first; a store at version v has had the first v applied.
const MIGRATIONS: &[Migration] = &[
    // Jobs, tile passes by sample count (and the finished tiles of before passes, kept so
    // that such a job resumes done), counters and workers set aside.
    Migration {
        version: 1,
        sql: "CREATE TABLE IF NOT EXISTS jobs (id INTEGER PRIMARY KEY, spec TEXT NOT NULL, state TEXT NOT NULL, error TEXT, idempotency_key TEXT UNIQUE);
              CREATE TABLE IF NOT EXISTS tiles (job INTEGER NOT NULL, idx INTEGER NOT NULL, exr BLOB NOT NULL, PRIMARY KEY (job, idx));
              CREATE TABLE IF NOT EXISTS tile_passes (job INTEGER NOT NULL, idx INTEGER NOT NULL, samples INTEGER NOT NULL, exr BLOB NOT NULL, unchecked_by TEXT NOT NULL DEFAULT '[]', PRIMARY KEY (job, idx, samples));
              CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
              CREATE TABLE IF NOT EXISTS set_aside (worker TEXT PRIMARY KEY, reason TEXT NOT NULL);",
    },
    // A job's verified count and webhook outcome move from `meta` keys spelt with the
    // job's id ("verified:7", "webhook:7") into a row per job.
    Migration {
        version: 2,
        sql: "CREATE TABLE job_notes (job INTEGER PRIMARY KEY, verified INTEGER NOT NULL DEFAULT 0, webhook INTEGER NOT NULL DEFAULT 0);
              INSERT INTO job_notes (job, verified)
                  SELECT CAST(substr(key, 10) AS INTEGER), value FROM meta WHERE key LIKE 'verified:%';
              INSERT INTO job_notes (job, webhook)
                  SELECT CAST(substr(key, 9) AS INTEGER), value FROM meta WHERE key LIKE 'webhook:%'
                  ON CONFLICT (job) DO UPDATE SET webhook = excluded.webhook;
              DELETE FROM meta WHERE key LIKE 'verified:%' OR key LIKE 'webhook:%';",
    },
    // Issued tokens: role, whose, the SHA-256 of the secret, and whether revoked.
    Migration {
        version: 3,
        sql: "CREATE TABLE tokens (id INTEGER PRIMARY KEY, role TEXT NOT NULL, name TEXT NOT NULL, hash TEXT NOT NULL UNIQUE, revoked INTEGER NOT NULL DEFAULT 0);",
    },
];

/// The driver's error as the store's.
fn failed(e: rusqlite::Error) -> StoreError {
    StoreError::new(e.to_string())
}

/// The SQLite connection.
pub(in crate::coordinator) struct SqliteStore {
    db: Connection,
}

impl SqliteStore {
    /// Opens (or creates) the store at `path` and brings its schema up to date.
    pub fn open(path: &Path) -> Result<SqliteStore, StoreError> {
        let mut db = Connection::open(path).map_err(failed)?;
        db.execute_batch("PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL;")
            .map_err(failed)?;
        migrate(&mut db).map_err(|e| StoreError::new(format!("{}: {e}", path.display())))?;
        Ok(SqliteStore { db })
    }

    /// The schema version this build writes.
    #[cfg(test)]
    pub fn latest_version() -> u32 {
        MIGRATIONS.last().map_or(0, |m| m.version)
    }
}

/// Applies the migrations the store lacks, each with its version in one transaction.
fn migrate(db: &mut Connection) -> Result<(), StoreError> {
    let current: u32 = db
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .map_err(failed)?;
    let latest = MIGRATIONS.last().map_or(0, |m| m.version);
    if current > latest {
        return Err(StoreError::new(format!(
            "the job store is at schema version {current}, written by a newer Kiln; this one knows versions up to {latest}"
        )));
    }
    for m in MIGRATIONS.iter().filter(|m| m.version > current) {
        let tx = db.transaction().map_err(failed)?;
        tx.execute_batch(m.sql).map_err(|e| {
            StoreError::new(format!("upgrading to schema version {}: {e}", m.version))
        })?;
        tx.pragma_update(None, "user_version", m.version)
            .map_err(failed)?;
        tx.commit().map_err(failed)?;
    }
    Ok(())
}

impl SqliteStore {
    /// Sets one of a job's notes (a column of `job_notes`, named by the caller, never by
    /// input).
    fn set_note(&self, job: u64, column: &str, value: i64) -> Result<(), StoreError> {
        self.db
            .execute(
                &format!(
                    "INSERT INTO job_notes (job, {column}) VALUES (?1, ?2)
                     ON CONFLICT (job) DO UPDATE SET {column} = ?2"
                ),
                params![job as i64, value],
            )
            .map_err(failed)?;
        Ok(())
    }

    /// One of a job's notes, 0 when it has none.
    fn note(&self, job: u64, column: &str) -> Result<i64, StoreError> {
        Ok(self
            .db
            .query_row(
                &format!("SELECT {column} FROM job_notes WHERE job = ?1"),
                [job as i64],
                |r| r.get::<_, i64>(0),
            )
            .optional()
            .map_err(failed)?
            .unwrap_or(0))
    }
}

impl JobStore for SqliteStore {
    fn next_epoch(&self) -> Result<u64, StoreError> {
        let epoch: i64 = self
            .db
            .query_row(
                "INSERT INTO meta (key, value) VALUES ('epoch', 1)
                 ON CONFLICT (key) DO UPDATE SET value = value + 1
                 RETURNING value",
                [],
                |row| row.get(0),
            )
            .map_err(failed)?;
        Ok(epoch as u64)
    }

    fn jobs(&self) -> Result<Vec<StoredJob>, StoreError> {
        let mut stmt = self
            .db
            .prepare("SELECT id, spec, state, error FROM jobs ORDER BY id")
            .map_err(failed)?;
        let rows = stmt
            .query_map([], |r| {
                let id = r.get::<_, i64>(0)? as u64;
                let fields = (|| {
                    Ok::<_, rusqlite::Error>((
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                        r.get::<_, Option<String>>(3)?,
                    ))
                })();
                Ok((id, fields))
            })
            .map_err(failed)?;
        let mut jobs = Vec::new();
        for row in rows {
            let (id, fields) = row.map_err(failed)?;
            let job = match fields {
                Ok((spec, state, error)) => StoredJob {
                    id,
                    spec: serde_json::from_str(&spec)
                        .map_err(|e| format!("its record in the store is damaged: {e}")),
                    state: JobState::from_name(&state).unwrap_or(JobState::Failed),
                    error,
                },
                Err(e) => StoredJob {
                    id,
                    spec: Err(format!("its record in the store is damaged: {e}")),
                    state: JobState::Failed,
                    error: None,
                },
            };
            jobs.push(job);
        }
        Ok(jobs)
    }

    fn job_with_key(&self, key: &str) -> Result<Option<u64>, StoreError> {
        Ok(self
            .db
            .query_row(
                "SELECT id FROM jobs WHERE idempotency_key = ?1",
                [key],
                |r| r.get::<_, i64>(0),
            )
            .optional()
            .map_err(failed)?
            .map(|id| id as u64))
    }

    fn insert_job(&self, spec: &JobSpec, key: Option<&str>) -> Result<u64, StoreError> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        self.db
            .execute(
                "INSERT INTO jobs (spec, state, idempotency_key) VALUES (?1, 'running', ?2)",
                params![spec_json, key],
            )
            .map_err(failed)?;
        Ok(self.db.last_insert_rowid() as u64)
    }

    fn set_spec(&self, job: u64, spec: &JobSpec) -> Result<(), StoreError> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        self.db
            .execute(
                "UPDATE jobs SET spec = ?1 WHERE id = ?2",
                params![spec_json, job as i64],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn set_state(&self, job: u64, state: JobState, error: Option<&str>) -> Result<(), StoreError> {
        self.db
            .execute(
                "UPDATE jobs SET state = ?1, error = ?2 WHERE id = ?3",
                params![state.as_str(), error, job as i64],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn tiles(&self, job: u64, legacy_samples: u32) -> Result<Vec<KeptTile>, StoreError> {
        let mut stmt = self
            .db
            .prepare("SELECT idx, samples, exr, unchecked_by FROM tile_passes WHERE job = ?1")
            .map_err(failed)?;
        let mut tiles: Vec<KeptTile> = stmt
            .query_map([job as i64], |r| {
                let by: String = r.get(3)?;
                Ok(KeptTile {
                    idx: r.get::<_, i64>(0)? as usize,
                    samples: r.get::<_, i64>(1)? as u32,
                    exr: r.get(2)?,
                    unchecked_by: serde_json::from_str(&by).unwrap_or_default(),
                    legacy: false,
                })
            })
            .map_err(failed)?
            .filter_map(|r| r.ok())
            .collect();
        let mut legacy = self
            .db
            .prepare("SELECT idx, exr FROM tiles WHERE job = ?1")
            .map_err(failed)?;
        tiles.extend(
            legacy
                .query_map([job as i64], |r| {
                    Ok(KeptTile {
                        idx: r.get::<_, i64>(0)? as usize,
                        samples: legacy_samples,
                        exr: r.get(1)?,
                        unchecked_by: Default::default(),
                        legacy: true,
                    })
                })
                .map_err(failed)?
                .filter_map(|r| r.ok()),
        );
        Ok(tiles)
    }

    fn tile(&self, job: u64, idx: usize, samples: u32) -> Result<Option<Vec<u8>>, StoreError> {
        self.db
            .query_row(
                "SELECT exr FROM tile_passes WHERE job = ?1 AND idx = ?2 AND samples = ?3",
                params![job as i64, idx as i64, samples],
                |r| r.get(0),
            )
            .optional()
            .map_err(failed)
    }

    fn holds_tile(&self, job: u64, idx: usize, exr: &[u8]) -> Result<bool, StoreError> {
        let found: Option<i64> = self
            .db
            .query_row(
                "SELECT 1 FROM tile_passes WHERE job = ?1 AND idx = ?2 AND exr = ?3
                 UNION ALL SELECT 1 FROM tiles WHERE job = ?1 AND idx = ?2 AND exr = ?3 LIMIT 1",
                params![job as i64, idx as i64, exr],
                |r| r.get(0),
            )
            .optional()
            .map_err(failed)?;
        Ok(found.is_some())
    }

    fn insert_tile(
        &self,
        job: u64,
        idx: usize,
        samples: u32,
        exr: &[u8],
        unchecked_by: &BTreeSet<String>,
    ) -> Result<(), StoreError> {
        let by = serde_json::to_string(unchecked_by).expect("names serialize");
        self.db
            .execute(
                "INSERT OR IGNORE INTO tile_passes (job, idx, samples, exr, unchecked_by) VALUES (?1, ?2, ?3, ?4, ?5)",
                params![job as i64, idx as i64, samples, exr, by],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn drop_tiles(&self, job: u64, tiles: &[usize]) -> Result<(), StoreError> {
        let tx = self.db.unchecked_transaction().map_err(failed)?;
        for &t in tiles {
            for sql in [
                "DELETE FROM tile_passes WHERE job = ?1 AND idx = ?2",
                "DELETE FROM tiles WHERE job = ?1 AND idx = ?2",
            ] {
                tx.execute(sql, params![job as i64, t as i64])
                    .map_err(failed)?;
            }
        }
        tx.commit().map_err(failed)
    }

    fn drop_passes_before(&self, job: u64, samples: u32) -> Result<(), StoreError> {
        self.db
            .execute(
                "DELETE FROM tile_passes WHERE job = ?1 AND samples < ?2",
                params![job as i64, samples],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn add_verified(&self, job: u64) -> Result<(), StoreError> {
        self.db
            .execute(
                "INSERT INTO job_notes (job, verified) VALUES (?1, 1)
                 ON CONFLICT (job) DO UPDATE SET verified = verified + 1",
                [job as i64],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn verified(&self, job: u64) -> Result<u64, StoreError> {
        Ok(self.note(job, "verified")? as u64)
    }

    fn webhook(&self, job: u64) -> Result<WebhookOutcome, StoreError> {
        Ok(match self.note(job, "webhook")? {
            1 => WebhookOutcome::Delivered,
            2 => WebhookOutcome::GaveUp,
            _ => WebhookOutcome::Pending,
        })
    }

    fn set_webhook(&self, job: u64, outcome: WebhookOutcome) -> Result<(), StoreError> {
        self.set_note(job, "webhook", outcome as i64)
    }

    fn set_aside(&self, worker: &str, reason: &str) -> Result<(), StoreError> {
        self.db
            .execute(
                "INSERT OR IGNORE INTO set_aside (worker, reason) VALUES (?1, ?2)",
                params![worker, reason],
            )
            .map_err(failed)?;
        Ok(())
    }

    fn insert_token(&self, role: Role, name: &str, hash: &str) -> Result<u64, StoreError> {
        self.db
            .execute(
                "INSERT INTO tokens (role, name, hash) VALUES (?1, ?2, ?3)",
                params![role.as_str(), name, hash],
            )
            .map_err(failed)?;
        Ok(self.db.last_insert_rowid() as u64)
    }

    fn revoke_token(&self, id: u64) -> Result<bool, StoreError> {
        let n = self
            .db
            .execute("UPDATE tokens SET revoked = 1 WHERE id = ?1", [id as i64])
            .map_err(failed)?;
        Ok(n > 0)
    }

    fn tokens(&self) -> Result<Vec<StoredToken>, StoreError> {
        let mut q = self
            .db
            .prepare("SELECT id, role, name, hash, revoked FROM tokens ORDER BY id")
            .map_err(failed)?;
        let rows = q
            .query_map([], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, String>(3)?,
                    r.get::<_, bool>(4)?,
                ))
            })
            .map_err(failed)?;
        let mut out = Vec::new();
        for row in rows {
            let (id, role, name, hash, revoked) = row.map_err(failed)?;
            // A role this Kiln does not know (a newer one's) grants nothing.
            let role = match role.as_str() {
                "admin" => Role::Admin,
                "submitter" => Role::Submitter,
                "worker" => Role::Worker,
                _ => continue,
            };
            out.push(StoredToken {
                id: id as u64,
                role,
                name,
                hash,
                revoked,
            });
        }
        Ok(out)
    }

    fn reinstate(&self, worker: &str) -> Result<(), StoreError> {
        self.db
            .execute("DELETE FROM set_aside WHERE worker = ?1", [worker])
            .map_err(failed)?;
        Ok(())
    }

    fn set_aside_workers(&self) -> Result<Vec<(String, String)>, StoreError> {
        let mut stmt = self
            .db
            .prepare("SELECT worker, reason FROM set_aside ORDER BY worker")
            .map_err(failed)?;
        let rows = stmt
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(failed)?;
        rows.collect::<Result<_, _>>().map_err(failed)
    }
}

#[cfg(test)]
mod tests;
