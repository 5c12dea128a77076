//! A small harness for the integration tests: run `kiln`, read what it wrote,
//! find the shared reference scenes, and compare images statistically.

use kiln_image::RgbBuffer;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path under the repository's scenes/.
pub fn scene(rel: &str) -> PathBuf {
    repo().join("scenes").join(rel)
}

/// A reference scene from ../shared, or `None` (with a plain message) when that folder
/// is not beside the checkout, as on a user's fresh clone.
pub fn reference_scene(name: &str) -> Option<PathBuf> {
    let p = repo()
        .join("../shared/reference-scenes")
        .join(name)
        .join("scene.pbrt");
    if p.exists() {
        Some(p)
    } else {
        eprintln!(
            "SKIPPED: {} is not present (../shared exists beside the checkout and in CI only)",
            p.display()
        );
        None
    }
}

/// The `kiln` binary, with no camera data or measured spectra unless a test gives it some
/// (a developer's own KILN_SENSOR_DATA or KILN_SPECTRUM_DATA must not change what a test
/// sees).
pub fn kiln() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_kiln"));
    cmd.env_remove("KILN_SENSOR_DATA");
    cmd.env_remove("KILN_SPECTRUM_DATA");
    cmd
}

pub struct Rendered {
    pub image: RgbBuffer,
    pub bytes: Vec<u8>,
    pub output: Output,
}

/// Runs `kiln render SCENE ARGS -o DIR/NAME.exr` and reads the EXR back; panics with kiln's stderr on failure.
pub fn render(scene: &Path, dir: &Path, name: &str, args: &[&str]) -> Rendered {
    render_with_env(scene, dir, name, args, &[])
}

