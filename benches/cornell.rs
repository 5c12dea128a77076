//! Cornell box benchmark: renders reference-scenes/cornell-box at 256x256, 64 spp and
//! the file's max depth (65), with 1 and 2 threads, and prints samples per second,
//! rays per second, peak memory, and the error against Tungsten's converged render.
//!
//! `cargo bench --bench cornell [-- --spp N --resolution N --repeats N --spectral]`
//! (`--spectral`: four wavelengths per sample; the table of spectra is built before the
//! timed renders, once per process, and its time printed).
//! Mitsuba 3's figures on the same scene and settings: benches/mitsuba/.

mod common;
use common::{arg, peak_rss_mib};
use kiln_render::{Renderer, TileStats, render_tile, split_into_tiles};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("../shared/reference-scenes/cornell-box");
    let path = dir.join("scene.pbrt");
    if !path.exists() {
        println!(
            "SKIPPED: {} is not present (../shared exists beside the checkout and in CI only)",
            path.display()
        );
        return;
    }
    let res = arg("--resolution", 256);
    let spp = arg("--spp", 64);
    let repeats = arg("--repeats", 3);
    let mut desc = kiln_scene::load_file(&path).expect("the reference scene loads");
    desc.film.xresolution = res;
    desc.film.yresolution = res;
    desc.film.pixel_bounds = [0, res, 0, res];
    desc.sampler.pixel_samples = spp;
    desc.spectral = std::env::args().any(|a| a == "--spectral");
    if desc.spectral {
        let start = Instant::now();
        kiln_scene::sigmoid_table::SigmoidTable::srgb();
        println!(
            "spectral: sigmoid table built in {:.3} s",
            start.elapsed().as_secs_f64()
        );
    }
    let renderer = Renderer::build(&desc).expect("the reference scene builds");
    let scene = renderer.scene();
    let tiles = split_into_tiles(desc.film.pixel_bounds, 32);
    let reference = reference_image(&dir, res);
    println!(
        "cornell-box {res}x{res}, {spp} spp, max depth {}, BVH build {:.1} ms",
        desc.integrator.max_depth,
        scene.geometry.build_time.as_secs_f64() * 1e3
    );
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut times = Vec::new();
        let mut last = None;
        // One warm-up render, then the timed ones.
        for i in 0..=repeats {
            let start = Instant::now();
            let results: Vec<_> = pool.install(|| {
                tiles
                    .par_iter()
                    .map(|t| render_tile(&renderer, *t))
                    .collect()
            });
            if i > 0 {
                times.push(start.elapsed().as_secs_f64());
            }
            last = Some(results);
        }
        times.sort_by(f64::total_cmp);
        let secs = times[times.len() / 2];
        let results = last.unwrap();
        let mut stats = TileStats::default();
        let mut image = vec![[0.0f32; 3]; (res * res) as usize];
        for r in &results {
            stats.merge(&r.stats);
            for y in 0..r.rect.height {
                for x in 0..r.rect.width {
                    image[((r.rect.y0 + y) * res + r.rect.x0 + x) as usize] =
                        r.pixels[(y * r.rect.width + x) as usize];
                }
            }
        }
        let mean = (0..3)
            .map(|c| image.iter().map(|p| p[c] as f64).sum::<f64>() / image.len() as f64)
            .collect::<Vec<_>>();
        let errors = reference.as_ref().map(|r| rmse(&image, r));
        println!(
            "kiln threads={threads} seconds={secs:.4} samples_per_sec={:.0} rays_per_sec={:.0} mean={:.5},{:.5},{:.5}{}",
            stats.samples as f64 / secs,
            stats.rays as f64 / secs,
            mean[0],
            mean[1],
            mean[2],
            errors
                .map(|(a, b)| format!(" rmse={a:.5} rmse_nolight={b:.5}"))
                .unwrap_or_default(),
        );
    }
    if let Some(mib) = peak_rss_mib() {
        println!("kiln peak_rss_mib={mib:.1}");
    }
}

/// Tungsten's render box-averaged down to `res`, if the file is there and divides evenly.
fn reference_image(dir: &std::path::Path, res: u32) -> Option<Vec<[f32; 3]>> {
    let img = kiln_image::read_exr_rgb(&dir.join("TungstenRender.exr")).ok()?;
    if img.width != img.height || img.width % res != 0 {
        return None;
    }
    let k = img.width / res;
    let mut out = vec![[0.0f32; 3]; (res * res) as usize];
    for y in 0..img.height {
        for x in 0..img.width {
            let p = img.pixels[(y * img.width + x) as usize];
            let o = &mut out[((y / k) * res + x / k) as usize];
            for c in 0..3 {
                o[c] += p[c] / (k * k) as f32;
            }
        }
    }
    Some(out)
}

/// RMSE over all pixels, and without the pixels that show the light (reference above 1,
/// widened by 2 pixels), whose filtered edges dominate the first figure (as in benches/mitsuba).
fn rmse(image: &[[f32; 3]], reference: &[[f32; 3]]) -> (f64, f64) {
    let res = (image.len() as f64).sqrt() as i64;
    let bright: Vec<bool> = reference
        .iter()
        .map(|p| p.iter().cloned().fold(0.0, f32::max) > 1.0)
        .collect();
    let near_light = |x: i64, y: i64| {
        (-2..=2).any(|dy| {
            (-2..=2).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0 && v >= 0 && u < res && v < res && bright[(v * res + u) as usize]
            })
        })
    };
    let (mut all, mut n_all, mut rest, mut n_rest) = (0.0, 0.0, 0.0, 0.0);
    for y in 0..res {
        for x in 0..res {
            let i = (y * res + x) as usize;
            let se: f64 = (0..3)
                .map(|c| (image[i][c] as f64 - reference[i][c] as f64).powi(2))
                .sum::<f64>()
                / 3.0;
            all += se;
            n_all += 1.0;
            if !near_light(x, y) {
                rest += se;
                n_rest += 1.0;
            }
        }
    }
    ((all / n_all).sqrt(), (rest / n_rest).sqrt())
}
