//! What the farm's https rests on, shared by its client side (`client.rs`: `kiln submit`,
//! workers) and the coordinator (its TLS listener, its webhook calls): rustls's crypto
//! provider (ring), and the certificates an https peer is trusted through, those in the PEM
//! file `KILN_TLS_CA` names and no others (never the platform's store, which a FROM-scratch
//! image lacks). Knows nothing of jobs, the API or HTTP.

/// The environment variable naming the PEM file of certificates an https coordinator (or a
/// webhook's endpoint) is trusted through.
pub const TLS_CA_VAR: &str = "KILN_TLS_CA";

/// Installs ring as the process's rustls provider (the first call wins; every https user
/// calls it before building anything).
pub fn install_provider() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

/// The certificates `KILN_TLS_CA` names (none if it names none, or an unreadable file:
/// then nothing https is trusted).
pub fn trusted_roots() -> Vec<reqwest::Certificate> {
    std::env::var_os(TLS_CA_VAR)
        .and_then(|path| std::fs::read(path).ok())
        .and_then(|pem| reqwest::Certificate::from_pem_bundle(&pem).ok())
        .unwrap_or_default()
}
