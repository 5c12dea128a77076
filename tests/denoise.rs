//! Denoising with the feature buffers every render keeps: the built-in denoiser's output is
//! the same bytes for any tiling, thread count and farm; it lowers the error against a long
//! render and keeps the energy and the textures; an image it cannot denoise is refused
//! with its raw render kept.

use crate::util::{kiln, render, scene};
use kiln_denoise::metrics;

fn plane(image: &kiln_image::RgbBuffer, names: [&str; 3]) -> Vec<[f32; 3]> {
    let slots = names.map(|n| image.aovs.names.iter().position(|s| s == n).unwrap());
    (0..image.pixels.len() as u32)
        .map(|i| {
            let px = image.aovs_at(i % image.width, i / image.width);
            slots.map(|s| px[s])
        })
        .collect()
}

/// `kiln render --denoise` gives the same bytes for other tile sizes and thread counts,
/// `kiln farm --denoise` (two workers, other tiles) gives them too, and so does `kiln
/// denoise` of its frame on one thread or two:
/// every feature of a pixel comes from its own samples, and the filter computes each pixel
/// on its own in a fixed order.
#[test]
fn the_denoised_frame_is_the_same_bytes_for_any_split_thread_count_and_farm() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("textures/scene.pbrt");
    let common = ["--resolution", "96x64", "--spp", "8", "--denoise"];
    let a = render(
        &path,
        dir.path(),
        "a",
        &[&common[..], &["--tile", "16", "--threads", "1"]].concat(),
    );
    let b = render(
        &path,
        dir.path(),
        "b",
        &[&common[..], &["--tile", "7", "--threads", "2"]].concat(),
    );
    assert!(
        a.bytes == b.bytes,
        "tiling or threads changed the denoised frame"
    );
    // The raw beauty is kept beside the denoised one, and they differ.
    let raw = plane(&a.image, kiln_denoise::RAW);
    assert_ne!(raw, a.image.pixels);
    // `kiln farm --denoise`: two workers, other tiles, the same bytes.
    let farm = crate::farm::farm(
        &path,
        dir.path(),
        "farm",
        &[
            "--resolution",
            "96x64",
            "--spp",
            "8",
            "--tile",
            "11",
            "--workers",
            "2",
            "--denoise",
        ],
    );
    assert!(
        farm == a.bytes,
        "kiln farm --denoise differs from kiln render --denoise"
    );
    // `kiln denoise` of it (denoised again from its raw beauty) on one thread or two.
    let farm_exr = dir.path().join("farm.exr");
    let out = dir.path().join("farm-denoised.exr");
    for threads in ["1", "2"] {
        let o = kiln()
            .env("RAYON_NUM_THREADS", threads)
            .args(["denoise", "-q", "-o"])
            .arg(&out)
            .arg(&farm_exr)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(&out).unwrap();
        assert!(
            bytes == a.bytes,
            "the farm's frame denoised on {threads} threads differs from kiln render --denoise"
        );
    }
}

/// Against a render of 64 times the samples, the denoised 16-spp image has less than 1/1.3
/// of the raw one's relative error (1.43x less on 2026-11-29: this scene's glossy spheres
/// have noisy albedo features; the bar, below the raw 256-spp image's, is measured
/// by `cargo bench --bench denoise`), less where the texture changes too, and the same mean
/// within 1% per channel.
#[test]
fn the_denoiser_lowers_the_error_and_keeps_the_energy_and_the_textures() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("textures/scene.pbrt");
    let size = ["--resolution", "96x64"];
    let noisy = render(
        &path,
        dir.path(),
        "noisy",
        &[&size[..], &["--spp", "16", "--denoise"]].concat(),
    );
    let reference = render(
        &path,
        dir.path(),
        "ref",
        &[&size[..], &["--spp", "1024", "--seed", "7"]].concat(),
    );
    let (w, h) = (96, 64);
    let r = &reference.image.pixels;
    let raw = plane(&noisy.image, kiln_denoise::RAW);
    let denoised = &noisy.image.pixels;
    let textured = metrics::textured(&plane(&reference.image, kiln_denoise::ALBEDO), w, h);
    assert!(
        textured.iter().filter(|&&t| t).count() > 100,
        "the scene has textures"
    );
    let (e_raw, e_den) = (
        metrics::rel_mse(&raw, r, None),
        metrics::rel_mse(denoised, r, None),
    );
    let (t_raw, t_den) = (
        metrics::rel_mse(&raw, r, Some(&textured)),
        metrics::rel_mse(denoised, r, Some(&textured)),
    );
    eprintln!(
        "relMSE raw {e_raw:.5} denoised {e_den:.5}; textured raw {t_raw:.5} denoised {t_den:.5}"
    );
    assert!(e_den < e_raw / 1.3, "denoised {e_den} against raw {e_raw}");
    assert!(
        t_den < t_raw,
        "textures blurred: {t_den} against raw {t_raw}"
    );
    let (m_raw, m_den) = (metrics::mean(&raw), metrics::mean(denoised));
    for c in 0..3 {
        assert!(
            (m_den[c] / m_raw[c] - 1.0).abs() < 0.01,
            "channel {c}: mean {} against raw {}",
            m_den[c],
            m_raw[c]
        );
    }
}

/// SPPM keeps no variance: `--denoise` says so, fails, and keeps the raw render.
#[test]
fn a_render_that_cannot_be_denoised_is_refused_and_its_raw_image_kept() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ball.exr");
    let o = kiln()
        .arg("render")
        .arg(scene("photons/ball.pbrt"))
        .args([
            "-q",
            "--resolution",
            "32x32",
            "--spp",
            "2",
            "--denoise",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("variance") && err.contains("raw render was written"),
        "{err}"
    );
    let kept = kiln_image::decode_exr(&std::fs::read(&out).unwrap()).unwrap();
    assert!(kept.aovs.names.iter().all(|n| !n.starts_with("raw.")));
    // An image from elsewhere, without features, is refused by name.
    let bare = dir.path().join("bare.exr");
    kiln_image::write_exr(&bare, &kiln_image::RgbBuffer::new(4, 4, 0, 0, 4, 4)).unwrap();
    let o = kiln()
        .args(["denoise", "-o"])
        .arg(dir.path().join("x.exr"))
        .arg(&bare)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("features.albedo.R"));
    // Open Image Denoise in a build without it is refused before anything renders.
    if !kiln_denoise::Denoiser::oidn_available() {
        let never = dir.path().join("never.exr");
        let o = kiln()
            .arg("render")
            .arg(scene("textures/scene.pbrt"))
            .args(["-q", "--denoise", "--denoiser", "oidn", "-o"])
            .arg(&never)
            .output()
            .unwrap();
        assert!(!o.status.success());
        assert!(String::from_utf8_lossy(&o.stderr).contains("built without Open Image Denoise"));
        assert!(!never.exists(), "nothing was rendered");
    }
}
