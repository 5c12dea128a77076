//! Light-sampler benchmark (issue 13): the corridor of 100 lights (scenes/lights) rendered
//! with each of pbrt-v4's light samplers, "bvh" (Kiln's default), "power", "uniform" and "exhaustive".
//!
//! Prints samples per second, the mean squared error against a reference (the hierarchy at
//! many samples) at equal samples, and the error at equal time (MSE times seconds: lower
//! is better), with each sampler's efficiency relative to the power sampler.
//!
//! `cargo bench --bench lights [-- --spp N --ref-spp N --resolution WxH]`

mod common;
use common::{arg, render_image};
use kiln_render::Renderer;

/// Renders the frame with `spp` samples and `seed`; returns seconds and the pixels.
fn render(
    renderer: Renderer,
    spp: u32,
    seed: u32,
    (w, h): (u32, u32),
) -> (Renderer, f64, Vec<[f32; 3]>) {
    let mut settings = renderer.settings().clone();
    settings.samples_per_pixel = spp;
    settings.seed = seed;
    let renderer = renderer.with_settings(settings);
    let (secs, _, pixels) = render_image(&renderer, (w, h));
    (renderer, secs, pixels)
}

fn load(sampler: &str, (w, h): (u32, u32)) -> Renderer {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/lights/scene.pbrt");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "\"string lightsampler\" \"bvh\"",
        &format!("\"string lightsampler\" \"{sampler}\""),
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("scene.pbrt");
    std::fs::write(&file, text).unwrap();
    let mut desc = kiln_scene::load_file(&file).unwrap();
    desc.apply_overrides(&kiln_scene::Overrides {
        resolution: Some((w, h)),
        spp: None,
        seed: None,
        ..Default::default()
    })
    .unwrap();
    Renderer::build(&desc).unwrap()
}

fn main() {
    let spp = arg("--spp", 16u32);
    let ref_spp = arg("--ref-spp", 1024u32);
    let res: String = arg("--resolution", "192x128".to_string());
    let (w, h) = res
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
        .expect("--resolution WxH");
    println!(
        "lights bench: scenes/lights ({w}x{h}), {spp} spp against a {ref_spp} spp reference, {} threads",
        rayon::current_num_threads()
    );
    let (_, ref_secs, reference) = render(load("bvh", (w, h)), ref_spp, 999, (w, h));
    println!("reference: {ref_secs:.1} s");
    let mut rows = Vec::new();
    for sampler in ["bvh", "power", "uniform", "exhaustive"] {
        let start = std::time::Instant::now();
        let renderer = load(sampler, (w, h));
        let build = start.elapsed().as_secs_f64();
        // Three seeds, for a steadier error.
        let (mut secs, mut mse) = (0.0, 0.0);
        let mut renderer = Some(renderer);
        for seed in 0..3 {
            let (r, s, pixels) = render(renderer.take().unwrap(), spp, seed, (w, h));
            renderer = Some(r);
            secs += s / 3.0;
            mse += pixels
                .iter()
                .zip(&reference)
                .map(|(a, b)| {
                    (0..3)
                        .map(|c| (a[c] as f64 - b[c] as f64).powi(2))
                        .sum::<f64>()
                        / 3.0
                })
                .sum::<f64>()
                / pixels.len() as f64
                / 3.0;
        }
        let samples_per_s = (w * h * spp) as f64 / secs;
        println!(
            "{sampler:>8}: build {build:.3} s, {:.2} M samples/s, {secs:.2} s per frame, MSE {mse:.3e}, MSE x time {:.3e}",
            samples_per_s / 1e6,
            mse * secs
        );
        rows.push((sampler, mse * secs));
    }
    let power = rows[1].1;
    for (sampler, e) in &rows {
        println!(
            "{sampler:>8}: efficiency {:.2}x the power sampler's (equal-time MSE)",
            power / e
        );
    }
}
