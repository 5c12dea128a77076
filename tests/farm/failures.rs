//! What the farm survives: workers killed mid-job, a coordinator killed and started again,
//! signals to stop, a worker that keeps failing, a job that cannot be rendered, and a
//! seeded run of random kills.

use super::{Farm, Worker, wait_for};
use crate::util::{render, scene};
use kiln_farm::api::JobState;
use std::time::Duration;

const SLOW_JOB: &[&str] = &["--spp", "64", "--resolution", "192x108", "--tile", "16"];

#[test]
fn a_killed_worker_loses_nothing() {
    let farm = Farm::process();
    let path = scene("mis/scene.pbrt");
    let direct = render(&path, farm.dir.path(), "direct", &SLOW_JOB[..4]);
    let mut a = farm.worker_with("a", "cache", &[]);
    let id = farm.submit(&path, SLOW_JOB);
    // Once worker a has rendered a tile, kill it mid-job; b arrives later and finishes.
    a.wait_rendered(2, Duration::from_secs(60));
    a.kill();
    let _b = farm.worker_with("b", "cache", &[]);
    let status = farm.wait_done(id, Duration::from_secs(120));
    assert_eq!(status.state, JobState::Done, "{status:?}");
    let merged = farm.result(id);
    assert_eq!(
        kiln_image::decode_exr(&merged).unwrap().pixels,
        direct.image.pixels
    );
    assert_eq!(merged, direct.bytes);
}

#[test]
fn a_killed_coordinator_resumes_without_rendering_finished_tiles_again() {
    let mut farm = Farm::process();
    let path = scene("mis/scene.pbrt");
    let direct = render(&path, farm.dir.path(), "direct", &SLOW_JOB[..4]);
    let w = farm.worker("w");
    let id = farm.submit(&path, SLOW_JOB);
    let mut before = None;
    wait_for("ten tiles done", Duration::from_secs(60), || {
        before = Some(farm.status(id)).filter(|s| s.tiles_done >= 10);
        before.is_some()
    });
    let before = before.unwrap();
    farm.kill_coordinator();
    let rendered_before = w.rendered();
    farm.start_coordinator();
    let resumed = farm.status(id);
    assert!(
        resumed.tiles_done >= before.tiles_done,
        "{} tiles were done, {} after the restart",
        before.tiles_done,
        resumed.tiles_done
    );
    let status = farm.wait_done(id, Duration::from_secs(120));
    assert_eq!(status.state, JobState::Done, "{status:?}");
    assert_eq!(farm.result(id), direct.bytes);
    // Every tile kept before the restart stayed kept: only the rest (plus the tile the
    // worker held at the kill) were rendered afterwards.
    let rendered_after = w.rendered() - rendered_before;
    let left = (status.tiles_total - resumed.tiles_done) as usize;
    assert!(
        rendered_after <= left + 1,
        "{rendered_after} tiles rendered after the restart, {left} were left"
    );
}

#[test]
fn a_worker_that_keeps_failing_is_set_aside() {
    let farm = Farm::in_process(None);
    let (rt, client) = (&farm.rt, &farm.client);
    let id = farm.job("furnace/scene.pbrt", Some(1), None, 8);
    // Five failures on five different tiles: no tile reaches three, so the job goes on...
    for _ in 0..kiln_farm::coordinator::MAX_WORKER_FAILURES {
        let lease = rt.block_on(client.lease("flaky")).unwrap().unwrap();
        rt.block_on(client.fail(lease.lease, "out of memory"))
            .unwrap();
        // Another worker takes the returned tile, so the next failure is on another one.
        let other = rt.block_on(client.lease("steady")).unwrap().unwrap();
        assert_eq!(other.tile_index, lease.tile_index);
    }
    assert_eq!(farm.status(id).state, JobState::Running);
    // ...but the worker is set aside.
    let err = rt.block_on(client.lease("flaky")).unwrap_err();
    assert_eq!(err.status(), Some(reqwest::StatusCode::FORBIDDEN), "{err}");
    assert!(err.to_string().contains("set aside"));
    assert!(rt.block_on(client.lease("steady")).unwrap().is_some());
}

