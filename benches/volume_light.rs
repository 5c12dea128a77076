//! VolumeLight benchmark: a glass sphere mesh of 120,000+ faces (the size of seed 000's
//! snail) as a VolumeLight over a floor. Prints load time, power-estimation time, peak
//! memory, and render samples per second against the same mesh as a plain diffuse area
//! light at equal samples per pixel.
//!
//! `cargo bench --bench volume_light [-- --rings N --spp N --resolution N]`

mod common;
use common::{arg, peak_rss_mib, render_tiles};
use kiln_render::lights::volume::{VOLUME_POWER_SEED, power_estimates};
use kiln_render::{Renderer, TileStats};
use std::io::Write;
use std::time::Instant;

/// Writes a binary PLY UV sphere with smooth normals; returns its face count.
fn write_sphere_ply(path: &std::path::Path, rings: usize, segments: usize) -> usize {
    let mut verts = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            verts.push([
                libm::sinf(theta) * libm::cosf(phi),
                libm::cosf(theta),
                libm::sinf(theta) * libm::sinf(phi),
            ]);
        }
    }
    let mut faces = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = (i * segments + j) as u32;
            let b = (i * segments + (j + 1) % segments) as u32;
            let (c, d) = (a + segments as u32, b + segments as u32);
            if i != 0 {
                faces.push([a, b, c]);
            }
            if i != rings - 1 {
                faces.push([b, d, c]);
            }
        }
    }
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(
        f,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        verts.len(),
        faces.len()
    )
    .unwrap();
    for v in &verts {
        for c in v.iter().chain(v.iter()) {
            f.write_all(&c.to_le_bytes()).unwrap();
        }
    }
    for t in &faces {
        f.write_all(&[3u8]).unwrap();
        for i in t {
            f.write_all(&(*i as i32).to_le_bytes()).unwrap();
        }
    }
    faces.len()
}

fn scene_text(light: &str, material: &str, res: u32, spp: u32) -> String {
    format!(
        "Integrator \"path\" \"integer maxdepth\" [ 5 ]
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
