//! The dashboard in a real browser: tests/dashboard/drive.py drives headless Chromium
//! (Debian's chromium and chromium-driver, Selenium from PyPI, which .ci/run installs)
//! against a coordinator with a token and a worker: it signs in, watches a job go through
//! its passes to done while the frame changes, moves the exposure, downloads the EXR,
//! cancels another job, checks a narrow screen, a screenshot that is not blank and a
//! console without errors. Where Chromium or Selenium is missing it prints SKIPPED.

use crate::farm::{in_process, start_worker_with};
use crate::util::{repo, scene};
use kiln_farm::api::{JobSpec, JobState};
use kiln_farm::client::Client;
use std::path::Path;
use std::process::Command;

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
    let dir = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let token = "s3cret-dashboard-token";
    let url = in_process(&rt, &dir.path().join("data"), Some(token));
    let client = Client::new(&url, Some(token.to_string()));
    let bundle = kiln_farm::bundle::pack(&scene("materials/scene.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = |passes: Vec<u32>, priority: i32| JobSpec {
        scene: digest.clone(),
        spp: None,
        resolution: Some((192, 128)),
        tile: 32,
        seed: None,
        passes: Some(passes),
        verify: None,
        priority,
        webhook: None,
    };
    // A job of four passes to watch, and one below it in priority to cancel.
    let watch = rt
        .block_on(client.create_job(&spec(vec![8, 32, 128, 256], 0), None))
        .unwrap();
    let cancel = rt
        .block_on(client.create_job(&spec(vec![4096], -1), None))
        .unwrap();
    let _worker = start_worker_with(
        &url,
        "w1",
        &dir.path().join("cache"),
        &dir.path().join("w.log"),
        &["--token", token],
    );
    let shot = dir.path().join("dashboard.png");
    let out = Command::new("python3")
        .arg(repo().join("tests/dashboard/drive.py"))
        .args(["--url", &url, "--token", token])
        .args([
            "--watch",
            &watch.to_string(),
            "--cancel",
            &cancel.to_string(),
        ])
        .arg("--screenshot")
        .arg(&shot)
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{said}");
    assert!(out.status.success(), "the browser test failed:\n{said}");
    let s = rt.block_on(client.status(watch)).unwrap();
    assert_eq!((s.state, s.passes_done), (JobState::Done, 4));
    let s = rt.block_on(client.status(cancel)).unwrap();
    assert_eq!(s.state, JobState::Cancelled);
    assert!(std::fs::metadata(&shot).unwrap().len() > 10_000);
    // The README's picture comes from here: KILN_DASHBOARD_SCREENSHOT=docs/dashboard.png.
    if let Ok(keep) = std::env::var("KILN_DASHBOARD_SCREENSHOT") {
        std::fs::copy(&shot, keep).unwrap();
    }
}
