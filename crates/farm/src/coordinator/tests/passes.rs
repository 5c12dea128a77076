//! Progressive passes through the app: passes lent in order, each tile's pass continuing
//! the sums its last upload carried, a whole frame merged after each pass, a job stopped
//! after the pass in progress and extended later, and all of it across a restart.

use super::*;
use crate::api::PassRange;

fn range(index: u32, from: u32, to: u32) -> PassRange {
    PassRange { index, from, to }
}

async fn post_json(app: &Router, path: &str, body: &str) -> (StatusCode, Bytes) {
    let req = Request::builder()
        .method("POST")
        .uri(path)
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from(body.to_string()))
        .unwrap();
    send(app, req).await
}

async fn get(app: &Router, path: &str) -> (StatusCode, Bytes) {
    call(app, "GET", path, None, Body::empty()).await
}

/// Uploads `lease`'s tile, every pixel `value`; returns its bytes.
async fn land(app: &Router, lease: &Lease, value: f32) -> Vec<u8> {
    let bytes = exr(&tile_of(lease, (16, 8), value));
    let (status, body) = upload(app, lease.lease, bytes.clone()).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    bytes
}

async fn result_pixels(app: &Router, job: u64) -> Vec<[f32; 3]> {
    let (status, body) = get(app, &format!("/v1/jobs/{job}/result.exr")).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    kiln_image::decode_exr(&body).unwrap().pixels
}

