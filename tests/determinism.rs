//! The image is a pure function of (scene, settings, seed): the same bytes for any
//! tile split and thread count, and a different image for a different seed.

use crate::util::{reference_scene, render, scene};
use std::path::Path;

fn assert_same_bytes_for_any_split(path: &Path, extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let reference = render(
        path,
        dir.path(),
        "whole",
        &[&["--tile", "100000", "--threads", "2"], extra].concat(),
    );
    for (tile, threads) in [
        ("16", "1"),
        ("16", "2"),
        ("37", "2"),
        ("64", "1"),
        ("64", "2"),
        ("100000", "1"),
    ] {
        let name = format!("t{tile}-n{threads}");
        let r = render(
            path,
            dir.path(),
            &name,
            &[&["--tile", tile, "--threads", threads], extra].concat(),
        );
        let same_pixels = r
            .image
            .pixels
            .iter()
            .zip(&reference.image.pixels)
            .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits));
        assert!(
            same_pixels,
            "{}: pixels differ for --tile {tile} --threads {threads}",
            path.display()
        );
        assert_eq!(
            r.bytes,
            reference.bytes,
            "{}: EXR bytes differ for --tile {tile} --threads {threads}",
            path.display()
        );
    }
    let other_seed = render(
        path,
        dir.path(),
        "seed",
        &[&["--seed", "7"], extra].concat(),
    );
    assert_ne!(
        other_seed.image.pixels, reference.image.pixels,
        "a different --seed must change the image"
    );
    // Same seed again, in another process: the same bytes.
    let again = render(
        path,
        dir.path(),
        "again",
        &[&["--tile", "100000", "--threads", "2"], extra].concat(),
    );
    assert_eq!(again.bytes, reference.bytes);
}

#[test]
fn every_material_and_light_is_bit_identical_across_tiles_and_threads() {
    assert_same_bytes_for_any_split(&scene("materials/scene.pbrt"), &["--spp", "8"]);
}

#[test]
fn mis_scene_is_bit_identical_across_tiles_and_threads() {
    assert_same_bytes_for_any_split(
        &scene("mis/scene.pbrt"),
        &["--spp", "4", "--resolution", "80x45"],
    );
}

#[test]
fn cornell_box_is_bit_identical_across_tiles_and_threads() {
    let Some(path) = reference_scene("cornell-box") else {
        return;
    };
    assert_same_bytes_for_any_split(&path, &["--spp", "4", "--resolution", "72x72"]);
}

#[test]
fn volume_lights_are_bit_identical_across_tiles_and_threads() {
    // A glass VolumeLight sphere with a voxel grid (Le evaluated at hits and by light
    // sampling); then a mesh VolumeLight, whose faces' powers are estimated in parallel
    // when the scene is built.
    assert_same_bytes_for_any_split(
        &scene("volume-light/voxel-grid.pbrt"),
        &["--spp", "4", "--resolution", "60x45"],
    );
    assert_same_bytes_for_any_split(
        &scene("volume-light/blue-volume.pbrt"),
        &["--spp", "4", "--resolution", "60x45"],
    );
}

#[test]
fn media_are_bit_identical_across_tiles_and_threads() {
    assert_same_bytes_for_any_split(
        &scene("media/fog.pbrt"),
        &["--spp", "4", "--resolution", "60x40"],
    );
    // Caustic photon maps: built once per render, the same for every tile.
    assert_same_bytes_for_any_split(
        &scene("media/lens.pbrt"),
        &["--spp", "4", "--resolution", "40x40"],
    );
    // A grid medium: delta and ratio tracking, and a flame sampled as a light.
    assert_same_bytes_for_any_split(
        &scene("media/ember.pbrt"),
        &["--spp", "4", "--resolution", "60x40"],
    );
}
