//! Shots: a job of many frames is lent first, last, middle, then the rest; each frame is
//! pasted and merged into a result of its own, listed with its progress and previewed; a
//! frame list that names no scene of the bundle, or frames that differ in size, are
//! refused naming the frame, and nothing is created.

use super::*;
use crate::api::FrameStatus;

/// Uploads a shot of `count` frames, frame k's file `fK.pbrt` of the size `size(k)`, each
/// including the shared `world.pbrt`; returns the bundle's digest and the frames' names.
async fn upload_shot(
    f: &Farm,
    count: usize,
    size: impl Fn(usize) -> (u32, u32),
) -> (String, Vec<String>) {
    let dir = f
        .dir
        .path()
        .join(format!("shot-{count}-{}", size(count - 1).0));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("world.pbrt"), "LightSource \"infinite\"\n").unwrap();
    let frames: Vec<std::path::PathBuf> = (0..count)
        .map(|k| {
            let (w, h) = size(k);
            let path = dir.join(format!("f{k}.pbrt"));
            std::fs::write(
                &path,
                format!(
                    "Film \"rgb\" \"integer xresolution\" [ {w} ] \"integer yresolution\" [ {h} ]\nWorldBegin\nInclude \"world.pbrt\"\n"
                ),
            )
            .unwrap();
            path
        })
        .collect();
    let (bundle, names) = crate::bundle::pack_frames(&frames).unwrap();
    let (status, body) = call(&f.app, "POST", "/v1/scenes", None, bundle.bytes).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    (bundle.digest, names)
}

fn shot_spec(digest: String, frames: Vec<String>) -> JobSpec {
    JobSpec {
        spp: Some(1),
        tile: 8,
        frames,
        ..JobSpec::new(&digest)
    }
}

async fn frames_of(f: &Farm, job: u64) -> Vec<FrameStatus> {
    let (status, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/frames"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    json(&body)
}

#[tokio::test]
async fn a_shot_is_lent_first_last_middle_then_the_rest_and_each_frame_is_its_own_result() {
    let f = farm(None);
    let (digest, names) = upload_shot(&f, 5, |_| (8, 8)).await;
    assert_eq!(
        names,
        ["f0.pbrt", "f1.pbrt", "f2.pbrt", "f3.pbrt", "f4.pbrt"]
    );
    let (status, body) = post_job(&f, &shot_spec(digest, names)).await;
    assert_eq!(
        status,
        StatusCode::CREATED,
        "{}",
        String::from_utf8_lossy(&body)
    );
    let job = json::<crate::api::JobCreated>(&body).id;
    let s = job_status(&f.app, job).await;
    assert_eq!((s.frame_count, s.tiles_total), (5, 5));
    let mut lent = Vec::new();
    while let Some(l) = lease(&f.app, "w").await {
        lent.push(l);
    }
    let order: Vec<u32> = lent.iter().map(|l| l.frame).collect();
    assert_eq!(order, [0, 4, 2, 1, 3], "first, last, middle, then the rest");
    // Frame k's tile is worth k + 1 everywhere.
    let first = &lent[0];
    assert_eq!(
        upload(&f.app, first.lease, exr(&tile_of(first, (8, 8), 1.0)))
            .await
            .0,
        StatusCode::OK
    );
    let frames = frames_of(&f, job).await;
    assert_eq!(frames.len(), 5);
    assert_eq!(
        (
            frames[0].progress,
            frames[0].passes_done,
            frames[0].tiles_done
        ),
        (1.0, 1, 1)
    );
    assert!(
        frames[1..]
            .iter()
            .all(|fr| fr.progress == 0.0 && fr.passes_done == 0)
    );
    assert_eq!(frames[3].scene, "f3.pbrt");
    // A frame not merged yet has no result; one in progress has a preview.
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/frames/4/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT);
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/frames/4/preview.png"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    for l in &lent[1..] {
        let value = (l.frame + 1) as f32;
        let (status, body) = upload(&f.app, l.lease, exr(&tile_of(l, (8, 8), value))).await;
        assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    }
    let s = job_status(&f.app, job).await;
    assert_eq!(
        (s.state, s.passes_done, s.tiles_done),
        (JobState::Done, 1, 5)
    );
    for k in 0..5u32 {
        let (status, body) = call(
            &f.app,
            "GET",
            &format!("/v1/jobs/{job}/frames/{k}/result.exr"),
            None,
            Body::empty(),
        )
        .await;
        assert_eq!(status, StatusCode::OK);
        let frame = kiln_image::decode_exr(&body).unwrap();
        assert_eq!(
            frame.get(3, 5),
            [(k + 1) as f32; 3],
            "frame {k} holds its own tile"
        );
        // A finished frame's preview is drawn from its result file.
        let (status, png) = call(
            &f.app,
            "GET",
            &format!("/v1/jobs/{job}/frames/{k}/preview.png?exposure=1"),
            None,
            Body::empty(),
        )
        .await;
        assert_eq!(status, StatusCode::OK);
        assert!(png.starts_with(b"\x89PNG"));
    }
    // The job's own result is its first frame's.
    let (_, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(kiln_image::decode_exr(&body).unwrap().get(0, 0), [1.0; 3]);
    // No such frame, and a frame that is no number.
    let (status, body) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/frames/5/result.exr"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(
        error_of(&body).contains(&format!("job {job} has no frame 5")),
        "{}",
        error_of(&body)
    );
    let (status, _) = call(
        &f.app,
        "GET",
        &format!("/v1/jobs/{job}/frames/x/preview.png"),
        None,
        Body::empty(),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
}

