//! The client's side of the coordinator handle: scenes uploaded and downloaded, jobs
//! created and cancelled, results, previews and metrics read.
//!
//! Each operation takes the lock only to read or record a few fields; parsing scenes,
//! unpacking bundles and encoding images happen outside it. Nothing here speaks HTTP.

use super::job::Job;
use super::metrics::Snapshot;
use super::store::WebhookOutcome;
use super::{Coordinator, Error, PlanError, Stored};
use crate::api::{FrameStatus, JobSpec, JobState, JobStatus, WorkerLease, WorkerStatus};

impl Coordinator {
    /// Keeps an uploaded scene bundle; returns its digest.
    pub async fn save_scene(&self, bundle: axum::body::Bytes) -> Result<String, Error> {
        self.off_runtime(move |c| {
            let digest = c.files().save_bundle(&bundle)?;
            c.keep_object(&super::objects::keys::bundle(&digest), bundle)?;
            Ok(digest)
        })
        .await
    }

    /// Keeps a scene bundle as it arrives: the body is written to a file and hashed chunk by
    /// chunk, refused past the configured size as soon as it passes it, and unpacked from
    /// the file, so no upload is ever held in memory whole. Nothing is left of a refused
    /// or broken upload.
    pub async fn save_scene_stream(&self, body: axum::body::Body) -> Result<String, Error> {
        let files = self.files().clone();
        let limit = self.config().max_scene_bytes;
        let path = files.upload_path();
        let received = super::data_dir::receive_upload(body, &path, limit).await;
        let saved = match received {
            Ok(digest) => {
                let (files, path2) = (files.clone(), path.clone());
                tokio::task::spawn_blocking(move || {
                    files
                        .save_bundle_from(crate::bundle::Source::File(&path2), &digest)
                        .map(|()| digest)
                })
                .await
                .map_err(Error::from)
                .and_then(|r| r)
            }
            Err(e) => Err(e),
        };
        let _ = tokio::fs::remove_file(&path).await;
        let digest = saved?;
        let kept = files
            .scenes()
            .join(&digest)
            .join(crate::bundle::BUNDLE_FILE);
        self.keep_file(kept, super::objects::keys::bundle(&digest))
            .await?;
        Ok(digest)
    }

    /// A kept scene bundle's bytes (fetched from the object store if it is kept there
    /// only).
    pub async fn scene_bundle(&self, digest: &str) -> Result<Stored, Error> {
        if self.shared.objects.is_some() {
            let d = digest.to_string();
            self.off_runtime(move |c| c.ensure_bundle(&d)).await?;
        }
        self.files().bundle(digest).await
    }

    /// Creates a job, or finds the one created earlier with the same idempotency key.
    /// Returns its id and whether it is new.
    pub async fn create_job(
        &self,
        spec: JobSpec,
        idempotency_key: Option<String>,
    ) -> Result<(u64, bool), Error> {
        if let Some(k) = idempotency_key.clone()
            && let Some(id) = self
                .off_runtime(move |c| Ok(c.lock().store.job_with_key(&k)?))
                .await?
        {
            return Ok((id, false));
        }
        if let Some(url) = &spec.webhook {
            super::webhooks::check_url(url)
                .map_err(|e| Error::Unplannable(PlanError::Webhook(e)))?;
        }
        check_requirements(&spec).map_err(|e| Error::Unplannable(PlanError::Requirements(e)))?;
        self.lock()
            .check_after(&spec.after)
            .map_err(|e| Error::Unplannable(PlanError::After(e)))?;
        // With passes, the job's samples per pixel are the last pass's, and are pinned in the
        // spec: they set the renderer's texture footprint for the job's whole life, through
        // stops and extensions.
        let mut spec = spec;
        if let Some(last) = spec.passes.as_ref().and_then(|p| p.last().copied()) {
            match spec.spp {
                None => spec.spp = Some(last),
                Some(spp) if spp != last => {
                    return Err(Error::Unplannable(PlanError::Passes(format!(
                        "spp {spp} is not the last pass's {last}"
                    ))));
                }
                Some(_) => {}
            }
        }
        let scenes = self.files().scenes();
        let max_pixels = self.config().max_frame_pixels;
        let spec2 = spec;
        // Planning reads the whole scene into memory: a few at a time, the rest queued, so
        // that memory does not grow with the number of submissions in flight.
        let _turn = self
            .shared
            .plannings
            .acquire()
            .await
            .expect("the planning semaphore is never closed");
        #[cfg(test)]
        let hook = self.shared.plan_hook.lock().unwrap().clone();
        let c = self.clone();
        let mut job = tokio::task::spawn_blocking(move || {
            #[cfg(test)]
            if let Some(hook) = hook {
                hook();
            }
            // A scene uploaded to another coordinator of the farm is in the object store.
            c.ensure_bundle(&spec2.scene)?;
            Job::plan(&scenes, 0, spec2, JobState::Running, max_pixels).map_err(Error::Unplannable)
        })
        .await??;
        let (id, created) = self
            .off_runtime(move |c| {
                let mut state = c.lock();
                // A retry may have created it while this one planned.
                if let Some(k) = &idempotency_key
                    && let Some(id) = state.store.job_with_key(k)?
                {
                    return Ok((id, false));
                }
                // The planned spec: its colour mode pinned (Job::plan).
                let id = state
                    .store
                    .insert_job(&job.spec, idempotency_key.as_deref())?;
                job.id = id;
                state.jobs.insert(id, job);
                Ok((id, true))
            })
            .await?;
        if created {
            self.notify(id);
        }
        Ok((id, created))
    }

