//! The job store: what survives a restart. Jobs and every finished tile pass's EXR (with
//! its running sums) live in SQLite (`kiln.sqlite`, [`Store`]); scene bundles (unpacked under `scenes/<digest>`) and
//! merged frames (`jobs/<id>/result.exr`) are files ([`DataDir`]), written atomically.
//!
//! It records and reads back; it must never decide anything about jobs or leases, and it
//! keeps no state in memory beyond the connection.

use super::Error;
use super::job::KeptTile;
use crate::api::{JobSpec, JobState};
use crate::bundle;
use rusqlite::{Connection, OptionalExtension, params};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The data directory's layout. Cheap to clone; needs no lock.
#[derive(Debug, Clone)]
pub(super) struct DataDir {
    root: PathBuf,
}

impl DataDir {
    /// Creates the directory and its `scenes/` and `jobs/` folders if they are missing.
    pub fn create(root: &Path) -> Result<DataDir, Error> {
        let dir = DataDir {
            root: root.to_path_buf(),
        };
        for sub in [dir.scenes(), dir.root.join("jobs")] {
            std::fs::create_dir_all(&sub).map_err(|e| Error::io(&sub, e))?;
        }
        Ok(dir)
    }

    /// Where bundles are unpacked, one folder per digest (see [`bundle::unpack_into_cache`]).
    pub fn scenes(&self) -> PathBuf {
        self.root.join("scenes")
    }

    /// The ids of the jobs whose folders (`jobs/<id>`, a merged frame) are in the data
    /// directory.
    pub fn job_folders(&self) -> Result<Vec<u64>, Error> {
        let jobs = self.root.join("jobs");
        let entries = std::fs::read_dir(&jobs).map_err(|e| Error::io(&jobs, e))?;
        let mut ids: Vec<u64> = entries
            .flatten()
            .filter_map(|e| e.file_name().to_str()?.parse().ok())
            .collect();
        ids.sort_unstable();
        Ok(ids)
    }

    /// A private file name for an upload in progress (beside the bundles it becomes one of).
    pub fn upload_path(&self) -> PathBuf {
        static UNIQUE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = UNIQUE.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.scenes()
            .join(format!(".upload.{}.{n}", std::process::id()))
    }

    pub fn result_path(&self, job: u64) -> PathBuf {
        self.root
            .join("jobs")
            .join(job.to_string())
            .join("result.exr")
    }

    /// Keeps a bundle (unpacked, with its bytes for workers) unless it is kept already, and
    /// returns its digest. Blocking.
    pub fn save_bundle(&self, bytes: &[u8]) -> Result<String, Error> {
        let digest = bundle::digest_of(bytes);
        self.save_bundle_from(bundle::Source::Bytes(bytes), &digest)?;
        Ok(digest)
    }

    /// Keeps a bundle whose digest is known (an upload hashed as it streamed to disk).
    /// Blocking.
    pub fn save_bundle_from(&self, source: bundle::Source, digest: &str) -> Result<(), Error> {
        match bundle::unpack_into_cache(source, digest, &self.scenes(), true) {
            Ok(_) => Ok(()),
            Err(e @ bundle::BundleError::Corrupt(_)) => Err(Error::BadBundle(e)),
            Err(e) => Err(Error::Unpack(e)),
        }
    }

    /// A kept bundle's bytes, as uploaded.
    pub async fn bundle(&self, digest: &str) -> Result<Vec<u8>, Error> {
        if !bundle::is_digest(digest) {
            return Err(Error::BadDigest);
        }
        let path = self.scenes().join(digest).join(bundle::BUNDLE_FILE);
        tokio::fs::read(path)
            .await
            .map_err(|_| Error::UnknownScene(digest.to_string()))
    }

