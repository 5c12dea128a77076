//! Farm benchmarks.
//!
//! 1. Efficiency: `kiln farm --workers 2 --threads-per-worker 1` against
//!    `kiln render --threads 2` on the same frame (wall time, both with process start).
//! 2. Coordinator scale: an in-process coordinator, a 2880x1920 job cut into 16 px tiles
//!    (21,600 tiles), and 1,000 simulated workers (10,000 for issue 40's figure) that
//!    lease tiles and return small EXRs as fast as they can, over loopback HTTP. Prints
//!    lease round trips per second, lease latency percentiles, and the time to merge the
//!    full frame. The job store is SQLite in a temporary data directory, or the
//!    PostgreSQL database `--store postgres://...` names (an empty one: the bench adds a
//!    job to it).
//!
//!    With `--think MS`, each worker waits about that long between tiles (rendering, as
//!    far as the coordinator can tell; spread evenly from 0.5x to 1.5x so they do not
//!    march in step): 10,000 workers thinking 500 ms offer 20,000 round trips a second,
//!    and the latencies are those of a farm at that load rather than of a queue of
//!    workers that never render.
//!
//! `cargo bench --bench farm [-- --skip-efficiency] [--workers N] [--think MS] [--tile PX] [--store URL]`

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

/// Every tile of the 2880x1920 frame cut into `tile` px tiles, as a worker's upload after one
/// pass of 1 sample: the pixels, and the running sums a real worker's tile carries.
fn tile_exrs(tile: u32) -> Vec<Vec<u8>> {
    kiln_render::split_into_tiles([0, 2880, 0, 1920], tile)
        .iter()
        .map(|r| {
            let mut tile = kiln_image::RgbBuffer::new(2880, 1920, r.x0, r.y0, r.width, r.height);
            tile.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
            let mut sums = kiln_render::TileSums::empty(*r, kiln_render::SumsLayout::default());
            sums.samples = 1;
            tile.words = kiln_image::Words {
                names: kiln_render::TileSums::word_names(kiln_render::SumsLayout::default()),
                values: sums.to_words(),
            };
            kiln_image::encode_exr(&tile).unwrap()
        })
        .collect()
}

/// The coordinator's configuration for `workers` simulated workers, on SQLite in `data` or
/// the PostgreSQL database `store` names.
fn scale_config(data: std::path::PathBuf, workers: usize, store: Option<String>) -> Config {
    let mut config = Config::new(data);
    // Every request in flight holds a connection, and the client's pool opens more as it
    // churns (up to twice as many were seen): none is turned away for the limit.
    config.max_connections = 4 * workers.min(2048) + 64;
    if let Some(url) = store {
        config.store = Some(url);
        config.candidate = Some(coordinator::Candidate::new(
            "http://bench".into(),
            Duration::from_secs(5),
        ));
    }
    config
}

fn scale(workers: usize, think_ms: u64, tile: u32, store: Option<String>) {
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
    let which = if store.is_some() {
        "PostgreSQL"
    } else {
        "SQLite"
    };
    let config = scale_config(dir.path().join("data"), workers, store);
    let c = Coordinator::open(config).unwrap();
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
        tile,
        ..JobSpec::new(&digest)
    };
    let id = rt.block_on(client.create_job(&spec, None)).unwrap();
    let total = rt.block_on(client.status(id)).unwrap().tiles_total;
    // The simulated workers neither render nor encode: their tiles' EXRs are made before
    // the clock starts, so the figures are the coordinator's (it still decodes and checks
    // every upload).
    let tiles = Arc::new(tile_exrs(tile));
    let latencies = Arc::new(std::sync::Mutex::new(Vec::with_capacity(total as usize)));
    // Both ends of every connection are in this process, which may open 20,000 files here:
    // at most 2,048 workers have requests in flight at once, whatever the number of workers.
    let in_flight = Arc::new(tokio::sync::Semaphore::new(workers.min(2048)));
    let retries = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let start = Instant::now();
    rt.block_on(async {
        let mut tasks = Vec::new();
        for w in 0..workers {
            let client = client.clone();
            let latencies = latencies.clone();
            let tiles = tiles.clone();
            let in_flight = in_flight.clone();
            let retries = retries.clone();
            tasks.push(tokio::spawn(async move {
                let name = format!("sim-{w}");
                // A fixed spread of think times: worker w waits 0.5x to 1.5x the mean.
                let think = Duration::from_micros(
                    think_ms * 1000 * (500 + (w as u64 * 7919) % 1000) / 1000,
                );
                if think_ms > 0 {
                    tokio::time::sleep(think.mul_f64((w % 97) as f64 / 97.0)).await;
                }
                loop {
                    let turn = in_flight.acquire().await.unwrap();
                    let t = Instant::now();
                    let Ok(Some(lease)) = client.lease(&name).await else {
                        break;
                    };
                    latencies.lock().unwrap().push(t.elapsed().as_secs_f64());
                    let exr = tiles[lease.tile_index as usize].clone();
                    // As a worker does, an upload that fails (a connection closed under
                    // it) is sent again.
                    let mut tries = 0;
                    while let Err(e) = client.upload_tile(lease.lease, exr.clone()).await {
                        tries += 1;
                        assert!(tries < 5, "upload failed 5 times: {e}");
                        retries.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                    drop(turn);
                    if think_ms > 0 {
                        tokio::time::sleep(think).await;
                    }
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
        "scale ({which}): {workers} simulated workers thinking {think_ms} ms, {total} tiles of {tile} px on 2880x1920: {:.0} lease round trips/s (lease + upload: {:.0} tiles/s), lease latency p50 {:.2} ms p99 {:.2} ms, merge {:.3} s, state {:?}, uploads sent again {}",
        l.len() as f64 / secs,
        total as f64 / secs,
        pct(0.5),
        pct(0.99),
        status.merge_seconds.unwrap_or(f64::NAN),
        status.state,
        retries.load(std::sync::atomic::Ordering::Relaxed)
    );
}

fn main() {
    if !std::env::args().any(|a| a == "--skip-efficiency") {
        efficiency();
    }
    let store = arg("--store", String::new());
    scale(
        arg("--workers", 1000),
        arg("--think", 0),
        arg("--tile", 16),
        Some(store).filter(|s| !s.is_empty()),
    );
}
