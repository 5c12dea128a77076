//! Objects in S3-compatible storage (`--objects s3://bucket/prefix`): scene bundles,
//! pre-pass files and merged frames, kept where every coordinator of a farm finds them, so
//! that a standby on another host can take the lead with nothing on its disk. The data
//! directory stays the working copy: what is written goes there and here; what is needed
//! and missing there is fetched from here.
//!
//! Every object is written with a sidecar `<key>.sha256` (its SHA-256, written after it),
//! and every read checks the bytes against it: a damaged or half-written object is an
//! error, never a scene or a frame. Objects past 16 MiB are sent in parts (multipart
//! upload). Requests are retried with backoff for up to a minute, so that an outage of the
//! server shorter than that costs only time; a longer one is an error that names the store.
//!
//! The client (Apache Arrow's `object_store`) is async; it runs on a runtime of its own,
//! and the methods here block their caller, from any thread, as the job store's do.

use axum::body::Bytes;
use object_store::aws::AmazonS3Builder;
use object_store::path::Path as Key;
use object_store::{ObjectStore, ObjectStoreExt, PutPayload, WriteMultipart};
use sha2::{Digest, Sha256};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

/// Objects larger than this are uploaded in parts of this size.
const PART_BYTES: usize = 16 << 20;

/// The most bytes a merged frame's object may hold for a frame of `pixels`: four float
/// channels a pixel and room for the EXR's header and offsets, which no frame Kiln writes
/// reaches.
pub(super) fn frame_limit(pixels: u64) -> u64 {
    pixels.saturating_mul(16).saturating_add(64 << 20)
}

/// A bucket (and prefix) of an S3-compatible server.
pub(super) struct Objects {
    store: Arc<dyn ObjectStore>,
    /// Always Some until dropped (taken then, to be shut down without blocking).
    runtime: Option<tokio::runtime::Runtime>,
    /// The URL it was opened with, as errors name it.
    url: String,
}

/// Why an object could not be written or read: the store and the object, and the reason.
#[derive(Debug, Clone, thiserror::Error)]
#[error("the object store {url}, {key}: {why}")]
pub struct ObjectsError {
    url: String,
    key: String,
    why: String,
}

impl Objects {
    /// The bucket of `url` (`s3://bucket` or `s3://bucket/prefix`), reached through the
    /// endpoint and credentials of the usual AWS_* variables (AWS_ENDPOINT,
    /// AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY, AWS_REGION, AWS_ALLOW_HTTP for an http
    /// endpoint).
    pub fn open(url: &str) -> Result<Objects, String> {
        // The client options set below replace those from_env read: AWS_ALLOW_HTTP is
        // applied again (or an http endpoint, such as a server on the farm's network).
        let http = ["AWS_ALLOW_HTTP"]
            .iter()
            .any(|v| std::env::var(v).is_ok_and(|x| x.eq_ignore_ascii_case("true") || x == "1"))
            || ["AWS_ENDPOINT", "AWS_ENDPOINT_URL"]
                .iter()
                .any(|v| std::env::var(v).is_ok_and(|x| x.starts_with("http://")));
        Objects::build(url, AmazonS3Builder::from_env(), http)
    }

    fn build(url: &str, builder: AmazonS3Builder, allow_http: bool) -> Result<Objects, String> {
        let rest = url
            .strip_prefix("s3://")
            .ok_or_else(|| format!("--objects '{url}' is not an s3://bucket/prefix URL"))?;
        let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(format!("--objects '{url}' names no bucket"));
        }
        crate::trust::install_provider();
        let retry = object_store::RetryConfig {
            max_retries: 12,
            retry_timeout: Duration::from_secs(60),
            ..Default::default()
        };
        // As every https peer of the farm, an https endpoint is trusted through the
        // certificates in KILN_TLS_CA only (never the platform's store, which a
        // FROM-scratch image lacks and whose verifier cannot even be built there).
        let mut options = object_store::ClientOptions::new()
            .with_connect_timeout(Duration::from_secs(5))
            .with_timeout(Duration::from_secs(120))
            .with_allow_http(allow_http)
            .with_no_system_certificates(true);
        if let Some(path) = std::env::var_os(crate::trust::TLS_CA_VAR) {
            let pem = std::fs::read(&path).map_err(|e| {
                format!(
                    "cannot read {}={}: {e}",
                    crate::trust::TLS_CA_VAR,
                    std::path::Path::new(&path).display()
                )
            })?;
            for root in object_store::Certificate::from_pem_bundle(&pem)
                .map_err(|e| format!("{}: {e}", crate::trust::TLS_CA_VAR))?
            {
                options = options.with_root_certificate(root);
            }
        }
        let s3 = builder
            .with_bucket_name(bucket)
            .with_retry(retry)
            .with_client_options(options)
            .build()
            .map_err(|e| format!("--objects '{url}': {e}"))?;
        let store: Arc<dyn ObjectStore> = match prefix.trim_matches('/') {
            "" => Arc::new(s3),
            p => Arc::new(object_store::prefix::PrefixStore::new(s3, p)),
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("kiln-objects")
            .enable_all()
            .build()
            .map_err(|e| format!("cannot start the object store's runtime: {e}"))?;
        Ok(Objects {
            store,
            runtime: Some(runtime),
            url: url.to_string(),
        })
    }

