//! Webhooks: a job's spec may name a URL that the coordinator POSTs the job's status to
//! (JSON, as GET /v1/jobs/{id} gives it, with an `X-Kiln-Event` header: `job.done`,
//! `job.failed` or `job.cancelled`) once the job has ended.
//!
//! Delivery is at least once: a call that fails (no answer in 10 s, or not 2xx) is retried
//! with exponential backoff, up to [`MAX_ATTEMPTS`] times; one that succeeds is recorded in
//! the store, so a restarted coordinator calls only those never answered. Each job's
//! delivery is one task at a time; what became of it is in the job's status (`webhook`).
//! Nothing here holds the lock across a call.

use super::Coordinator;
use crate::api::JobState;
use std::time::Duration;

/// Calls of one webhook before giving up.
pub const MAX_ATTEMPTS: u32 = 8;

/// Where a job's webhook stands.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub(super) enum Delivery {
    /// Not called yet (the job has not ended, or the sweep has not come by).
    #[default]
    Waiting,
    /// A task is calling it.
    Calling,
    /// It answered 2xx after this many calls.
    Delivered(u32),
    /// It never answered 2xx; the last error.
    GaveUp(String),
}

impl Delivery {
    /// As the job's status says it.
    pub fn describe(&self) -> Option<String> {
        match self {
            Delivery::Waiting => None,
            Delivery::Calling => Some("calling".into()),
            Delivery::Delivered(n) => Some(format!("delivered after {n} call(s)")),
            Delivery::GaveUp(e) => Some(format!("gave up after {MAX_ATTEMPTS} calls: {e}")),
        }
    }
}

/// Checks a webhook URL when a job is created: http or https, with a host.
pub fn check_url(url: &str) -> Result<(), String> {
    let parsed = reqwest::Url::parse(url).map_err(|e| format!("webhook '{url}': {e}"))?;
    if !matches!(parsed.scheme(), "http" | "https") || parsed.host().is_none() {
        return Err(format!("webhook '{url}' is not an http(s) URL with a host"));
    }
    Ok(())
}

impl Coordinator {
    /// Starts a delivery for every ended job whose webhook is waiting. Called whenever
    /// a job changes, and now and then in case an event was missed.
    pub(super) fn sweep_webhooks(&self) {
        let due: Vec<(u64, String)> = {
            let mut state = self.lock();
            let state = &mut *state;
            let mut due = Vec::new();
            for job in state.jobs.values_mut() {
                let Some(url) = job.spec.webhook.clone() else {
                    continue;
                };
                if job.state == JobState::Running || job.webhook != Delivery::Waiting {
                    continue;
                }
                // Delivered before a restart: done.
                if state.store.webhook_delivered(job.id).unwrap_or(false) {
                    job.webhook = Delivery::Delivered(1);
                    continue;
                }
                job.webhook = Delivery::Calling;
                due.push((job.id, url));
            }
            due
        };
        for (id, url) in due {
            let c = self.clone();
            tokio::spawn(async move { c.deliver(id, url).await });
        }
    }

    async fn deliver(&self, id: u64, url: String) {
        let http = reqwest::Client::builder()
            .timeout(Duration::from_secs(10))
            .build()
            .unwrap_or_default();
        let mut pause = self.config().webhook_backoff;
        let mut last = String::new();
        for attempt in 1..=MAX_ATTEMPTS {
            let Some(status) = self.status(id) else {
                return;
            };
            let event = format!("job.{}", status.state.as_str());
            let sent = http
                .post(&url)
                .header("x-kiln-event", event)
                .json(&status)
                .send()
                .await;
            match sent {
                Ok(r) if r.status().is_success() => {
                    let mut state = self.lock();
                    if let Err(e) = state.store.set_webhook_delivered(id, true) {
                        tracing::warn!("job {id}: cannot record its webhook's delivery: {e}");
                    }
                    if let Some(job) = state.jobs.get_mut(&id) {
                        job.webhook = Delivery::Delivered(attempt);
                    }
                    drop(state);
                    self.notify(id);
                    return;
                }
                Ok(r) => last = format!("{url} answered {}", r.status()),
                Err(e) => last = format!("{url}: {e}"),
            }
            tracing::warn!("job {id}: webhook call {attempt} of {MAX_ATTEMPTS} failed: {last}");
            if attempt < MAX_ATTEMPTS {
                tokio::time::sleep(pause).await;
                pause = (pause * 2).min(Duration::from_secs(60));
            }
        }
        if let Some(job) = self.lock().jobs.get_mut(&id) {
            job.webhook = Delivery::GaveUp(last);
        }
        self.notify(id);
    }
}

/// Sweeps webhooks whenever a job changes, and every second, forever.
pub(super) async fn deliver_webhooks_forever(c: Coordinator) {
    let mut events = c.subscribe();
    loop {
        let _ = tokio::time::timeout(Duration::from_secs(1), events.recv()).await;
        c.sweep_webhooks();
    }
}

#[cfg(test)]
mod tests {
    use super::check_url;

    #[test]
    fn only_http_urls_with_a_host_are_webhooks() {
        assert!(check_url("http://127.0.0.1:9/hook").is_ok());
        assert!(check_url("https://example.com/x?y=1").is_ok());
        for bad in [
            "ftp://example.com/",
            "file:///etc/passwd",
            "not a url",
            "http://",
        ] {
            assert!(check_url(bad).is_err(), "{bad}");
        }
    }
}