#[tokio::test]
async fn passes_go_in_order_merge_whole_frames_stop_and_extend() {
    let f = farm(None);
    let data = f.dir.path().join("data");
    // Two 8x8 tiles, passes ending at 64, 80 and 96 samples.
    let job = submit_passes(&f, 16, 8, 8, Some(vec![64, 80, 96])).await;
    let a = lease(&f.app, "w").await.unwrap();
    let b = lease(&f.app, "w").await.unwrap();
    assert_eq!((a.tile_index, a.pass), (0, range(0, 0, 64)));
    assert_eq!((b.tile_index, b.pass), (1, range(0, 0, 64)));
    assert!(lease(&f.app, "w").await.is_none(), "both tiles are lent");
    // A first pass has no sums to continue.
    let (status, _) = get(&f.app, &format!("/v1/leases/{}/sums", a.lease)).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let a_bytes = land(&f.app, &a, 1.0).await;
    // Tile 0 may go on to its second pass before tile 1 is back (one pass ahead).
    let c = lease(&f.app, "w").await.unwrap();
    assert_eq!((c.tile_index, c.pass), (0, range(1, 64, 80)));
    let (status, sums) = get(&f.app, &format!("/v1/leases/{}/sums", c.lease)).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        &sums[..],
        &a_bytes[..],
        "the pass continues tile 0's first pass"
    );
    let s = job_status(&f.app, job).await;
    assert_eq!((s.passes_done, s.samples_per_pixel_done), (0, 0));
    let (status, _) = get(&f.app, &format!("/v1/jobs/{job}/result.exr")).await;
    assert_eq!(status, StatusCode::CONFLICT, "no pass is merged yet");
    land(&f.app, &b, 2.0).await;
    // The first pass is whole: merged, and the job runs on.
    let s = job_status(&f.app, job).await;
    assert_eq!(s.state, JobState::Running);
    assert_eq!((s.passes_done, s.samples_per_pixel_done), (1, 64));
    assert_eq!(s.passes, vec![64, 80, 96]);
    assert_eq!(s.samples_done, 64 * 64 + 64 * 64);
    let pixels = result_pixels(&f.app, job).await;
    assert_eq!((pixels[0], pixels[8]), ([1.0; 3], [2.0; 3]));
    let c_bytes = land(&f.app, &c, 3.0).await;
    let d = lease(&f.app, "w").await.unwrap();
    assert_eq!((d.tile_index, d.pass), (1, range(1, 64, 80)));
    // Tile 0 goes one pass ahead again, no further.
    let h = lease(&f.app, "w").await.unwrap();
    assert_eq!((h.tile_index, h.pass), (0, range(2, 80, 96)));
    assert!(lease(&f.app, "w").await.is_none());
    // Stopped now, the job ends after the pass in progress (80 samples); the pass already
    // lent beyond it is still taken back, and changes nothing.
    let (status, body) = post_json(&f.app, &format!("/v1/jobs/{job}/stop"), "").await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(json::<JobStatus>(&body).passes, vec![64, 80]);
    land(&f.app, &h, 5.0).await;
    assert_eq!(job_status(&f.app, job).await.passes_done, 1);
    land(&f.app, &d, 4.0).await;
    let s = job_status(&f.app, job).await;
    assert_eq!(s.state, JobState::Done);
    assert_eq!((s.passes_done, s.samples_per_pixel_done), (2, 80));
    let pixels = result_pixels(&f.app, job).await;
    assert_eq!((pixels[0], pixels[8]), ([3.0; 3], [4.0; 3]));
    // Extensions must go forward.
    let (status, body) = post_json(
        &f.app,
        &format!("/v1/jobs/{job}/extend"),
        r#"{"passes":[80]}"#,
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert!(
        error_of(&body).contains("each above"),
        "{}",
        error_of(&body)
    );
    // Extended, the done job runs on from its 80 samples.
    let (status, body) = post_json(
        &f.app,
        &format!("/v1/jobs/{job}/extend"),
        r#"{"passes":[96]}"#,
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{}", error_of(&body));
    let s: JobStatus = json(&body);
    assert_eq!(
        (s.state, s.passes.clone()),
        (JobState::Running, vec![64, 80, 96])
    );
    let e = lease(&f.app, "w").await.unwrap();
    assert_eq!((e.tile_index, e.pass), (0, range(2, 80, 96)));
    let (_, sums) = get(&f.app, &format!("/v1/leases/{}/sums", e.lease)).await;
    assert_eq!(&sums[..], &c_bytes[..]);
    land(&f.app, &e, 5.0).await;
    // A restart in the middle of the pass: the pass resumes where it was.
    let Farm { dir, c, app } = f;
    drop((c, app));
    let (_c, app) = open(&data, None);
    let s = job_status(&app, job).await;
    assert_eq!(s.state, JobState::Running);
    assert_eq!((s.passes_done, s.samples_per_pixel_done), (2, 80));
    assert_eq!(s.samples_done, 64 * 96 + 64 * 80);
    let g = lease(&app, "w").await.unwrap();
    assert_eq!((g.tile_index, g.pass), (1, range(2, 80, 96)));
    assert!(lease(&app, "w").await.is_none());
    land(&app, &g, 6.0).await;
    let s = job_status(&app, job).await;
    assert_eq!(s.state, JobState::Done);
    assert_eq!((s.passes_done, s.samples_per_pixel_done), (3, 96));
    let pixels = result_pixels(&app, job).await;
    assert_eq!((pixels[0], pixels[8]), ([5.0; 3], [6.0; 3]));
    drop(dir);
}

/// A tile's upload must carry the running sums of its own pass: sums of another sample
/// count, or none, are refused as a failed attempt.
#[tokio::test]
async fn an_upload_with_the_wrong_sums_is_refused() {
    let f = farm(None);
    submit_passes(&f, 16, 8, 16, Some(vec![4, 8])).await;
    let a = lease(&f.app, "w").await.unwrap();
    let mut wrong = a.clone();
    wrong.pass.to = 3;
    let (status, body) = upload(&f.app, a.lease, exr(&tile_of(&wrong, (16, 8), 1.0))).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("not the 4 of its pass"),
        "{}",
        error_of(&body)
    );
    let b = lease(&f.app, "w").await.unwrap();
    let mut bare = tile_of(&b, (16, 8), 1.0);
    bare.words = kiln_image::Words::default();
    let (status, body) = upload(&f.app, b.lease, exr(&bare)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("running sums"),
        "{}",
        error_of(&body)
    );
}

/// Schedules that cannot be rendered are refused when the job is created, saying why.
#[tokio::test]
async fn bad_schedules_are_refused_with_the_reason() {
    let f = farm(None);
    let digest = upload_scene(&f, 8, 8).await;
    for (passes, spp, says) in [
        ("[4, 4]", "null", "each above the one before"),
        ("[]", "null", "give 1 to 64 passes"),
        ("[4, 8]", "16", "spp 16 is not the last pass's 8"),
    ] {
        let body = format!(
            r#"{{"scene":"{}","tile":8,"passes":{passes},"spp":{spp}}}"#,
            digest
        );
        let (status, text) = post_json(&f.app, "/v1/jobs", &body).await;
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{passes}");
        assert!(
            error_of(&text).contains(says),
            "{passes}: {}",
            error_of(&text)
        );
    }
}
