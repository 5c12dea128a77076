//! Denoised previews: `preview.png?denoise=1` denoises the merged frame with its features,
//! the same bytes on every request; a frame without variance, or a bad value, is refused
//! with its reason.

use super::*;

/// `lease`'s tile with noisy pixels and the features of a flat grey wall: every pixel's
/// variance says how noisy it is.
fn noisy_tile_of(lease: &Lease, frame: (u32, u32)) -> RgbBuffer {
    let mut tile = tile_of(lease, frame, 0.5);
    for (i, p) in tile.pixels.iter_mut().enumerate() {
        let noise = ((i * 7919) % 13) as f32 / 13.0 - 0.5;
        *p = [0.5 + 0.3 * noise; 3];
    }
    let names = tile.aovs.names.clone();
    let per = names.len();
    for (k, name) in names.iter().enumerate() {
        let value = match name.as_str() {
            n if n.starts_with("features.albedo") => 0.5,
            "features.normal.Z" | "features.depth" => 1.0,
            n if n.starts_with("features.variance") => 0.01,
            _ => 0.0,
        };
        for px in tile.aovs.values.chunks_exact_mut(per) {
            px[k] = value;
        }
    }
    tile
}

async fn preview(app: &Router, job: u64, query: &str) -> (StatusCode, Bytes) {
    let path = format!("/v1/jobs/{job}/preview.png{query}");
    call(app, "GET", &path, None, Body::empty()).await
}

#[tokio::test]
async fn a_denoised_preview_is_the_frame_denoised_the_same_on_every_request() {
    let f = farm(None);
    let frame = (32, 16);
    let job = submit(&f, 32, 16, 16).await;
    // Nothing rendered yet: the black frame's features say nothing of its noise.
    let (status, body) = preview(&f.app, job, "?denoise=1").await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert!(
        error_of(&body).contains("cannot be denoised"),
        "{}",
        error_of(&body)
    );
    let (status, body) = preview(&f.app, job, "?denoise=maybe").await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).contains("denoise"), "{}", error_of(&body));
    let a = lease(&f.app, "w").await.unwrap();
    let (status, _) = upload(&f.app, a.lease, exr(&noisy_tile_of(&a, frame))).await;
    assert_eq!(status, StatusCode::OK);
    let (status, raw) = preview(&f.app, job, "?denoise=0").await;
    assert_eq!(status, StatusCode::OK);
    let (status, first) = preview(&f.app, job, "?denoise=1&exposure=0").await;
    assert_eq!(status, StatusCode::OK);
    assert_ne!(raw, first, "the denoiser smoothed the noise");
    assert_eq!(preview(&f.app, job, "?denoise=true").await.1, first);
    // Finished, the frame is denoised from its result file, the same way every time.
    let b = lease(&f.app, "w").await.unwrap();
    let (status, _) = upload(&f.app, b.lease, exr(&noisy_tile_of(&b, frame))).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(job_status(&f.app, job).await.state, JobState::Done);
    let (status, done) = preview(&f.app, job, "?denoise=1").await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(preview(&f.app, job, "?denoise=1").await.1, done);
    assert_ne!(preview(&f.app, job, "").await.1, done);
}

/// A frame larger than the coordinator denoises is refused with the limit and what to do
/// instead, before anything of its size is allocated; the raw preview is still served.
#[tokio::test]
async fn a_frame_too_large_to_denoise_is_refused_with_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = Config::new(dir.path().join("data"));
    config.max_denoised_pixels = 500;
    let c = Coordinator::open(config).unwrap();
    let f = Farm {
        dir,
        app: app(c.clone()),
        c,
    };
    let job = submit(&f, 32, 16, 16).await;
    let (status, body) = preview(&f.app, job, "?denoise=1").await;
    assert_eq!(status, StatusCode::CONFLICT);
    let error = error_of(&body);
    assert!(
        error.contains("512 pixels") && error.contains("500"),
        "{error}"
    );
    assert_eq!(preview(&f.app, job, "").await.0, StatusCode::OK);
}
