//! Texture benchmark (issue 12): a scene whose every surface is textured against the same
//! scene with each texture replaced by a constant, twice: with image textures (a 2048²
//! image with MIP maps and trilinear, bilinear and EWA lookups) and a filtered
//! checkerboard, what real scenes mostly use (target: ≥ 0.8x the constants' samples per
//! second); and with procedural noise too (marble, fBm roughness, an fBm bump map, each
//! several octaves of Perlin noise per lookup, three lookups per bump). Prints samples per
//! second and their ratios, the MIP map's memory and the process's peak memory, and heap
//! allocations per sample (texture lookups must not allocate: all three must be equal).
//!
//! `cargo bench --bench textures [-- --resolution N --spp N --runs N --image N]`

mod common;
use common::{arg, peak_rss_mib, render_tiles};
use kiln_render::Renderer;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

/// Counts heap allocations, to show that rendering a textured scene allocates no more
/// than rendering the same scene untextured.
struct Counting;
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}
#[global_allocator]
static GLOBAL: Counting = Counting;

/// A 8-bit RGB PNG of n x n pixels: coloured stripes under a fine grid, detail at every
/// scale for the MIP map to filter.
fn write_image(path: &std::path::Path, n: u32) {
    let mut rgb = Vec::with_capacity((n * n * 3) as usize);
    for y in 0..n {
        for x in 0..n {
            let grid = (x % 16 == 0 || y % 16 == 0) as u8;
            let r = ((x * 255) / n) as u8;
            let g = (((x ^ y) & 0xff) as u8) / 2 + 60;
            let b = ((y * 255) / n) as u8;
            rgb.extend_from_slice(&if grid == 1 { [20, 20, 20] } else { [r, g, b] });
        }
    }
    let file = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), n, n);
    enc.set_color(png::ColorType::Rgb);
    enc.write_header().unwrap().write_image_data(&rgb).unwrap();
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Every texture replaced by a constant.
    Constant,
    /// Image and checkerboard textures (what real scenes mostly use); the spheres' noise
    /// textures replaced by constants.
    Images,
    /// Everything: images, checkerboard, marble, fBm roughness and an fBm bump map.
    All,
}

fn scene_text(kind: Kind, res: u32, spp: u32) -> String {
    let t = |texture: &str, constant: &str| {
        if kind != Kind::Constant {
            texture.to_string()
        } else {
            constant.to_string()
        }
    };
    let noise = |texture: &str, image: &str, constant: &str| match kind {
        Kind::All => texture.to_string(),
        Kind::Images => image.to_string(),
        Kind::Constant => constant.to_string(),
    };
    // In RGB, as the recorded figures were measured.
    format!(
        r#"Option "kiln.spectral" false
Integrator "path" "integer maxdepth" [ 5 ]
Sampler "zsobol" "integer pixelsamples" [ {spp} ]
Film "rgb" "integer xresolution" [ {res} ] "integer yresolution" [ {res} ]
LookAt 0 1.5 5  0 0.5 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.4 0.45 0.5 ]
LightSource "distant" "point3 from" [ 2 4 3 ] "point3 to" [ 0 0 0 ] "rgb L" [ 2 2 2 ]
Texture "img-tri" "spectrum" "imagemap" "string filename" "image.png" "string filter" "trilinear" "float uscale" [ 8 ] "float vscale" [ 8 ]
Texture "img-ewa" "spectrum" "imagemap" "string filename" "image.png" "string filter" "ewa"
Texture "img-bi" "spectrum" "imagemap" "string filename" "image.png"
Texture "checks" "spectrum" "checkerboard" "float uscale" [ 200 ] "float vscale" [ 200 ] "rgb tex1" [ 0.8 0.8 0.8 ] "rgb tex2" [ 0.1 0.1 0.1 ]
Texture "marble" "spectrum" "marble" "float scale" [ 3 ]
Texture "noise" "float" "fbm"
Texture "rough" "float" "scale" "texture tex" "noise" "float scale" [ 0.2 ]
Texture "bumps" "float" "scale" "texture tex" "noise" "float scale" [ 0.01 ]
AttributeBegin
  {floor}
  Shape "trianglemesh" "point3 P" [ -50 0 -50  50 0 -50  50 0 50  -50 0 50 ] "integer indices" [ 0 1 2 0 2 3 ] "point2 uv" [ 0 0 1 0 1 1 0 1 ]
AttributeEnd
AttributeBegin
  {panel}
  Translate 0 1 -2
  Shape "trianglemesh" "point3 P" [ -2 -1 0  2 -1 0  2 1 0  -2 1 0 ] "integer indices" [ 0 1 2 0 2 3 ] "point2 uv" [ 0 0 1 0 1 1 0 1 ]
AttributeEnd
AttributeBegin
  {sphere1}
  Translate -1.2 0.6 0
  Shape "sphere" "float radius" [ 0.6 ]
AttributeEnd
AttributeBegin
  {sphere2}
  Translate 0 0.6 0.5
  Shape "sphere" "float radius" [ 0.6 ]
AttributeEnd
AttributeBegin
  {sphere3}
  Translate 1.2 0.6 0
  Shape "sphere" "float radius" [ 0.6 ]
AttributeEnd
"#,
        floor = t(
            r#"Material "diffuse" "texture reflectance" "checks""#,
            r#"Material "diffuse" "rgb reflectance" [ 0.45 0.45 0.45 ]"#
        ),
        panel = t(
            r#"Material "diffuse" "texture reflectance" "img-tri""#,
            r#"Material "diffuse" "rgb reflectance" [ 0.5 0.4 0.5 ]"#
        ),
        sphere1 = noise(
            r#"Material "coateddiffuse" "texture reflectance" "img-ewa" "texture displacement" "bumps""#,
            r#"Material "coateddiffuse" "texture reflectance" "img-ewa""#,
            r#"Material "coateddiffuse" "rgb reflectance" [ 0.5 0.4 0.5 ]"#
        ),
        sphere2 = noise(
            r#"Material "conductor" "texture roughness" "rough" "texture reflectance" "img-bi""#,
            r#"Material "conductor" "float roughness" [ 0.1 ] "texture reflectance" "img-bi""#,
            r#"Material "conductor" "float roughness" [ 0.1 ] "rgb reflectance" [ 0.5 0.4 0.5 ]"#
        ),
        sphere3 = noise(
            r#"Material "diffuse" "texture reflectance" "marble""#,
            r#"Material "diffuse" "texture reflectance" "img-tri""#,
            r#"Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]"#
        ),
    )
}

