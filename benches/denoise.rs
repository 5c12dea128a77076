//! The denoisers against the bar: on each scene at preview size, the denoised
//! 16-spp image against a 4096-spp reference, beside the raw 16-spp and raw 256-spp
//! images. For each it prints the relative MSE (over the whole image, and over its
//! textured pixels, its geometric edges and its hardest-to-sample 5%: caustics, found from
//! the 256-spp render's features and variance), the SSIM,
//! the mean against the raw mean, and the denoiser's time; and writes side-by-side
//! pictures (raw 16 spp | denoised 16 spp | reference) and the denoised EXRs to
//! target/denoise/.
//!
//! Renders are kept in target/denoise/<scene>-<spp>.exr and reused: the references take
//! about 30 minutes together on this project's 2-core machine the first time.
//! `cargo bench --bench denoise [-- --scenes cornell,lily-pond,martini,headline
//!  --ref-spp 4096]` (Open Image Denoise's figures too with `--features oidn`); the
//! built-in filter's settings can be varied with `--iterations N --color K --albedo S
//! --depth S --normal-power P`.

mod common;
use common::arg;
use kiln_denoise::{Denoiser, Settings, metrics};
use kiln_image::RgbBuffer;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A scene measured: its name, file (from the repository root) and preview size.
const SCENES: [(&str, &str, (u32, u32)); 4] = [
    (
        "cornell",
        "../shared/reference-scenes/cornell-box/scene.pbrt",
        (256, 256),
    ),
    ("lily-pond", "scenes/lily-pond/scene.pbrt", (240, 160)),
    ("martini", "scenes/martini/scene.pbrt", (360, 240)),
    ("headline", "scenes/molten-glass/scene.pbrt", (360, 240)),
];

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let wanted = arg("--scenes", "cornell,lily-pond,martini,headline".to_string());
    let ref_spp: u32 = arg("--ref-spp", 4096);
    let out = root.join("target/denoise");
    std::fs::create_dir_all(&out).expect("target/denoise can be made");
    let d = Settings::default();
    let settings = Settings {
        iterations: arg("--iterations", d.iterations),
        color: arg("--color", d.color),
        normal_power: arg("--normal-power", d.normal_power),
        depth: arg("--depth", d.depth),
        albedo: arg("--albedo", d.albedo),
    };
    let dr = kiln_denoise::Regression::default();
    let regression = kiln_denoise::Regression {
        radius: arg("--radius", dr.radius),
        color: arg("--regression-color", dr.color),
        ridge: arg("--ridge", dr.ridge),
    };
    let mut denoisers = vec![Denoiser::BuiltIn(settings, Some(regression))];
    if std::env::args().any(|a| a == "--both-stages") {
        denoisers.push(Denoiser::BuiltIn(settings, None));
    }
    if Denoiser::oidn_available() {
        denoisers.push(Denoiser::Oidn);
    }
    for (name, file, size) in SCENES {
        if !wanted.split(',').any(|w| w == name) {
            continue;
        }
        let path = root.join(file);
        if !path.exists() {
            println!("{name}: SKIPPED: {} is not present", path.display());
            continue;
        }
        let get = |spp| frame(&path, &out.join(format!("{name}-{spp}.exr")), size, spp);
        let (raw16, raw256, reference) = (get(16), get(256), get(ref_spp));
        report(name, &raw16, &raw256, &reference, ref_spp, &denoisers, &out);
    }
}

/// The render of `scene` at `size` and `spp`, kept in `cache` (rendered there if missing).
fn frame(scene: &Path, cache: &Path, size: (u32, u32), spp: u32) -> RgbBuffer {
    if let Ok(bytes) = std::fs::read(cache) {
        return kiln_image::decode_exr(&bytes).expect("a kept render reads back");
    }
    let mut desc = kiln_scene::load_file(scene).expect("the scene loads");
    desc.apply_overrides(&kiln_scene::Overrides {
        resolution: Some(size),
        spp: Some(spp),
        ..Default::default()
    })
    .expect("the overrides apply");
    let renderer = kiln_render::Renderer::build(&desc).expect("the scene builds");
    let start = Instant::now();
    let [x0, x1, y0, y1] = desc.film.pixel_bounds;
    let tiles = kiln_render::split_into_tiles(desc.film.pixel_bounds, 32);
    let names = kiln_render::aov_names(desc.film.gbuffer);
    let mut image = RgbBuffer::new(size.0, size.1, x0, y0, x1 - x0, y1 - y0).with_aovs(&names);
    for r in kiln_render::render_tiles(&renderer, &tiles, &|| {}) {
        let t = r.rect;
        let aovs = kiln_image::Aovs {
            names: names.clone(),
            values: r.aovs,
        };
        let tile =
            RgbBuffer::new(size.0, size.1, t.x0, t.y0, t.width, t.height).holding(r.pixels, aovs);
        image.paste(&tile).expect("a tile fits its frame");
    }
    println!(
        "  rendered {} at {spp} spp in {:.0} s",
        scene.display(),
        start.elapsed().as_secs_f64()
    );
    kiln_image::write_exr(cache, &image).expect("the render can be kept");
    image
}

