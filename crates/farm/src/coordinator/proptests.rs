//! Property tests of the lease state machine: random sequences of leases, heartbeats,
//! uploads (right, wrong and damaged), failures, clock jumps past the lease time and
//! coordinator restarts, run against the coordinator itself on tokio's paused clock, for a
//! shot of two frames in one pass and one in three, kept to two workers at once, and a
//! second job that starts after it. After any sequence: no operation is an internal error, no tile pass is
//! ever accepted with bytes other than those first accepted for it, the samples done are
//! exactly those of the passes accepted, the first job never has more than two workers
//! and the second is lent nothing before the first is done; and driving the jobs on with a
//! healthy worker ends them: the first done, each of its frames holding exactly the bytes
//! accepted for each of its tiles' last pass, and the second done after it; or the first failed because a
//! tile failed its three attempts or lost its renderers too often, and the second failed
//! for it.

use super::{Config, Coordinator, Error};
use crate::api::{JobSpec, JobState, Lease};
use axum::body::Bytes;
use kiln_image::RgbBuffer;
use proptest::prelude::*;
use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

const TTL: Duration = Duration::from_secs(10);
/// A 24 x 16 frame of 8-pixel tiles: six tiles.
const FRAME: (u32, u32) = (24, 16);
/// The first job is a shot of two frames: twelve tiles.
const TILES: u32 = 12;

#[derive(Debug, Clone)]
enum Op {
    Lease(u8),
    Heartbeat(u8),
    /// Upload under held lease n: the right pixels, other pixels, or damaged bytes.
    Upload(u8, Kind),
    Fail(u8),
    /// Move the clock on by this many seconds, and expire what is due.
    Advance(u8),
    Restart,
}

#[derive(Debug, Clone, Copy)]
enum Kind {
    Right,
    Other,
    Damaged,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0u8..3).prop_map(Op::Lease),
        2 => any::<u8>().prop_map(Op::Heartbeat),
        5 => (any::<u8>(), prop_oneof![4 => Just(Kind::Right), 1 => Just(Kind::Other), 1 => Just(Kind::Damaged)])
            .prop_map(|(n, k)| Op::Upload(n, k)),
        1 => any::<u8>().prop_map(Op::Fail),
        2 => (1u8..25).prop_map(Op::Advance),
        1 => Just(Op::Restart),
    ]
}

fn open(data: &Path) -> Coordinator {
    let mut config = Config::new(data.to_path_buf());
    config.lease_ttl = TTL;
    Coordinator::open(config).unwrap()
}

/// The tile pass a lease asks for, every pixel `value`, with the running sums its pass
/// must carry (their values are the worker's business), encoded.
fn tile_bytes(lease: &Lease, value: f32) -> Vec<u8> {
    let t = lease.tile;
    let mut tile = RgbBuffer::new(FRAME.0, FRAME.1, t.x0, t.y0, t.width, t.height);
    tile.pixels.iter_mut().for_each(|p| *p = [value; 3]);
    let mut sums = kiln_render::TileSums::empty(t.into(), kiln_render::SumsLayout::default());
    sums.samples = lease.pass.to;
    tile.words = kiln_image::Words {
        names: kiln_render::TileSums::word_names(kiln_render::SumsLayout::default()),
        values: sums.to_words(),
    };
    kiln_image::encode_exr(&tile).unwrap()
}

/// The pixel value a right render of `lease`'s tile pass has.
fn right_value(lease: &Lease) -> f32 {
    (lease.tile_index * 10 + lease.pass.index) as f32
}

/// Client mistakes and refusals are answers; anything else is a defect.
fn assert_not_internal(r: &Result<(), Error>) {
    if let Err(e) = r {
        assert!(
            matches!(
                e,
                Error::UnknownLease(_)
                    | Error::StaleTile(_)
                    | Error::Relent(_)
                    | Error::RejectedTile(_)
                    | Error::SetAside { .. }
                    | Error::JobEnded(_)
            ),
            "internal error: {e:?}"
        );
    }
}