/// [`render`] with environment variables set for `kiln`.
pub fn render_with_env(
    scene: &Path,
    dir: &Path,
    name: &str,
    args: &[&str],
    env: &[(&str, &str)],
) -> Rendered {
    let out = dir.join(format!("{name}.exr"));
    let output = kiln()
        .envs(env.iter().copied())
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(&out)
        .arg("--quiet")
        .args(args)
        .output()
        .expect("kiln runs");
    assert!(
        output.status.success(),
        "kiln render {} {args:?} failed:\n{}",
        scene.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    let bytes = std::fs::read(&out).expect("kiln wrote its output");
    let image = kiln_image::decode_exr(&bytes).expect("kiln wrote a readable EXR");
    Rendered {
        image,
        bytes,
        output,
    }
}

/// Writes `text` as DIR/NAME and returns its path.
pub fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Replaces a scene's Integrator directive (and its parameter lines) by `integrator`.
pub fn with_integrator(text: &str, integrator: &str) -> String {
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("Integrator") {
            skipping = true;
            out.push_str(integrator);
            out.push('\n');
            continue;
        }
        if skipping && t.starts_with('"') {
            continue;
        }
        skipping = false;
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Mean and standard error of one channel over a block of pixels. Pixels are independent
/// estimates (each has its own scrambled sample sequence), so the standard error of their
/// mean is their standard deviation over sqrt(n).
pub fn block_stats(img: &RgbBuffer, x0: u32, y0: u32, w: u32, h: u32, c: usize) -> (f64, f64) {
    mean_and_error((y0..y0 + h).flat_map(|y| (x0..x0 + w).map(move |x| img.get(x, y)[c] as f64)))
}

pub fn mean_and_error(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut n, mut sum, mut sum2) = (0.0, 0.0, 0.0);
    for v in values {
        n += 1.0;
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n;
    let var = (sum2 / n - mean * mean).max(0.0) * n / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Compares two independent renders of the same scene (different seeds) block by block
/// (a `bx` by `by` grid) and channel by channel, and returns the largest |z| of the mean
/// per-pixel difference. Differencing pixel by pixel removes the image's own structure,
/// so what is left is noise, whose standard error the pixels themselves estimate.
pub fn max_z_score(a: &RgbBuffer, b: &RgbBuffer, bx: u32, by: u32) -> f64 {
    max_z_score_to_rounding(a, b, bx, by, 0.0)
}

/// As [`max_z_score`], where noise-free blocks may differ by up to `rounding` (an average
/// of several renders sums fractions that need not add back to the bits of the whole).
pub fn max_z_score_to_rounding(
    a: &RgbBuffer,
    b: &RgbBuffer,
    bx: u32,
    by: u32,
    rounding: f64,
) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (bw, bh) = (a.width / bx, a.height / by);
    let mut worst: f64 = 0.0;
    for j in 0..by {
        for i in 0..bx {
            for c in 0..3 {
                let diffs = (j * bh..(j + 1) * bh)
                    .flat_map(|y| (i * bw..(i + 1) * bw).map(move |x| (x, y)))
                    .map(|(x, y)| a.get(x, y)[c] as f64 - b.get(x, y)[c] as f64);
                let (mean, se) = mean_and_error(diffs);
                if se > rounding {
                    worst = worst.max(mean.abs() / se);
                } else {
                    assert!(
                        mean.abs() <= rounding,
                        "noise-free blocks must match (to {rounding}): {mean}"
                    );
                }
            }
        }
    }
    worst
}

/// Renders `path` once per direct-lighting strategy (light, bsdf, mis) with the given
/// integrator and depth, each with its own seed (`first_seed`, +1, +2) so the three
/// estimates are independent. Variants are written to a temp dir, or beside `path` (then
/// removed) when `beside`, for scenes that refer to other files.
pub fn render_strategies(
    path: &Path,
    integrator: &str,
    max_depth: u32,
    first_seed: usize,
    beside: bool,
    args: &[&str],
) -> Vec<RgbBuffer> {
    render_strategies_with(path, integrator, "", max_depth, first_seed, beside, args)
}

/// As [`render_strategies`], with `extra` integrator parameters (such as a light sampler).
pub fn render_strategies_with(
    path: &Path,
    integrator: &str,
    extra: &str,
    max_depth: u32,
    first_seed: usize,
    beside: bool,
    args: &[&str],
) -> Vec<RgbBuffer> {
    let text = std::fs::read_to_string(path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for (i, strategy) in ["light", "bsdf", "mis"].iter().enumerate() {
        let line = format!(
            "Integrator \"{integrator}\" \"integer maxdepth\" [ {max_depth} ] \"string strategy\" \"{strategy}\" {extra}"
        );
        let variant = with_integrator(&text, &line);
        let file = if beside {
            write_scene(
                path.parent().unwrap(),
                &format!(".{strategy}-{}.pbrt", std::process::id()),
                &variant,
            )
        } else {
            write_scene(dir.path(), &format!("{strategy}.pbrt"), &variant)
        };
        let seed = (first_seed + i).to_string();
        let r = render(
            &file,
            dir.path(),
            strategy,
            &[args, &["--seed", &seed]].concat(),
        );
        if beside {
            std::fs::remove_file(&file).ok();
        }
        images.push(r.image);
    }
    images
}

/// Asserts that every pair of strategy images agrees: each of a 4x2 grid of blocks within
/// `max_z` standard errors and, with `mean_within`, each channel's image mean within that many.
pub fn assert_strategies_agree(
    label: &str,
    images: &[RgbBuffer],
    max_z: f64,
    mean_within: Option<f64>,
) {
    assert_strategies_agree_in_blocks(label, images, max_z, mean_within, (4, 2));
}

/// As [`assert_strategies_agree`], comparing `blocks` (columns, rows) of the images.
pub fn assert_strategies_agree_in_blocks(
    label: &str,
    images: &[RgbBuffer],
    max_z: f64,
    mean_within: Option<f64>,
    (bx, by): (u32, u32),
) {
    let names = ["light", "bsdf", "mis"];
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let what = format!("{label}: {} vs {}", names[a], names[b]);
        if let Some(k) = mean_within {
            for c in 0..3 {
                let diffs = images[a]
                    .pixels
                    .iter()
                    .zip(&images[b].pixels)
                    .map(|(x, y)| x[c] as f64 - y[c] as f64);
                let (mean, se) = mean_and_error(diffs);
                assert!(
                    mean.abs() < k * se,
                    "{what}, channel {c}: means differ by {mean} (standard error {se})"
                );
            }
        }
        let z = max_z_score(&images[a], &images[b], bx, by);
        eprintln!(
            "{what}: max z {z:.2}, means {:?} vs {:?}",
            images[a].mean(),
            images[b].mean()
        );
        assert!(
            z < max_z,
            "{what}: worst block differs by {z:.2} standard errors (means {:?} vs {:?})",
            images[a].mean(),
            images[b].mean()
        );
    }
}

/// Renders `text` as scene.pbrt and returns kiln's stderr, asserting that it failed with
/// status 1, without a panic and without writing an image.
pub fn failing(text: &str) -> (String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    (failing_in(dir.path(), text), dir)
}

/// As [`failing`], with scene.pbrt written in `dir` (beside files it refers to).
pub fn failing_in(dir: &Path, text: &str) -> String {
    let path = write_scene(dir, "scene.pbrt", text);
    let out = kiln()
        .arg("render")
        .arg(&path)
        .arg("-o")
        .arg(dir.join("out.exr"))
        .arg("--quiet")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "kiln accepted a bad scene:\n{text}");
    assert_eq!(out.status.code(), Some(1));
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        !dir.join("out.exr").exists(),
        "no image is written for a bad scene"
    );
    stderr
}