#[cfg(unix)]
#[test]
fn sigterm_lets_a_worker_finish_its_tile_and_leave() {
    let farm = Farm::process();
    let mut w = farm.worker("w");
    let id = farm.submit(&scene("mis/scene.pbrt"), SLOW_JOB);
    w.wait_rendered(1, Duration::from_secs(60));
    w.sigterm();
    let status = w.wait_exit(Duration::from_secs(30));
    assert!(status.success(), "{status:?}");
    let text = w.text();
    assert!(text.contains("stopped after"), "{text}");
    // Every tile it says it rendered was delivered: none is lost or held.
    let s = farm.status(id);
    assert_eq!(s.tiles_done as usize, w.rendered(), "{text}");
}

/// A medium too dense for tracking to cross (density 10^30 beside 0: the walk's steps
/// vanish below f32's precision) used to keep a worker tracking for ever, its lease alive
/// through heartbeats. Now each walk stops at its step limit, the worker fails the tile
/// with the reason, and after three attempts the job fails with it.
#[test]
fn a_medium_too_dense_to_track_fails_its_job_with_the_reason() {
    let farm = Farm::in_process(None);
    let scene_path =
        crate::util::write_scene(farm.dir.path(), "dense.pbrt", crate::util::TOO_DENSE);
    let spec = kiln_farm::api::JobSpec {
        spp: Some(1),
        tile: 8,
        ..Farm::spec(&farm.upload(&scene_path))
    };
    let id = farm.create(&spec);
    let _worker = farm.worker("w");
    let s = farm.wait_done(id, Duration::from_secs(60));
    assert_eq!(s.state, JobState::Failed);
    let error = s.error.unwrap();
    assert!(error.contains("tracking steps in a medium"), "{error}");
}

/// A tile that would take minutes (one 64x64 tile at 16,384 spp). Cancelling its job stops
/// the worker mid-tile: its next heartbeat is refused and the render stops between rounds.
/// A worker told twice to stop leaves at once and gives its tile back, which is lent
/// again straight away. The second signal is sent once the worker says it took the first
/// (two signals sent together may reach a process as one).
#[test]
fn cancel_and_a_second_sigterm_reach_a_worker_mid_tile() {
    const ONE_LONG_TILE: &[&str] = &["--spp", "16384", "--resolution", "64x64", "--tile", "64"];
    let farm = Farm::process();
    let (rt, client) = (&farm.rt, &farm.client);
    let w = farm.worker("w");
    let id = farm.submit(&scene("mis/scene.pbrt"), ONE_LONG_TILE);
    farm.wait_for_leases(1);
    let start = std::time::Instant::now();
    rt.block_on(client.cancel(id)).unwrap();
    w.wait_for_log("abandoned part way", Duration::from_secs(10));
    assert!(start.elapsed() < Duration::from_secs(10));
    // Twice SIGTERM: the second stops the render, and the tile is given back. (Another
    // seed: the same settings again would be the cancelled job, as submits are idempotent.)
    let id = farm.submit(
        &scene("mis/scene.pbrt"),
        &[ONE_LONG_TILE, &["--seed", "2"]].concat(),
    );
    let mut w2 = farm.worker("w2");
    farm.wait_for_leases(2);
    w2.sigterm();
    w2.wait_for_log("stopping after this tile", Duration::from_secs(10));
    w2.sigterm();
    let status = w2.wait_exit(Duration::from_secs(10));
    assert!(status.success(), "{status:?}");
    let s = farm.status(id);
    assert_eq!((s.state, s.tiles_done), (JobState::Running, 0));
    assert!(s.failures >= 1, "the tile was given back: {s:?}");
    rt.block_on(client.cancel(id)).unwrap();
}

