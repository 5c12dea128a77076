//! Progressive passes: a tile rendered in passes, its running sums carried between them as
//! integer words (as the farm carries them), is the same bytes as the tile rendered in one
//! go, for any pass schedule and tile size, adaptive sampling included (a pixel stops at
//! the same checkpoint whichever passes led there).

use crate::determinism::load;
use crate::util::{scene, write_scene};
use kiln_render::{
    Renderer, SumsLayout, TileRect, TileSums, render_tile, render_tile_pass, split_into_tiles,
};
use std::path::Path;

/// `path` at `spp` and `resolution` with adaptive sampling at `threshold`, checking from
/// `min_samples` on.
pub(crate) fn load_adaptive(
    path: &Path,
    spp: u32,
    resolution: (u32, u32),
    threshold: f32,
    min_samples: u32,
) -> Renderer {
    let mut desc = kiln_scene::load_file(path).unwrap();
    desc.apply_overrides(&kiln_scene::Overrides {
        resolution: Some(resolution),
        spp: Some(spp),
        noise_threshold: Some(threshold),
        ..Default::default()
    })
    .unwrap();
    desc.sampler.min_samples = min_samples;
    Renderer::build(&desc).unwrap()
}

/// A tile's pixels and further channels, as bits.
fn bits(pixels: &[[f32; 3]], aovs: &[f32]) -> (Vec<[u32; 3]>, Vec<u32>) {
    (
        pixels.iter().map(|p| p.map(f32::to_bits)).collect(),
        aovs.iter().map(|v| v.to_bits()).collect(),
    )
}

/// Renders `rect` through the passes ending at each of `schedule`'s sample counts, the
/// sums going through words between passes.
fn in_passes(renderer: &Renderer, rect: TileRect, schedule: &[u32]) -> (Vec<[u32; 3]>, Vec<u32>) {
    let layout = renderer.settings().sums_layout();
    let names = TileSums::word_names(layout);
    let mut sums = TileSums::empty(rect, layout);
    let mut last = None;
    for &to in schedule {
        let (result, after) = render_tile_pass(renderer, &sums, to, &|| false)
            .unwrap()
            .unwrap();
        assert_eq!(after.samples, to);
        let taken: u64 = after.pixels.iter().map(|p| u64::from(p.taken)).sum::<u64>()
            - sums.pixels.iter().map(|p| u64::from(p.taken)).sum::<u64>();
        assert_eq!(result.stats.samples, taken);
        if !layout.adaptive {
            assert_eq!(taken, (to - sums.samples) as u64 * rect.pixel_count());
        }
        sums = TileSums::from_words(rect, layout, &names, &after.to_words()).unwrap();
        last = Some(bits(&result.pixels, &result.aovs));
    }
    last.unwrap()
}

fn assert_passes_match(name: &str, renderer: &Renderer, spp: u32) {
    let (w, h) = renderer.scene().resolution;
    // The last ends on every power of two: with adaptive sampling, on every checkpoint.
    let powers: Vec<u32> = (1..)
        .map(|k| 1u32 << k)
        .take_while(|&p| p < spp)
        .chain([spp])
        .collect();
    let schedules: [&[u32]; 5] = [
        &[spp],
        &[1, spp],
        &[3, 4, spp],
        &[spp / 2, spp - 1, spp],
        &powers,
    ];
    for tile in [7, 16] {
        for rect in split_into_tiles([0, w, 0, h], tile) {
            let one = render_tile(renderer, rect);
            let one = bits(&one.pixels, &one.aovs);
            for schedule in schedules {
                assert!(
                    in_passes(renderer, rect, schedule) == one,
                    "{name}: tile {rect:?} in passes {schedule:?} differs from one go"
                );
            }
        }
    }
}

#[test]
fn passes_give_the_bytes_of_one_go() {
    let spp = 8;
    let materials = load(&scene("materials/scene.pbrt"), spp, Some((24, 16)));
    assert_passes_match("materials", &materials, spp);
    let textures = load(&scene("textures/scene.pbrt"), spp, Some((24, 16)));
    assert_passes_match("textures", &textures, spp);
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "gb.pbrt", crate::gbuffer::SCENE);
    let gbuffer = load(&path, spp, Some((24, 16)));
    assert!(gbuffer.settings().gbuffer.is_some());
    assert_passes_match("gbuffer", &gbuffer, spp);
}

/// With adaptive sampling a pixel stops at a checkpoint (here every power of two from 2)
/// when its own sums say so, and whichever passes led there (ending on a checkpoint or
/// between two) it stops at the same one: the same bytes as one go. Some pixels stop early
/// and some take every sample, or the test would prove nothing.
#[test]
fn adaptive_sampling_in_passes_gives_the_bytes_of_one_go() {
    let spp = 16;
    let renderer = load_adaptive(&scene("materials/scene.pbrt"), spp, (24, 16), 0.05, 2);
    assert!(renderer.settings().adaptive.is_some());
    let whole = TileRect {
        x0: 0,
        y0: 0,
        width: 24,
        height: 16,
    };
    let (_, sums) = render_tile_pass(
        &renderer,
        &TileSums::empty(whole, renderer.settings().sums_layout()),
        spp,
        &|| false,
    )
    .unwrap()
    .unwrap();
    let stopped = sums.pixels.iter().filter(|p| p.taken < spp).count();
    let full = sums.pixels.iter().filter(|p| p.taken == spp).count();
    assert!(
        stopped > 20 && full > 20,
        "{stopped} pixels stopped early, {full} took all {spp}"
    );
    assert!(
        sums.pixels
            .iter()
            .all(|p| p.taken == spp || p.taken.is_power_of_two())
    );
    assert_passes_match("materials, adaptive", &renderer, spp);
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "gb.pbrt", crate::gbuffer::SCENE);
    let gbuffer = load_adaptive(&path, spp, (24, 16), 0.05, 2);
    assert_passes_match("gbuffer, adaptive", &gbuffer, spp);
}

#[test]
fn a_pass_must_go_forward_and_fit_its_sums() {
    let renderer = load(&scene("materials/scene.pbrt"), 4, Some((8, 8)));
    let rect = TileRect {
        x0: 0,
        y0: 0,
        width: 4,
        height: 4,
    };
    let sums = TileSums::empty(rect, SumsLayout::default());
    let (_, after) = render_tile_pass(&renderer, &sums, 2, &|| false)
        .unwrap()
        .unwrap();
    let err = render_tile_pass(&renderer, &after, 2, &|| false).unwrap_err();
    assert!(err.to_string().contains("past the 2 samples"), "{err}");
    for other in [
        SumsLayout {
            gbuffer: true,
            adaptive: false,
        },
        SumsLayout {
            gbuffer: false,
            adaptive: true,
        },
    ] {
        let wrong = TileSums::empty(rect, other);
        assert!(render_tile_pass(&renderer, &wrong, 2, &|| false).is_err());
    }
    let stopped = render_tile_pass(&renderer, &sums, 2, &|| true).unwrap();
    assert!(stopped.is_none(), "a stopped pass gives nothing");
}
