//! Adaptive sampling at equal error: the headline frame (scenes/molten-glass, the whole
//! frame at a reduced resolution, so every part of it counts as it does at full size)
//! rendered with every pixel taking `--spp` samples and with adaptive sampling at each
//! threshold, each timed and compared with a converged reference (another seed, `--ref-spp`
//! samples, rendered once and kept in target/adaptive/). For each it prints the time, the
//! RMSE of linear radiance and of the sRGB image, the mean (the bias of stopping before a
//! rare bright path shows), the samples taken, and the efficiency against the uniform
//! render (its MSE times its time over this one's): above 1, adaptive sampling reaches a
//! given error sooner.
//!
//! `cargo bench --bench adaptive [-- --resolution 360 --spp 2048 --ref-spp 8192
//!  --thresholds 0.005,0.01,0.02 --min-samples 256]` (about 25 minutes the first time on
//! this project's 2-core machine, 10 once the reference is kept)

mod common;
use common::{arg, render_image};
use kiln_render::Renderer;
use std::path::{Path, PathBuf};

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = root.join("scenes/molten-glass/scene.pbrt");
    let width: u32 = arg("--resolution", 360);
    let height = width * 2 / 3;
    let spp: u32 = arg("--spp", 2048);
    let ref_spp: u32 = arg("--ref-spp", 8192);
    let min_samples: u32 = arg("--min-samples", 256);
    let thresholds: Vec<f32> = arg("--thresholds", "0.005,0.01,0.02".to_string())
        .split(',')
        .filter_map(|t| t.trim().parse().ok())
        .collect();
    let build = |spp: u32, seed: u32, threshold: Option<f32>| {
        let mut desc = kiln_scene::load_file(&scene).expect("the headline scene loads");
        desc.apply_overrides(&kiln_scene::Overrides {
            resolution: Some((width, height)),
            spp: Some(spp),
            seed: Some(seed),
            noise_threshold: Some(threshold.unwrap_or(0.0)),
            ..Default::default()
        })
        .unwrap();
        desc.sampler.min_samples = min_samples;
        Renderer::build(&desc).expect("the headline scene builds")
    };
    let cache = root.join(format!(
        "target/adaptive/ref-{width}x{height}-{ref_spp}.f32"
    ));
    let reference = read_cached(&cache, width * height).unwrap_or_else(|| {
        println!("adaptive: rendering the reference ({ref_spp} spp, seed 99) once");
        let (secs, _, pixels) = render_image(&build(ref_spp, 99, None), (width, height));
        println!(
            "adaptive: reference in {secs:.0} s, kept in {}",
            cache.display()
        );
        write_cached(&cache, &pixels);
        pixels
    });
    println!(
        "adaptive molten-glass {width}x{height}, at most {spp} spp, min {min_samples}, reference {ref_spp} spp"
    );
    let mut uniform: Option<(f64, f64, f64)> = None;
    for threshold in std::iter::once(None).chain(thresholds.into_iter().map(Some)) {
        let renderer = build(spp, 0, threshold);
        let (secs, samples, pixels) = render_image(&renderer, (width, height));
        let (mse, mse_srgb, mean) = errors(&pixels, &reference);
        let (mu, msu, tu) = *uniform.get_or_insert((mse, mse_srgb, secs));
        println!(
            "adaptive threshold={} seconds={secs:.1} samples_per_pixel={:.0} rmse={:.5} rmse_srgb={:.5} mean={mean:.5} reference_mean={:.5} efficiency={:.2} efficiency_srgb={:.2}",
            threshold.map_or("off".to_string(), |t| t.to_string()),
            samples as f64 / (width * height) as f64,
            mse.sqrt(),
            mse_srgb.sqrt(),
            reference
                .iter()
                .map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0)
                .sum::<f64>()
                / reference.len() as f64,
            mu * tu / (mse * secs),
            msu * tu / (mse_srgb * secs),
        );
    }
}

/// Mean squared error of linear radiance and of sRGB values (clamped to 0..1), and the
/// image's mean.
fn errors(image: &[[f32; 3]], reference: &[[f32; 3]]) -> (f64, f64, f64) {
    let srgb = |v: f32| {
        let v = f64::from(v.clamp(0.0, 1.0));
        if v <= 0.0031308 {
            12.92 * v
        } else {
            1.055 * libm::pow(v, 1.0 / 2.4) - 0.055
        }
    };
    let (mut mse, mut mse_srgb, mut mean) = (0.0, 0.0, 0.0);
    for (p, q) in image.iter().zip(reference) {
        for c in 0..3 {
            mse += (f64::from(p[c]) - f64::from(q[c])).powi(2);
            mse_srgb += (srgb(p[c]) - srgb(q[c])).powi(2);
            mean += f64::from(p[c]);
        }
    }
    let n = (3 * image.len()) as f64;
    (mse / n, mse_srgb / n, mean / n)
}

fn read_cached(path: &Path, pixels: u32) -> Option<Vec<[f32; 3]>> {
    let bytes = std::fs::read(path).ok()?;
    if bytes.len() != pixels as usize * 12 {
        return None;
    }
    Some(
        bytes
            .chunks_exact(12)
            .map(|c| {
                std::array::from_fn(|i| f32::from_le_bytes(c[4 * i..4 * i + 4].try_into().unwrap()))
            })
            .collect(),
    )
}

fn write_cached(path: &Path, pixels: &[[f32; 3]]) {
    let _ = std::fs::create_dir_all(path.parent().unwrap());
    let bytes: Vec<u8> = pixels
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let _ = std::fs::write(path, bytes);
}