    /// Runs `f` on the store's runtime and waits for it, from any thread.
    fn block<T: Send + 'static>(
        &self,
        f: impl std::future::Future<Output = T> + Send + 'static,
    ) -> Option<T> {
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        self.runtime.as_ref()?.spawn(async move {
            let _ = tx.send(f.await);
        });
        rx.recv().ok()
    }

    fn error(&self, key: &str, why: impl ToString) -> ObjectsError {
        ObjectsError {
            url: self.url.clone(),
            key: key.to_string(),
            why: why.to_string(),
        }
    }

    /// Writes `bytes` as `key`, then its SHA-256 beside it.
    pub fn put(&self, key: &str, bytes: Bytes) -> Result<(), ObjectsError> {
        let store = self.store.clone();
        let path = Key::from(key);
        let sum = Key::from(format!("{key}.sha256"));
        let digest = hex(&Sha256::digest(&bytes));
        let done = self.block(async move {
            if bytes.len() > PART_BYTES {
                let upload = store.put_multipart(&path).await?;
                let mut parts = WriteMultipart::new_with_chunk_size(upload, PART_BYTES);
                parts.write(&bytes);
                parts.finish().await?;
            } else {
                store.put(&path, PutPayload::from(bytes)).await?;
            }
            store
                .put(&sum, PutPayload::from(digest.into_bytes()))
                .await?;
            Ok::<(), object_store::Error>(())
        });
        match done {
            Some(Ok(())) => Ok(()),
            Some(Err(e)) => Err(self.error(key, e)),
            None => Err(self.error(key, "the object store's runtime stopped")),
        }
    }

    /// The bytes of `key`, checked against its SHA-256; None when there is no such object.
    /// An object of more than `limit` bytes is refused before it is read.
    pub fn get(&self, key: &str, limit: u64) -> Result<Option<Vec<u8>>, ObjectsError> {
        /// What a read found.
        enum Found {
            Missing,
            TooLarge(u64),
            Whole(Vec<u8>, Vec<u8>),
        }
        let store = self.store.clone();
        let path = Key::from(key);
        let sum = Key::from(format!("{key}.sha256"));
        let got = self.block(async move {
            let digest = match store.get(&sum).await {
                // A SHA-256 in hex is 64 bytes: a larger sidecar is not one.
                Ok(r) if r.meta.size > 256 => return Ok(Found::TooLarge(r.meta.size)),
                Ok(r) => r.bytes().await?,
                Err(object_store::Error::NotFound { .. }) => return Ok(Found::Missing),
                Err(e) => return Err(e),
            };
            let object = store.get(&path).await?;
            if object.meta.size > limit {
                return Ok(Found::TooLarge(object.meta.size));
            }
            Ok(Found::Whole(
                object.bytes().await?.to_vec(),
                digest.to_vec(),
            ))
        });
        let (bytes, digest) = match got {
            Some(Ok(Found::Whole(bytes, digest))) => (bytes, digest),
            Some(Ok(Found::Missing)) => return Ok(None),
            Some(Ok(Found::TooLarge(size))) => {
                return Err(self.error(
                    key,
                    format!("it holds {size} bytes, more than the {limit} such an object may"),
                ));
            }
            Some(Err(e)) => return Err(self.error(key, e)),
            None => return Err(self.error(key, "the object store's runtime stopped")),
        };
        let have = hex(&Sha256::digest(&bytes));
        if have.as_bytes() != digest.trim_ascii() {
            return Err(self.error(
                key,
                format!(
                    "its bytes have SHA-256 {have}, not the {} written with them: damaged",
                    String::from_utf8_lossy(&digest)
                ),
            ));
        }
        Ok(Some(bytes))
    }

    /// Whether `key` was written whole (its SHA-256 is written last).
    pub fn exists(&self, key: &str) -> Result<bool, ObjectsError> {
        let store = self.store.clone();
        let sum = Key::from(format!("{key}.sha256"));
        match self.block(async move { store.head(&sum).await }) {
            Some(Ok(_)) => Ok(true),
            Some(Err(object_store::Error::NotFound { .. })) => Ok(false),
            Some(Err(e)) => Err(self.error(key, e)),
            None => Err(self.error(key, "the object store's runtime stopped")),
        }
    }
}

