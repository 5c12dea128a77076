//! Progressive passes: a tile rendered in passes, its running sums carried between them as
//! integer words (as the farm carries them), is the same bytes as the tile rendered in one
//! go, for any pass schedule and tile size.

use crate::determinism::load;
use crate::util::{scene, write_scene};
use kiln_render::{Renderer, TileRect, TileSums, render_tile, render_tile_pass, split_into_tiles};

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
    let gbuffer = renderer.settings().gbuffer.is_some();
    let names = TileSums::word_names(gbuffer);
    let mut sums = TileSums::empty(rect, gbuffer);
    let mut last = None;
    for &to in schedule {
        let (result, after) = render_tile_pass(renderer, &sums, to, &|| false)
            .unwrap()
            .unwrap();
        assert_eq!(after.samples, to);
        assert_eq!(
            result.stats.samples,
            (to - sums.samples) as u64 * rect.pixel_count()
        );
        sums = TileSums::from_words(rect, gbuffer, &names, &after.to_words()).unwrap();
        last = Some(bits(&result.pixels, &result.aovs));
    }
    last.unwrap()
}

fn assert_passes_match(name: &str, renderer: &Renderer, spp: u32) {
    let (w, h) = renderer.scene().resolution;
    let schedules: [&[u32]; 4] = [&[spp], &[1, spp], &[3, 4, spp], &[spp / 2, spp - 1, spp]];
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

#[test]
fn a_pass_must_go_forward_and_fit_its_sums() {
    let renderer = load(&scene("materials/scene.pbrt"), 4, Some((8, 8)));
    let rect = TileRect {
        x0: 0,
        y0: 0,
        width: 4,
        height: 4,
    };
    let sums = TileSums::empty(rect, false);
    let (_, after) = render_tile_pass(&renderer, &sums, 2, &|| false)
        .unwrap()
        .unwrap();
    let err = render_tile_pass(&renderer, &after, 2, &|| false).unwrap_err();
    assert!(err.to_string().contains("past the 2 samples"), "{err}");
    let gb = TileSums::empty(rect, true);
    assert!(render_tile_pass(&renderer, &gb, 2, &|| false).is_err());
    let stopped = render_tile_pass(&renderer, &sums, 2, &|| true).unwrap();
    assert!(stopped.is_none(), "a stopped pass gives nothing");
}
