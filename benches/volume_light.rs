//! VolumeLight benchmark: a glass sphere mesh of 120,000+ faces (the size of seed 000's
//! snail) as a VolumeLight over a floor. Prints load time, power-estimation time, peak
//! memory, and render samples per second against the same mesh as a plain diffuse area
//! light at equal samples per pixel.
//!
//! `cargo bench --bench volume_light [-- --rings N --spp N --resolution N]`

mod common;
use common::{arg, peak_rss_mib, render_tiles, write_sphere_ply};
use kiln_render::lights::volume::{VOLUME_POWER_SEED, power_estimates};
use kiln_render::{Renderer, TileStats};
use std::time::Instant;

fn scene_text(light: &str, material: &str, res: u32, spp: u32) -> String {
    // In RGB, as the recorded figures were measured.
    format!(
        "Option \"kiln.spectral\" false
        Integrator \"path\" \"integer maxdepth\" [ 5 ]
        Sampler \"zsobol\" \"integer pixelsamples\" [ {spp} ]
        Film \"rgb\" \"integer xresolution\" [ {res} ] \"integer yresolution\" [ {res} ]
        LookAt 0 2 5  0 0.6 0  0 1 0
        Camera \"perspective\" \"float fov\" [ 40 ]
        WorldBegin
        Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]
        Shape \"bilinearmesh\" \"point3 P\" [ -10 -1 -10  10 -1 -10  -10 -1 10  10 -1 10 ]
        AttributeBegin
        {light}
        {material}
        Translate 0 0.2 0
        Shape \"plymesh\" \"string filename\" \"sphere.ply\"
        AttributeEnd"
    )
}

fn render(renderer: &Renderer, bounds: [u32; 4]) -> (f64, TileStats) {
    let (secs, results) = render_tiles(renderer, bounds);
    let mut stats = TileStats::default();
    for r in &results {
        stats.merge(&r.stats);
    }
    (secs, stats)
}

fn main() {
    let rings = arg("--rings", 174) as usize;
    let spp = arg("--spp", 16);
    let res = arg("--resolution", 160);
    let dir = tempfile::tempdir().unwrap();
    let faces = write_sphere_ply(&dir.path().join("sphere.ply"), rings, 2 * rings);
    println!(
        "volume-light bench: {faces} faces, {res}x{res}, {spp} spp, {} threads",
        rayon::current_num_threads()
    );
    let cases = [
        (
            "volume",
            "AreaLightSource \"volume\" \"rgb Le\" [ 2 0.8 0.2 ]",
            "Material \"dielectric\" \"float eta\" [ 1.5 ]",
        ),
        // The same mesh as a plain area light, with the same glass surface (only how the
        // emission is computed differs) and with a black one (paths end at the light).
        (
            "area (glass)",
            "AreaLightSource \"diffuse\" \"rgb L\" [ 2 0.8 0.2 ]",
            "Material \"dielectric\" \"float eta\" [ 1.5 ]",
        ),
        (
            "area (black)",
            "AreaLightSource \"diffuse\" \"rgb L\" [ 2 0.8 0.2 ]",
            "Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]",
        ),
    ];
    let mut rates = Vec::new();
    for (name, light, material) in cases {
        let path = dir.path().join(format!("{}.pbrt", rates.len()));
        std::fs::write(&path, scene_text(light, material, res, spp)).unwrap();
        let start = Instant::now();
        let desc = kiln_scene::load_file(&path).unwrap();
        let load = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let renderer = Renderer::build(&desc).unwrap();
        let scene = renderer.scene();
        let build = start.elapsed().as_secs_f64();
        let (secs, stats) = render(&renderer, desc.film.pixel_bounds);
        let rate = stats.samples as f64 / secs;
        rates.push(rate);
        println!(
            "{name}: load {load:.3} s, build {build:.3} s (BVH {:.3} s), render {secs:.2} s, {:.0} samples/s, {:.0} rays/s",
            scene.geometry.build_time.as_secs_f64(),
            rate,
            stats.rays as f64 / secs
        );
        if name == "volume" {
            // The power estimation on its own, as Scene::build runs it.
            let start = Instant::now();
            let powers = power_estimates(&scene.lights, &scene.light_context(), VOLUME_POWER_SEED);
            println!(
                "volume: power estimation for {} faces ({} segments each): {:.3} s",
                powers.iter().flatten().count(),
                50,
                start.elapsed().as_secs_f64()
            );
        }
    }
    println!(
        "volume / area samples per second: {:.2} (glass area light), {:.2} (black area light)",
        rates[0] / rates[1],
        rates[0] / rates[2]
    );
    println!("peak_rss_mib={:.1}", peak_rss_mib().unwrap_or(0.0));
}