    /// Cancels a running job (its leases end at their next heartbeat); returns its status.
    pub fn cancel(&self, id: u64) -> Result<JobStatus, Error> {
        let now = self.now();
        let status = {
            let mut state = self.lock();
            let job = state.jobs.get_mut(&id).ok_or(Error::UnknownJob(id))?;
            if job.state == JobState::Running {
                job.state = JobState::Cancelled;
                state.persist(id);
            }
            state.jobs[&id].status(now)
        };
        self.notify(id);
        Ok(status)
    }

    /// Ends a running job after the pass its slowest tile is on: its result will be that
    /// pass's whole frame. Returns its status.
    pub fn stop_after_pass(&self, id: u64) -> Result<JobStatus, Error> {
        let now = self.now();
        let status = {
            let mut state = self.lock();
            let job = state.jobs.get_mut(&id).ok_or(Error::UnknownJob(id))?;
            if job.stop_after_pass() {
                let spec = job.spec.clone();
                state.store.set_spec(id, &spec)?;
            }
            state.jobs[&id].status(now)
        };
        self.notify(id);
        Ok(status)
    }

    /// Adds passes to a running or done job (a done one runs again, from the samples it
    /// has). Returns its status.
    pub fn extend(&self, id: u64, more: &[u32]) -> Result<JobStatus, Error> {
        let now = self.now();
        let status = {
            let mut state = self.lock();
            let job = state.jobs.get_mut(&id).ok_or(Error::UnknownJob(id))?;
            let spec = job
                .check_extend(more)
                .map_err(|why| Error::Passes { id, why })?;
            // Recorded first: a job is never extended in memory only.
            state.store.set_spec(id, &spec)?;
            state.store.set_webhook(id, WebhookOutcome::Pending)?;
            let job = state.jobs.get_mut(&id).expect("found above");
            job.extend(more).map_err(|why| Error::Passes { id, why })?;
            state.persist(id);
            state.jobs[&id].status(now)
        };
        self.notify(id);
        Ok(status)
    }

    /// The merged EXR of a job's last merged pass (a done job's whole render); of a shot,
    /// its first frame's.
    pub async fn result(&self, id: u64) -> Result<Stored, Error> {
        self.frame_result(id, 0).await
    }

    /// The merged EXR of frame `frame`'s last merged pass.
    pub async fn frame_result(&self, id: u64, frame: u32) -> Result<Stored, Error> {
        let (has, state) = {
            let state = self.lock();
            let job = state.jobs.get(&id).ok_or(Error::UnknownJob(id))?;
            if frame as usize >= job.frame_count() {
                return Err(Error::UnknownFrame { id, frame });
            }
            (job.has_result(frame as usize), job.state)
        };
        // A job that ended keeps the result it had, whether or not its tiles could be
        // read back at a restart.
        if !has && state == JobState::Running {
            return Err(Error::NotDone { id, state });
        }
        let path = self.files().result_path(id, frame);
        // A frame merged by another coordinator of the farm is in the object store.
        self.fetch_frame_if_missing(id, frame, &path).await?;
        match Stored::open(&path).await {
            Ok(stored) => Ok(stored),
            // An ended job that never merged a pass has none (one that did and lost the
            // file is the operator's problem, below).
            Err(e) if !has && e.kind() == std::io::ErrorKind::NotFound => {
                Err(Error::NotDone { id, state })
            }
            Err(e) => Err(Error::io(path, e)),
        }
    }

    /// Fetches job `id`'s frame `frame` into `path` from the object store unless the data
    /// directory has it.
    async fn fetch_frame_if_missing(
        &self,
        id: u64,
        frame: u32,
        path: &std::path::Path,
    ) -> Result<(), Error> {
        let key = super::objects::keys::frame(id, frame);
        let limit = super::objects::frame_limit(self.config().max_frame_pixels);
        self.fetch_if_missing(path.to_path_buf(), key, limit).await
    }

