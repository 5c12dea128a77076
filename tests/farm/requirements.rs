//! What a job asks of the farm, through the processes: worker tags and requirements
//! (`kiln worker --tags`, `kiln submit --requires --max-workers`: the tagged worker renders
//! the whole job while an untagged one waits), jobs that start after others (`kiln submit
//! --after`), and tags or jobs that are not, refused by name.

use super::Farm;
use crate::util::{kiln, scene};
use kiln_farm::api::JobState;
use std::time::Duration;

/// Runs `kiln` with `args`, which must fail with a message holding `names`.
fn assert_refused(args: &[&str], names: &str) {
    let o = kiln().args(args).output().unwrap();
    assert!(!o.status.success(), "{args:?} succeeded");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(names), "{err}");
}

#[test]
fn a_job_that_requires_tags_is_rendered_only_by_the_worker_that_has_them() {
    let farm = Farm::in_process(None);
    let plain = farm.worker("plain");
    let tagged = farm.worker_with("tagged", "cache-tagged", &["--tags", "gpu,big-mem"]);
    let id = farm.submit(
        &scene("furnace/scene.pbrt"),
        &[
            "--spp",
            "1",
            "--resolution",
            "32x32",
            "--tile",
            "16",
            "--requires",
            "gpu",
            "--max-workers",
            "1",
        ],
    );
    let status = farm.wait_done(id, Duration::from_secs(120));
    assert_eq!(status.state, JobState::Done, "{status:?}");
    assert_eq!(
        (status.requires.clone(), status.max_workers),
        (vec!["gpu".to_string()], Some(1))
    );
    let workers = farm.rt.block_on(farm.client.workers()).unwrap();
    let done = |name: &str| {
        workers
            .iter()
            .find(|w| w.name == name)
            .map(|w| (w.tiles_done, w.tags.clone()))
    };
    assert_eq!(
        done("tagged"),
        Some((4, vec!["gpu".into(), "big-mem".into()]))
    );
    // Workers offer the machine's memory unless told otherwise (Linux says how much).
    if std::path::Path::new("/proc/meminfo").exists() {
        assert!(workers.iter().all(|w| w.memory_mib.is_some_and(|m| m > 0)));
    }
    assert!(status.memory_mib >= 16, "{status:?}");
    // The untagged worker asked for work all along and was given none of it.
    assert_eq!(done("plain"), Some((0, vec![])), "{}", plain.text());
    // The CLI's lists: a table for people, the API's JSON for scripts.
    let list = |what: &str, json: bool| {
        let mut cmd = kiln();
        cmd.args([what, "--coordinator", &farm.url]);
        if json {
            cmd.arg("--json");
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let table = list("workers", false);
    let row = table
        .lines()
        .find(|l| l.starts_with("tagged"))
        .expect(&table);
    assert!(
        row.contains("gpu,big-mem") && row.contains(" 4 "),
        "{table}"
    );
    let jobs: Vec<kiln_farm::api::JobStatus> = serde_json::from_str(&list("jobs", true)).unwrap();
    assert_eq!(
        (jobs.len(), jobs[0].id, jobs[0].state),
        (1, id, JobState::Done)
    );
    assert!(list("jobs", false).lines().nth(1).unwrap().contains("done"));
    drop((plain, tagged));
    // A job nobody can take says so.
    let waiting = farm.submit(
        &scene("furnace/scene.pbrt"),
        &[
            "--spp",
            "1",
            "--resolution",
            "16x16",
            "--requires",
            "big-mem,tpu",
        ],
    );
    let why = farm.status(waiting).waiting.expect("no worker has tpu");
    assert!(why.contains("tpu") && !why.contains("big-mem"), "{why}");
}

#[test]
fn tags_that_are_not_tags_are_refused_by_name() {
    let farm = Farm::in_process(None);
    let url = farm.url.as_str();
    assert_refused(
        &["worker", "--coordinator", url, "--tags", "ok,Not Ok"],
        "'Not Ok'",
    );
    assert_refused(
        &["worker", "--coordinator", url, "--memory", "lots"],
        "'lots'",
    );
    let furnace = scene("furnace/scene.pbrt");
    let furnace = furnace.to_str().unwrap();
    assert_refused(
        &["submit", furnace, "--coordinator", url, "--requires", "a/b"],
        "'a/b'",
    );
}

#[test]
fn a_job_submitted_after_another_waits_for_it_then_renders() {
    let farm = Farm::in_process(None);
    let args = ["--spp", "1", "--resolution", "16x16"];
    let first = farm.submit(&scene("furnace/scene.pbrt"), &args);
    let after = first.to_string();
    let second = farm.submit(
        &scene("furnace/scene.pbrt"),
        &[&args[..], &["--after", &after]].concat(),
    );
    let why = farm
        .status(second)
        .waiting
        .expect("no worker yet, and the first not done");
    assert!(why.contains(&format!("job {first}")), "{why}");
    let w = farm.worker("w");
    for id in [first, second] {
        let s = farm.wait_done(id, Duration::from_secs(120));
        assert_eq!(s.state, JobState::Done, "{s:?} {}", w.text());
    }
    assert_eq!(farm.status(second).after, vec![first]);
    let furnace = scene("furnace/scene.pbrt");
    let url = farm.url.as_str();
    let args = [
        "submit",
        furnace.to_str().unwrap(),
        "--coordinator",
        url,
        "--after",
        "999",
    ];
    assert_refused(&args, "no job 999");
}
