//! Which job store a coordinator opens, and, on a store that several coordinators share,
//! leading them: waiting as a standby until the lead is free, then renewing it, and
//! stopping the moment another has taken it.
//!
//! A standby opens nothing of the farm's until it leads. It answers every request, its
//! health check too, with a 503 that names the leader's address (in its body and the
//! `X-Kiln-Leader` header, see [`stand_by`]), so a load balancer or a Kubernetes Service
//! whose readiness is `/healthz` sends requests to the leader only, and clients given
//! several coordinator URLs move on to it. The lead's TTL is measured on the store's
//! clock. A deposed leader cannot write (the store fences every write by its epoch); it
//! stops serving within a renewal period and exits, to come back as a standby.

use super::store::{JobStore, Leadership, PostgresStore, SqliteStore, StoreError};
use super::{Coordinator, Error};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::api::LEADER_HEADER;

/// Opens the store the configuration names: SQLite in the data directory by default, or
/// the PostgreSQL server of a `postgres://` URL.
pub(super) fn open_store(
    store: Option<&str>,
    database: &Path,
) -> Result<Box<dyn JobStore>, StoreError> {
    match store {
        None => Ok(Box::new(SqliteStore::open(database)?)),
        Some(url) if url.starts_with("postgres://") || url.starts_with("postgresql://") => {
            Ok(Box::new(PostgresStore::open(url)?))
        }
        Some(other) => Err(StoreError::new(format!(
            "--store '{other}' is not a job store: give a postgres:// URL, or nothing for SQLite in the data directory"
        ))),
    }
}

/// Whom a coordinator leads as, for the store's leader row.
#[derive(Debug, Clone)]
pub struct Candidate {
    /// Unique to this process: host, process id and start time.
    pub name: String,
    /// The URL this coordinator serves at, which standbys report.
    pub address: String,
    /// How long the lead lasts unrenewed before a standby takes it.
    pub ttl: Duration,
    /// Who leads while this one stands by: the leader's name and address, as last seen.
    pub leader: Arc<Mutex<Option<(String, String)>>>,
}

impl Candidate {
    pub fn new(address: String, ttl: Duration) -> Candidate {
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|h| h.trim().to_string())
            .unwrap_or_else(|_| "host".into());
        let started = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        Candidate {
            name: format!("{host}-{}-{started}", std::process::id()),
            address,
            ttl,
            leader: Arc::new(Mutex::new(None)),
        }
    }

    /// How often the leader renews and a standby asks: a fifth of the TTL, at most a second.
    pub fn period(&self) -> Duration {
        (self.ttl / 5).clamp(Duration::from_millis(50), Duration::from_secs(1))
    }
}

/// Blocks until `me` leads the coordinators sharing `store`; returns its epoch. Says once
/// who leads each time that changes, and keeps asking through an outage of the store.
pub(super) fn wait_for_lead(store: &dyn JobStore, me: &Candidate) -> Result<u64, Error> {
    let mut said: Option<(String, u64)> = None;
    let mut failing: Option<String> = None;
    let waited = std::time::Instant::now();
    loop {
        match store.lead(&me.name, &me.address, me.ttl) {
            Ok(Leadership::Leading { epoch, after }) => {
                let standby = waited.elapsed().as_secs_f64();
                match after {
                    Some((before, silent)) if silent.is_finite() => tracing::warn!(
                        "took the lead at epoch {epoch} from coordinator {before}, last heard {silent:.1} s ago (after {standby:.1} s standing by)"
                    ),
                    Some((before, _)) => tracing::warn!(
                        "took the lead at epoch {epoch} from coordinator {before}, which gave it up (after {standby:.1} s standing by)"
                    ),
                    None => tracing::info!("took the lead at epoch {epoch}, the first"),
                }
                return Ok(epoch);
            }
            Ok(Leadership::Led {
                holder,
                address,
                epoch,
            }) => {
                failing = None;
                if said.as_ref() != Some(&(holder.clone(), epoch)) {
                    tracing::info!(
                        "standing by: coordinator {holder} leads at {address} (epoch {epoch})"
                    );
                    *me.leader.lock().unwrap_or_else(|p| p.into_inner()) =
                        Some((holder.clone(), address));
                    said = Some((holder, epoch));
                }
            }
            Err(e) => {
                // Said once per reason, not every period of an outage.
                let why = e.to_string();
                if failing.as_deref() != Some(why.as_str()) {
                    tracing::warn!(
                        "cannot ask who leads: {why}; asking again every {:?}",
                        me.period()
                    );
                    failing = Some(why);
                }
            }
        }
        std::thread::sleep(me.period());
    }
}

/// Renews the lead every period until it is lost; returns why. A renewal the store cannot
/// answer is retried: the fence keeps a deposed leader from writing meanwhile, and the
/// next answer says whether it still leads.
pub(super) async fn keep_lead(c: Coordinator, me: Candidate) -> String {
    let mut failing_since: Option<std::time::Instant> = None;
    loop {
        tokio::time::sleep(me.period()).await;
        let c2 = c.clone();
        let renewed = tokio::task::spawn_blocking(move || c2.lock().store.renew_lead()).await;
        match renewed {
            Ok(Ok(true)) => {
                if let Some(since) = failing_since.take() {
                    tracing::info!(
                        "renewed the lead again after {:.1} s",
                        since.elapsed().as_secs_f64()
                    );
                }
            }
            Ok(Ok(false)) => return "another coordinator has taken the lead".into(),
            Ok(Err(e)) if e.is_deposed() => return e.to_string(),
            Ok(Err(e)) => {
                if failing_since.is_none() {
                    tracing::warn!("cannot renew the lead: {e}; trying again");
                    failing_since = Some(std::time::Instant::now());
                }
            }
            Err(e) => return format!("the lead's renewal failed: {e}"),
        }
    }
}

/// Answers every request on `listener` while this coordinator stands by, until `until`
/// resolves: a 503 that names the leader (`X-Kiln-Leader` and the body's `leader`), or says
/// that no leader is known yet. Requests already being answered are finished.
pub async fn stand_by(
    listener: tokio::net::TcpListener,
    me: Candidate,
    until: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    use axum::http::{HeaderValue, StatusCode, header};
    use axum::response::IntoResponse;
    let answer = move || {
        let leader = me.leader.lock().unwrap_or_else(|p| p.into_inner()).clone();
        async move {
            let (error, address) = match &leader {
                Some((holder, address)) => (
                    format!("this coordinator stands by: coordinator {holder} leads at {address}"),
                    Some(address.clone()),
                ),
                None => (
                    "this coordinator stands by, and no coordinator leads yet: try again in a moment".to_string(),
                    None,
                ),
            };
            let body = serde_json::json!({ "error": error, "leader": address });
            let mut response = (StatusCode::SERVICE_UNAVAILABLE, axum::Json(body)).into_response();
            let headers = response.headers_mut();
            headers.insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            if let Some(v) = address.and_then(|a| HeaderValue::from_str(&a).ok()) {
                headers.insert(LEADER_HEADER, v);
            }
            response
        }
    };
    let app = axum::Router::new().fallback(answer);
    axum::serve(listener, app)
        .with_graceful_shutdown(until)
        .await
}