/// A small, valid EXR whose header claims a `width x height` data window (the rest of the
/// file is a 1x1 image's): what a hostile upload or bundle sends.
#[allow(dead_code)]
pub fn exr_claiming(width: i32, height: i32) -> Vec<u8> {
    let mut bytes = kiln_image::encode_exr(&RgbBuffer::new(1, 1, 0, 0, 1, 1)).unwrap();
    for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = bytes
            .windows(name.len())
            .position(|w| w == name)
            .expect("the attribute is in the header")
            + name.len()
            + 4;
        bytes[at + 8..at + 12].copy_from_slice(&(width - 1).to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&(height - 1).to_le_bytes());
    }
    bytes
}

/// A scene whose medium no tracking can cross: density 10^30 beside 0, seen along the axis
/// where they meet, so that every camera ray's walk visits collisions without end unless
/// it is cut off.
#[allow(dead_code)]
pub const TOO_DENSE: &str = r#"Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
Sampler "sobol" "integer pixelsamples" [ 1 ]
LookAt -5 0 0  0 0 0  0 1 0
Camera "perspective" "float fov" [ 10 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
MakeNamedMedium "dense" "string type" "uniformgrid" "integer nx" 2 "integer ny" 1 "integer nz" 1
  "float density" [ 0 1e30 ] "rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 1 1 1 ]
  "point3 p0" [ -1 -1 -1 ] "point3 p1" [ 1 1 1 ]
AttributeBegin
MediumInterface "dense" ""
Material "interface"
Shape "sphere" "float radius" [ 1.8 ]
AttributeEnd
"#;

/// Asserts that Kiln's mean RGB is within the relative `within` of pbrt-v4's recorded mean in
/// the first `channels` channels.
pub fn assert_matches_pbrt(
    what: &str,
    kiln: [f64; 3],
    pbrt: [f64; 3],
    within: f64,
    channels: usize,
) {
    for c in 0..channels {
        assert!(
            (kiln[c] / pbrt[c] - 1.0).abs() < within,
            "{what}, channel {c}: Kiln {kiln:?} vs pbrt-v4 {pbrt:?}"
        );
    }
}

/// Writes a PFM image (rows given top to bottom; PFM stores them bottom up).
pub fn write_pfm(path: &std::path::Path, width: usize, height: usize, rgb: &[[f32; 3]]) {
    let mut bytes = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    for y in (0..height).rev() {
        for p in &rgb[y * width..(y + 1) * width] {
            for c in p {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    std::fs::write(path, bytes).unwrap();
}
