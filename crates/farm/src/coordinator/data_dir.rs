//! The data directory's files: scene bundles (unpacked under `scenes/<digest>`, with their
//! bytes for workers) and merged frames (`jobs/<id>/result.exr`), written atomically. The
//! job store's database lives beside them (`kiln.sqlite`, see `store/`).
//!
//! It reads and writes files; it must never decide anything about jobs or leases.

use super::{Error, Stored};
use crate::bundle;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes an upload's `body` to `path` as it arrives, hashing it chunk by chunk and
/// refusing it as soon as it passes `limit` bytes; returns its SHA-256 in hex. What it
/// wrote is left for the caller to rename or remove.
pub(super) async fn receive_upload(
    body: axum::body::Body,
    path: &Path,
    limit: usize,
) -> Result<String, Error> {
    use sha2::{Digest, Sha256};
    use tokio::io::AsyncWriteExt;
    use tokio_stream::StreamExt;
    let mut file = tokio::fs::File::create(path)
        .await
        .map_err(|e| Error::io(path, e))?;
    let (mut hasher, mut total) = (Sha256::new(), 0usize);
    let mut chunks = body.into_data_stream();
    while let Some(chunk) = chunks.next().await {
        let chunk = chunk.map_err(|e| Error::BrokenUpload(e.to_string()))?;
        total += chunk.len();
        if total > limit {
            return Err(Error::TooLarge { limit });
        }
        hasher.update(&chunk);
        file.write_all(&chunk)
            .await
            .map_err(|e| Error::io(path, e))?;
    }
    file.flush().await.map_err(|e| Error::io(path, e))?;
    Ok(hex(&hasher.finalize()))
}

/// Bytes as lower-case hex.
pub(super) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

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
        dir.remove_leftovers();
        Ok(dir)
    }

    /// Removes what a coordinator that stopped mid-write left behind: uploads in progress
    /// (`scenes/.upload.*`), bundles half unpacked (`scenes/.<digest>.*.tmp`) and merged
    /// frames half written (`jobs/<id>/*.tmp`). None of them is anything's only copy: an
    /// upload was never acknowledged, and a frame is merged again from the kept tiles.
    fn remove_leftovers(&self) {
        let entries = |dir: &Path| -> Vec<std::fs::DirEntry> {
            std::fs::read_dir(dir)
                .map(|d| d.flatten().collect())
                .unwrap_or_default()
        };
        for e in entries(&self.scenes()) {
            let name = e.file_name();
            let name = name.to_string_lossy();
            let half_unpacked = name.starts_with('.') && name.ends_with(".tmp");
            if name.starts_with(".upload.") || half_unpacked {
                let path = e.path();
                let removed = if path.is_dir() {
                    std::fs::remove_dir_all(&path)
                } else {
                    std::fs::remove_file(&path)
                };
                match removed {
                    Ok(()) => tracing::info!("removed {}, left by an earlier run", path.display()),
                    Err(err) => tracing::warn!("cannot remove {}: {err}", path.display()),
                }
            }
        }
        for job in entries(&self.root.join("jobs")) {
            for e in entries(&job.path()) {
                let path = e.path();
                if path.extension().is_some_and(|x| x == "tmp") {
                    match std::fs::remove_file(&path) {
                        Ok(()) => {
                            tracing::info!("removed {}, left by an earlier run", path.display())
                        }
                        Err(err) => tracing::warn!("cannot remove {}: {err}", path.display()),
                    }
                }
            }
        }
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

    /// The job store's database file.
    pub fn database(&self) -> PathBuf {
        self.root.join("kiln.sqlite")
    }

    /// Where job `job`'s frame `frame` is merged: `jobs/<id>/result.exr` for the first (a
    /// job of one frame has only it), `jobs/<id>/frame-<k>.exr` for the others of a shot.
    pub fn result_path(&self, job: u64, frame: u32) -> PathBuf {
        let name = match frame {
            0 => "result.exr".to_string(),
            k => format!("frame-{k}.exr"),
        };
        self.root.join("jobs").join(job.to_string()).join(name)
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
    pub async fn bundle(&self, digest: &str) -> Result<Stored, Error> {
        if !bundle::is_digest(digest) {
            return Err(Error::BadDigest);
        }
        let path = self.scenes().join(digest).join(bundle::BUNDLE_FILE);
        Stored::open(&path)
            .await
            .map_err(|_| Error::UnknownScene(digest.to_string()))
    }

    /// Writes a job's merged EXR after pass `pass` beside its result, synced, and returns
    /// where: [`DataDir::publish_result`] then renames it over the result, so a reader or a
    /// crash sees one whole file or the other. Blocking.
    pub fn stage_result(
        &self,
        job: u64,
        frame: u32,
        pass: u32,
        bytes: &[u8],
    ) -> Result<PathBuf, Error> {
        let path = self
            .result_path(job, frame)
            .with_extension(format!("pass-{pass}.tmp"));
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        let mut file = std::fs::File::create(&path).map_err(|e| Error::io(&path, e))?;
        if let Err(e) = file.write_all(bytes).and_then(|()| file.sync_all()) {
            // A half-written frame (a full disk) is no use to anyone.
            drop(file);
            let _ = std::fs::remove_file(&path);
            return Err(Error::io(&path, e));
        }
        Ok(path)
    }

    /// Makes a staged merge the job's result (a rename: quick, and atomic).
    pub fn publish_result(&self, job: u64, frame: u32, staged: &Path) -> Result<(), Error> {
        let path = self.result_path(job, frame);
        std::fs::rename(staged, &path).map_err(|e| Error::io(&path, e))
    }
}
