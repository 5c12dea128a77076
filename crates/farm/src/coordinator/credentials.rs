//! Who a request is from and what it may do. The coordinator's own token (`--token`) is the
//! admin's; submitter tokens and per-worker credentials are issued and revoked through the
//! API (`/v1/tokens`, admin only), kept as the SHA-256 of their secrets in the job store and
//! in memory here, so a revoked token is refused from the next request on. A worker's
//! credential names it: it leases only under that name and touches only its own leases, so a
//! worker set aside cannot come back under another name. A submitter sees and changes only
//! the jobs it created.
//!
//! What each role may call is [`may`], by method and path: no HTTP types here. Secrets are
//! never logged, stored or put in an error.

use super::store::StoredToken;
use super::{Coordinator, Error};
use crate::api::{Role, TokenInfo, TokenIssued, TokenRequest};
use sha2::{Digest, Sha256};
use std::collections::HashMap;

/// Who a request is from: a role and a name (the admin's is `admin`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Principal {
    pub role: Role,
    pub name: String,
}

impl Principal {
    /// The admin (the coordinator's own token, or anyone where it has none).
    pub fn admin() -> Principal {
        Principal {
            role: Role::Admin,
            name: "admin".into(),
        }
    }
}

/// The tokens issued, by the SHA-256 of their secrets.
#[derive(Default)]
pub(super) struct Credentials {
    by_hash: HashMap<String, StoredToken>,
}

impl Credentials {
    pub fn new(tokens: Vec<StoredToken>) -> Credentials {
        Credentials {
            by_hash: tokens.into_iter().map(|t| (t.hash.clone(), t)).collect(),
        }
    }

    /// Whose `secret` is, if it is an issued token not revoked.
    pub fn find(&self, secret: &str) -> Option<Principal> {
        let t = self.by_hash.get(&hash(secret))?;
        (!t.revoked).then(|| Principal {
            role: t.role,
            name: t.name.clone(),
        })
    }

    pub fn add(&mut self, token: StoredToken) {
        self.by_hash.insert(token.hash.clone(), token);
    }

    /// Marks token `id` revoked here; returns it.
    pub fn revoke(&mut self, id: u64) -> Option<TokenInfo> {
        let t = self.by_hash.values_mut().find(|t| t.id == id)?;
        t.revoked = true;
        Some(info(t))
    }

    /// Every token issued, oldest first.
    pub fn list(&self) -> Vec<TokenInfo> {
        let mut all: Vec<TokenInfo> = self.by_hash.values().map(info).collect();
        all.sort_by_key(|t| t.id);
        all
    }
}

fn info(t: &StoredToken) -> TokenInfo {
    TokenInfo {
        id: t.id,
        role: t.role,
        name: t.name.clone(),
        revoked: t.revoked,
    }
}

