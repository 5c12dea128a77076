//! Estimators that must agree: light sampling alone, BSDF sampling alone, and their
//! combination by multiple importance sampling estimate the same direct lighting.

use crate::util::{max_z_score, reference_scene, render, with_integrator, write_scene};
use std::path::Path;

/// Renders the scene's direct lighting with each strategy and compares them block by block.
fn strategies_agree(path: &Path, args: &[&str], max_z: f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for (i, strategy) in ["light", "bsdf", "mis"].iter().enumerate() {
        let variant = with_integrator(
            &text,
            &format!(
                "Integrator \"path\" \"integer maxdepth\" [ 1 ] \"string strategy\" \"{strategy}\""
            ),
        );
        // Different seeds keep the three estimates independent.
        let seed = (i + 1).to_string();
        // The test scenes refer to no other file, so the variant can live in the temp dir.
        let file = write_scene(dir.path(), &format!("{strategy}.pbrt"), &variant);
        let r = render(
            &file,
            dir.path(),
            strategy,
            &[args, &["--seed", &seed]].concat(),
        );
        images.push(r.image);
    }
    let means: Vec<[f64; 3]> = images.iter().map(|i| i.mean()).collect();
    for (a, b, what) in [
        (0, 1, "light vs bsdf"),
        (0, 2, "light vs mis"),
        (1, 2, "bsdf vs mis"),
    ] {
        let z = max_z_score(&images[a], &images[b], 4, 2);
        eprintln!(
            "{}: {what}: max z {z:.2}, means {:?} vs {:?}",
            path.display(),
            means[a],
            means[b]
        );
        assert!(
            z < max_z,
            "{}: {what}: worst block differs by {z:.2} standard errors (means {:?} vs {:?})",
            path.display(),
            means[a],
            means[b]
        );
    }
}

#[test]
fn light_and_bsdf_sampling_agree_on_the_mis_scene() {
    // 24 block-channel comparisons per pair: 4.5 standard errors is a false alarm rate
    // below 1e-4 for Gaussian errors, while a wrong pdf or a missing cosine shows as tens.
    strategies_agree(
        &crate::util::scene("mis/scene.pbrt"),
        &["--spp", "256", "--resolution", "128x72"],
        4.5,
    );
}

#[test]
fn light_and_bsdf_sampling_agree_on_veach_mis() {
    let Some(path) = reference_scene("veach-mis") else {
        return;
    };
    strategies_agree(&path, &["--spp", "256", "--resolution", "160x90"], 4.5);
}
