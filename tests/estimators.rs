//! Estimators that must agree: light sampling alone, BSDF sampling alone, and their
//! combination by multiple importance sampling estimate the same direct lighting.

use crate::util::{
    assert_strategies_agree_in_blocks, reference_scene, render_strategies, write_scene,
};
use std::path::Path;

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
/// alias table: light sampling still agrees with BSDF sampling.
#[test]
fn many_emitters_sampled_by_power_agree_with_bsdf_sampling() {
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
                2.0 + 0.1 * (3.0 * x).sin()
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
    strategies_agree(&path, &[], 4.5, true, (4, 2));
}
