//! Waves of paths give the bytes of one path at a time: every tile renders its rows as waves
//! (each stage of the path tracer over all the live paths, shadow rays traced together
//! after their vertices), and the pixels, the G-buffer's channels and the statistics must
//! be the same bits as tracing each camera sample on its own from the camera to its end, for
//! every wave size: a wave of one, waves that split a pixel's samples, waves of many pixels.

use crate::determinism::load;
use crate::util::{reference_scene, scene};
use kiln_render::tile::render_tile_reference;
use kiln_render::{Renderer, TileRect, TileResult, render_tile};

/// The wave sizes every scene is rendered with, beside production's.
const WAVES: [usize; 4] = [1, 3, 64, 4096];

fn bits(t: &TileResult) -> (Vec<[u32; 3]>, Vec<u32>) {
    (
        t.pixels.iter().map(|p| p.map(f32::to_bits)).collect(),
        t.aovs.iter().map(|v| v.to_bits()).collect(),
    )
}

/// Renders the whole film of `renderer` as one tile, and a column one pixel wide (whose
/// waves of one hold one path, of three a pixel's three samples), path after path and in
/// waves of every size, and requires the same bits and statistics. The whole film's
/// reference.
fn assert_waves_match_one_path_at_a_time(name: &str, renderer: &Renderer) -> TileResult {
    let (w, h) = renderer.scene().resolution;
    let column = TileRect {
        x0: w / 2,
        y0: 0,
        width: 1,
        height: h,
    };
    assert_waves_match_in(&format!("{name}, a column"), renderer, column);
    let film = TileRect {
        x0: 0,
        y0: 0,
        width: w,
        height: h,
    };
    assert_waves_match_in(name, renderer, film)
}

fn assert_waves_match_in(name: &str, renderer: &Renderer, rect: TileRect) -> TileResult {
    let reference = render_tile_reference(renderer, rect, None);
    assert!(
        reference.pixels.iter().any(|p| p.iter().any(|&c| c > 0.0)),
        "{name}: the reference is black"
    );
    let mut renders = vec![("production".to_string(), render_tile(renderer, rect))];
    for wave in WAVES {
        renders.push((
            format!("waves of {wave}"),
            render_tile_reference(renderer, rect, Some(wave)),
        ));
    }
    for (how, tile) in renders {
        let (pixels, aovs) = bits(&tile);
        let (ref_pixels, ref_aovs) = bits(&reference);
        if let Some(i) = (0..pixels.len()).find(|&i| pixels[i] != ref_pixels[i]) {
            panic!(
                "{name}, {how}: pixel {i} is {:?}, one path at a time gives {:?}",
                tile.pixels[i], reference.pixels[i]
            );
        }
        assert!(aovs == ref_aovs, "{name}, {how}: the G-buffer differs");
        assert_eq!(tile.stats, reference.stats, "{name}, {how}: statistics");
    }
    reference
}

#[test]
fn surfaces_textures_and_lights_in_waves_are_one_path_at_a_time() {
    let materials = load(&scene("materials/scene.pbrt"), 4, Some((24, 16)));
    assert_waves_match_one_path_at_a_time("materials", &materials);
    let textures = load(&scene("textures/scene.pbrt"), 2, Some((32, 20)));
    assert_waves_match_one_path_at_a_time("textures", &textures);
    let shapes = load(&scene("shapes/scene.pbrt"), 2, Some((24, 16)));
    assert_waves_match_one_path_at_a_time("shapes", &shapes);
    let motion = load(&scene("motion/scene.pbrt"), 2, Some((24, 18)));
    assert_waves_match_one_path_at_a_time("motion", &motion);
    if let Some(path) = reference_scene("cornell-box") {
        let cornell = load(&path, 8, Some((24, 24)));
        assert_waves_match_one_path_at_a_time("cornell-box", &cornell);
    }
}

/// Media (tracked, emissive grids sampled as lights), VolumeLights (their chords traced
/// inside light sampling), nested dielectrics with photon maps, and subsurface walks.
#[test]
fn media_volume_lights_photons_and_walks_in_waves_are_one_path_at_a_time() {
    for (name, spp, res) in [
        ("media/fog.pbrt", 4, (24, 16)),
        ("media/ember.pbrt", 4, (24, 16)),
        ("media/haze.pbrt", 2, (20, 20)),
        ("media/lens.pbrt", 2, (20, 20)),
        ("volume-light/voxel-grid.pbrt", 2, (24, 18)),
        ("martini/scene.pbrt", 1, (24, 16)),
        ("lily-pond/scene.pbrt", 1, (24, 16)),
    ] {
        let renderer = load(&scene(name), spp, Some(res));
        assert_waves_match_one_path_at_a_time(name, &renderer);
    }
}

/// Adaptive sampling (rounds end at its checkpoints, and some pixels stop before others),
/// a G-buffer film, spectral paths, and a realistic camera whose lens stops some rays (a
/// sample without a path).
#[test]
fn adaptive_gbuffer_spectral_and_lens_renders_in_waves_are_one_path_at_a_time() {
    let path = scene("mis/scene.pbrt");
    let adaptive = crate::passes::load_adaptive(&path, 32, (24, 14), 0.05, 4);
    let reference = assert_waves_match_one_path_at_a_time("mis, adaptive", &adaptive);
    assert!(
        reference.stats.samples < 32 * 24 * 14,
        "no pixel stopped early: {} samples",
        reference.stats.samples
    );
    let mut desc = kiln_scene::load_file(&scene("materials/scene.pbrt")).unwrap();
    desc.apply_overrides(&kiln_scene::Overrides {
        resolution: Some((24, 16)),
        spp: Some(4),
        spectral: Some(true),
        ..Default::default()
    })
    .unwrap();
    desc.film.gbuffer = Some(kiln_scene::GBufferSpace::Camera);
    let renderer = Renderer::build(&desc).unwrap();
    assert_waves_match_one_path_at_a_time("materials, spectral, G-buffer", &renderer);
    // A singlet with a stop wider than its elements: rays off the axis are stopped.
    let dir = tempfile::tempdir().unwrap();
    let lens = "# radius thickness eta aperture\n40 6 1.6 24\n-40 4 1 24\n0 0 0 16\n";
    std::fs::write(dir.path().join("singlet.dat"), lens).unwrap();
    let file = dir.path().join("lens.pbrt");
    std::fs::write(
        &file,
        r#"Integrator "volpath" "integer maxdepth" [ 3 ]
Sampler "independent" "integer pixelsamples" [ 4 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 16 ] "float diagonal" [ 30 ]
LookAt 0 0.3 0  0 0 -3  0 1 0
Camera "realistic" "string lensfile" "singlet.dat" "float aperturediameter" [ 30 ] "float focusdistance" [ 2.5 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0.8 0.3 0.2 ]
Shape "bilinearmesh" "point3 P" [ -4 -0.5 -8  4 -0.5 -8  -4 -0.5 1  4 -0.5 1 ]
Translate 0.4 0 -2.5
Shape "sphere" "float radius" [ 0.3 ]
"#,
    )
    .unwrap();
    let renderer = load(&file, 4, None);
    assert_waves_match_one_path_at_a_time("a realistic camera", &renderer);
}
