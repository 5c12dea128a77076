//! Estimators that must agree: light sampling alone, BSDF sampling alone, and their
//! combination by multiple importance sampling estimate the same direct lighting.

use crate::util::{
    assert_strategies_agree_in_blocks, max_z_score, reference_scene, render, render_strategies,
    render_strategies_with, with_integrator, write_scene,
};
use std::path::Path;

/// The noise variance of one render, from two of the same scene with their own seeds: half
/// the mean squared difference of their pixels, summed over the channels.
fn noise_variance(a: &kiln_image::RgbBuffer, b: &kiln_image::RgbBuffer) -> f64 {
    let sq: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(a, b)| {
            (0..3)
                .map(|c| (a[c] as f64 - b[c] as f64).powi(2))
                .sum::<f64>()
        })
        .sum();
    sq / (2.0 * a.pixels.len() as f64)
}

/// Renders the scene's direct lighting with each strategy and compares them in `blocks`.
/// Variants are written to a temp dir, or beside `path` when `beside` (for scenes that refer to other files).
fn strategies_agree(path: &Path, args: &[&str], max_z: f64, beside: bool, blocks: (u32, u32)) {
    let images = render_strategies(path, "path", 1, 1, beside, args);
    assert_strategies_agree_in_blocks(&path.display().to_string(), &images, max_z, None, blocks);
}

#[test]
fn light_and_bsdf_sampling_agree_on_the_mis_scene() {
    // 12 block-channel comparisons per pair: 4.5 standard errors is a false alarm rate
    // below 1e-4 for Gaussian errors, while a wrong pdf or a missing cosine shows as tens.
    // The errors are Gaussian only where each block holds many BSDF-sampled hits on the
    // tiny (radius 0.03) light: with 4x2 blocks at 256 spp a block of the back wall holds
    // about ten, and the z statistic is no longer Gaussian (two seeds of BSDF sampling
    // alone differed there by 2.7 "standard errors", light against BSDF sampling by up to
    // 6.2 over four seeds), while at 65,536 spp the two agree there within 0.02%. So: 2x2
    // blocks at 1024 spp, eight times the samples per block.
    strategies_agree(
        &crate::util::scene("mis/scene.pbrt"),
        &["--spp", "1024", "--resolution", "128x72"],
        4.5,
        false,
        (2, 2),
    );
}

#[test]
fn light_and_bsdf_sampling_agree_on_veach_mis() {
    let Some(path) = reference_scene("veach-mis") else {
        return;
    };
    strategies_agree(
        &path,
        &["--spp", "256", "--resolution", "160x90"],
        4.5,
        false,
        (4, 2),
    );
}

/// Environment maps with a bright, small sun: importance sampling the map (its 2D
/// distribution and the equal-area or lat-long mapping) must agree with BSDF sampling.
#[test]
fn light_and_bsdf_sampling_agree_under_environment_maps() {
    let dir = tempfile::tempdir().unwrap();
    for (name, w, h) in [("square", 32u32, 32u32), ("latlong", 64, 32)] {
        let mut map = kiln_image::RgbBuffer::new(w, h, 0, 0, w, h);
        for y in 0..h {
            for x in 0..w {
                // A soft gradient plus a hot 2x2 patch.
                let hot = (x / 2 == 5 && y / 2 == 3) as u32 as f32 * 400.0;
                map.pixels[(y * w + x) as usize] = [
                    0.2 + x as f32 / w as f32 + hot,
                    0.3 + hot,
                    0.4 + y as f32 / h as f32,
                ];
            }
        }
        kiln_image::write_exr(&dir.path().join(format!("{name}.exr")), &map).unwrap();
        let text = format!(
            "Integrator \"path\" \"integer maxdepth\" [ 1 ]
            Sampler \"zsobol\" \"integer pixelsamples\" [ 256 ]
            Film \"rgb\" \"integer xresolution\" [ 48 ] \"integer yresolution\" [ 32 ]
            LookAt 0 4 6  0 0 0  0 1 0
            Camera \"perspective\" \"float fov\" [ 40 ]
            WorldBegin
            AttributeBegin Rotate -90 1 0 0 LightSource \"infinite\" \"string filename\" \"{name}.exr\" AttributeEnd
            Material \"conductor\" \"float roughness\" [ 0.05 ] \"rgb reflectance\" [ 0.8 0.8 0.8 ]
            Shape \"sphere\" \"float radius\" [ 1 ]
            Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]
            Shape \"bilinearmesh\" \"point3 P\" [ -10 -1 -10  10 -1 -10  -10 -1 10  10 -1 10 ]"
        );
        let path = write_scene(dir.path(), &format!("{name}.pbrt"), &text);
        strategies_agree(&path, &[], 4.5, true, (4, 2));
    }
}

