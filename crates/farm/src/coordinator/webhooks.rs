//! Webhooks: a job's spec may name a URL that the coordinator POSTs the job's status to
//! (JSON, as GET /v1/jobs/{id} gives it, with an `X-Kiln-Event` header: `job.done`,
//! `job.failed` or `job.cancelled`) once the job has ended.
//!
//! Delivery is at least once: a call that fails (no answer in 10 s, or not 2xx) is retried
//! with exponential backoff, up to [`MAX_ATTEMPTS`] times; what became of it (answered, or
//! given up on) is recorded in the store, so a restarted coordinator calls only those still
//! pending. Each job's delivery is one task at a time; what became of it is in the job's
//! status (`webhook`). A job that runs again (extended, or reopened) while a call for its
//! earlier end is on its way starts a new round: that call's outcome no longer counts, and
//! the job's next end is announced. Nothing here holds the lock across a call.

use super::Coordinator;
use super::store::WebhookOutcome;
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
    /// What the store says became of it before the coordinator restarted.
    Recorded(WebhookOutcome),
}

impl Delivery {
    /// As the job's status says it.
    pub fn describe(&self) -> Option<String> {
        match self {
            Delivery::Waiting => None,
            Delivery::Calling => Some("calling".into()),
            Delivery::Delivered(n) => Some(format!("delivered after {n} call(s)")),
            Delivery::GaveUp(e) => Some(format!("gave up after {MAX_ATTEMPTS} calls: {e}")),
            Delivery::Recorded(WebhookOutcome::Delivered) => {
                Some("delivered before the coordinator restarted".into())
            }
            Delivery::Recorded(WebhookOutcome::GaveUp) => Some(format!(
                "gave up after {MAX_ATTEMPTS} calls before the coordinator restarted"
            )),
            Delivery::Recorded(WebhookOutcome::Pending) => None,
        }
    }
}

/// A job's webhook: where its call stands, and how often the job was made to run again
/// after it ended (extended, or reopened): a call announcing an earlier end must not count
/// for the next.
#[derive(Debug, Clone, Default)]
pub(super) struct WebhookState {
    pub delivery: Delivery,
    pub round: u64,
}

impl WebhookState {
    /// The job runs again: its next end is announced by a round of its own.
    pub fn run_again(&mut self) {
        self.delivery = Delivery::Waiting;
        self.round += 1;
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
        let due: Vec<(u64, String, u64)> = {
            let mut state = self.lock();
            let state = &mut *state;
            let mut due = Vec::new();
            for job in state.jobs.values_mut() {
                let Some(url) = job.spec.webhook.clone() else {
                    continue;
                };
                if job.state == JobState::Running || job.webhook.delivery != Delivery::Waiting {
                    continue;
                }
                // Answered, or given up on, before a restart: done.
                let outcome = state
                    .store
                    .webhook(job.id)
                    .unwrap_or(WebhookOutcome::Pending);
                if outcome != WebhookOutcome::Pending {
                    job.webhook.delivery = Delivery::Recorded(outcome);
                    continue;
                }
                job.webhook.delivery = Delivery::Calling;
                due.push((job.id, url, job.webhook.round));
            }
            due
        };
        for (id, url, round) in due {
            let c = self.clone();
            tokio::spawn(async move { c.deliver(id, url, round).await });
        }
    }

    /// Records `outcome` of round `round`'s delivery for job `id`, unless the job has
    /// started another round meanwhile (it was extended or reopened). Returns whether it
    /// was recorded.
    fn settle(&self, id: u64, round: u64, outcome: WebhookOutcome, delivery: Delivery) -> bool {
        let mut state = self.lock();
        let state = &mut *state;
        let Some(job) = state.jobs.get_mut(&id) else {
            return false;
        };
        if job.webhook.round != round {
            return false;
        }
        if let Err(e) = state.store.set_webhook(id, outcome) {
            tracing::warn!("job {id}: cannot record its webhook's outcome: {e}");
        }
        job.webhook.delivery = delivery;
        true
    }

    /// Whether job `id` is still in round `round` (it has not run again since it ended).
    fn in_round(&self, id: u64, round: u64) -> bool {
        self.lock()
            .jobs
            .get(&id)
            .is_some_and(|j| j.webhook.round == round)
    }

    async fn deliver(&self, id: u64, url: String, round: u64) {
        // https endpoints are trusted through KILN_TLS_CA, as the farm's own clients are.
        crate::trust::install_provider();
        let built = reqwest::Client::builder()
            .timeout(Duration::from_secs(10))
            .tls_certs_only(crate::trust::trusted_roots())
            .build();
        let http = match built {
            Ok(http) => http,
            Err(e) => {
                tracing::error!("job {id}: cannot set up the webhook's HTTP client: {e}");
                return;
            }
        };
        let mut pause = self.config().webhook_backoff;
        let mut last = String::new();
        for attempt in 1..=MAX_ATTEMPTS {
            // A job that runs again is announced when it ends again, by a new round.
            if !self.in_round(id, round) {
                return;
            }
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
                    let delivered = Delivery::Delivered(attempt);
                    let settled = self
                        .off_runtime(move |c| {
                            Ok(c.settle(id, round, WebhookOutcome::Delivered, delivered))
                        })
                        .await;
                    if settled.unwrap_or(false) {
                        self.notify(id);
                    }
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
        let settled = self
            .off_runtime(move |c| {
                Ok(c.settle(id, round, WebhookOutcome::GaveUp, Delivery::GaveUp(last)))
            })
            .await;
        if settled.unwrap_or(false) {
            self.notify(id);
        }
    }
}

/// Sweeps webhooks whenever a job changes, and every second, forever.
pub(super) async fn deliver_webhooks_forever(c: Coordinator) {
    let mut events = c.subscribe();
    loop {
        let _ = tokio::time::timeout(Duration::from_secs(1), events.recv()).await;
        // Off the runtime's threads: a sweep reads the job store.
        let _ = c
            .off_runtime(|c| {
                c.sweep_webhooks();
                Ok(())
            })
            .await;
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
