//! What a job's workers compute once and share: its photon maps and SPPM's photon passes.
//! Each is a pure function of the job (its scene bundle and overrides), so whichever worker
//! computes it uploads the same bytes. They are kept beside the scene bundle, in
//! `scenes/<digest>.prepass/<name>`, under a name the workers derive from the job's inputs,
//! and served with the SHA-256 of their bytes, which the upload had to give and match.
//!
//! Only the names a job of the scene can share are taken (its photon maps, its SPPM
//! passes, named after the job's inputs: `api::is_prepass_of`), and an upload streams to
//! disk, hashed on the way, refused past `Config::max_prepass_bytes`: nothing a client
//! sends is held in memory whole.
//!
//! A claim says who is computing what is not stored yet, so the others wait for it (or
//! compute the passes nobody has claimed) instead of computing it too. Claims live in
//! memory only: after a restart, or [`CLAIM_TTL`] after a claim whose worker went quiet,
//! the next worker to ask computes it; a worker that cannot upload what it computed gives
//! its claim up.

use super::data_dir::{hex, receive_upload};
use super::{Coordinator, Error, Stored};
use crate::api::{PrepassClaim, is_prepass_of};
use crate::bundle;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncSeekExt};
use tokio::time::Instant;

/// How long a claim holds without the pre-pass arriving.
pub const CLAIM_TTL: Duration = Duration::from_secs(600);

/// Who claimed which (scene, name), and when.
#[derive(Default)]
pub struct Claims(HashMap<(String, String), Instant>);

/// A name a worker may give a pre-pass: it becomes a file name.
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 128
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
}

impl Coordinator {
    /// The folder of a scene's pre-passes, once the scene and the name are known good.
    fn prepass_path(&self, scene: &str, name: &str) -> Result<PathBuf, Error> {
        if !bundle::is_digest(scene) {
            return Err(Error::BadDigest);
        }
        if !valid_name(name) {
            return Err(Error::BadPrepassName);
        }
        let scenes = self.files().scenes();
        if bundle::cached_scene(&scenes, scene).is_none() {
            return Err(Error::UnknownScene(scene.to_string()));
        }
        Ok(scenes.join(format!("{scene}.prepass")).join(name))
    }

    /// Refuses a name no job of the scene can share: pre-passes are a job's, and a client
    /// must not store files under names of its choosing.
    fn check_wanted(&self, scene: &str, name: &str) -> Result<(), Error> {
        let state = self.lock();
        // Each frame of a shot has pre-passes of its own.
        let wanted = state.jobs.values().any(|j| {
            j.spec.scene == scene
                && (0..j.spec.frame_count()).any(|k| is_prepass_of(name, &j.spec.prepass_prefix(k)))
        });
        if wanted {
            Ok(())
        } else {
            Err(Error::UnwantedPrepass(name.to_string()))
        }
    }

    /// A stored pre-pass, opened, with the SHA-256 of its bytes (hex), read through once
    /// to hash them: a pre-pass may be hundreds of megabytes, and is never held whole.
    pub async fn prepass(&self, scene: &str, name: &str) -> Result<(Stored, String), Error> {
        let path = self.prepass_path(scene, name)?;
        // Computed for another coordinator of the farm: in the object store.
        let key = super::objects::keys::prepass(scene, name);
        let limit = self.config().max_prepass_bytes as u64;
        self.fetch_if_missing(path.clone(), key, limit).await?;
        let mut stored = Stored::open(&path)
            .await
            .map_err(|_| Error::UnknownPrepass(name.to_string()))?;
        let hashed = async {
            let mut hasher = Sha256::new();
            let mut buf = vec![0u8; 256 << 10];
            loop {
                let n = stored.file.read(&mut buf).await?;
                if n == 0 {
                    break;
                }
                hasher.update(&buf[..n]);
            }
            stored.file.seek(std::io::SeekFrom::Start(0)).await?;
            Ok::<_, std::io::Error>(hasher.finalize())
        };
        let digest = hashed.await.map_err(|e| Error::io(&path, e))?;
        Ok((stored, hex(&digest)))
    }

    /// Keeps an uploaded pre-pass whose bytes have the SHA-256 `sha` (hex): streamed to a
    /// temporary file and hashed on the way (at most `max_prepass_bytes`), then renamed
    /// into place, so a reader sees all of it or none. A second upload of the same name
    /// replaces it with the same bytes.
    pub async fn save_prepass(
        &self,
        scene: &str,
        name: &str,
        body: axum::body::Body,
        sha: &str,
    ) -> Result<(), Error> {
        let path = self.prepass_path(scene, name)?;
        self.check_wanted(scene, name)?;
        let limit = self.config().max_prepass_bytes;
        let tmp = self.files().upload_path();
        let received = async {
            let digest = receive_upload(body, &tmp, limit).await?;
            if digest != sha.to_ascii_lowercase() {
                return Err(Error::PrepassDigest);
            }
            // In the object store before it is ready here.
            self.keep_file(tmp.clone(), super::objects::keys::prepass(scene, name))
                .await?;
            let dir = path.parent().expect("a pre-pass has a folder");
            tokio::fs::create_dir_all(dir)
                .await
                .map_err(|e| Error::io(dir, e))?;
            tokio::fs::rename(&tmp, &path)
                .await
                .map_err(|e| Error::io(&path, e))
        }
        .await;
        if received.is_err() {
            let _ = tokio::fs::remove_file(&tmp).await;
        }
        received?;
        self.claims()
            .0
            .remove(&(scene.to_string(), name.to_string()));
        Ok(())
    }

    /// Who computes a pre-pass: ready if stored; else the asker, unless another worker
    /// claimed it within [`CLAIM_TTL`].
    pub fn claim_prepass(&self, scene: &str, name: &str) -> Result<PrepassClaim, Error> {
        let path = self.prepass_path(scene, name)?;
        if path.exists() {
            return Ok(PrepassClaim::Ready);
        }
        if let Some(objects) = &self.shared.objects {
            let key = super::objects::keys::prepass(scene, name);
            if objects
                .exists(&key)
                .map_err(|e| Error::Objects(e.to_string()))?
            {
                return Ok(PrepassClaim::Ready);
            }
        }
        self.check_wanted(scene, name)?;
        let mut claims = self.claims();
        let now = self.now();
        // Lapsed claims go, so that names asked for and never uploaded do not pile up.
        claims
            .0
            .retain(|_, since| now.duration_since(*since) < CLAIM_TTL);
        let key = (scene.to_string(), name.to_string());
        match claims.0.get(&key) {
            Some(since) if now.duration_since(*since) < CLAIM_TTL => Ok(PrepassClaim::Theirs),
            _ => {
                claims.0.insert(key, now);
                Ok(PrepassClaim::Yours)
            }
        }
    }

    /// Gives a claim up (its worker could not upload what it computed, say larger than
    /// this coordinator accepts): the next worker to ask computes it, without waiting for
    /// the claim to lapse.
    pub fn release_prepass(&self, scene: &str, name: &str) -> Result<(), Error> {
        self.prepass_path(scene, name)?;
        self.claims()
            .0
            .remove(&(scene.to_string(), name.to_string()));
        Ok(())
    }

    fn claims(&self) -> std::sync::MutexGuard<'_, Claims> {
        self.shared
            .prepass_claims
            .lock()
            .unwrap_or_else(|e| e.into_inner())
    }
}
