//! Emissive-medium benchmark (issue 5): a 128³ temperature grid (a procedural flame, read
//! from Mitsuba .vol files) lighting a diffuse floor.
//!
//! Prints render samples per second with and without emitter sampling, the variance of the
//! floor's pixels at equal time (MIS, where the flame is sampled as a light by its 3D
//! distribution, against phase/BSDF sampling alone), and the throughput of heterogeneous
//! tracking on one thread (tentative collisions, each a density lookup, per second).
//!
//! `cargo bench --bench media [-- --grid N --spp N --resolution N --runs N]`

mod common;
use common::{arg, peak_rss_mib, render_image};
use kiln_render::media::Medium;
use kiln_render::sampling::TrackingRng;
use kiln_render::{RenderSettings, Renderer};
use kiln_scene::VoxelGrid;
use std::time::Instant;

/// A flame: a teardrop of density with a hot core, rippled by a few sines so that the
/// grid is truly heterogeneous. Returns (density, temperature).
fn flame(n: usize) -> (VoxelGrid, VoxelGrid) {
    let mut density = Vec::with_capacity(n * n * n);
    let mut temperature = Vec::with_capacity(n * n * n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let u = (x as f32 + 0.5) / n as f32 * 2.0 - 1.0;
                let v = (y as f32 + 0.5) / n as f32;
                let w = (z as f32 + 0.5) / n as f32 * 2.0 - 1.0;
                let ripple = 0.12 * libm::sinf(9.0 * v + 3.0 * u) * libm::cosf(7.0 * w + 5.0 * v);
                let r =
                    (libm::hypotf(u - 0.2 * v * v + ripple, w)) / (0.7 * (1.0 - 0.85 * v) + 0.04);
                let d = (1.0 - r * r).max(0.0) * (1.0 - 0.6 * v);
                density.push(d);
                temperature.push(if d > 0.0 {
                    900.0 + 1700.0 * (1.0 - r).max(0.0) * (1.0 - 0.5 * v)
                } else {
                    300.0
                });
            }
        }
    }
    let grid = |values| VoxelGrid {
        nx: n,
        ny: n,
        nz: n,
        values,
    };
    (grid(density), grid(temperature))
}

fn scene_text(strategy: &str, res: u32, spp: u32) -> String {
    // In RGB, as the recorded figures were measured.
    format!(
        "Option \"kiln.spectral\" false
        Integrator \"volpath\" \"integer maxdepth\" [ 5 ] \"string strategy\" \"{strategy}\"
        Sampler \"zsobol\" \"integer pixelsamples\" [ {spp} ]
        Film \"rgb\" \"integer xresolution\" [ {res} ] \"integer yresolution\" [ {res} ]
        LookAt 0 1.2 4.5  0 0.5 0  0 1 0
        Camera \"perspective\" \"float fov\" [ 40 ]
        WorldBegin
        AttributeBegin
          Translate 0 0.05 0
          Scale 0.5 1.4 0.5
          MakeNamedMedium \"flame\" \"string type\" \"uniformgrid\"
            \"string densityfile\" \"density.vol\" \"string temperaturefile\" \"temperature.vol\"
            \"point3 p0\" [ -1 0 -1 ] \"point3 p1\" [ 1 1 1 ]
            \"rgb sigma_a\" [ 4 4 4 ] \"rgb sigma_s\" [ 0.5 0.5 0.5 ] \"float Lescale\" [ 300 ]
          MediumInterface \"flame\" \"\"
          Material \"interface\"
          Shape \"trianglemesh\"
            \"point3 P\" [ -1 0 -1  1 0 -1  1 1 -1  -1 1 -1  -1 0 1  1 0 1  1 1 1  -1 1 1 ]
            \"integer indices\" [ 0 2 1 0 3 2 4 5 6 4 6 7 0 1 5 0 5 4 2 7 6 2 3 7 1 2 6 1 6 5 0 7 3 0 4 7 ]
        AttributeEnd
        Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]
        Shape \"bilinearmesh\" \"point3 P\" [ -6 0 -6  6 0 -6  -6 0 6  6 0 6 ]"
    )
}

