//! The image is a pure function of (scene, settings, seed): the same bits for any tile
//! split and thread count, and a different image for a different seed.
//!
//! The splits are checked in-process through `render_tile`, the function both `kiln render`
//! and the farm's workers call: each scene is built once and rendered under every split.
//! One cross-process check per property stays: `kiln render` writes the same EXR bytes for
//! two splits and thread counts, twice in two processes, and those pixels are the ones the
//! in-process renders give.

use crate::util::{reference_scene, render, render_with_env, scene};
use kiln_render::{Renderer, render_tile, split_into_tiles};
use kiln_scene::Overrides;
use rayon::prelude::*;
use std::path::Path;

/// The tile sizes and thread counts every scene is rendered with.
const SPLITS: [(u32, usize); 6] = [(16, 1), (16, 2), (37, 2), (64, 1), (64, 2), (100_000, 1)];

pub(crate) fn load(path: &Path, spp: u32, resolution: Option<(u32, u32)>) -> Renderer {
    let mut desc = kiln_scene::load_file(path).unwrap();
    desc.apply_overrides(&Overrides {
        resolution,
        spp: Some(spp),
        seed: None,
        ..Default::default()
    })
    .unwrap();
    Renderer::build(&desc).unwrap()
}

/// [`load`] for a spectral render.
fn load_spectral(path: &Path, spp: u32, resolution: Option<(u32, u32)>) -> Renderer {
    let mut desc = kiln_scene::load_file(path).unwrap();
    desc.apply_overrides(&Overrides {
        resolution,
        spp: Some(spp),
        spectral: Some(true),
        ..Default::default()
    })
    .unwrap();
    Renderer::build(&desc).unwrap()
}

/// The frame's pixels (as bits, row-major over the film's pixel bounds) rendered in
/// `tile`-pixel tiles on a pool of `threads` threads, tiles taken in parallel.
fn render_split(renderer: &Renderer, tile: u32, threads: usize) -> Vec<[u32; 3]> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (w, h) = renderer.scene().resolution;
    let tiles = split_into_tiles([0, w, 0, h], tile);
    let results: Vec<_> = pool.install(|| {
        tiles
            .par_iter()
            .map(|t| render_tile(renderer, *t))
            .collect()
    });
    let mut frame = vec![[0u32; 3]; (w * h) as usize];
    for r in &results {
        for (i, p) in r.pixels.iter().enumerate() {
            let (x, y) = (
                r.rect.x0 + i as u32 % r.rect.width,
                r.rect.y0 + i as u32 / r.rect.width,
            );
            frame[(y * w + x) as usize] = p.map(f32::to_bits);
        }
    }
    frame
}

/// Renders `renderer`'s frame under every split of [`SPLITS`] and asserts the same bits;
/// then with another seed, which must change the image. Returns the frame.
fn assert_same_bits_for_any_split(name: &str, renderer: Renderer) -> Vec<[u32; 3]> {
    let reference = render_split(&renderer, 100_000, 2);
    for (tile, threads) in SPLITS {
        assert!(
            render_split(&renderer, tile, threads) == reference,
            "{name}: pixels differ for tiles of {tile} on {threads} threads"
        );
    }
    let mut settings = renderer.settings().clone();
    settings.seed = settings.seed.wrapping_add(7);
    let other_seed = render_split(&renderer.with_settings(settings), 64, 2);
    assert!(
        other_seed != reference,
        "{name}: a different seed must change the image"
    );
    reference
}

#[test]
fn every_material_and_light_is_bit_identical_across_tiles_and_threads() {
    let path = scene("materials/scene.pbrt");
    assert_same_bits_for_any_split("materials", load(&path, 8, None));
}

/// Adaptive sampling stops each pixel by its own sums alone: any split and thread count
/// stops every pixel after the same samples, and the image is the same bits.
#[test]
fn adaptive_sampling_is_bit_identical_across_tiles_and_threads() {
    let path = scene("mis/scene.pbrt");
    let renderer = crate::passes::load_adaptive(&path, 32, (80, 45), 0.05, 4);
    assert_same_bits_for_any_split("mis, adaptive", renderer);
}

#[test]
fn every_texture_kind_is_bit_identical_across_tiles_and_threads() {
    let path = scene("textures/scene.pbrt");
    assert_same_bits_for_any_split("textures", load(&path, 4, Some((96, 64))));
}