/// 120,000 emitting triangles (the size of seed 000's snail) chosen by power through the
/// alias table and through the light hierarchy (120,000 leaves): light sampling still
/// agrees with BSDF sampling.
#[test]
fn many_emitters_sampled_by_power_or_hierarchy_agree_with_bsdf_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let (nx, nz) = (300usize, 200usize);
    let mut p = String::new();
    let mut idx = String::new();
    for j in 0..=nz {
        for i in 0..=nx {
            // A wavy ceiling, brighter along x through the per-face scale below.
            let x = -3.0 + 6.0 * i as f64 / nx as f64;
            let z = -2.0 + 4.0 * j as f64 / nz as f64;
            p.push_str(&format!(
                "{x:.4} {:.4} {z:.4} ",
                2.0 + 0.1 * libm::sin(3.0 * x)
            ));
        }
    }
    for j in 0..nz {
        for i in 0..nx {
            let a = j * (nx + 1) + i;
            let (b, c, d) = (a + 1, a + nx + 1, a + nx + 2);
            idx.push_str(&format!("{a} {c} {b} {b} {c} {d} "));
        }
    }
    let ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n{}\n{}",
        (nx + 1) * (nz + 1),
        nx * nz * 2,
        p.split_whitespace()
            .collect::<Vec<_>>()
            .chunks(3)
            .map(|c| c.join(" "))
            .collect::<Vec<_>>()
            .join("\n"),
        idx.split_whitespace()
            .collect::<Vec<_>>()
            .chunks(3)
            .map(|c| format!("3 {}", c.join(" ")))
            .collect::<Vec<_>>()
            .join("\n"),
    );
    std::fs::write(dir.path().join("ceiling.ply"), ply).unwrap();
    let text = "Integrator \"path\" \"integer maxdepth\" [ 1 ]
        Sampler \"zsobol\" \"integer pixelsamples\" [ 64 ]
        Film \"rgb\" \"integer xresolution\" [ 48 ] \"integer yresolution\" [ 32 ]
        LookAt 0 1 5  0 0.5 0  0 1 0
        Camera \"perspective\" \"float fov\" [ 50 ]
        WorldBegin
        Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]
        Shape \"bilinearmesh\" \"point3 P\" [ -5 0 -5  5 0 -5  -5 0 5  5 0 5 ]
        AttributeBegin
        AreaLightSource \"diffuse\" \"rgb L\" [ 3 2 1 ] \"bool twosided\" true
        Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]
        Shape \"plymesh\" \"string filename\" \"ceiling.ply\"
        AttributeEnd";
    let path = write_scene(dir.path(), "many.pbrt", text);
    for sampler in ["power", "bvh"] {
        let extra = format!("\"string lightsampler\" \"{sampler}\"");
        let images = render_strategies_with(&path, "path", &extra, 1, 1, true, &[]);
        assert_strategies_agree_in_blocks(sampler, &images, 4.5, None, (4, 2));
    }
}