fn main() {
    let n = arg("--grid", 128usize);
    let spp = arg("--spp", 16u32);
    let res = arg("--resolution", 128u32);
    let runs = arg("--runs", 6usize);
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let (density, temperature) = flame(n);
    let bbox = ([-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]);
    for (name, grid) in [("density.vol", &density), ("temperature.vol", &temperature)] {
        std::fs::write(
            dir.path().join(name),
            kiln_scene::files::vol::write_vol(grid, bbox),
        )
        .unwrap();
    }
    println!(
        "media bench: {n}^3 temperature grid ({:.2} s to generate), {res}x{res}, {spp} spp x {runs} runs, {} threads",
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    // The floor: the bottom quarter of the frame, below the flame.
    let floor: Vec<usize> = ((res * 3 / 4)..res)
        .flat_map(|y| (0..res).map(move |x| (y * res + x) as usize))
        .collect();
    let mut results = Vec::new();
    for strategy in ["mis", "bsdf"] {
        let path = dir.path().join(format!("{strategy}.pbrt"));
        std::fs::write(&path, scene_text(strategy, res, spp)).unwrap();
        let start = Instant::now();
        let desc = kiln_scene::load_file(&path).unwrap();
        let mut renderer = Renderer::build(&desc).unwrap();
        let build = start.elapsed().as_secs_f64();
        let mut settings = RenderSettings::from_description(&desc);
        let mut images = Vec::new();
        let (mut secs, mut samples) = (0.0, 0u64);
        for run in 0..runs {
            settings.seed = 1000 + run as u32;
            renderer = renderer.with_settings(settings.clone());
            let (s, count, pixels) = render_image(&renderer, (res, res));
            secs += s;
            samples += count;
            images.push(pixels);
        }
        // Per-pixel variance across the independent runs, averaged over the floor.
        let mut variance = 0.0f64;
        for &i in &floor {
            let lum: Vec<f64> = images
                .iter()
                .map(|img| {
                    0.2126 * img[i][0] as f64
                        + 0.7152 * img[i][1] as f64
                        + 0.0722 * img[i][2] as f64
                })
                .collect();
            let mean = lum.iter().sum::<f64>() / runs as f64;
            variance += lum.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (runs - 1) as f64;
        }
        variance /= floor.len() as f64;
        let floor_mean: f64 = floor
            .iter()
            .map(|&i| images.iter().map(|img| img[i][0] as f64).sum::<f64>() / runs as f64)
            .sum::<f64>()
            / floor.len() as f64;
        let per_run = secs / runs as f64;
        println!(
            "{strategy}: build {build:.2} s, {:.0} samples/s, {per_run:.2} s per run, floor mean R {floor_mean:.4}, floor pixel variance {variance:.3e}, variance x time {:.3e}",
            samples as f64 / secs,
            variance * per_run
        );
        results.push(variance * per_run);
    }
    println!(
        "variance at equal time: phase/BSDF sampling alone / MIS with emitter sampling = {:.1}x (target >= 4x)",
        results[1] / results[0]
    );

    // Tracking throughput on one thread: ratio tracking along random rays through the grid.
    let path = dir.path().join("mis.pbrt");
    let desc = kiln_scene::load_file(&path).unwrap();
    let renderer = Renderer::build(&desc).unwrap();
    let Some(Medium::Grid(grid)) = renderer.scene().media.first() else {
        panic!("the flame is the scene's first medium");
    };
    // Two workloads: shadow rays towards points sampled from the flame's emission (what
    // next-event estimation traces), and rays towards uniform points of the grid's box.
    for (name, towards_emission) in [
        ("towards sampled flame points", true),
        ("towards uniform points of the box", false),
    ] {
        let mut rng = TrackingRng::new(42);
        let (mut lookups, mut rays) = (0u64, 0u64);
        let start = Instant::now();
        while start.elapsed().as_secs_f64() < 2.0 {
            for _ in 0..1000 {
                let a = glam::Vec3A::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                );
                let o = a.normalize_or_zero() * 2.0 + glam::Vec3A::new(0.0, 0.75, 0.0);
                let target = if towards_emission {
                    let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                    grid.sample_emission(u, &mut rng).unwrap().0
                } else {
                    glam::Vec3A::new(
                        rng.next_f32() - 0.5,
                        0.05 + 1.4 * rng.next_f32(),
                        rng.next_f32() - 0.5,
                    )
                };
                let d = (target - o).normalize();
                let mut sum = 0.0f32;
                grid.walk(o, d, 10.0, &mut rng, |_, p, _| {
                    sum += grid.coefficients(p).1.x;
                    lookups += 1;
                    true
                });
                std::hint::black_box(sum);
                rays += 1;
            }
        }
        let secs = start.elapsed().as_secs_f64();
        println!(
            "tracking (1 thread), rays {name}: {:.2} M medium samples/s (tentative collisions, each a density lookup; target >= 2 M), {:.0} rays/s, {:.1} samples per ray",
            lookups as f64 / secs / 1e6,
            rays as f64 / secs,
            lookups as f64 / rays as f64
        );
    }
    if let Some(mib) = peak_rss_mib() {
        println!("peak memory {mib:.0} MiB");
    }
}