/// Chaos: jobs on a farm of three workers while a driver kills (SIGKILL) a random worker
/// or the coordinator at random moments and starts it again. No tile is lost: each job
/// ends done, its merged EXR byte-identical to `kiln render`'s. The kills follow a fixed
/// seed (the moments are the schedule under test, not a wait), so a failure can be
/// replayed; the counts are printed. The second job runs in progressive passes, so kills
/// land between passes and in them.
#[test]
fn chaos_random_kills_of_workers_and_the_coordinator_lose_nothing() {
    const ROUNDS: u32 = 2;
    let mut farm = Farm::process();
    let path = scene("mis/scene.pbrt");
    let worker = |farm: &Farm, i: usize, life: u32| -> Worker {
        farm.worker_with(&format!("w{i}-{life}"), &format!("cache{i}"), &[])
    };
    let mut lives = [0u32; 3];
    let mut workers: Vec<Worker> = (0..3).map(|i| worker(&farm, i, 0)).collect();
    // xorshift64*, seeded: the same kills at the same moments on every run.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = |n: u64| {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d) % n
    };
    let (mut worker_kills, mut coordinator_kills) = (0u32, 0u32);
    for round in 0..ROUNDS {
        let seed = (round + 1).to_string();
        let settings = [
            "--spp",
            "512",
            "--resolution",
            "192x108",
            "--seed",
            seed.as_str(),
        ];
        let direct = render(&path, farm.dir.path(), &format!("direct{round}"), &settings);
        // The second round in passes: kills land between passes and in them.
        let passes: &[&str] = if round == 1 {
            &["--passes", "64,256,512"]
        } else {
            &[]
        };
        let id = farm.submit(&path, &[&settings[..], &["--tile", "16"], passes].concat());
        let start = std::time::Instant::now();
        loop {
            if let Ok(s) = farm.rt.block_on(farm.client.status(id))
                && s.state != JobState::Running
            {
                assert_eq!(s.state, JobState::Done, "{s:?}");
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(240),
                "round {round} did not finish"
            );
            std::thread::sleep(Duration::from_millis(150 + next(500)));
            match next(4) {
                3 => {
                    farm.kill_coordinator();
                    farm.start_coordinator();
                    coordinator_kills += 1;
                }
                i => {
                    let i = i as usize;
                    workers[i].kill();
                    lives[i] += 1;
                    workers[i] = worker(&farm, i, lives[i]);
                    worker_kills += 1;
                }
            }
        }
        let merged = farm.result(id);
        assert!(
            merged == direct.bytes,
            "round {round}: the merged frame differs"
        );
    }
    eprintln!(
        "chaos: {ROUNDS} rounds, {worker_kills} worker kills, {coordinator_kills} coordinator kills"
    );
    assert!(
        worker_kills >= ROUNDS && coordinator_kills >= 1,
        "too few kills to prove anything"
    );
}

/// A scene that kills every worker that takes it (here a test fault: workers abort on a
/// marked scene), on a farm of three workers that restart when they die, as a service
/// manager restarts them: its job fails within three attempts with the reason, no worker
/// is set aside (a machine that dies is not to blame), and another job finishes.
#[test]
fn a_scene_that_kills_its_workers_fails_its_job_and_blames_no_worker() {
    let farm = Farm::process();
    let text = std::fs::read_to_string(scene("furnace/scene.pbrt")).unwrap();
    let poison_path = crate::util::write_scene(
        farm.dir.path(),
        "poison.pbrt",
        &format!("{}\n{text}", kiln_farm::worker::ABORT_MARKER),
    );
    let poison = farm.submit(
        &poison_path,
        &[
            "--spp",
            "1",
            "--resolution",
            "16x16",
            "--tile",
            "16",
            "--priority",
            "1",
        ],
    );
    let healthy = farm.submit(
        &scene("furnace/scene.pbrt"),
        &["--spp", "1", "--resolution", "32x32", "--tile", "16"],
    );
    let start = |i: usize, life: u32| {
        farm.worker_with(
            &format!("w{i}"),
            &format!("cache{i}-{life}"),
            &["--inject-fault", "abort-on-marked-scene"],
        )
    };
    let mut lives = [0u32; 3];
    let mut workers: Vec<Worker> = (0..3).map(|i| start(i, 0)).collect();
    let mut deaths = 0;
    wait_for("both jobs ending", Duration::from_secs(120), || {
        for (i, w) in workers.iter_mut().enumerate() {
            if let Some(status) = w.child.try_wait().unwrap() {
                assert!(!status.success(), "a worker left: {}", w.text());
                deaths += 1;
                lives[i] += 1;
                *w = start(i, lives[i]);
            }
        }
        farm.status(poison).state != JobState::Running
            && farm.status(healthy).state != JobState::Running
    });
    let s = farm.status(poison);
    assert_eq!((s.state, s.failures), (JobState::Failed, 3), "{s:?}");
    let error = s.error.unwrap();
    assert!(
        error.starts_with("3 renderers in a row died, hung or lost their link rendering tile 0 (16x16 at 0,0) while no tile of the job was done"),
        "{error}"
    );
    assert!(deaths >= 3, "{deaths} workers died");
    assert_eq!(farm.status(healthy).state, JobState::Done);
    let listed: Vec<kiln_farm::api::WorkerStatus> = farm
        .rt
        .block_on(async {
            reqwest::get(format!("{}/v1/workers", farm.url))
                .await?
                .json()
                .await
        })
        .unwrap();
    assert!(listed.iter().all(|w| w.set_aside.is_none()), "{listed:?}");
}