/// The light hierarchy (pbrt-v4's "bvh", Kiln's default), choosing by power, uniformly and
/// by every light's importance ("exhaustive") are four estimators of the same image of a corridor of 100 lights of every
/// kind: each pair agrees block by block, and with the hierarchy light, BSDF and MIS
/// sampling agree (the MIS weights use the hierarchy's probability of the light from the
/// previous vertex, which must be the one it was chosen with). The hierarchy's noise is
/// lower than power's and uniform's at equal samples.
#[test]
fn light_samplers_agree_and_the_hierarchy_is_the_least_noisy() {
    let path = crate::util::scene("lights/scene.pbrt");
    let args = ["--spp", "256", "--resolution", "48x32"];
    let text = std::fs::read_to_string(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // BSDF sampling cannot find point and spot lights: the strategies are compared on the
    // corridor without them.
    let no_delta: String = text
        .lines()
        .filter(|l| {
            !l.starts_with("LightSource \"point\"") && !l.starts_with("LightSource \"spot\"")
        })
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(no_delta.len() < text.len());
    let area_only = write_scene(dir.path(), "area-only.pbrt", &no_delta);
    strategies_agree(&area_only, &args, 4.5, false, (4, 2));
    // Per sampler, two renders with their own seeds: their agreement, and half the mean
    // squared difference of their pixels (each render's noise variance).
    let mut images = Vec::new();
    let mut noise = Vec::new();
    let names = ["bvh", "power", "uniform", "exhaustive"];
    for (i, sampler) in names.iter().enumerate() {
        let line = format!(
            "Integrator \"volpath\" \"integer maxdepth\" [ 3 ] \"string lightsampler\" \"{sampler}\""
        );
        let file = write_scene(
            dir.path(),
            &format!("{sampler}.pbrt"),
            &with_integrator(&text, &line),
        );
        let pair: Vec<_> = [10 + i, 20 + i]
            .iter()
            .map(|seed| {
                let seed = seed.to_string();
                let name = format!("{sampler}-{seed}");
                render(
                    &file,
                    dir.path(),
                    &name,
                    &[&args[..], &["--seed", &seed]].concat(),
                )
                .image
            })
            .collect();
        noise.push(noise_variance(&pair[0], &pair[1]));
        images.push(pair.into_iter().next().unwrap());
    }
    for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        // 2x2 blocks: uniform choice among 100 lights finds the bright ones rarely, and a
        // smaller block's mean is far from Gaussian.
        let z = max_z_score(&images[a], &images[b], 2, 2);
        eprintln!("light samplers {} vs {}: max z {z:.2}", names[a], names[b]);
        assert!(
            z < 4.5,
            "light samplers {} and {} differ by {z:.2} standard errors",
            names[a],
            names[b]
        );
    }
    eprintln!(
        "pixel noise variance: bvh {:.3e}, power {:.3e}, uniform {:.3e}, exhaustive {:.3e}",
        noise[0], noise[1], noise[2], noise[3]
    );
    assert!(noise[0] < noise[1] && noise[0] < noise[2], "{noise:?}");
}

/// pbrt-v4's "regularize": after a non-specular bounce, microfacet BSDFs are roughened
/// (a smooth silver ball becomes glossy, alpha 0.1), so paths from the floor find a tiny
/// light through it by light sampling. The estimate is biased by design, and less noisy:
/// the regularised image's noise (two seeds) is below the plain one's, and its mean is
/// within 5% of pbrt-v4's (its two renders of the same file, 1024 spp, differ by 4%
/// between seeds; Kiln's measured 0.8% from their average).
#[test]
fn regularize_roughens_after_a_diffuse_bounce_as_pbrt_v4_does() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |regularize: bool| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 6 ] "bool regularize" {regularize}
Sampler "independent" "integer pixelsamples" [ 1024 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]
LookAt 0 3 5  0 0.3 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "bilinearmesh" "point3 P" [ -5 0 -5  5 0 -5  -5 0 5  5 0 5 ]
AttributeBegin
Material "conductor" "spectrum eta" "metal-Ag-eta" "spectrum k" "metal-Ag-k" "float roughness" [ 0 ]
Translate 0 0.8 0
Shape "sphere" "float radius" [ 0.8 ]
AttributeEnd
AttributeBegin
Material "dielectric" "float eta" [ 1.5 ]
Translate 1.6 0.5 0.5
Shape "sphere" "float radius" [ 0.5 ]
AttributeEnd
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 400 400 400 ]
Translate 1.5 2.5 -1
Shape "sphere" "float radius" [ 0.05 ]
AttributeEnd
"#
        )
    };
    let mut noise = Vec::new();
    let mut means = Vec::new();
    for regularize in [true, false] {
        let path = write_scene(
            dir.path(),
            &format!("r{regularize}.pbrt"),
            &scene(regularize),
        );
        let pair: Vec<_> = ["1", "2"]
            .iter()
            .map(|seed| {
                render(
                    &path,
                    dir.path(),
                    &format!("r{regularize}{seed}"),
                    &["--seed", seed],
                )
                .image
            })
            .collect();
        noise.push(noise_variance(&pair[0], &pair[1]));
        means.push(pair[0].mean());
    }
    eprintln!(
        "noise regularised {:.3e}, plain {:.3e}; means {:?}",
        noise[0], noise[1], means
    );
    assert!(noise[0] < noise[1], "{noise:?}");
    crate::util::assert_matches_pbrt(
        "regularised",
        means[0],
        [0.021454, 0.021400, 0.020900],
        0.05,
        3,
    );
}