/// One channel triple of every pixel of `image`, by name.
fn plane(image: &RgbBuffer, names: [&str; 3]) -> Vec<[f32; 3]> {
    let slot = names.map(|n| {
        image
            .aovs
            .names
            .iter()
            .position(|s| s == n)
            .expect("a feature channel")
    });
    (0..image.pixels.len() as u32)
        .map(|i| {
            let px = image.aovs_at(i % image.width, i / image.width);
            slot.map(|s| px[s])
        })
        .collect()
}

fn report(
    name: &str,
    raw16: &RgbBuffer,
    raw256: &RgbBuffer,
    reference: &RgbBuffer,
    ref_spp: u32,
    denoisers: &[Denoiser],
    out: &Path,
) {
    let (w, h) = (reference.width as usize, reference.height as usize);
    let r = &reference.pixels;
    // The regions, from the 256-spp render's features (the reference's beauty alone is
    // needed, so a reference rendered before the features changed still serves).
    let albedo = plane(raw256, kiln_denoise::ALBEDO);
    let normal = plane(raw256, kiln_denoise::NORMAL);
    let depth: Vec<f32> = plane(raw256, [kiln_denoise::DEPTH; 3])
        .iter()
        .map(|v| v[0])
        .collect();
    let variance = plane(raw256, kiln_denoise::VARIANCE);
    let masks = [
        ("textured", metrics::textured(&albedo, w, h)),
        ("edges", metrics::edges(&normal, &depth, w, h)),
        (
            "caustic",
            metrics::hard_to_sample(&raw256.pixels, &variance, 256, 0.05),
        ),
    ];
    let share = |m: &[bool]| 100.0 * m.iter().filter(|&&b| b).count() as f64 / m.len() as f64;
    println!(
        "{name} {w}x{h}: relMSE against {ref_spp} spp (regions: textured {:.1}%, edges {:.1}%, caustic {:.1}% of pixels)",
        share(&masks[0].1),
        share(&masks[1].1),
        share(&masks[2].1)
    );
    println!(
        "  {:<16} {:>9} {:>9} {:>9} {:>9} {:>7} {:>8} {:>8}",
        "image", "relMSE", "textured", "edges", "caustic", "SSIM", "mean/raw", "seconds"
    );
    let raw_mean = metrics::mean(&raw16.pixels);
    let line = |label: &str, img: &[[f32; 3]], secs: Option<f64>| {
        let m = metrics::mean(img);
        let ratio: Vec<String> = (0..3)
            .map(|c| format!("{:.3}", m[c] / raw_mean[c].max(1e-12)))
            .collect();
        println!(
            "  {:<16} {:>9.5} {:>9.5} {:>9.5} {:>9.5} {:>7.4} {} {}",
            label,
            metrics::rel_mse(img, r, None),
            metrics::rel_mse(img, r, Some(&masks[0].1)),
            metrics::rel_mse(img, r, Some(&masks[1].1)),
            metrics::rel_mse(img, r, Some(&masks[2].1)),
            metrics::ssim(img, r, w, h),
            ratio.join("/"),
            secs.map_or(String::new(), |s| format!("{s:.2}")),
        );
    };
    line("raw 16 spp", &raw16.pixels, None);
    line("raw 256 spp", &raw256.pixels, None);
    for d in denoisers {
        let start = Instant::now();
        let denoised = kiln_denoise::denoise(raw16, *d, &|_, _| {}).expect("it denoises");
        let secs = start.elapsed().as_secs_f64();
        let label = match d {
            Denoiser::BuiltIn(_, None) => "kiln-atrous",
            _ => d.name(),
        };
        line(&format!("{label} 16 spp"), &denoised, Some(secs));
        let kept = kiln_denoise::with_denoised(raw16, denoised.clone());
        let path = out.join(format!("{name}-{label}.exr"));
        kiln_image::write_exr(&path, &kept).expect("the denoised image can be kept");
        side_by_side(
            &[&raw16.pixels, &denoised, r],
            w,
            h,
            &out.join(format!("{name}-{label}.png")),
        );
    }
}

/// Writes images of `w` x `h` side by side as one PNG.
fn side_by_side(images: &[&[[f32; 3]]], w: usize, h: usize, path: &Path) {
    let n = images.len();
    let mut strip = RgbBuffer::new((w * n) as u32, h as u32, 0, 0, (w * n) as u32, h as u32);
    for (k, img) in images.iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                strip.pixels[y * w * n + k * w + x] = img[y * w + x];
            }
        }
    }
    kiln_image::write_png(path, &strip, 0.0).expect("the picture can be written");
}