#[test]
fn mis_scene_is_bit_identical_across_tiles_and_threads() {
    let path = scene("mis/scene.pbrt");
    assert_same_bits_for_any_split("mis", load(&path, 4, Some((80, 45))));
}

#[test]
fn cornell_box_is_bit_identical_across_tiles_and_threads() {
    let Some(path) = reference_scene("cornell-box") else {
        return;
    };
    assert_same_bits_for_any_split("cornell-box", load(&path, 4, Some((72, 72))));
}

#[test]
fn volume_lights_are_bit_identical_across_tiles_and_threads() {
    // A glass VolumeLight sphere with a voxel grid (Le evaluated at hits and by light
    // sampling); then a mesh VolumeLight, whose faces' powers are estimated in parallel
    // when the scene is built.
    for name in ["voxel-grid", "blue-volume"] {
        let path = scene(&format!("volume-light/{name}.pbrt"));
        assert_same_bits_for_any_split(name, load(&path, 4, Some((60, 45))));
    }
}

#[test]
fn quadrics_curves_hair_and_motion_are_bit_identical_across_tiles_and_threads() {
    let path = scene("shapes/scene.pbrt");
    assert_same_bits_for_any_split("shapes", load(&path, 4, Some((48, 32))));
    let path = scene("shapes/curves.pbrt");
    assert_same_bits_for_any_split("curves", load(&path, 4, Some((48, 36))));
    let path = scene("shapes/hair.pbrt");
    assert_same_bits_for_any_split("hair", load(&path, 4, Some((48, 32))));
    let path = scene("motion/scene.pbrt");
    assert_same_bits_for_any_split("motion", load(&path, 4, Some((48, 36))));
}

/// Surfaces of revolution and nested dielectrics: the martini scene (three glasses of drink
/// sharing their boundaries by priority, a scattering medium, caustic and volume photon
/// maps); and the lily pond's subsurface walks.
#[test]
fn revolutions_and_nested_dielectrics_are_bit_identical_across_tiles_and_threads() {
    let path = scene("martini/scene.pbrt");
    assert_same_bits_for_any_split("martini", load(&path, 2, Some((48, 32))));
    // Subsurface walks (the pads), curves (the stems) and a volume photon map (the water).
    let path = scene("lily-pond/scene.pbrt");
    assert_same_bits_for_any_split("lily-pond", load(&path, 2, Some((48, 32))));
}

#[test]
fn media_are_bit_identical_across_tiles_and_threads() {
    assert_same_bits_for_any_split("fog", load(&scene("media/fog.pbrt"), 4, Some((60, 40))));
    // Caustic photon maps: built once per render, the same for every tile.
    assert_same_bits_for_any_split("lens", load(&scene("media/lens.pbrt"), 4, Some((40, 40))));
    // A volume photon map (k-nearest gathers in a k-d tree) with weight-aware roulette.
    assert_same_bits_for_any_split("haze", load(&scene("media/haze.pbrt"), 4, Some((40, 40))));
    // SPPM: each tile runs every iteration's photon pass itself.
    assert_same_bits_for_any_split("sppm", load(&scene("photons/ball.pbrt"), 4, Some((24, 24))));
    // A grid medium: delta and ratio tracking, and a flame sampled as a light.
    assert_same_bits_for_any_split("ember", load(&scene("media/ember.pbrt"), 4, Some((60, 40))));
}

/// Spectral renders keep every guarantee: SPPM (each iteration's wavelengths shared by its
/// camera paths and photons), caustic and volume photon maps (photons at wavelengths of
/// their own), a grid medium with a flame sampled as a light, a VolumeLight.
#[test]
fn spectral_sppm_grid_media_and_volume_lights_are_bit_identical_across_tiles_and_threads() {
    let lens = load_spectral(&scene("media/lens.pbrt"), 4, Some((40, 40)));
    assert_same_bits_for_any_split("spectral caustic map", lens);
    let haze = load_spectral(&scene("media/haze.pbrt"), 4, Some((40, 40)));
    assert_same_bits_for_any_split("spectral volume map", haze);
    let sppm = load_spectral(&scene("photons/ball.pbrt"), 4, Some((24, 24)));
    assert_same_bits_for_any_split("spectral sppm", sppm);
    let ember = load_spectral(&scene("media/ember.pbrt"), 4, Some((60, 40)));
    assert_same_bits_for_any_split("spectral ember", ember);
    let glass = load_spectral(&scene("volume-light/glass-sphere.pbrt"), 4, Some((48, 32)));
    assert_same_bits_for_any_split("spectral VolumeLight", glass);
}

