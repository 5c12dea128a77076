//! A coordinator serving https itself (`--tls-cert`, `--tls-key`): a start with a file that
//! is missing or holds no certificate stops, naming it; clients that trust its certificate
//! (`KILN_TLS_CA`) check its health, and a worker renders through it the job `kiln submit`
//! sent, the same bytes as `kiln render`; a client that does not trust it, and plain http to
//! its port, are refused.

use super::{Guard, listening};
use crate::util::{kiln, render, scene};
use std::process::Stdio;

#[test]
fn a_coordinator_with_tls_serves_clients_that_trust_its_certificate() {
    let dir = tempfile::tempdir().unwrap();
    let key =
        rcgen::generate_simple_self_signed(vec!["127.0.0.1".into(), "localhost".into()]).unwrap();
    let (cert_pem, key_pem) = (dir.path().join("cert.pem"), dir.path().join("key.pem"));
    std::fs::write(&cert_pem, key.cert.pem()).unwrap();
    std::fs::write(&key_pem, key.signing_key.serialize_pem()).unwrap();
    let coordinator = |cert: &std::path::Path| {
        let mut cmd = kiln();
        cmd.args([
            "coordinator",
            "--listen",
            "127.0.0.1:0",
            "--token",
            "tls-s3cret",
        ])
        .arg("--data-dir")
        .arg(dir.path().join("data"))
        .arg("--tls-cert")
        .arg(cert)
        .arg("--tls-key")
        .arg(&key_pem);
        cmd
    };
    // Files that make no server: the start stops, naming the file.
    let missing = dir.path().join("missing.pem");
    for (cert, says) in [(&missing, "missing.pem"), (&key_pem, "no PEM certificate")] {
        let o = coordinator(cert).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(says), "{err}");
    }
    let (_coordinator, url) = listening(coordinator(&cert_pem).stderr(Stdio::null()));
    assert!(url.starts_with("https://"), "{url}");
    let health = |ca: Option<&std::path::Path>, url: &str| {
        let mut cmd = kiln();
        cmd.args(["health", "--coordinator", url])
            .env_remove("KILN_TLS_CA");
        if let Some(ca) = ca {
            cmd.env("KILN_TLS_CA", ca);
        }
        let o = cmd.output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let (ok, err) = health(Some(&cert_pem), &url);
    assert!(ok, "{err}");
    let (ok, err) = health(None, &url);
    assert!(
        !ok,
        "a client that does not trust the certificate reached it: {err}"
    );
    let plain = url.replace("https://", "http://");
    assert!(
        !health(Some(&cert_pem), &plain).0,
        "plain http was answered"
    );
    let (ok, err) = health(Some(&missing), &url);
    assert!(!ok && err.contains("cannot read KILN_TLS_CA"), "{err}");

    // A worker and a submission through https.
    let worker = kiln()
        .args([
            "worker",
            "--coordinator",
            &url,
            "--token",
            "tls-s3cret",
            "--threads",
            "1",
            "--name",
            "w1",
        ])
        .arg("--cache-dir")
        .arg(dir.path().join("cache"))
        .env("KILN_TLS_CA", &cert_pem)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _worker = Guard(worker);
    let furnace = scene("furnace/scene.pbrt");
    let args = ["--spp", "2", "--resolution", "32x32", "--tile", "16"];
    let out = dir.path().join("farm.exr");
    let o = kiln()
        .arg("submit")
        .arg(&furnace)
        .args([
            "--coordinator",
            &url,
            "--token",
            "tls-s3cret",
            "--wait",
            "-q",
            "-o",
        ])
        .arg(&out)
        .args(args)
        .env("KILN_TLS_CA", &cert_pem)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let direct = render(&furnace, dir.path(), "direct", &args).bytes;
    assert!(
        std::fs::read(&out).unwrap() == direct,
        "the job through https differs from kiln render"
    );
}
