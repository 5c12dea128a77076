//! Verified workers on real processes: a worker that flips bits is caught and set aside,
//! honest ones never are, and the job is `kiln render`'s bytes.

use super::{Farm, Worker};
use crate::util::{render, scene};
use kiln_farm::api::{JobSpec, JobState};
use std::time::Duration;

/// Verified workers on real processes: a worker started in a fault-injection mode (it
/// flips the lowest bit of some pixels it uploads) is caught on its first tile and set
/// aside with the reason, two honest workers finish the job with `kiln render`'s bytes,
/// and no honest worker is ever flagged, here or on a job of honest workers alone.
#[test]
fn verification_catches_a_worker_that_flips_bits_and_never_an_honest_one() {
    let farm = Farm::in_process(None);
    let (rt, client, url, dir) = (&farm.rt, &farm.client, &farm.url, &farm.dir);
    let path = scene("materials/scene.pbrt");
    let digest = farm.upload(&path);
    let spec = |passes: Vec<u32>| JobSpec {
        resolution: Some((48, 32)),
        tile: 16,
        passes: Some(passes),
        verify: Some(1.0),
        ..JobSpec::new(&digest)
    };
    let workers = |rt: &tokio::runtime::Runtime| -> Vec<kiln_farm::api::WorkerStatus> {
        let http = reqwest::Client::new();
        rt.block_on(async {
            http.get(format!("{url}/v1/workers"))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap()
        })
    };
    // Honest workers alone: every tile pass verified, nobody set aside.
    let honest_job = rt
        .block_on(client.create_job(&spec(vec![2, 4]), None))
        .unwrap();
    let honest_workers = |names: std::ops::Range<usize>| -> Vec<Worker> {
        names
            .map(|i| farm.worker_with(&format!("h{i}"), "cache", &[]))
            .collect()
    };
    let mut honest = honest_workers(0..2);
    let s = farm.wait_done(honest_job, Duration::from_secs(120));
    assert_eq!(s.state, JobState::Done, "{s:?}");
    assert_eq!(
        s.tile_passes_verified,
        6 * 2,
        "every tile pass of 6 tiles x 2 passes"
    );
    assert!(workers(rt).iter().all(|w| w.set_aside.is_none()));
    // Now a bad worker takes the first tiles of a new job before the honest ones come.
    for w in &mut honest {
        w.kill();
    }
    let job = rt
        .block_on(client.create_job(&spec(vec![3]), None))
        .unwrap();
    let mut bad = farm.worker_with("bad", "cache", &["--inject-fault", "flip-low-bit"]);
    bad.wait_rendered(1, Duration::from_secs(60));
    let _honest = honest_workers(2..4);
    let s = farm.wait_done(job, Duration::from_secs(120));
    assert_eq!(s.state, JobState::Done, "{s:?}");
    let direct = render(
        &path,
        dir.path(),
        "direct",
        &["--spp", "3", "--resolution", "48x32"],
    );
    let merged = rt.block_on(client.result(job)).unwrap();
    assert!(
        merged == direct.bytes,
        "the verified job is not kiln render's bytes"
    );
    let ws = workers(rt);
    for w in &ws {
        match w.name.as_str() {
            "bad" => {
                let why = w.set_aside.as_deref().expect("the bad worker is set aside");
                assert!(why.contains("differs, bit for bit"), "{why}");
            }
            name => assert!(w.set_aside.is_none(), "honest {name} was flagged: {w:?}"),
        }
    }
    // Refused, the bad worker leaves with the reason.
    let status = bad.wait_exit(Duration::from_secs(30));
    assert!(!status.success());
    let log = bad.text();
    assert!(log.contains("set aside"), "{log}");
}