/// The scene is built on every worker of a farm: building it twice (photon maps and
/// VolumeLight power estimates included) must give the same image, whatever the number
/// of threads the build ran on.
#[test]
fn building_the_scene_again_on_another_thread_count_gives_the_same_bits() {
    for (path, resolution) in [
        (scene("media/lens.pbrt"), (40, 40)),
        (scene("media/haze.pbrt"), (40, 40)),
        (scene("volume-light/blue-volume.pbrt"), (60, 45)),
    ] {
        let build_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| load(&path, 2, Some(resolution)))
        };
        assert!(
            render_split(&build_on(1), 64, 2) == render_split(&build_on(2), 64, 2),
            "{}: two builds differ",
            path.display()
        );
    }
}

/// The cross-process check: `kiln render` writes the same bytes for two splits and thread
/// counts and in two processes, and its pixels are those of `render_tile` in this process.
#[test]
fn kiln_render_writes_the_same_bytes_as_render_tile_for_any_split() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("materials/scene.pbrt");
    let whole = render(
        &path,
        dir.path(),
        "whole",
        &["--spp", "8", "--tile", "100000", "--threads", "2"],
    );
    let split = render(
        &path,
        dir.path(),
        "split",
        &["--spp", "8", "--tile", "16", "--threads", "1"],
    );
    assert_eq!(split.bytes, whole.bytes, "EXR bytes differ between splits");
    let again = render(
        &path,
        dir.path(),
        "again",
        &["--spp", "8", "--tile", "100000", "--threads", "2"],
    );
    assert_eq!(
        again.bytes, whole.bytes,
        "EXR bytes differ between processes"
    );
    let in_process = render_split(&load(&path, 8, None), 37, 2);
    let written: Vec<[u32; 3]> = whole
        .image
        .pixels
        .iter()
        .map(|p| p.map(f32::to_bits))
        .collect();
    assert!(
        written == in_process,
        "kiln render's pixels differ from render_tile's"
    );
}

