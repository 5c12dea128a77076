//! Finishing a job: its merged frame is encoded and written with no lock held, then the
//! outcome (done, or failed if the file cannot be written) is committed under the lock.
//!
//! The frame is shared, not copied: once every tile is done nothing pastes into it, so the
//! merge reads it while other requests go on. This must never hold the lock while encoding
//! or writing, nor mark a job done before its result file is in place. A crash before the
//! commit loses nothing: every tile is in the store, and resuming merges the frame again.

use super::{Coordinator, Error};
use crate::api::JobState;
use kiln_image::RgbBuffer;
use std::sync::Arc;
use std::time::Duration;

impl Coordinator {
    /// Writes `frame` as job `id`'s result on a blocking thread and commits the outcome.
    /// The work goes on to its end even if the caller stops waiting.
    pub(super) async fn merge(&self, id: u64, frame: Arc<RgbBuffer>) {
        let c = self.clone();
        let task = tokio::spawn(async move {
            let c2 = c.clone();
            let merged = tokio::task::spawn_blocking(move || c2.merge_blocking(id, &frame)).await;
            if let Err(e) = merged {
                c.commit_merge(id, Err(Error::Task(e)), Duration::ZERO);
            }
        });
        let _ = task.await;
    }

    /// Encodes and writes the merged frame, then commits. Blocking; locks only to commit.
    pub(super) fn merge_blocking(&self, id: u64, frame: &RgbBuffer) {
        #[cfg(test)]
        self.before_merge();
        // Real time: this measures work done, it decides nothing.
        let start = std::time::Instant::now();
        let written = kiln_image::encode_exr(frame)
            .map_err(Error::Image)
            .and_then(|bytes| self.files().write_result(id, &bytes));
        self.commit_merge(id, written, start.elapsed());
    }

    fn commit_merge(&self, id: u64, written: Result<(), Error>, took: Duration) {
        if let Err(e) = &written {
            tracing::error!("job {id}: cannot write the result: {e}");
        }
        {
            let mut state = self.lock();
            let Some(job) = state.jobs.get_mut(&id) else {
                return;
            };
            // A job cancelled while its frame was written stays cancelled.
            if job.state != JobState::Running {
                return;
            }
            match written {
                Ok(()) => {
                    job.state = JobState::Done;
                    job.merge_seconds = Some(took.as_secs_f64());
                }
                Err(e) => {
                    job.state = JobState::Failed;
                    job.error = Some(format!("cannot write the result: {e}"));
                }
            }
            state.persist(id);
        }
        self.notify(id);
    }
}
