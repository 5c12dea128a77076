//! The object store against a real S3 server: `KILN_TEST_S3` is its endpoint, with a
//! bucket `kiln-test` (deploy/test-s3.sh starts moto's server and makes it). Without it
//! these tests print SKIPPED, unless `KILN_REQUIRE_S3` is set, when they fail.

use super::{AmazonS3Builder, Objects};
use object_store::{ObjectStoreExt, PutPayload};

/// No object of these tests comes near it.
const LIMIT: u64 = 1 << 30;

/// A prefix of the test bucket no other test uses, or None (SKIPPED) without a server.
pub(in crate::coordinator) fn fresh_objects(test: &str) -> Option<Objects> {
    let Some(endpoint) = std::env::var("KILN_TEST_S3").ok().filter(|u| !u.is_empty()) else {
        assert!(
            std::env::var_os("KILN_REQUIRE_S3").is_none(),
            "{test}: KILN_REQUIRE_S3 is set but KILN_TEST_S3 names no server"
        );
        println!(
            "{test}: SKIPPED: no S3 server (set KILN_TEST_S3 to an endpoint with a bucket kiln-test)"
        );
        return None;
    };
    let url = format!("s3://kiln-test/{test}-{}", std::process::id());
    let builder = AmazonS3Builder::new()
        .with_endpoint(endpoint)
        .with_access_key_id("kiln")
        .with_secret_access_key("kiln")
        .with_region("us-east-1");
    Some(Objects::build(&url, builder, true).unwrap())
}

#[test]
fn objects_are_kept_whole_and_checked_when_read() {
    let Some(objects) = fresh_objects("roundtrip") else {
        return;
    };
    assert_eq!(objects.get("bundles/none", LIMIT).unwrap(), None);
    assert!(!objects.exists("bundles/none").unwrap());
    objects
        .put("bundles/small", b"a scene".to_vec().into())
        .unwrap();
    assert!(objects.exists("bundles/small").unwrap());
    assert_eq!(
        objects.get("bundles/small", LIMIT).unwrap().unwrap(),
        b"a scene"
    );
    // Past 16 MiB, in parts.
    let big: Vec<u8> = (0..(40u32 << 20))
        .map(|i| (i.wrapping_mul(2654435761u32) >> 24) as u8)
        .collect();
    objects
        .put("jobs/1/frame-0.exr", big.clone().into())
        .unwrap();
    assert!(objects.get("jobs/1/frame-0.exr", LIMIT).unwrap().unwrap() == big);
    // An object whose bytes changed under it (a damaged copy) is an error, never data.
    let store = objects.store.clone();
    objects
        .block(async move {
            store
                .put(&"bundles/small".into(), PutPayload::from_static(b"a scenE"))
                .await
        })
        .unwrap()
        .unwrap();
    let err = objects.get("bundles/small", LIMIT).unwrap_err().to_string();
    assert!(
        err.contains("damaged") && err.contains("bundles/small"),
        "{err}"
    );
}

#[test]
fn a_url_that_is_not_a_bucket_is_refused() {
    for bad in ["kiln-test/x", "s3:///x", "http://bucket"] {
        let err = Objects::open(bad).err().unwrap();
        assert!(err.contains(bad), "{err}");
    }
}