    /// Writes a job's merged EXR after pass `pass` beside its result, synced, and returns
    /// where: [`DataDir::publish_result`] then renames it over the result, so a reader or a
    /// crash sees one whole file or the other. Blocking.
    pub fn stage_result(&self, job: u64, pass: u32, bytes: &[u8]) -> Result<PathBuf, Error> {
        let path = self
            .result_path(job)
            .with_extension(format!("pass-{pass}.tmp"));
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        let mut file = std::fs::File::create(&path).map_err(|e| Error::io(&path, e))?;
        file.write_all(bytes)
            .and_then(|()| file.sync_all())
            .map_err(|e| Error::io(&path, e))?;
        Ok(path)
    }

    /// Makes a staged merge the job's result (a rename: quick, and atomic).
    pub fn publish_result(&self, job: u64, staged: &Path) -> Result<(), Error> {
        let path = self.result_path(job);
        std::fs::rename(staged, &path).map_err(|e| Error::io(&path, e))
    }
}

/// A job as the store keeps it.
pub(super) struct StoredJob {
    pub id: u64,
    /// The job's spec, or why it cannot be read back.
    pub spec: Result<JobSpec, String>,
    pub state: JobState,
    pub error: Option<String>,
}

/// What became of a job's webhook call since the job last ended, as the store keeps it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum WebhookOutcome {
    /// Not answered yet: called after a restart.
    Pending = 0,
    Delivered = 1,
    /// Every call failed: not called again after a restart.
    GaveUp = 2,
}

/// The SQLite connection: one writer, used under the coordinator's lock.
pub(super) struct Store {
    db: Connection,
}

impl Store {
    pub fn open(dir: &DataDir) -> Result<Store, Error> {
        let db = Connection::open(dir.root.join("kiln.sqlite"))?;
        db.execute_batch(
            "PRAGMA journal_mode = WAL;
             PRAGMA synchronous = NORMAL;
             CREATE TABLE IF NOT EXISTS jobs (id INTEGER PRIMARY KEY, spec TEXT NOT NULL, state TEXT NOT NULL, error TEXT, idempotency_key TEXT UNIQUE);
             CREATE TABLE IF NOT EXISTS tiles (job INTEGER NOT NULL, idx INTEGER NOT NULL, exr BLOB NOT NULL, PRIMARY KEY (job, idx));
             CREATE TABLE IF NOT EXISTS tile_passes (job INTEGER NOT NULL, idx INTEGER NOT NULL, samples INTEGER NOT NULL, exr BLOB NOT NULL, unchecked_by TEXT NOT NULL DEFAULT '[]', PRIMARY KEY (job, idx, samples));
             CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
             CREATE TABLE IF NOT EXISTS set_aside (worker TEXT PRIMARY KEY, reason TEXT NOT NULL);",
        )?;
        Ok(Store { db })
    }

    /// Counts this opening of the store: 1 the first time, then one more at each restart,
    /// committed before it is returned. Lease ids carry it, so an id from before a restart
    /// never names a lease granted after it.
    pub fn next_epoch(&self) -> Result<u64, Error> {
        let epoch: i64 = self.db.query_row(
            "INSERT INTO meta (key, value) VALUES ('epoch', 1)
             ON CONFLICT (key) DO UPDATE SET value = value + 1
             RETURNING value",
            [],
            |row| row.get(0),
        )?;
        Ok(epoch as u64)
    }

