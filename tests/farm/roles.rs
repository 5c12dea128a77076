//! Roles and credentials through the processes: `kiln tokens` issues a submitter's token and
//! a worker's credential; a worker started with the credential under another name is
//! refused and stops, saying whose it is; under its own it renders the submitter's job,
//! which another submitter cannot see; revoked, it is refused at its next request and
//! stops; and the coordinator's log names tokens by id, never by their secrets.

use super::{Worker, free_port, listening, start_worker_with};
use crate::util::{kiln, scene};
use std::time::Duration;

const ADMIN: &str = "roles-admin-s3cret";

#[test]
fn credentials_issued_by_kiln_tokens_hold_each_role_to_its_part() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let url = format!("http://127.0.0.1:{port}");
    let log = dir.path().join("coordinator.log");
    let (_coordinator, _) = listening(
        kiln()
            .args([
                "coordinator",
                "--listen",
                &format!("127.0.0.1:{port}"),
                "--token",
                ADMIN,
            ])
            .arg("--data-dir")
            .arg(dir.path().join("data"))
            .env("RUST_LOG", "debug")
            .stderr(std::fs::File::create(&log).unwrap()),
    );
    let run = |token: &str, args: &[&str]| {
        let o = kiln()
            .args(args)
            .args(["--coordinator", &url, "--token", token])
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).trim().to_string(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let issue = |role: &str, name: &str| {
        let (ok, out, err) = run(ADMIN, &["tokens", "create", "--role", role, "--name", name]);
        assert!(ok, "{err}");
        out
    };
    let (alice, bob, w1) = (
        issue("submitter", "alice"),
        issue("submitter", "bob"),
        issue("worker", "w1"),
    );
    // Only the admin issues tokens.
    let (ok, _, err) = run(
        &alice,
        &["tokens", "create", "--role", "worker", "--name", "w9"],
    );
    assert!(
        !ok && err.contains("a submitter token may not POST /v1/tokens"),
        "{err}"
    );

    // A credential under another name: refused, and the worker stops saying whose it is.
    let impostor_log = dir.path().join("impostor.log");
    let mut impostor = Worker {
        child: start_worker_with(
            &url,
            "w2",
            &dir.path().join("cache-w2"),
            &impostor_log,
            &["--token", &w1],
        ),
        log: impostor_log,
    };
    assert!(!impostor.wait_exit(Duration::from_secs(30)).success());
    assert!(
        impostor.text().contains("this credential is worker w1's"),
        "{}",
        impostor.text()
    );

    // Under its own name it renders the submitter's job.
    let w1_log = dir.path().join("w1.log");
    let mut worker = Worker {
        child: start_worker_with(
            &url,
            "w1",
            &dir.path().join("cache-w1"),
            &w1_log,
            &["--token", &w1],
        ),
        log: w1_log,
    };
    let out = dir.path().join("alice.exr");
    let furnace = scene("furnace/scene.pbrt");
    let (ok, _, err) = run(
        &alice,
        &[
            "submit",
            furnace.to_str().unwrap(),
            "--spp",
            "1",
            "--resolution",
            "32x32",
            "--tile",
            "16",
            "--wait",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
    assert!(out.exists());
    let jobs = |token: &str| -> Vec<kiln_farm::api::JobStatus> {
        let (ok, out, err) = run(token, &["jobs", "--json"]);
        assert!(ok, "{err}");
        serde_json::from_str(&out).unwrap()
    };
    assert_eq!(jobs(&alice).len(), 1);
    assert_eq!(jobs(&alice)[0].owner.as_deref(), Some("alice"));
    assert!(jobs(&bob).is_empty(), "bob sees alice's job");
    let (ok, _, err) = run(&bob, &["workers"]);
    assert!(!ok && err.contains("may not GET /v1/workers"), "{err}");

    // Revoked: the worker's next request for work is refused, and it stops.
    let (_, listed, _) = run(ADMIN, &["tokens", "list", "--json"]);
    let all: Vec<kiln_farm::api::TokenInfo> = serde_json::from_str(&listed).unwrap();
    assert_eq!(all.len(), 3);
    let id = all.iter().find(|t| t.name == "w1").unwrap().id;
    let (ok, said, err) = run(ADMIN, &["tokens", "revoke", &id.to_string()]);
    assert!(ok && said.contains("is revoked"), "{err}");
    assert!(!worker.wait_exit(Duration::from_secs(30)).success());
    assert!(
        worker.text().contains("missing or wrong bearer token"),
        "{}",
        worker.text()
    );
    let (_, table, _) = run(ADMIN, &["tokens", "list"]);
    assert!(
        table
            .lines()
            .any(|l| l.contains("w1") && l.ends_with("revoked")),
        "{table}"
    );

    // No secret in any log: the coordinator's names tokens by id.
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains(&format!("token {id} revoked")), "{text}");
    for (name, secret) in [
        ("admin", ADMIN),
        ("alice", alice.as_str()),
        ("bob", bob.as_str()),
        ("w1", w1.as_str()),
    ] {
        assert!(
            !text.contains(secret),
            "the coordinator's log holds {name}'s token"
        );
        assert!(
            !worker.text().contains(secret) && !impostor.text().contains(secret),
            "a worker's log holds {name}'s token"
        );
    }
}