#[tokio::test]
async fn bad_frame_lists_are_refused_naming_the_frame() {
    let f = farm(None);
    let (digest, names) = upload_shot(&f, 3, |_| (8, 8)).await;
    let missing = vec![names[0].clone(), names[1].clone(), "f9.pbrt".into()];
    assert_refused(
        &f,
        &shot_spec(digest.clone(), missing),
        "frames: frame 3: 'f9.pbrt' is not in the scene bundle",
    )
    .await;
    let outside = vec![names[0].clone(), "../f1.pbrt".into()];
    assert_refused(
        &f,
        &shot_spec(digest.clone(), outside),
        "frame 2: '../f1.pbrt' is not a path inside the scene bundle",
    )
    .await;
    let twice = vec![names[0].clone(), names[0].clone()];
    assert_refused(&f, &shot_spec(digest, twice), "listed twice").await;
    let (digest, names) = upload_shot(&f, 2, |k| (8 + 8 * k as u32, 8)).await;
    assert_refused(
        &f,
        &shot_spec(digest, names),
        "frame 2 (f1.pbrt): its film is 16x8 and frame 1's is 8x8",
    )
    .await;
}

#[tokio::test(start_paused = true)]
async fn a_shot_in_progress_resumes_after_a_restart() {
    let mut f = farm(None);
    let (digest, names) = upload_shot(&f, 3, |_| (16, 8)).await;
    let (_, body) = post_job(&f, &shot_spec(digest, names)).await;
    let job = json::<crate::api::JobCreated>(&body).id;
    // Frame 0 finishes (two tiles), and one tile of the last frame.
    for _ in 0..3 {
        let l = lease(&f.app, "w").await.unwrap();
        let value = (l.frame + 1) as f32;
        assert_eq!(
            upload(&f.app, l.lease, exr(&tile_of(&l, (16, 8), value)))
                .await
                .0,
            StatusCode::OK
        );
    }
    drop(f.c);
    let (c, app) = open(&f.dir.path().join("data"), None);
    (f.c, f.app) = (c, app);
    let frames = frames_of(&f, job).await;
    let done: Vec<u32> = frames.iter().map(|fr| fr.tiles_done).collect();
    assert_eq!(done, [2, 0, 1], "each frame keeps its tiles");
    assert_eq!(
        frames[0].passes_done, 1,
        "frame 0 is merged again on resume"
    );
    while let Some(l) = lease(&f.app, "w").await {
        let value = (l.frame + 1) as f32;
        assert_eq!(
            upload(&f.app, l.lease, exr(&tile_of(&l, (16, 8), value)))
                .await
                .0,
            StatusCode::OK
        );
    }
    assert_eq!(job_status(&f.app, job).await.state, JobState::Done);
    for k in 0..3u32 {
        let (_, body) = call(
            &f.app,
            "GET",
            &format!("/v1/jobs/{job}/frames/{k}/result.exr"),
            None,
            Body::empty(),
        )
        .await;
        let frame = kiln_image::decode_exr(&body).unwrap();
        assert_eq!(frame.get(15, 7), [(k + 1) as f32; 3]);
        assert_eq!(frame.get(0, 0), [(k + 1) as f32; 3]);
    }
}
