//! Scenes whose answer is known exactly.

use crate::util::{render, scene};

/// Inside a closed surface of albedo 0.5 that emits 0.5, radiance is 1 everywhere.
fn check_furnace(file: &str) {
    let dir = tempfile::tempdir().unwrap();
    let r = render(&scene(file), dir.path(), "furnace", &[]);
    let img = &r.image;
    for c in 0..3 {
        // Every 8x8 block, not only the mean, must be 1 within noise.
        for by in 0..4 {
            for bx in 0..4 {
                let (mean, se) = crate::util::block_stats(img, bx * 8, by * 8, 8, 8, c);
                assert!(
                    (mean - 1.0).abs() < 0.02 + 4.0 * se,
                    "{file}: block ({bx},{by}) channel {c}: {mean} ± {se}"
                );
            }
        }
        let m = img.mean()[c];
        assert!((m - 1.0).abs() < 0.005, "{file}: mean {m}");
    }
}

#[test]
fn furnace_sphere_is_one_everywhere() {
    check_furnace("furnace/scene.pbrt");
}

#[test]
fn furnace_triangle_mesh_is_one_everywhere() {
    check_furnace("furnace/mesh.pbrt");
}
