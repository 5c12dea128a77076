//! The dashboard in a real browser: tests/dashboard/drive.py drives headless Chromium
//! (Debian's chromium and chromium-driver, Selenium from PyPI, which .ci/run installs)
//! against a coordinator with a token and a worker started once the browser has signed in:
//! it stops a job after its first pass before it starts, watches another go through its
//! passes to done while the frame's pixels change and its ETA and the worker's tile show,
//! moves the exposure, shows the denoised frame and the raw one again, downloads the EXR,
//! extends the job, downloads the stopped job's
//! PNG, cancels a third job, shows a shot's strip of frames and downloads its third frame,
//! revokes a worker's credential (the worker stops, refused) and signs in as a submitter
//! who sees only its own job, and checks a narrow screen, a frame and a screenshot that are
//! not blank and a console without errors. Where Chromium or Selenium is missing it
//! prints SKIPPED.

use crate::farm::Farm;
use crate::farm::Worker;
use crate::util::{repo, scene};
use kiln_farm::api::{JobSpec, JobState, Role, TokenRequest};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

/// Why the browser test cannot run here, if it cannot.
fn missing() -> Option<String> {
    for exe in ["/usr/bin/chromium", "/usr/bin/chromedriver"] {
        if !Path::new(exe).exists() {
            return Some(format!(
                "{exe} is not installed (apt-get install chromium chromium-driver)"
            ));
        }
    }
    let selenium = Command::new("python3")
        .args(["-c", "import selenium"])
        .output();
    if !selenium.is_ok_and(|o| o.status.success()) {
        return Some("python3 cannot import selenium (pip install selenium)".into());
    }
    None
}