fn run(ops: Vec<Op>, passes: Option<Vec<u32>>) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .start_paused(true)
        .build()
        .unwrap();
    rt.block_on(async {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data");
        let mut c = open(&data);
        let scene = dir.path().join("scene");
        std::fs::create_dir_all(&scene).unwrap();
        let film = format!(
            "Film \"rgb\" \"integer xresolution\" [ {} ] \"integer yresolution\" [ {} ]\nWorldBegin\n",
            FRAME.0, FRAME.1
        );
        std::fs::write(scene.join("scene.pbrt"), &film).unwrap();
        std::fs::write(scene.join("second.pbrt"), format!("{film}LightSource \"infinite\"\n")).unwrap();
        let (bundle, frames) = crate::bundle::pack_frames(&[scene.join("scene.pbrt"), scene.join("second.pbrt")]).unwrap();
        let digest = c.save_scene(Bytes::from(bundle.bytes)).await.unwrap();
        let spec = JobSpec {
            frames,
            spp: passes.is_none().then_some(1),
            tile: 8,
            passes: passes.clone(),
            max_workers: Some(2),
            ..JobSpec::new(&digest)
        };
        let (job, _) = c.create_job(spec.clone(), None).await.unwrap();
        let then = JobSpec {
            spp: Some(1),
            passes: None,
            max_workers: None,
            after: vec![job],
            frames: Vec::new(),
            ..spec
        };
        let (next, _) = c.create_job(then, None).await.unwrap();
        let schedule = passes.unwrap_or(vec![1]);
        let mut held: Vec<Lease> = Vec::new();
        // The bytes first accepted for each tile pass of the first job: (tile, pass).
        let mut accepted: HashMap<(u32, u32), Vec<u8>> = HashMap::new();
        // The first job's workers at once never pass its cap, and the second job is lent
        // nothing before the first is done.
        let check_lent = |c: &Coordinator, l: &Lease| {
            if l.job == next {
                assert_eq!(c.status(job).unwrap().state, JobState::Done, "lent before its job");
            }
            let holders = c
                .worker_statuses()
                .iter()
                .filter(|w| w.leases.iter().any(|h| h.job == job))
                .count();
            assert!(holders <= 2, "{holders} workers hold the capped job's leases");
        };
        // The samples per pixel of a tile's passes accepted so far.
        let samples_done = |accepted: &HashMap<(u32, u32), Vec<u8>>| -> u64 {
            (0..TILES)
                .map(|t| {
                    let passes = accepted.keys().filter(|(tile, _)| *tile == t).count();
                    64 * passes.checked_sub(1).map_or(0, |p| u64::from(schedule[p]))
                })
                .sum()
        };
        let upload = |c: &Coordinator, lease: &Lease, bytes: Vec<u8>, digest: String| {
            let c = c.clone();
            let id = lease.lease;
            async move { c.upload_tile(id, Bytes::from(bytes), &digest).await }
        };
        for op in ops {
            match op {
                Op::Lease(w) => match c.lease(&format!("w{w}")) {
                    Ok(Some(l)) => {
                        check_lent(&c, &l);
                        held.push(l);
                    }
                    Ok(None) => {}
                    Err(e) => assert_not_internal(&Err(e)),
                },
                Op::Heartbeat(n) if !held.is_empty() => {
                    let l = &held[n as usize % held.len()];
                    assert_not_internal(&c.heartbeat(l.lease));
                }
                Op::Upload(n, kind) if !held.is_empty() => {
                    let l = held[n as usize % held.len()].clone();
                    let right = tile_bytes(&l, right_value(&l));
                    let (bytes, digest) = match kind {
                        Kind::Right => (right.clone(), crate::bundle::digest_of(&right)),
                        Kind::Other => {
                            let other = tile_bytes(&l, 100.0 + right_value(&l));
                            let d = crate::bundle::digest_of(&other);
                            (other, d)
                        }
                        Kind::Damaged => (b"not an exr".to_vec(), crate::bundle::digest_of(&right)),
                    };
                    let r = upload(&c, &l, bytes.clone(), digest).await;
                    assert_not_internal(&r);
                    if r.is_ok() && l.job == job {
                        let first = accepted
                            .entry((l.tile_index, l.pass.index))
                            .or_insert_with(|| bytes.clone());
                        assert_eq!(
                            *first, bytes,
                            "tile {} pass {} accepted with other bytes than before",
                            l.tile_index, l.pass.index
                        );
                    }
                }
                Op::Fail(n) if !held.is_empty() => {
                    let l = &held[n as usize % held.len()];
                    assert_not_internal(&c.fail_lease(l.lease, "injected"));
                }
                Op::Advance(s) => {
                    tokio::time::advance(Duration::from_secs(s as u64)).await;
                    c.expire_leases();
                }
                Op::Restart => {
                    drop(c);
                    c = open(&data);
                }
                _ => {}
            }
            // The samples done are exactly those of the tile passes accepted, restarts or
            // not.
            assert_eq!(c.status(job).unwrap().samples_done, samples_done(&accepted));
        }
        // A healthy worker drives the jobs to their ends.
        for _ in 0..100 {
            let running = |id| c.status(id).unwrap().state == JobState::Running;
            if !running(job) && !running(next) {
                break;
            }
            tokio::time::advance(TTL * 2).await;
            c.expire_leases();
            while let Ok(Some(l)) = c.lease("healthy") {
                check_lent(&c, &l);
                let right = tile_bytes(&l, right_value(&l));
                let digest = crate::bundle::digest_of(&right);
                let r = upload(&c, &l, right.clone(), digest).await;
                assert_not_internal(&r);
                if r.is_ok() && l.job == job {
                    let first = accepted
                        .entry((l.tile_index, l.pass.index))
                        .or_insert_with(|| right.clone());
                    assert_eq!(*first, right);
                }
            }
        }
        let s = c.status(job).unwrap();
        let after = c.status(next).unwrap();
        match s.state {
            JobState::Done => {
                assert_eq!(after.state, JobState::Done, "{after:?}");
                let mut frames = Vec::new();
                for k in 0..2 {
                    let file = c.frame_result(job, k).await.unwrap().bytes().await.unwrap();
                    frames.push(kiln_image::decode_exr(&file).unwrap());
                }
                assert_eq!(s.frame_count, 2);
                let last = schedule.len() as u32 - 1;
                assert_eq!(
                    accepted.len() as u32,
                    s.tiles_total * schedule.len() as u32,
                    "every tile pass accepted"
                );
                for ((idx, _), bytes) in accepted.iter().filter(|((_, p), _)| *p == last) {
                    let tile = kiln_image::decode_exr(bytes).unwrap();
                    let frame = &frames[*idx as usize / 6];
                    for y in 0..tile.height {
                        for x in 0..tile.width {
                            assert_eq!(
                                frame.get(tile.x0 + x, tile.y0 + y),
                                tile.get(x, y),
                                "tile {idx}"
                            );
                        }
                    }
                }
            }
            JobState::Failed => {
                assert_eq!(after.state, JobState::Failed);
                let why = after.error.unwrap_or_default();
                assert!(why.contains(&format!("job {job}")) && why.contains("failed"), "{why}");
                let error = s.error.unwrap_or_default();
                assert!(
                    error.contains("failed 3 times")
                        || error.starts_with("3 renderers in a row died")
                        || error.starts_with("10 renderers died"),
                    "{error}"
                );
            }
            other => panic!("the job ended {other:?}"),
        }
    });
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn no_tile_is_lost_or_accepted_twice_with_other_bytes(ops in prop::collection::vec(op(), 0..60)) {
        run(ops, None);
    }

    #[test]
    fn no_tile_pass_is_lost_or_accepted_twice_with_other_bytes(ops in prop::collection::vec(op(), 0..80)) {
        run(ops, Some(vec![1, 2, 3]));
    }
}
