//! Shots of many frames through the processes: `kiln farm` of three frames writes three
//! EXRs, each the same bytes as `kiln render` of its file; a 48-frame shot submitted as a
//! glob and rendered by three workers reads its shared mesh once per worker (their geometry
//! counts say so).

use super::{Farm, wait_for};
use crate::util::{kiln, render};
use kiln_farm::api::JobState;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Writes a shot of `frames` frames into `dir`: a shared mesh (`mesh.ply`, a ground and a
/// pyramid) and world (`world.pbrt`), and per frame a file `fNNN.pbrt` whose camera circles
/// the pyramid. Returns the frames' files.
fn write_shot(dir: &Path, frames: usize, size: (u32, u32)) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let ply = "ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\nelement face 8\nproperty list uchar int vertex_indices\nend_header\n\
        -3 0 -3\n3 0 -3\n3 0 3\n-3 0 3\n\
        -1 0.01 -1\n1 0.01 -1\n1 0.01 1\n-1 0.01 1\n0 1.5 0\n\
        3 0 2 1\n3 0 3 2\n3 4 5 8\n3 5 6 8\n3 6 7 8\n3 7 4 8\n3 4 6 5\n3 4 7 6\n";
    std::fs::write(dir.join("mesh.ply"), ply).unwrap();
    std::fs::write(
        dir.join("world.pbrt"),
        "AttributeBegin\n  Material \"diffuse\" \"rgb reflectance\" [0.7 0.4 0.2]\n  Shape \"plymesh\" \"string filename\" \"mesh.ply\"\nAttributeEnd\n\
         AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [6 6 6]\n  Translate 1 3 1\n  Shape \"sphere\" \"float radius\" 0.4\nAttributeEnd\n\
         LightSource \"infinite\" \"rgb L\" [0.1 0.12 0.15]\n",
    )
    .unwrap();
    (0..frames)
        .map(|k| {
            let a = k as f64 / frames as f64 * std::f64::consts::TAU;
            let (x, z) = (5.0 * libm::cos(a), 5.0 * libm::sin(a));
            let path = dir.join(format!("f{k:03}.pbrt"));
            std::fs::write(
                &path,
                format!(
                    "LookAt {x:.4} 2.5 {z:.4}  0 0.5 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\n\
                     Film \"rgb\" \"integer xresolution\" [ {} ] \"integer yresolution\" [ {} ] \"string filename\" \"f{k:03}.exr\"\n\
                     WorldBegin\nInclude \"world.pbrt\"\n",
                    size.0, size.1
                ),
            )
            .unwrap();
            path
        })
        .collect()
}

#[test]
fn a_three_frame_shot_through_kiln_farm_gives_each_frame_kiln_renders_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let frames = write_shot(&dir.path().join("shot"), 3, (48, 32));
    let out = dir.path().join("out");
    let args = ["--spp", "4", "--tile", "16"];
    let o = kiln()
        .arg("farm")
        .args(&frames)
        .arg("-o")
        .arg(&out)
        .args(["-q", "--workers", "2", "--threads-per-worker", "1"])
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut seen = Vec::new();
    for (k, frame) in frames.iter().enumerate() {
        let merged = std::fs::read(out.join(format!("f{k:03}.exr"))).unwrap();
        let direct = render(frame, dir.path(), &format!("direct{k}"), &args).bytes;
        assert!(
            merged == direct,
            "frame {k} differs from kiln render of its file"
        );
        assert!(
            !seen.contains(&merged),
            "frame {k} is another frame's picture"
        );
        seen.push(merged);
    }
}

#[test]
fn a_48_frame_shot_on_3_workers_reads_its_shared_mesh_once_per_worker() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot");
    write_shot(&shot, 48, (8, 8));
    let farm = Farm::in_process(None);
    let workers: Vec<_> = ["a", "b", "c"].iter().map(|n| farm.worker(n)).collect();
    // The glob is the CLI's to expand (quoted in a shell), in name order.
    let o = kiln()
        .args([
            "submit",
            "--coordinator",
            &farm.url,
            "--spp",
            "1",
            "--tile",
            "8",
        ])
        .arg(shot.join("f*.pbrt"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let id: u64 = String::from_utf8_lossy(&o.stdout)
        .trim()
        .rsplit(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let status = farm.wait_done(id, Duration::from_secs(240));
    assert_eq!(
        (status.state, status.frame_count),
        (JobState::Done, 48),
        "{status:?}"
    );
    let frames = farm.rt.block_on(farm.client.frames(id)).unwrap();
    assert_eq!(frames.len(), 48);
    assert!(
        frames
            .iter()
            .all(|f| f.passes_done == 1 && f.progress == 1.0)
    );
    assert_eq!(frames[47].scene, "f047.pbrt");
    // Each worker says what its geometry cache did with its next request for work.
    let mut counts = Vec::new();
    wait_for(
        "every frame's load counted",
        Duration::from_secs(60),
        || {
            let all = farm.rt.block_on(farm.client.workers()).unwrap();
            counts = all
                .iter()
                .map(|w| (w.name.clone(), w.tiles_done, w.geometry.unwrap_or_default()))
                .collect();
            let loaded: u64 = counts.iter().map(|(_, _, g)| g.loads + g.reused).sum();
            counts.len() == 3 && loaded >= 48
        },
    );
    for (name, tiles, g) in &counts {
        // A worker loads each frame it renders; the mesh is read once.
        assert_eq!(g.loads, u64::from(*tiles > 0), "worker {name}: {g:?}");
        assert!(
            g.loads + g.reused >= *tiles,
            "worker {name}: {tiles} frames, {g:?}"
        );
    }
    let busy = counts.iter().filter(|(_, t, _)| *t > 0).count();
    assert!(
        busy >= 2,
        "the shot was spread over the workers: {counts:?}"
    );
    // The CLI's tables say the same: the job's frames, each worker's meshes.
    let table = |what: &str| {
        let o = kiln()
            .args([what, "--coordinator", &farm.url])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let jobs = table("jobs");
    let row = jobs.lines().nth(1).unwrap_or_default();
    assert!(row.contains("done") && row.contains(" 48 "), "{jobs}");
    let listed = table("workers");
    assert!(listed.contains("1 read, "), "{listed}");
    drop(workers);
}