/// Every BVH kernel this CPU runs (SSE, AVX2, AVX-512) gives `kiln render` the same bytes: on the
/// snail's glass (camera rays, bounces, VolumeLight chords and shadow rays through 124k
/// triangles), the MIS scene, the materials and the textures (alpha cutouts), so a farm may
/// mix machines of either kind.
#[test]
fn every_bvh_kernel_renders_the_same_bytes() {
    use kiln_render::shapes::wide::Kernel;
    let kernels = Kernel::available();
    if kernels.len() < 2 {
        println!("SKIPPED the comparison: this CPU runs only {kernels:?}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, spp, mode) in [
        ("molten-glass/scene.pbrt", "4", "--rgb"),
        ("mis/scene.pbrt", "8", "--rgb"),
        ("materials/scene.pbrt", "4", "--rgb"),
        ("materials/scene.pbrt", "4", "--spectral"),
        ("textures/scene.pbrt", "4", "--rgb"),
    ] {
        let args = [
            "--spp",
            spp,
            "--resolution",
            "96x64",
            "--threads",
            "2",
            mode,
        ];
        let images: Vec<Vec<u8>> = kernels
            .iter()
            .map(|k| {
                let (kernel, said) = (k.name(), format!("{k:?}"));
                let out = format!("{}-{kernel}{mode}", name.replace('/', "-"));
                let r = render_with_env(
                    &scene(name),
                    dir.path(),
                    &out,
                    &args,
                    &[("KILN_BVH_KERNEL", kernel)],
                );
                let log = String::from_utf8_lossy(&r.output.stderr).to_string();
                assert!(log.contains(&format!("BVH kernel {said}")), "{log}");
                r.bytes
            })
            .collect();
        assert!(
            images[0] == images[1],
            "{name} ({mode}): SSE and AVX2 give other bytes"
        );
    }
}

/// A farm's store of shared pre-passes, in memory: the first to ask for a name that is not
/// there claims it; what is published stays.
#[derive(Default)]
struct MemoryShare {
    published: std::sync::Mutex<std::collections::HashMap<String, Vec<u8>>>,
    claimed: std::sync::Mutex<std::collections::HashSet<String>>,
    publishes: std::sync::atomic::AtomicUsize,
}

impl kiln_render::shared::SharedPrepass for MemoryShare {
    fn fetch(&self, name: &str) -> kiln_render::shared::Shared {
        use kiln_render::shared::Shared;
        if let Some(bytes) = self.published.lock().unwrap().get(name) {
            return Shared::Ready(bytes.clone());
        }
        if self.claimed.lock().unwrap().insert(name.to_string()) {
            Shared::Yours
        } else {
            Shared::Theirs
        }
    }

    fn publish(&self, name: &str, bytes: &[u8]) {
        self.publishes
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        self.published
            .lock()
            .unwrap()
            .insert(name.to_string(), bytes.to_vec());
    }
}

/// Workers that share a job's photon maps and SPPM passes (one computes each, the others
/// decode it) render the same bits as a worker that computes everything itself; each map
/// or pass is computed once, however many workers render.
#[test]
fn shared_photon_maps_and_sppm_passes_give_the_same_bits_computed_once() {
    for (name, spp, resolution, published, spectral) in [
        ("media/haze.pbrt", 2, (24, 24), 1, false),
        ("photons/ball.pbrt", 6, (24, 24), 6, false),
        // Spectral photons carry four wavelengths through the bytes.
        ("photons/ball.pbrt", 3, (24, 24), 3, true),
        ("media/haze.pbrt", 2, (24, 24), 1, true),
    ] {
        let mut desc = kiln_scene::load_file(&scene(name)).unwrap();
        desc.apply_overrides(&Overrides {
            resolution: Some(resolution),
            spp: Some(spp),
            seed: None,
            spectral: Some(spectral),
            ..Default::default()
        })
        .unwrap();
        let alone = render_split(&Renderer::build(&desc).unwrap(), 8, 2);
        let share = std::sync::Arc::new(MemoryShare::default());
        // Three workers, one after another and then two at once, each rendering tiles.
        for _ in 0..3 {
            let worker = Renderer::build_sharing(&desc, Some(share.clone())).unwrap();
            assert!(
                render_split(&worker, 8, 2) == alone,
                "{name}: a sharing worker's pixels differ"
            );
        }
        let (a, b) = rayon::join(
            || {
                render_split(
                    &Renderer::build_sharing(&desc, Some(share.clone())).unwrap(),
                    8,
                    1,
                )
            },
            || {
                render_split(
                    &Renderer::build_sharing(&desc, Some(share.clone())).unwrap(),
                    8,
                    1,
                )
            },
        );
        assert!(
            a == alone && b == alone,
            "{name}: concurrent sharing workers differ"
        );
        assert_eq!(
            share.publishes.load(std::sync::atomic::Ordering::SeqCst),
            published,
            "{name}: each map or pass is computed once"
        );
    }
}

/// `render_pixel` gives an SPPM pixel the value its tile gives (not a single camera sample's,
/// which SPPM has no estimate for).
#[test]
fn an_sppm_pixel_alone_is_its_tiles_pixel() {
    let renderer = load(&scene("photons/ball.pbrt"), 3, Some((12, 12)));
    let frame = render_split(&renderer, 5, 1);
    let mut stats = kiln_render::TileStats::default();
    for (x, y) in [(0, 0), (6, 7), (11, 11)] {
        let alone = kiln_render::render_pixel(&renderer, x, y, &mut stats).map(f32::to_bits);
        assert_eq!(alone, frame[(y * 12 + x) as usize], "pixel {x}, {y}");
    }
    assert_eq!(stats.samples, 9, "three pixels of three iterations");
}

/// What glibc is told to hide, as a CPU without them would: its libm then takes its SSE2
/// code paths for exp, log, pow, sin, cos and the rest, which give other bits than its FMA
/// ones. (Unknown names are ignored, so AVX512F does no harm where glibc lacks it.)
const HIDE_FMA_AND_AVX2: &str = "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F";

/// Set in the child process [`glibc_masking_changes_std_math_here`] starts: that child prints
/// std's f64 results instead of returning at once.
const PROBE_ENV: &str = "KILN_TEST_LIBM_PROBE";

/// A fingerprint of glibc's f64 exp, log, pow, sin, cos, tan, atan2 and acos over 200,000 inputs.
#[test]
fn std_math_fingerprint() {
    if std::env::var_os(PROBE_ENV).is_none() {
        return;
    }
    let mut hash = 0u64;
    let mut x = 1e-4f64;
    for _ in 0..200_000 {
        x = x * 1.000_037 + 1e-7;
        #[allow(clippy::disallowed_methods)] // the point: glibc's own functions
        let y = [
            (3.0 * x).exp(),
            x.ln(),
            x.powf(1.7),
            (50.0 * x).sin(),
            (30.0 * x).cos(),
            x.tan(),
            x.atan2(0.3),
            (x % 1.0).acos(),
        ];
        for v in y {
            hash = hash.wrapping_mul(1_000_003) ^ v.to_bits();
        }
    }
    println!("std-fingerprint {hash:016x}");
}

/// Runs [`std_math_fingerprint`] in a child process, with glibc's FMA and AVX2 hidden or not.
fn std_fingerprint(hide: bool) -> String {
    let mut cmd = std::process::Command::new(std::env::current_exe().unwrap());
    cmd.args([
        "--exact",
        "determinism::std_math_fingerprint",
        "--nocapture",
    ])
    .args(["--test-threads", "1"])
    .env(PROBE_ENV, "1");
    if hide {
        cmd.env("GLIBC_TUNABLES", HIDE_FMA_AND_AVX2);
    } else {
        cmd.env_remove("GLIBC_TUNABLES");
    }
    let out = cmd.output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    stdout
        .lines()
        .find_map(|l| l.split("std-fingerprint ").nth(1))
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("the probe printed no fingerprint:\n{stdout}"))
        .to_string()
}