/// The object keys of what a farm keeps.
pub(super) mod keys {
    /// A scene bundle, by its digest.
    pub fn bundle(digest: &str) -> String {
        format!("bundles/{digest}")
    }

    /// A shared pre-pass file of a scene.
    pub fn prepass(scene: &str, name: &str) -> String {
        format!("prepass/{scene}/{name}")
    }

    /// A job's merged frame.
    pub fn frame(job: u64, frame: u32) -> String {
        format!("jobs/{job}/frame-{frame}.exr")
    }
}

fn hex(bytes: &[u8]) -> String {
    super::data_dir::hex(bytes)
}

#[cfg(test)]
mod tests;

impl Drop for Objects {
    fn drop(&mut self) {
        // The runtime may be dropped from a runtime's thread (a coordinator in a test),
        // where waiting for its threads is not allowed.
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_background();
        }
    }
}

/// What the coordinator keeps in and fetches from the object store, when it has one.
impl super::Coordinator {
    /// Writes `bytes` as `key` in the object store, if there is one. Blocking.
    pub(super) fn keep_object(&self, key: &str, bytes: Bytes) -> Result<(), super::Error> {
        match &self.shared.objects {
            Some(objects) => objects
                .put(key, bytes)
                .map_err(|e| super::Error::Objects(e.to_string())),
            None => Ok(()),
        }
    }

    /// Writes the file at `path` as `key` in the object store, if there is one, off the
    /// runtime's threads.
    pub(super) async fn keep_file(&self, path: PathBuf, key: String) -> Result<(), super::Error> {
        if self.shared.objects.is_none() {
            return Ok(());
        }
        self.off_runtime(move |c| {
            let bytes = std::fs::read(&path).map_err(|e| super::Error::io(&path, e))?;
            c.keep_object(&key, bytes.into())
        })
        .await
    }

    /// Fetches `key` from the object store into `path` when the data directory lacks it
    /// (the work of another coordinator of the farm), off the runtime's threads; nothing
    /// without an object store, or when neither has it.
    pub(super) async fn fetch_if_missing(
        &self,
        path: PathBuf,
        key: String,
        limit: u64,
    ) -> Result<(), super::Error> {
        if self.shared.objects.is_none() {
            return Ok(());
        }
        self.off_runtime(move |c| c.fetch_missing(&path, &key, limit))
            .await
    }

    /// Makes sure the bundle of `digest` is unpacked in the data directory, fetching it
    /// from the object store if it is not (a coordinator that took the lead on another
    /// host). Nothing happens for a digest the store does not hold either. Blocking.
    pub(super) fn ensure_bundle(&self, digest: &str) -> Result<(), super::Error> {
        let Some(objects) = &self.shared.objects else {
            return Ok(());
        };
        if !crate::bundle::is_digest(digest) || self.files().scenes().join(digest).is_dir() {
            return Ok(());
        }
        let key = keys::bundle(digest);
        let limit = self.config().max_scene_bytes as u64;
        let Some(bytes) = objects
            .get(&key, limit)
            .map_err(|e| super::Error::Objects(e.to_string()))?
        else {
            return Ok(());
        };
        if crate::bundle::digest_of(&bytes) != digest {
            return Err(super::Error::Objects(format!(
                "the object store {}, {key}: its bytes are not the bundle of that digest",
                objects.url
            )));
        }
        tracing::info!("fetched scene bundle {digest} from the object store");
        self.files()
            .save_bundle_from(crate::bundle::Source::Bytes(&bytes), digest)
    }

    /// Fetches `key` (at most `limit` bytes) from the object store into `path` unless the
    /// data directory has it. Blocking.
    fn fetch_missing(
        &self,
        path: &std::path::Path,
        key: &str,
        limit: u64,
    ) -> Result<(), super::Error> {
        let Some(objects) = &self.shared.objects else {
            return Ok(());
        };
        if path.exists() {
            return Ok(());
        }
        let Some(bytes) = objects
            .get(key, limit)
            .map_err(|e| super::Error::Objects(e.to_string()))?
        else {
            return Ok(());
        };
        let dir = path.parent().expect("a kept file has a folder");
        std::fs::create_dir_all(dir).map_err(|e| super::Error::io(dir, e))?;
        let tmp = path.with_extension("fetched.tmp");
        std::fs::write(&tmp, &bytes)
            .and_then(|()| std::fs::rename(&tmp, path))
            .map_err(|e| super::Error::io(path, e))?;
        tracing::info!("fetched {key} from the object store");
        Ok(())
    }
}