/// The SHA-256 of a secret, in hex: what the store keeps. Secrets are 256 random bits, so
/// a fast hash is enough: no dictionary reaches them.
pub fn hash(secret: &str) -> String {
    Sha256::digest(secret.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Compares a given secret with a known one in time that does not depend on where they
/// first differ.
pub(super) fn same_secret(given: &str, known: &str) -> bool {
    let (a, b) = (given.as_bytes(), known.as_bytes());
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

/// A new secret: `kiln-` and 256 bits from the operating system's entropy, in hex.
fn new_secret() -> Result<String, Error> {
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| Error::Io {
        path: "the operating system's random source".into(),
        message: e.to_string(),
    })?;
    Ok(format!("kiln-{}", super::data_dir::hex(&bytes)))
}

/// Whether `role` may call `method` `path`. The admin may call everything; a submitter
/// uploads scenes and creates, lists and follows jobs (its own: the handlers check whose);
/// a worker leases and renders. Anything else is the admin's alone (workers, tokens,
/// metrics).
pub fn may(role: Role, method: &str, path: &str) -> bool {
    let parts: Vec<&str> = path.trim_start_matches('/').split('/').collect();
    let p = parts.as_slice();
    if method == "GET" && p == ["v1", "openapi.json"] {
        return true;
    }
    match role {
        Role::Admin => true,
        Role::Submitter => matches!(
            (method, p),
            ("POST", ["v1", "scenes"])
                | ("POST" | "GET", ["v1", "jobs"])
                | ("GET", ["v1", "jobs", _])
                | (
                    "GET",
                    [
                        "v1",
                        "jobs",
                        _,
                        "events" | "result.exr" | "preview.png" | "frames"
                    ]
                )
                | (
                    "GET",
                    ["v1", "jobs", _, "frames", _, "result.exr" | "preview.png"]
                )
                | ("POST", ["v1", "jobs", _, "cancel" | "stop" | "extend"])
        ),
        Role::Worker => matches!(
            (method, p),
            ("POST", ["v1", "leases"])
                | ("POST", ["v1", "leases", _, "heartbeat" | "fail"])
                | ("PUT", ["v1", "leases", _, "tile"])
                | ("GET", ["v1", "leases", _, "sums"])
                | ("GET", ["v1", "scenes", _])
                | ("GET" | "PUT", ["v1", "scenes", _, "prepass", _])
                | (
                    "POST" | "DELETE",
                    ["v1", "scenes", _, "prepass", _, "claim"]
                )
        ),
    }
}

impl Coordinator {
    /// Whose `secret` is: the admin's (the coordinator's token), an issued token's, or no
    /// one's.
    pub fn principal(&self, secret: &str) -> Option<Principal> {
        if let Some(admin) = &self.config().token
            && same_secret(secret, admin)
        {
            return Some(Principal::admin());
        }
        self.lock().credentials.find(secret)
    }

    /// Issues a token of `req.role` for `req.name` (a name as workers' are): recorded in the
    /// store first (its hash), then usable. The secret is in the answer only.
    pub fn issue_token(&self, req: &TokenRequest) -> Result<TokenIssued, Error> {
        crate::api::check_worker_name(&req.name).map_err(Error::BadToken)?;
        let secret = new_secret()?;
        let digest = hash(&secret);
        let mut state = self.lock();
        let id = state.store.insert_token(req.role, &req.name, &digest)?;
        let token = StoredToken {
            id,
            role: req.role,
            name: req.name.clone(),
            hash: digest,
            revoked: false,
        };
        let info = info(&token);
        state.credentials.add(token);
        tracing::info!("token {id} issued: {} {}", req.role.as_str(), req.name);
        Ok(TokenIssued {
            info,
            token: secret,
        })
    }

    /// Revokes token `id`: recorded in the store first, then refused from the next
    /// request on. A worker's leases end now, their tiles lent again.
    pub fn revoke_token(&self, id: u64) -> Result<TokenInfo, Error> {
        let mut state = self.lock();
        let state = &mut *state;
        if !state.store.revoke_token(id)? {
            return Err(Error::UnknownToken(id));
        }
        let info = state
            .credentials
            .revoke(id)
            .ok_or(Error::UnknownToken(id))?;
        if info.role == Role::Worker {
            for (lease, held) in state.leases.remove_where(|h| h.worker == info.name) {
                if let Some(job) = state.jobs.get_mut(&held.job) {
                    job.lease_lost(held.tile, lease);
                }
            }
        }
        tracing::info!("token {id} revoked: {} {}", info.role.as_str(), info.name);
        Ok(info)
    }

    /// Every token issued (never their secrets).
    pub fn tokens(&self) -> Vec<TokenInfo> {
        self.lock().credentials.list()
    }

    /// The worker holding lease `lease`, if it is live.
    pub fn lease_holder(&self, lease: u64) -> Option<String> {
        self.lock().leases.get(lease).map(|h| h.worker.clone())
    }

    /// The submitter that created job `id` (None: the admin).
    pub fn job_owner(&self, id: u64) -> Result<Option<String>, Error> {
        let state = self.lock();
        let job = state.jobs.get(&id).ok_or(Error::UnknownJob(id))?;
        Ok(job.spec.owner.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_role_may_call_its_routes_and_no_other() {
        use Role::*;
        let cases = [
            (Submitter, "POST", "/v1/jobs", true),
            (Submitter, "GET", "/v1/jobs/7/frames/2/result.exr", true),
            (Submitter, "POST", "/v1/jobs/7/cancel", true),
            (Submitter, "GET", "/v1/workers", false),
            (Submitter, "POST", "/v1/leases", false),
            (Submitter, "GET", "/metrics", false),
            (Submitter, "POST", "/v1/tokens", false),
            (Submitter, "GET", "/v1/scenes/abc", false),
            (Worker, "POST", "/v1/leases", true),
            (Worker, "PUT", "/v1/leases/3/tile", true),
            (Worker, "GET", "/v1/scenes/abc", true),
            (Worker, "POST", "/v1/scenes/abc/prepass/x/claim", true),
            (Worker, "GET", "/v1/jobs", false),
            (Worker, "POST", "/v1/jobs", false),
            (Worker, "POST", "/v1/scenes", false),
            (Worker, "POST", "/v1/workers/w/reinstate", false),
            (Worker, "GET", "/v1/tokens", false),
            (Worker, "GET", "/v1/openapi.json", true),
            (Admin, "POST", "/v1/tokens/3/revoke", true),
        ];
        for (role, method, path, allowed) in cases {
            assert_eq!(may(role, method, path), allowed, "{role:?} {method} {path}");
        }
    }

    #[test]
    fn a_revoked_token_is_no_ones() {
        let t = StoredToken {
            id: 1,
            role: Role::Worker,
            name: "w1".into(),
            hash: hash("secret"),
            revoked: false,
        };
        let mut c = Credentials::new(vec![t]);
        assert_eq!(c.find("secret").map(|p| p.name), Some("w1".into()));
        assert_eq!(c.find("secreT"), None);
        assert!(c.revoke(1).is_some_and(|i| i.revoked));
        assert_eq!(c.find("secret"), None);
        assert_eq!(c.revoke(2), None);
    }
}
