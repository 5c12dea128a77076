//! Showing and writing what a farm's render gives: the progress bar a job is followed with,
//! and a file replaced whole, so a reader (an image viewer watching the file, a script)
//! never sees half of one.

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use kiln_farm::api::{JobState, JobStatus};

/// Whether a followed job has ended done; an error saying so if it failed or was cancelled.
pub fn ended(id: u64, s: &JobStatus) -> Result<bool> {
    match s.state {
        JobState::Running => Ok(false),
        JobState::Done => Ok(true),
        JobState::Failed => bail!("job {id} failed: {}", s.error.clone().unwrap_or_default()),
        JobState::Cancelled => bail!("job {id} was cancelled"),
    }
}

/// A bar of a job's progress in thousandths (hidden when `quiet`), with a message after it.
pub fn progress_bar(quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(1000)
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] [{wide_bar}] {percent}% {msg}")
            .expect("the template is valid")
            .progress_chars("=> "),
    );
    bar
}

/// Writes `bytes` to `path` through a temporary file renamed over it: a reader sees the old
/// file or the new one, never half of one.
pub fn write_replacing(path: &std::path::Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}