fn main() {
    let res: u32 = arg("--resolution", 256);
    let spp: u32 = arg("--spp", 16);
    let runs: usize = arg("--runs", 3);
    let image: u32 = arg("--image", 2048);
    let dir = tempfile::tempdir().unwrap();
    write_image(&dir.path().join("image.png"), image);
    println!(
        "textures: {res}x{res}, {spp} spp, {} threads, a {image}x{image} 8-bit image, best of {runs}",
        rayon::current_num_threads()
    );
    let mut rates = Vec::new();
    for (kind, name) in [
        (Kind::Constant, "constants"),
        (Kind::Images, "images"),
        (Kind::All, "all kinds"),
    ] {
        let path = dir.path().join("scene.pbrt");
        std::fs::write(&path, scene_text(kind, res, spp)).unwrap();
        let start = std::time::Instant::now();
        let desc = kiln_scene::load_file(&path).unwrap();
        let renderer = Renderer::build(&desc).unwrap();
        let load = start.elapsed().as_secs_f64();
        let mut best = f64::INFINITY;
        let mut allocations = 0;
        for _ in 0..runs {
            let before = ALLOCATIONS.load(Ordering::Relaxed);
            let (secs, _) = render_tiles(&renderer, [0, res, 0, res]);
            allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
            best = best.min(secs);
        }
        let samples = (res * res * spp) as f64;
        let rate = samples / best / 1e6;
        println!(
            "  {:<10} load+MIP {load:.2} s, render {best:.3} s: {rate:.3} M samples/s, {:.4} heap allocations per sample",
            name,
            allocations as f64 / samples
        );
        rates.push(rate);
    }
    let levels: f64 = (0..=image.trailing_zeros())
        .map(|l| 4f64.powi(-(l as i32)))
        .sum();
    println!(
        "  images / constants: {:.3} (target >= 0.8); all kinds / constants: {:.3}",
        rates[1] / rates[0],
        rates[2] / rates[0]
    );
    println!(
        "  MIP map of the image {:.1} MiB (8-bit RGB, all levels); peak RSS {:.0} MiB",
        (image as f64 * image as f64 * 3.0 * levels) / (1 << 20) as f64,
        peak_rss_mib().unwrap_or(f64::NAN)
    );
}
