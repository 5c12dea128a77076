//! The coordinator's optional TLS (`--tls-cert`, `--tls-key`) for farms without an ingress
//! in front: the certificate chain and key read from PEM files once, at start, through
//! rustls on the ring provider. A file that cannot be read or holds no certificate or key
//! stops the start with a message that names it.

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio_rustls::TlsAcceptor;

/// Where the coordinator's certificate chain and private key are (PEM).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    pub cert: PathBuf,
    pub key: PathBuf,
}

/// Whether `files` make a TLS server, or why not (naming the file): a start checks before
/// it says it listens.
pub fn check(files: &TlsFiles) -> Result<(), String> {
    acceptor(files).map(|_| ())
}

/// The acceptor for `files`, or why not (naming the file).
pub fn acceptor(files: &TlsFiles) -> Result<TlsAcceptor, String> {
    crate::trust::install_provider();
    let named = |p: &Path, e: &dyn std::fmt::Display| format!("{}: {e}", p.display());
    let certs: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(&files.cert)
        .map_err(|e| named(&files.cert, &e))?
        .collect::<Result<_, _>>()
        .map_err(|e| named(&files.cert, &e))?;
    if certs.is_empty() {
        return Err(named(&files.cert, &"no PEM certificate in it"));
    }
    let key = PrivateKeyDer::from_pem_file(&files.key).map_err(|e| named(&files.key, &e))?;
    let config = rustls::ServerConfig::builder()
        .with_no_client_auth()
        .with_single_cert(certs, key)
        .map_err(|e| format!("{} and {}: {e}", files.cert.display(), files.key.display()))?;
    Ok(TlsAcceptor::from(Arc::new(config)))
}