#[test]
fn the_dashboard_works_in_a_real_browser() {
    if let Some(why) = missing() {
        // CI installs them and says so: there a missing browser is a failure.
        assert!(
            std::env::var_os("KILN_REQUIRE_BROWSER").is_none(),
            "KILN_REQUIRE_BROWSER is set but {why}"
        );
        println!("SKIPPED the_dashboard_works_in_a_real_browser: {why}");
        return;
    }
    let token = "s3cret-dashboard-token";
    let farm = Farm::in_process(Some(token));
    let (rt, client, url, dir) = (&farm.rt, &farm.client, &farm.url, &farm.dir);
    let digest = farm.upload(&scene("materials/scene.pbrt"));
    let spec = |passes: Vec<u32>, priority: i32| JobSpec {
        resolution: Some((192, 128)),
        passes: Some(passes),
        priority,
        ..JobSpec::new(&digest)
    };
    // A job of four passes to watch, one below it in priority to stop after its first
    // pass, and one below that to cancel.
    let watch = rt
        .block_on(client.create_job(&spec(vec![8, 64, 256, 512], 0), None))
        .unwrap();
    let stop = rt
        .block_on(client.create_job(&spec(vec![8, 4096], -1), None))
        .unwrap();
    let cancel = rt
        .block_on(client.create_job(&spec(vec![4096], -2), None))
        .unwrap();
    // A shot of three small frames sharing a mesh, rendered first.
    let shot_dir = dir.path().join("shot");
    std::fs::create_dir_all(&shot_dir).unwrap();
    std::fs::write(
        shot_dir.join("ball.ply"),
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n-2 -1 -2\n2 -1 -2\n2 -1 2\n-2 -1 2\n3 0 2 1\n3 0 3 2\n",
    )
    .unwrap();
    let frames: Vec<std::path::PathBuf> = (0..3)
        .map(|k| {
            let path = shot_dir.join(format!("f{k}.pbrt"));
            let c = [0.8, 0.2 + 0.3 * k as f32, 0.2];
            std::fs::write(
                &path,
                format!(
                    "LookAt 0 1 -4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 50\nFilm \"rgb\" \"integer xresolution\" [ 64 ] \"integer yresolution\" [ 48 ]\nWorldBegin\nLightSource \"infinite\" \"rgb L\" [0.6 0.7 0.8]\nShape \"plymesh\" \"string filename\" \"ball.ply\"\nMaterial \"diffuse\" \"rgb reflectance\" [{} {} {}]\nShape \"sphere\" \"float radius\" 0.8\n",
                    c[0], c[1], c[2]
                ),
            )
            .unwrap();
            path
        })
        .collect();
    let (bundle, names) = kiln_farm::bundle::pack_frames(&frames).unwrap();
    let shot_digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let shot_job = rt
        .block_on(client.create_job(
            &JobSpec {
                spp: Some(4),
                tile: 32,
                priority: 1,
                frames: names,
                ..JobSpec::new(&shot_digest)
            },
            None,
        ))
        .unwrap();
    // A submitter with a job of its own, and a worker under its own credential, which the
    // browser revokes.
    let issue = |role: Role, name: &str| {
        let req = TokenRequest {
            role,
            name: name.into(),
        };
        rt.block_on(client.issue_token(&req)).unwrap()
    };
    let alice = issue(Role::Submitter, "alice");
    let w2 = issue(Role::Worker, "w2");
    let as_alice = kiln_farm::client::Client::new(url, Some(alice.token.clone()));
    let alices = rt
        .block_on(as_alice.create_job(&spec(vec![4], -3), None))
        .unwrap();
    let shot = dir.path().join("dashboard.png");
    let mut driver = Command::new("python3")
        .arg(repo().join("tests/dashboard/drive.py"))
        .args(["--url", url, "--token", token])
        .args([
            "--watch",
            &watch.to_string(),
            "--stop",
            &stop.to_string(),
            "--cancel",
            &cancel.to_string(),
            "--shot",
            &shot_job.to_string(),
            "--submitter-token",
            &alice.token,
            "--submitter-job",
            &alices.to_string(),
            "--revoke",
            &w2.info.id.to_string(),
        ])
        .arg("--screenshot")
        .arg(&shot)
        .arg("--shot-screenshot")
        .arg(dir.path().join("dashboard-shot.png"))
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(dir.path().join("drive.err")).unwrap())
        .spawn()
        .unwrap();
    // The worker starts once the browser has signed in, so the browser sees the watched
    // job from its first tile, however fast this machine renders it.
    let mut worker = None;
    let mut said = String::new();
    for line in BufReader::new(driver.stdout.take().unwrap()).lines() {
        let line = line.unwrap();
        println!("{line}");
        if line == "dashboard: signed in" && worker.is_none() {
            let log = dir.path().join("w2.log");
            let cache = dir.path().join("cache-w2");
            let credential = ["--token", w2.token.as_str()];
            worker = Some((
                farm.worker_with("w1", "cache-w1", &["--tags", "big-mem"]),
                Worker {
                    child: crate::farm::start_worker_with(url, "w2", &cache, &log, &credential),
                    log,
                },
            ));
        }
        said += &line;
        said.push('\n');
    }
    let status = driver.wait().unwrap();
    let errors = std::fs::read_to_string(dir.path().join("drive.err")).unwrap_or_default();
    assert!(status.success(), "the browser test failed:\n{said}{errors}");
    let s = rt.block_on(client.status(watch)).unwrap();
    assert_eq!(
        (s.state, s.passes_done, s.samples_per_pixel_done),
        (JobState::Done, 5, 1024)
    );
    let s = rt.block_on(client.status(stop)).unwrap();
    assert_eq!(
        (s.state, s.passes, s.samples_per_pixel_done),
        (JobState::Done, vec![8], 8)
    );
    let s = rt.block_on(client.status(cancel)).unwrap();
    assert_eq!(s.state, JobState::Cancelled);
    let s = rt.block_on(client.status(shot_job)).unwrap();
    assert_eq!((s.state, s.frame_count), (JobState::Done, 3));
    // The revoked worker was refused at its next request and stopped.
    let (_, mut revoked) = worker.expect("the workers started");
    assert!(
        !revoked
            .wait_exit(std::time::Duration::from_secs(30))
            .success()
    );
    assert!(
        revoked.text().contains("missing or wrong bearer token"),
        "{}",
        revoked.text()
    );
    assert!(std::fs::metadata(&shot).unwrap().len() > 10_000);
    // The README's picture comes from here: KILN_DASHBOARD_SCREENSHOT=docs/src/dashboard.png.
    if let Ok(keep) = std::env::var("KILN_DASHBOARD_SCREENSHOT") {
        std::fs::copy(&shot, keep).unwrap();
    }
    // And the manual's picture of a shot: KILN_DASHBOARD_SHOT_SCREENSHOT=docs/src/dashboard-shot.png.
    if let Ok(keep) = std::env::var("KILN_DASHBOARD_SHOT_SCREENSHOT") {
        std::fs::copy(dir.path().join("dashboard-shot.png"), keep).unwrap();
    }
}
