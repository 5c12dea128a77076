//! Farm benchmarks.
//!
//! 1. Efficiency: `kiln farm --workers 2 --threads-per-worker 1` against
//!    `kiln render --threads 2` on the same frame (wall time, both with process start).
//! 2. Coordinator scale: an in-process coordinator, a 2880x1920 job cut into 16 px tiles
//!    (21,600 tiles), and 1,000 simulated workers that lease tiles and return small EXRs
//!    as fast as they can. Prints lease round trips per second, lease latency
//!    percentiles, and the time to merge the full frame.
//!
//! `cargo bench --bench farm [-- --skip-efficiency] [--workers N]`

mod common;
use common::arg;
use kiln_farm::api::{JobSpec, JobState};
use kiln_farm::client::Client;
use kiln_farm::coordinator::{self, Config, Coordinator};
use std::process::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn efficiency() {
    let kiln = env!("CARGO_BIN_EXE_kiln");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/materials/scene.pbrt");
    let dir = tempfile::tempdir().unwrap();
    let frame = ["--spp", "512", "--resolution", "480x320", "--tile", "32"];
    let time = |args: &[&str]| {
        let start = Instant::now();
        let s = Command::new(kiln).args(args).output().unwrap();
        assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
        start.elapsed().as_secs_f64()
    };
    let out = dir.path().join("a.exr");
    let render = time(
        &[
            &[
                "render",
                scene,
                "-q",
                "--threads",
                "2",
                "-o",
                out.to_str().unwrap(),
            ],
            &frame[..],
        ]
        .concat(),
    );
    let out2 = dir.path().join("b.exr");
    let farm = time(
        &[
            &[
                "farm",
                scene,
                "-q",
                "--workers",
                "2",
                "--threads-per-worker",
                "1",
                "-o",
                out2.to_str().unwrap(),
            ],
            &frame[..],
        ]
        .concat(),
    );
    let same = std::fs::read(&out).unwrap() == std::fs::read(&out2).unwrap();
    println!(
        "efficiency: kiln render --threads 2: {render:.2} s; kiln farm --workers 2 (1 thread each): {farm:.2} s; farm throughput {:.1}% of render; images identical: {same}",
        100.0 * render / farm
    );
}

fn scale(workers: usize) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    std::fs::write(
        scene_dir.join("frame.pbrt"),
        "Film \"rgb\" \"integer xresolution\" [ 2880 ] \"integer yresolution\" [ 1920 ]\nWorldBegin\nLightSource \"infinite\"\n",
    )
    .unwrap();
    let c = Coordinator::open(Config::new(dir.path().join("data"))).unwrap();
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    rt.spawn(coordinator::serve(listener, c, std::future::pending()));
    let client = Client::new(&url, None);
    let bundle = kiln_farm::bundle::pack(&scene_dir.join("frame.pbrt")).unwrap();
    let digest = rt.block_on(client.upload_scene(bundle.bytes)).unwrap();
    let spec = JobSpec {
        spp: Some(1),
        tile: 16,
        ..JobSpec::new(&digest)
    };
    let id = rt.block_on(client.create_job(&spec, None)).unwrap();
    let total = rt.block_on(client.status(id)).unwrap().tiles_total;
    // The simulated workers neither render nor encode: their tiles' EXRs are made before
    // the clock starts, so the figures are the coordinator's (it still decodes and checks
    // every upload).
    let tiles: Arc<Vec<Vec<u8>>> = Arc::new(
        kiln_render::split_into_tiles([0, 2880, 0, 1920], 16)
            .iter()
            .map(|r| {
                let mut tile =
                    kiln_image::RgbBuffer::new(2880, 1920, r.x0, r.y0, r.width, r.height);
                tile.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
                // The running sums a real worker's tile carries (one pass of 1 sample).
                let mut sums = kiln_render::TileSums::empty(*r, kiln_render::SumsLayout::default());
                sums.samples = 1;
                tile.words = kiln_image::Words {
                    names: kiln_render::TileSums::word_names(kiln_render::SumsLayout::default()),
                    values: sums.to_words(),
                };
                kiln_image::encode_exr(&tile).unwrap()
            })
            .collect(),
    );
    let latencies = Arc::new(std::sync::Mutex::new(Vec::with_capacity(total as usize)));
    let start = Instant::now();
    rt.block_on(async {
        let mut tasks = Vec::new();
        for w in 0..workers {
            let client = client.clone();
            let latencies = latencies.clone();
            let tiles = tiles.clone();
            tasks.push(tokio::spawn(async move {
                let name = format!("sim-{w}");
                loop {
                    let t = Instant::now();
                    let Ok(Some(lease)) = client.lease(&name).await else {
                        break;
                    };
                    latencies.lock().unwrap().push(t.elapsed().as_secs_f64());
                    let exr = tiles[lease.tile_index as usize].clone();
                    client.upload_tile(lease.lease, exr).await.unwrap();
                }
            }));
        }
        for t in tasks {
            t.await.unwrap();
        }
    });
    let secs = start.elapsed().as_secs_f64();
    let status = loop {
        let s = rt.block_on(client.status(id)).unwrap();
        if s.state != JobState::Running {
            break s;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut l = latencies.lock().unwrap().clone();
    l.sort_by(f64::total_cmp);
    let pct = |p: f64| l[((l.len() - 1) as f64 * p) as usize] * 1e3;
    println!(
        "scale: {workers} simulated workers, {total} tiles of 16 px on 2880x1920: {:.0} lease round trips/s (lease + upload: {:.0} tiles/s), lease latency p50 {:.2} ms p99 {:.2} ms, merge {:.3} s, state {:?}",
        l.len() as f64 / secs,
        total as f64 / secs,
        pct(0.5),
        pct(0.99),
        status.merge_seconds.unwrap_or(f64::NAN),
        status.state
    );
}

fn main() {
    if !std::env::args().any(|a| a == "--skip-efficiency") {
        efficiency();
    }
    scale(arg("--workers", 1000));
}
