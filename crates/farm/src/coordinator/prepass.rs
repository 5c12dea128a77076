//! What a job's workers compute once and share: its photon maps and SPPM's photon passes.
//! Each is a pure function of the job (its scene bundle and overrides), so whichever worker
//! computes it uploads the same bytes. They are kept beside the scene bundle, in
//! `scenes/<digest>.prepass/<name>`, under a name the workers derive from the job's inputs,
//! and served with the SHA-256 of their bytes, which the upload had to give and match.
//!
//! A claim says who is computing what is not stored yet, so the others wait for it (or
//! compute the passes nobody has claimed) instead of computing it too. Claims live in
//! memory only: after a restart, or [`CLAIM_TTL`] after a claim whose worker went quiet,
//! the next worker to ask computes it; a worker that cannot upload what it computed gives
//! its claim up.

use super::{Coordinator, Error};
use crate::api::PrepassClaim;
use crate::bundle;
use axum::body::Bytes;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;
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

    /// A stored pre-pass's bytes.
    pub async fn prepass(&self, scene: &str, name: &str) -> Result<Vec<u8>, Error> {
        let path = self.prepass_path(scene, name)?;
        tokio::fs::read(&path)
            .await
            .map_err(|_| Error::UnknownPrepass(name.to_string()))
    }

    /// Keeps an uploaded pre-pass whose bytes have the SHA-256 `sha` (hex): to a temporary
    /// file, then renamed into place, so a reader sees all of it or none. A second upload
    /// of the same name replaces it with the same bytes.
    pub async fn save_prepass(
        &self,
        scene: &str,
        name: &str,
        bytes: Bytes,
        sha: &str,
    ) -> Result<(), Error> {
        let path = self.prepass_path(scene, name)?;
        let this = self.clone();
        let key = (scene.to_string(), name.to_string());
        let sha = sha.to_ascii_lowercase();
        tokio::task::spawn_blocking(move || {
            if bundle::digest_of(&bytes) != sha {
                return Err(Error::PrepassDigest);
            }
            let dir = path.parent().expect("a pre-pass has a folder");
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            let tmp = this.files().upload_path();
            std::fs::write(&tmp, &bytes).map_err(|e| Error::io(&tmp, e))?;
            std::fs::rename(&tmp, &path).map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                Error::io(&path, e)
            })?;
            this.claims().0.remove(&key);
            Ok(())
        })
        .await?
    }

    /// Who computes a pre-pass: ready if stored; else the asker, unless another worker
    /// claimed it within [`CLAIM_TTL`].
    pub fn claim_prepass(&self, scene: &str, name: &str) -> Result<PrepassClaim, Error> {
        let path = self.prepass_path(scene, name)?;
        if path.exists() {
            return Ok(PrepassClaim::Ready);
        }
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