    /// The frame so far as an sRGB PNG, `exposure` stops brighter; of a shot, its first
    /// frame.
    pub async fn preview(&self, id: u64, exposure: f32) -> Result<Vec<u8>, Error> {
        self.frame_preview(id, 0, exposure, false).await
    }

    /// Frame `frame` so far as an sRGB PNG, `exposure` stops brighter, and with `denoise`
    /// denoised: from memory while it renders, from its result file once it is finished.
    pub async fn frame_preview(
        &self,
        id: u64,
        frame: u32,
        exposure: f32,
        denoise: bool,
    ) -> Result<Vec<u8>, Error> {
        let so_far = {
            let state = self.lock();
            let job = state.jobs.get(&id).ok_or(Error::UnknownJob(id))?;
            if frame as usize >= job.frame_count() {
                return Err(Error::UnknownFrame { id, frame });
            }
            (
                job.frame_so_far(frame as usize),
                job.frame_passes_written(frame as usize),
            )
        };
        let (so_far, written) = so_far;
        let rendering = so_far.is_some();
        let picture = match so_far {
            Some(p) => p,
            None => {
                let path = self.files().result_path(id, frame);
                self.fetch_frame_if_missing(id, frame, &path).await?;
                let bytes = tokio::fs::read(&path)
                    .await
                    .map_err(|e| Error::io(&path, e))?;
                let decoded = tokio::task::spawn_blocking(move || kiln_image::decode_exr(&bytes))
                    .await?
                    .map_err(Error::Image)?;
                std::sync::Arc::new(decoded)
            }
        };
        let picture = if denoise {
            let source = if rendering {
                super::denoised::Source::Rendering(picture)
            } else {
                super::denoised::Source::Finished { written, picture }
            };
            self.denoised((id, frame), source).await?
        } else {
            picture
        };
        tokio::task::spawn_blocking(move || kiln_image::encode_png(&picture, exposure))
            .await?
            .map_err(Error::Image)
    }

    /// Each frame's progress (a job of one frame has one).
    pub fn frames(&self, id: u64) -> Result<Vec<FrameStatus>, Error> {
        let state = self.lock();
        let job = state.jobs.get(&id).ok_or(Error::UnknownJob(id))?;
        Ok(job.frame_statuses())
    }

    /// Trusts `worker` again after it was set aside (an operator found and fixed its
    /// host): it gets leases again, and the store forgets the reason.
    pub fn reinstate(&self, worker: &str) -> Result<(), Error> {
        let mut state = self.lock();
        if state.workers.set_aside_reason(worker).is_none() {
            return Err(Error::NotSetAside(worker.to_string()));
        }
        state.store.reinstate(worker)?;
        state.workers.reinstate(worker);
        tracing::info!("worker {worker} is reinstated");
        Ok(())
    }

    /// Every worker seen, with what it is rendering now.
    pub fn worker_statuses(&self) -> Vec<WorkerStatus> {
        let now = self.now();
        let state = self.lock();
        state
            .workers
            .iter()
            .map(|(name, r)| {
                let mut leases: Vec<WorkerLease> = state
                    .leases
                    .iter()
                    .filter(|(_, h)| &h.worker == name)
                    .map(|(_, h)| WorkerLease {
                        job: h.job,
                        tile_index: h.tile as u32,
                        pass: h.pass,
                        frame: state.jobs.get(&h.job).map_or(0, |j| j.frame_of(h.tile)) as u32,
                    })
                    .collect();
                leases.sort_by_key(|l| (l.job, l.tile_index));
                WorkerStatus {
                    name: name.clone(),
                    tiles_done: r.tiles_done,
                    failures: r.failures,
                    last_seen_seconds: r
                        .last_seen
                        .map(|t| now.saturating_duration_since(t).as_secs_f64()),
                    set_aside: state.workers.set_aside_reason(name),
                    leases,
                    tags: r.tags.clone(),
                    memory_mib: r.memory_mib,
                    geometry: r.geometry,
                }
            })
            .collect()
    }

    /// The Prometheus text of the coordinator's counters and gauges.
    pub fn metrics_text(&self) -> String {
        let snapshot = {
            let state = self.lock();
            Snapshot::new(
                &state.metrics,
                state.jobs.values().map(|j| j.state),
                state.leases.len(),
            )
        };
        snapshot.render()
    }
}

/// What a job asks of its workers: tags that are tags (see [`crate::api::check_tags`]), and
/// a cap of at least one worker.
fn check_requirements(spec: &JobSpec) -> Result<(), String> {
    crate::api::check_tags(&spec.requires).map_err(|e| format!("requires: {e}"))?;
    if spec.max_workers == Some(0) {
        return Err("max_workers is at least 1".into());
    }
    Ok(())
}