    /// Every job, oldest first. A state the store does not know reads as failed.
    ///
    /// A row that cannot be read back (a damaged spec, a value of the wrong type) is
    /// returned with `spec` as the reason, so that the job can be reported failed while
    /// the others resume.
    pub fn jobs(&self) -> Result<Vec<StoredJob>, Error> {
        let mut stmt = self
            .db
            .prepare("SELECT id, spec, state, error FROM jobs ORDER BY id")?;
        let rows = stmt.query_map([], |r| {
            let id = r.get::<_, i64>(0)? as u64;
            let fields = (|| {
                Ok::<_, rusqlite::Error>((
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, Option<String>>(3)?,
                ))
            })();
            Ok((id, fields))
        })?;
        let mut jobs = Vec::new();
        for row in rows {
            let (id, fields) = row?;
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

    /// A job's kept tile passes. Rows that cannot be read are left out. Tiles kept before
    /// passes existed (the `tiles` table) come as passes of `legacy_samples`.
    pub fn tiles(&self, job: u64, legacy_samples: u32) -> Result<Vec<KeptTile>, Error> {
        let mut stmt = self
            .db
            .prepare("SELECT idx, samples, exr, unchecked_by FROM tile_passes WHERE job = ?1")?;
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
            })?
            .filter_map(|r| r.ok())
            .collect();
        let mut legacy = self
            .db
            .prepare("SELECT idx, exr FROM tiles WHERE job = ?1")?;
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
                })?
                .filter_map(|r| r.ok()),
        );
        Ok(tiles)
    }

    /// Forgets every kept pass of the job's `tiles`: they are rendered again from nothing.
    pub fn drop_tiles(&self, job: u64, tiles: &[usize]) -> Result<(), Error> {
        let tx = self.db.unchecked_transaction()?;
        for &t in tiles {
            tx.execute(
                "DELETE FROM tile_passes WHERE job = ?1 AND idx = ?2",
                params![job as i64, t as i64],
            )?;
            tx.execute(
                "DELETE FROM tiles WHERE job = ?1 AND idx = ?2",
                params![job as i64, t as i64],
            )?;
        }
        tx.commit()?;
        Ok(())
    }

    /// Records that `worker` is set aside for `reason` (the first reason stays), so that a
    /// restarted coordinator does not trust it again.
    pub fn set_aside(&self, worker: &str, reason: &str) -> Result<(), Error> {
        self.db.execute(
            "INSERT OR IGNORE INTO set_aside (worker, reason) VALUES (?1, ?2)",
            params![worker, reason],
        )?;
        Ok(())
    }

    /// Forgets that `worker` was set aside (an operator reinstated it).
    pub fn reinstate(&self, worker: &str) -> Result<(), Error> {
        self.db
            .execute("DELETE FROM set_aside WHERE worker = ?1", [worker])?;
        Ok(())
    }

    /// Every worker set aside, with the reason.
    pub fn set_aside_workers(&self) -> Result<Vec<(String, String)>, Error> {
        let mut stmt = self
            .db
            .prepare("SELECT worker, reason FROM set_aside ORDER BY worker")?;
        let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Counts a tile pass of the job that two workers agreed on.
    pub fn add_verified(&self, job: u64) -> Result<(), Error> {
        self.db.execute(
            "INSERT INTO meta (key, value) VALUES (?1, 1)
             ON CONFLICT (key) DO UPDATE SET value = value + 1",
            [format!("verified:{job}")],
        )?;
        Ok(())
    }

    /// What became of the job's webhook call since the job last ended.
    pub fn webhook(&self, job: u64) -> Result<WebhookOutcome, Error> {
        let v = self
            .db
            .query_row(
                "SELECT value FROM meta WHERE key = ?1",
                [format!("webhook:{job}")],
                |r| r.get::<_, i64>(0),
            )
            .optional()?;
        Ok(match v {
            Some(1) => WebhookOutcome::Delivered,
            Some(2) => WebhookOutcome::GaveUp,
            _ => WebhookOutcome::Pending,
        })
    }

    /// Records what became of the job's webhook call (or, with `Pending`, that it must be
    /// called again: the job runs again).
    pub fn set_webhook(&self, job: u64, outcome: WebhookOutcome) -> Result<(), Error> {
        self.db.execute(
            "INSERT INTO meta (key, value) VALUES (?1, ?2)
             ON CONFLICT (key) DO UPDATE SET value = ?2",
            params![format!("webhook:{job}"), outcome as i64],
        )?;
        Ok(())
    }

    /// How many of the job's tile passes two workers agreed on.
    pub fn verified(&self, job: u64) -> Result<u64, Error> {
        Ok(self
            .db
            .query_row(
                "SELECT value FROM meta WHERE key = ?1",
                [format!("verified:{job}")],
                |r| r.get::<_, i64>(0),
            )
            .optional()?
            .unwrap_or(0) as u64)
    }

    /// The EXR kept for a tile after `samples` samples.
    pub fn tile(&self, job: u64, idx: usize, samples: u32) -> Result<Option<Vec<u8>>, Error> {
        Ok(self
            .db
            .query_row(
                "SELECT exr FROM tile_passes WHERE job = ?1 AND idx = ?2 AND samples = ?3",
                params![job as i64, idx as i64, samples],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Whether `exr` is, byte for byte, one kept for the tile (any pass, or from before
    /// passes existed).
    pub fn holds_tile(&self, job: u64, idx: usize, exr: &[u8]) -> Result<bool, Error> {
        let found: Option<i64> = self
            .db
            .query_row(
                "SELECT 1 FROM tile_passes WHERE job = ?1 AND idx = ?2 AND exr = ?3
                 UNION ALL SELECT 1 FROM tiles WHERE job = ?1 AND idx = ?2 AND exr = ?3 LIMIT 1",
                params![job as i64, idx as i64, exr],
                |r| r.get(0),
            )
            .optional()?;
        Ok(found.is_some())
    }

    /// Forgets a job's tile passes of fewer than `samples` samples: once every tile has done
    /// the pass of `samples`, nothing continues from them or pastes them again.
    pub fn drop_passes_before(&self, job: u64, samples: u32) -> Result<(), Error> {
        self.db.execute(
            "DELETE FROM tile_passes WHERE job = ?1 AND samples < ?2",
            params![job as i64, samples],
        )?;
        Ok(())
    }

    /// The job created earlier under this idempotency key.
    pub fn job_with_key(&self, key: &str) -> Result<Option<u64>, Error> {
        Ok(self
            .db
            .query_row(
                "SELECT id FROM jobs WHERE idempotency_key = ?1",
                [key],
                |r| r.get::<_, i64>(0),
            )
            .optional()?
            .map(|id| id as u64))
    }

    /// Records a new running job; returns its id.
    pub fn insert_job(&self, spec: &JobSpec, key: Option<&str>) -> Result<u64, Error> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        self.db.execute(
            "INSERT INTO jobs (spec, state, idempotency_key) VALUES (?1, 'running', ?2)",
            params![spec_json, key],
        )?;
        Ok(self.db.last_insert_rowid() as u64)
    }

    /// Keeps a tile's EXR after `samples` samples. The first one kept for a tile's pass
    /// stays.
    pub fn insert_tile(
        &self,
        job: u64,
        idx: usize,
        samples: u32,
        exr: &[u8],
        unchecked_by: &std::collections::BTreeSet<String>,
    ) -> Result<(), Error> {
        let by = serde_json::to_string(unchecked_by).expect("names serialize");
        self.db.execute(
            "INSERT OR IGNORE INTO tile_passes (job, idx, samples, exr, unchecked_by) VALUES (?1, ?2, ?3, ?4, ?5)",
            params![job as i64, idx as i64, samples, exr, by],
        )?;
        Ok(())
    }

    /// Records a job's changed spec (its passes stopped early or extended).
    pub fn set_spec(&self, job: u64, spec: &JobSpec) -> Result<(), Error> {
        let spec_json = serde_json::to_string(spec).expect("a JobSpec serializes");
        self.db.execute(
            "UPDATE jobs SET spec = ?1 WHERE id = ?2",
            params![spec_json, job as i64],
        )?;
        Ok(())
    }

    pub fn set_state(&self, job: u64, state: JobState, error: Option<&str>) -> Result<(), Error> {
        self.db.execute(
            "UPDATE jobs SET state = ?1, error = ?2 WHERE id = ?3",
            params![state.as_str(), error, job as i64],
        )?;
        Ok(())
    }
}
