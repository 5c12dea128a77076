//! Merged images bit-identical to `kiln render`: any tile size and worker count, photon
//! maps and SPPM computed by every worker, and the headline scene.

use super::farm;
use crate::util::{render, scene};

#[test]
fn farm_images_are_bit_identical_to_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("materials/scene.pbrt");
    for tile in ["16", "37", "64"] {
        let direct = render(
            &path,
            dir.path(),
            &format!("direct{tile}"),
            &["--spp", "4", "--tile", tile],
        )
        .bytes;
        for workers in ["1", "3"] {
            let merged = farm(
                &path,
                dir.path(),
                &format!("farm{tile}-{workers}"),
                &[
                    "--spp",
                    "4",
                    "--tile",
                    tile,
                    "--workers",
                    workers,
                    "--threads-per-worker",
                    "1",
                ],
            );
            assert_eq!(merged, direct, "tile {tile}, {workers} workers");
        }
    }
}

/// A spectral render (a pbrt-v4 user's scene, spectral by default: the materials scene
/// without its RGB option, with a dispersive glass sphere added) through a farm of three
/// workers merges the same bytes as `kiln render`; so does the same job asked for in RGB
/// (`--rgb`, which the job carries to its workers).
#[test]
fn spectral_farm_images_are_bit_identical_to_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene("materials/scene.pbrt")).unwrap();
    let text = text.replace("Option \"kiln.spectral\" false", "");
    let path = crate::util::write_scene(
        dir.path(),
        "spectral.pbrt",
        &format!(
            "{text}\nAttributeBegin\n  Material \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n  Translate 0 0.4 0\n  Shape \"sphere\" \"float radius\" 0.3\nAttributeEnd\n"
        ),
    );
    let args = ["--spp", "4", "--resolution", "48x32", "--tile", "16"];
    let workers = ["--workers", "3", "--threads-per-worker", "1"];
    let direct = render(&path, dir.path(), "direct", &args).bytes;
    let merged = farm(&path, dir.path(), "farm", &[&args[..], &workers].concat());
    assert!(
        merged == direct,
        "the spectral farm's image differs from kiln render's"
    );
    let rgb_args = [&args[..], &["--rgb"]].concat();
    let rgb = render(&path, dir.path(), "direct-rgb", &rgb_args).bytes;
    assert!(rgb != direct, "--rgb changed nothing");
    let merged = farm(
        &path,
        dir.path(),
        "farm-rgb",
        &[&rgb_args[..], &workers].concat(),
    );
    assert!(
        merged == rgb,
        "the farm's job in RGB differs from kiln render --rgb"
    );
}

/// Photon maps are built by every worker from the same seeds: a farm of three workers
/// merges the same bytes as `kiln render` for caustic maps (lens), a volume map (haze) and
/// SPPM (ball: `kiln render` runs each iteration over every tile at once, a worker over
/// the tile it leased).
#[test]
fn farm_images_with_photon_maps_are_bit_identical_to_kiln_render() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["media/lens", "media/haze", "photons/ball", "martini/scene"] {
        let path = scene(&format!("{name}.pbrt"));
        let name = name.replace('/', "-");
        let args = ["--spp", "4", "--resolution", "32x32", "--tile", "16"];
        let direct = render(&path, dir.path(), &format!("{name}-direct"), &args).bytes;
        let mut farm_args = args.to_vec();
        farm_args.extend(["--workers", "3", "--threads-per-worker", "1"]);
        let merged = farm(&path, dir.path(), &format!("{name}-farm"), &farm_args);
        assert_eq!(
            merged, direct,
            "{name}: the farm's image differs from kiln render's"
        );
    }
}

/// The headline scene, scenes/molten-glass (a 124k-face VolumeLight with a voxel grid),
/// through a local farm of two workers and through `kiln render`: the same bytes.
///
/// It renders a fifth of the 2880x1920 frame on each axis (18 x 12 tiles of 32 pixels):
/// the full frame would prove nothing more, since every tile is a pure function of
/// (scene, settings, pixel) whatever the split (determinism.rs), and the coordinator
/// assembles and encodes a frame of any size with the same code. The README's first
/// command renders the full frame.
#[test]
fn molten_glass_through_the_farm_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("molten-glass/scene.pbrt");
    let args = ["--spp", "1", "--resolution", "576x384", "--tile", "32"];
    let direct = render(&path, dir.path(), "direct", &args);
    assert_eq!((direct.image.width, direct.image.height), (576, 384));
    let merged = farm(
        &path,
        dir.path(),
        "farm",
        &[&args[..], &["--workers", "2", "--threads-per-worker", "1"]].concat(),
    );
    assert!(
        merged == direct.bytes,
        "the farm's frame differs from kiln render's"
    );
}
