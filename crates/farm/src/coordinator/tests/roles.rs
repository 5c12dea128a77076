//! Roles and credentials: the admin issues submitter tokens and worker credentials and
//! revokes them; a submitter sees and changes only its own jobs; a worker's credential
//! leases only under its own name and touches only its own leases; a revoked token is
//! refused at its next request, and its worker's leases are lent again; tokens are kept
//! across restarts as hashes, listed without their secrets, and never echoed in an error.

use super::*;
use crate::api::{Role, TokenCheck, TokenInfo, TokenIssued};

const ADMIN: &str = "admin-s3cret";

async fn issue(f: &Farm, role: &str, name: &str) -> TokenIssued {
    let body = format!("{{\"role\": \"{role}\", \"name\": \"{name}\"}}");
    let (status, body) = call(&f.app, "POST", "/v1/tokens", Some(ADMIN), body).await;
    assert_eq!(
        status,
        StatusCode::CREATED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    json(&body)
}

/// Uploads the small scene and creates a job with `token`: its id.
async fn submit_as(f: &Farm, token: &str) -> u64 {
    let dir = f.dir.path().join("scene");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("scene.pbrt"),
        "Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\nWorldBegin\nLightSource \"infinite\"\n",
    )
    .unwrap();
    let bundle = crate::bundle::pack(&dir.join("scene.pbrt")).unwrap();
    let (status, _) = call(&f.app, "POST", "/v1/scenes", Some(token), bundle.bytes).await;
    assert_eq!(status, StatusCode::OK);
    let spec = JobSpec {
        spp: Some(1),
        tile: 16,
        // A client cannot say whose the job is.
        owner: Some("mallory".into()),
        ..JobSpec::new(&bundle.digest)
    };
    let body = serde_json::to_vec(&spec).unwrap();
    let (status, body) = call(&f.app, "POST", "/v1/jobs", Some(token), body).await;
    assert_eq!(
        status,
        StatusCode::CREATED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    json::<crate::api::JobCreated>(&body).id
}

async fn lease_as(f: &Farm, token: &str, worker: &str) -> (StatusCode, Bytes) {
    let body = format!("{{\"worker\": \"{worker}\"}}");
    call(&f.app, "POST", "/v1/leases", Some(token), body).await
}

#[tokio::test]
async fn each_role_does_only_its_part_and_a_revoked_token_is_refused_at_once() {
    let mut f = farm(Some(ADMIN));
    let alice = issue(&f, "submitter", "alice").await;
    let bob = issue(&f, "submitter", "bob").await;
    let w1 = issue(&f, "worker", "w1").await;
    assert_eq!(
        (alice.info.role, w1.info.role),
        (Role::Submitter, Role::Worker)
    );
    assert!(alice.token.starts_with("kiln-") && alice.token.len() == 69);
    // Only the admin issues and lists tokens; the list never holds a secret.
    let (status, _) = call(
        &f.app,
        "POST",
        "/v1/tokens",
        Some(&alice.token),
        "{\"role\": \"admin\", \"name\": \"me\"}",
    )
    .await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    let (status, body) = call(&f.app, "GET", "/v1/tokens", Some(ADMIN), Body::empty()).await;
    assert_eq!(status, StatusCode::OK);
    let text = String::from_utf8_lossy(&body);
    assert!(
        !text.contains(&alice.token) && !text.contains(&w1.token),
        "{text}"
    );
    assert_eq!(json::<Vec<TokenInfo>>(&body).len(), 3);
    // A name that is not one is refused, naming it.
    let (status, body) = call(
        &f.app,
        "POST",
        "/v1/tokens",
        Some(ADMIN),
        "{\"role\": \"worker\", \"name\": \"a b\"}",
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).contains("'a b'"), "{}", error_of(&body));

    // A submitter's job is its own: another submitter sees nothing of it.
    let job = submit_as(&f, &alice.token).await;
    let (_, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}"),
        Some(&alice.token),
        Body::empty(),
    )
    .await;
    assert_eq!(json::<JobStatus>(&body).owner.as_deref(), Some("alice"));
    let (_, body) = call(&f.app, "GET", "/v1/jobs", Some(&bob.token), Body::empty()).await;
    assert!(json::<Vec<JobStatus>>(&body).is_empty());
    for (method, path) in [
        ("GET", format!("/v1/jobs/{job}")),
        ("POST", format!("/v1/jobs/{job}/cancel")),
        ("GET", format!("/v1/jobs/{job}/frames/0/preview.png")),
    ] {
        let (status, body) = call(&f.app, method, &path, Some(&bob.token), Body::empty()).await;
        assert_eq!(status, StatusCode::NOT_FOUND, "{method} {path}");
        assert_eq!(error_of(&body), format!("no job {job}"));
    }
    let (_, body) = call(&f.app, "GET", "/v1/jobs", Some(ADMIN), Body::empty()).await;
    assert_eq!(
        json::<Vec<JobStatus>>(&body).len(),
        1,
        "the admin sees every job"
    );
    // A submitter does not lease or list workers; a worker does not see jobs.
    for (token, method, path) in [
        (&alice.token, "GET", "/v1/workers"),
        (&alice.token, "POST", "/v1/leases"),
        (&w1.token, "GET", "/v1/jobs"),
        (&w1.token, "GET", "/metrics"),
    ] {
        let (status, body) = call(&f.app, method, path, Some(token), "{}").await;
        assert_eq!(status, StatusCode::FORBIDDEN, "{method} {path}");
        assert!(
            error_of(&body).contains(&format!("may not {method} {path}")),
            "{}",
            error_of(&body)
        );
    }

    // A worker's credential is its name, and its leases are its own.
    let (status, body) = lease_as(&f, &w1.token, "w2").await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert!(
        error_of(&body).contains("worker w1's"),
        "{}",
        error_of(&body)
    );
    let (status, body) = lease_as(&f, &w1.token, "w1").await;
    assert_eq!(status, StatusCode::OK);
    let mine: Lease = json(&body);
    let other = f.c.lease("w9").unwrap();
    assert!(other.is_none(), "one tile, lent to w1");
    let beat = format!("/v1/leases/{}/heartbeat", mine.lease);
    assert_eq!(
        call(&f.app, "POST", &beat, Some(&w1.token), Body::empty())
            .await
            .0,
        StatusCode::NO_CONTENT
    );

    // Revoked: refused at the very next request, and the tile is lent again.
    let (status, body) = call(
        &f.app,
        "POST",
        &format!("/v1/tokens/{}/revoke", w1.info.id),
        Some(ADMIN),
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert!(json::<TokenInfo>(&body).revoked);
    let (status, body) = call(&f.app, "POST", &beat, Some(&w1.token), Body::empty()).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    assert!(
        !String::from_utf8_lossy(&body).contains(&w1.token),
        "the token is never echoed"
    );
    let again =
        f.c.lease("w9")
            .unwrap()
            .expect("the revoked worker's tile is lent again");
    assert_eq!(again.tile_index, mine.tile_index);
    let (status, _) = call(
        &f.app,
        "POST",
        "/v1/tokens/99/revoke",
        Some(ADMIN),
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);

    // The sign-in says who a token is.
    let check = |t: &str| format!("{{\"token\": \"{t}\"}}");
    let (_, body) = call(&f.app, "POST", "/v1/token/check", None, check(&alice.token)).await;
    assert_eq!(
        json::<TokenCheck>(&body),
        TokenCheck {
            valid: true,
            role: Some(Role::Submitter),
            name: Some("alice".into())
        }
    );
    let (_, body) = call(&f.app, "POST", "/v1/token/check", None, check(&w1.token)).await;
    assert!(!json::<TokenCheck>(&body).valid);

    // A restart keeps the tokens (their hashes) and what was revoked.
    drop(f.c);
    let (c, app) = open(&f.dir.path().join("data"), Some(ADMIN));
    (f.c, f.app) = (c, app);
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}"),
        Some(&alice.token),
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        lease_as(&f, &w1.token, "w1").await.0,
        StatusCode::UNAUTHORIZED
    );
    let secret = alice.token.as_bytes();
    for file in ["kiln.sqlite", "kiln.sqlite-wal"] {
        let bytes = std::fs::read(f.dir.path().join("data").join(file)).unwrap_or_default();
        assert!(
            !bytes.windows(secret.len()).any(|w| w == secret),
            "{file} keeps a secret"
        );
    }
    let hash = super::super::credentials::hash(&alice.token);
    let wal = std::fs::read(f.dir.path().join("data/kiln.sqlite-wal")).unwrap_or_default();
    let db = [
        std::fs::read(f.dir.path().join("data/kiln.sqlite")).unwrap(),
        wal,
    ]
    .concat();
    assert!(
        db.windows(64).any(|w| w == hash.as_bytes()),
        "its hash is what is kept"
    );
}
