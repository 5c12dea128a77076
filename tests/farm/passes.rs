//! Progressive passes through real workers: every pass the bytes of `kiln render` at its
//! count, whatever the schedule, tiles and workers; stopped after a pass and extended.

use super::{Farm, farm, wait_for};
use crate::util::{render, scene};
use kiln_farm::api::{JobSpec, JobState};
use std::time::Duration;

/// Progressive passes through real workers: whatever the schedule, tile size and worker
/// count, the frame after the last pass is `kiln render`'s at that many samples, byte for
/// byte (G-buffer channels too): each tile's pass continues the running sums the last
/// one uploaded, downloaded by whichever worker renders it.
#[test]
fn the_farm_in_passes_gives_the_bytes_of_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("materials/scene.pbrt");
    let base = ["--resolution", "48x32", "--threads-per-worker", "1"];
    let direct = render(
        &path,
        dir.path(),
        "direct",
        &["--spp", "6", "--resolution", "48x32", "--tile", "16"],
    )
    .bytes;
    for (passes, tile, workers) in [("1,3,6", "11", "2"), ("2,6", "7", "1"), ("6", "16", "2")] {
        let mut args = base.to_vec();
        args.extend(["--passes", passes, "--tile", tile, "--workers", workers]);
        let merged = farm(&path, dir.path(), &format!("p{tile}"), &args);
        assert!(
            merged == direct,
            "passes {passes}, tiles of {tile}, {workers} workers: not kiln render's bytes"
        );
    }
    let gb = crate::util::write_scene(dir.path(), "gb.pbrt", crate::gbuffer::SCENE);
    let direct = render(
        &gb,
        dir.path(),
        "gb-direct",
        &["--spp", "4", "--resolution", "24x16"],
    );
    let merged = farm(
        &gb,
        dir.path(),
        "gb-farm",
        &[
            "--passes",
            "1,4",
            "--tile",
            "9",
            "--resolution",
            "24x16",
            "--workers",
            "2",
        ],
    );
    assert!(merged == direct.bytes, "the G-buffer in passes differs");
    // Adaptive sampling: pixels stop at checkpoints by their own sums, whichever worker
    // and pass renders them; the coordinator checks no pixel took more than its pass.
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "Sampler \"sobol\" \"integer pixelsamples\" [ 16 ]",
        "Sampler \"sobol\" \"integer pixelsamples\" [ 16 ] \"float noisethreshold\" [ 0.05 ] \"integer minsamples\" [ 2 ]",
    );
    assert!(text.contains("noisethreshold"));
    let adaptive = crate::util::write_scene(dir.path(), "adaptive.pbrt", &text);
    let direct = render(
        &adaptive,
        dir.path(),
        "adaptive-direct",
        &["--spp", "16", "--resolution", "48x32"],
    );
    let plain = render(
        &adaptive,
        dir.path(),
        "adaptive-off",
        &[
            "--spp",
            "16",
            "--resolution",
            "48x32",
            "--noise-threshold",
            "0",
        ],
    );
    assert!(
        direct.bytes != plain.bytes,
        "adaptive sampling changed nothing"
    );
    let merged = farm(
        &adaptive,
        dir.path(),
        "adaptive-farm",
        &[
            "--passes",
            "2,5,8,16",
            "--tile",
            "11",
            "--resolution",
            "48x32",
            "--workers",
            "2",
        ],
    );
    assert!(
        merged == direct.bytes,
        "adaptive sampling in passes differs"
    );
}

/// A job stopped after a pass ends with that pass's whole frame; extended, it renders on
/// from there to `kiln render`'s bytes at the new count, the workers continuing the sums the
/// coordinator kept. Every pass is rendered with the footprint of the job's last pass, so a
/// pass of fewer than 64 samples (where pbrt-v4's texture footprint still narrows) is the
/// first samples of the longer render: `kiln render --spp N --footprint-spp LAST`, and on
/// this textured scene not `kiln render --spp N`.
#[test]
fn a_job_stopped_after_a_pass_and_extended_is_kiln_render_at_each_count() {
    let farm = Farm::in_process(None);
    let (rt, client, dir) = (&farm.rt, &farm.client, &farm.dir);
    let digest = farm.upload(&scene("textures/scene.pbrt"));
    let render_at = |spp: u32, footprint: Option<u32>| {
        let mut args = ["--spp", &spp.to_string(), "--resolution", "24x16"]
            .map(String::from)
            .to_vec();
        if let Some(f) = footprint {
            args.extend(["--footprint-spp".to_string(), f.to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        render(
            &scene("textures/scene.pbrt"),
            dir.path(),
            &format!("d{spp}-{footprint:?}"),
            &args,
        )
        .bytes
    };
    // Stopped mid-run, after its first pass merged, and at once, before any tile.
    for stop_at_once in [false, true] {
        let spec = JobSpec {
            resolution: Some((24, 16)),
            tile: 8,
            passes: Some(vec![16, 64, 72, 80, 88, 96]),
            ..JobSpec::new(&digest)
        };
        let id = rt.block_on(client.create_job(&spec, None)).unwrap();
        if stop_at_once {
            rt.block_on(client.stop_after_pass(id)).unwrap();
        }
        let _worker = farm.worker_with(&format!("p{stop_at_once}"), "cache", &[]);
        wait_for("a pass merged", Duration::from_secs(120), || {
            farm.status(id).passes_done > 0
        });
        rt.block_on(client.stop_after_pass(id)).unwrap();
        let s = farm.wait_done(id, Duration::from_secs(120));
        assert_eq!(s.state, JobState::Done);
        let stopped = s.samples_per_pixel_done;
        assert!(
            stopped < 96,
            "the job ran on to {stopped} samples after its stop"
        );
        if stop_at_once {
            assert_eq!(
                stopped, 16,
                "stopped before any tile, it ran past its first pass"
            );
        }
        assert_eq!(s.passes.last(), Some(&stopped));
        let result = rt.block_on(client.result(id)).unwrap();
        assert!(
            result == render_at(stopped, Some(96)),
            "stopped at {stopped}: not kiln render --footprint-spp 96's bytes"
        );
        if stopped < 64 {
            assert!(
                result != render_at(stopped, None),
                "this scene's textures should see the footprint of {stopped} samples"
            );
        } else {
            assert!(
                result == render_at(stopped, None),
                "stopped at {stopped}: not kiln render's bytes"
            );
        }
        let s = rt.block_on(client.extend(id, &[stopped + 8, 104])).unwrap();
        assert_eq!(s.state, JobState::Running);
        let s = farm.wait_done(id, Duration::from_secs(120));
        assert_eq!((s.state, s.samples_per_pixel_done), (JobState::Done, 104));
        let result = rt.block_on(client.result(id)).unwrap();
        assert!(
            result == render_at(104, None),
            "extended to 104: not kiln render's bytes"
        );
    }
}
