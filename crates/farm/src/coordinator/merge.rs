//! Merging a complete pass of one frame (a job of one frame, or a frame of a shot): its
//! picture is encoded and written beside the frame's result with no lock held, then, under the lock, renamed over the result (unless a later pass got there
//! first) and the outcome committed: the next pass goes on, or after the last the job is
//! done (or failed, if the file cannot be written).
//!
//! The frame is shared, not copied: once a pass's every tile is done nothing pastes into
//! its frame, so the merge reads it while other requests go on. This must never hold the
//! lock while encoding or writing, nor mark a job done before its result file is in place.
//! A crash before the commit loses nothing: every tile pass is in the store, and resuming
//! merges the frame again.

use super::job::ToMerge;
use super::{Coordinator, Error, Health};
use crate::api::JobState;
use kiln_image::RgbBuffer;
use std::sync::Arc;
use std::time::Duration;

impl Coordinator {
    /// Writes `frame`, job `id`'s frame `index` at pass `pass`, as that frame's result on a
    /// blocking thread and commits the outcome. The work goes on to its end even if the
    /// caller stops waiting.
    pub(super) async fn merge(&self, id: u64, index: u32, pass: u32, frame: Arc<RgbBuffer>) {
        let c = self.clone();
        let task = tokio::spawn(async move {
            let c2 = c.clone();
            let merged = tokio::task::spawn_blocking(move || {
                c2.merge_blocking(id, index, pass, &frame);
            })
            .await;
            if let Err(e) = merged {
                let _ = c
                    .off_runtime(move |c| {
                        c.commit_merge(id, index, pass, Err(Error::Task(e)), Duration::ZERO);
                        Ok(())
                    })
                    .await;
            }
        });
        let _ = task.await;
    }

    /// Encodes and writes the merged frame, then commits. Blocking; locks only to commit.
    pub(super) fn merge_blocking(&self, id: u64, index: u32, pass: u32, frame: &RgbBuffer) {
        #[cfg(test)]
        self.before_merge();
        // Real time: this measures work done, it decides nothing.
        let start = std::time::Instant::now();
        let staged = kiln_image::encode_exr(frame)
            .map_err(Error::Image)
            .and_then(|bytes| {
                let staged = self.files().stage_result(id, index, pass, &bytes)?;
                // Kept in the object store before it is the result: an outage of the store
                // is a write that fails, tried again later as a full disk's is.
                let key = super::objects::keys::frame(id, index);
                self.keep_object(&key, bytes.into()).map_err(|e| {
                    let _ = std::fs::remove_file(&staged);
                    Error::Io {
                        path: std::path::PathBuf::from(key),
                        message: e.to_string(),
                    }
                })?;
                Ok(staged)
            });
        self.commit_merge(id, index, pass, staged, start.elapsed());
    }

    /// Writes again the frames that could not be written (a full disk) once their wait
    /// is over. Called by the serving loop's tick.
    pub(super) fn retry_merges(&self) {
        let now = self.now();
        let due: Vec<(u64, ToMerge)> = {
            let mut state = self.lock();
            state
                .jobs
                .values_mut()
                .filter(|j| j.merge_due(now))
                .flat_map(|j| {
                    let id = j.id;
                    j.take_merge_retry().into_iter().map(move |m| (id, m))
                })
                .collect()
        };
        for (id, m) in due {
            let c = self.clone();
            tokio::spawn(async move { c.merge(id, m.index, m.pass, m.frame).await });
        }
    }

    fn commit_merge(
        &self,
        id: u64,
        index: u32,
        pass: u32,
        staged: Result<std::path::PathBuf, Error>,
        took: Duration,
    ) {
        {
            let mut state = self.lock();
            let state = &mut *state;
            let Some(job) = state.jobs.get_mut(&id) else {
                return;
            };
            // A later pass's merge that landed first wins; so does a cancellation, and tiles
            // that started again meanwhile (a worker set aside).
            let k = index as usize;
            if job.is_written(k, pass)
                || job.state != JobState::Running
                || !job.has_complete(k, pass)
            {
                if let Ok(path) = &staged {
                    let _ = std::fs::remove_file(path);
                }
                return;
            }
            let published = staged.and_then(|path| self.files().publish_result(id, index, &path));
            match published {
                Ok(()) => {
                    job.merge_seconds = Some(took.as_secs_f64());
                    if job.merged(k, pass) {
                        job.state = JobState::Done;
                    }
                    let samples = job.samples_of_pass(pass);
                    // Nothing continues from the passes before this one any more, once
                    // every frame has merged it.
                    if pass > 0
                        && job.merged_everywhere(pass)
                        && let Err(e) = state.store.drop_passes_before(id, samples)
                    {
                        tracing::warn!("job {id}: cannot forget its earlier passes: {e}");
                    }
                }
                Err(Error::Io { message, .. }) => {
                    // A full disk, a read-only remount: the tiles are kept, so the frame is
                    // written again later (and at a restart), not given up on. The path
                    // is the server's: logged, never shown.
                    let now = self.now();
                    let retry = self.config().merge_retry;
                    let wait = job.merge_failed(pass, &message, now, retry);
                    tracing::warn!("job {id}: pass {pass}'s frame is written again in {wait:?}");
                    Health::note(
                        &mut state.health.files,
                        "writing merged frames",
                        Some(message),
                    );
                }
                Err(e) => {
                    tracing::error!("job {id}: cannot write the result: {e}");
                    job.state = JobState::Failed;
                    job.error = Some(format!("cannot write the result: {e}"));
                }
            }
            if state.jobs.get(&id).is_some_and(|j| j.is_written(k, pass)) {
                Health::note(&mut state.health.files, "writing merged frames", None);
            }
            state.persist(id);
        }
        self.notify(id);
    }
}