/// A tmpfs mounted for a test, unmounted (lazily, whatever still uses it) when dropped.
struct Mounted(std::path::PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg("-l")
            .arg(&self.0)
            .status();
    }
}

/// A full disk under the coordinator (its data directory on a 16 MiB tmpfs, filled up
/// once the job is created): the workers' tiles cannot be kept, so they are answered with
/// an error, keep their renders and try again, while the job's status and /healthz say
/// why; the job stays running. Once space returns the job finishes, with kiln render's
/// bytes. Needs root to mount (CI runs as root); SKIPPED otherwise.
#[test]
fn a_full_disk_holds_the_job_until_space_returns_and_loses_nothing() {
    let mut mounted = None;
    let farm = Farm::process_with(|data| {
        std::fs::create_dir_all(data).unwrap();
        let ok = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=16m", "tmpfs"])
            .arg(data)
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            mounted = Some(Mounted(data.to_path_buf()));
        }
    });
    let Some(_mounted) = mounted else {
        println!(
            "SKIPPED a_full_disk_holds_the_job_until_space_returns_and_loses_nothing: cannot mount a tmpfs (not root?)"
        );
        return;
    };
    let path = scene("materials/scene.pbrt");
    let args = ["--spp", "4", "--resolution", "48x32", "--tile", "16"];
    let direct = render(&path, farm.dir.path(), "direct", &args);
    let id = farm.submit(&path, &args);
    // Fill the disk to the last byte.
    let filler = farm.data().join("filler");
    {
        use std::io::Write;
        let mut f = std::fs::File::create(&filler).unwrap();
        let chunk = vec![0u8; 64 << 10];
        while f.write_all(&chunk).is_ok() {}
        while f.write_all(&[0u8]).is_ok() {}
    }
    let _w = farm.worker("w");
    let mut notice = String::new();
    wait_for(
        "the job saying its tiles cannot be kept",
        Duration::from_secs(60),
        || {
            notice = farm.status(id).notice.unwrap_or_default();
            notice.contains("cannot keep its tiles")
        },
    );
    assert!(
        !notice.contains(&farm.data().display().to_string()),
        "{notice}"
    );
    let health = farm
        .rt
        .block_on(async {
            reqwest::get(format!("{}/healthz", farm.url))
                .await?
                .text()
                .await
        })
        .unwrap();
    assert!(
        health.contains("the job store cannot keep tiles"),
        "{health}"
    );
    assert_eq!(farm.status(id).state, JobState::Running);
    // Space returns: the worker's next try is kept, and the job ends with every tile.
    std::fs::remove_file(&filler).unwrap();
    let s = farm.wait_done(id, Duration::from_secs(120));
    assert_eq!((s.state, s.notice), (JobState::Done, None), "{:?}", s.error);
    assert_eq!(farm.result(id), direct.bytes);
}