/// The control for the test below: on a CPU with FMA, hiding it changes what std's f64
/// functions return, so a render that called them could change with the machine.
#[test]
fn glibc_masking_changes_std_math_here() {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let has_fma = cpuinfo
        .lines()
        .any(|l| l.starts_with("flags") && l.split_whitespace().any(|f| f == "fma"));
    if !has_fma || !cfg!(all(target_os = "linux", target_env = "gnu")) {
        eprintln!("SKIPPED: this CPU has no FMA for glibc to hide (or this is not glibc)");
        return;
    }
    assert_ne!(
        std_fingerprint(false),
        std_fingerprint(true),
        "hiding FMA and AVX2 from glibc no longer changes its f64 libm: the render test below \
         would prove nothing; check the GLIBC_TUNABLES names"
    );
}

/// Kiln calls the libm crate (pure Rust) for every transcendental function, and clippy
/// refuses std's (clippy.toml): so a render gives the same bytes whichever code paths glibc
/// picked for the CPU it started on. Scenes that reach Fresnel, microfacets, textures and
/// noise, loop subdivision, media, blackbody emission, spot lights, VolumeLights and hair.
#[test]
fn renders_are_the_same_bytes_whatever_cpu_glibc_sees() {
    let dir = tempfile::tempdir().unwrap();
    for rel in [
        "materials/scene.pbrt",
        "textures/scene.pbrt",
        "media/fog.pbrt",
        "fire/scene.pbrt",
        "lights/scene.pbrt",
        "shapes/hair.pbrt",
        "volume-light/voxel-grid.pbrt",
    ] {
        let path = scene(rel);
        let render = |hide: bool| {
            let out = dir
                .path()
                .join(format!("{}-{hide}.exr", rel.replace('/', "-")));
            let mut cmd = crate::util::kiln();
            cmd.arg("render")
                .arg(&path)
                .args(["--resolution", "64x48", "--spp", "4", "--quiet", "-o"])
                .arg(&out);
            if hide {
                cmd.env("GLIBC_TUNABLES", HIDE_FMA_AND_AVX2);
            } else {
                cmd.env_remove("GLIBC_TUNABLES");
            }
            let status = cmd.status().unwrap();
            assert!(status.success(), "kiln render {rel} failed");
            std::fs::read(&out).unwrap()
        };
        assert!(
            render(false) == render(true),
            "{rel}: hiding FMA and AVX2 from glibc changed the rendered bytes"
        );
    }
}
