//! Surfaces of revolution against their meshes (issue 15): the martini glass's contour
//! (scenes/martini/glass.pbrt) as Kiln's exact "revolution" shape and as triangle meshes cut
//! finely enough round to be as accurate (the chord of each segment within `--tolerance`
//! of the radius; the contour's own points are shared, so along the contour they are equal).
//! Prints rays per second on one thread (closest hits of rays aimed at the glass from all
//! round), the memory each takes (its primitive data, and the resident growth while
//! building, which includes the parser's transient text) and how often the two
//! agree on hit or miss.
//!
//! `cargo bench --bench revolution [-- --rays N --tolerance T]`

mod common;
use common::arg;
use glam::{Vec2, Vec3A};
use kiln_render::math::Ray;
use kiln_render::{MediaPolicy, Scene};
use std::f64::consts::PI;
use std::fmt::Write;
use std::path::Path;
use std::time::Instant;

/// The glass's contour: the first "point2 contour" of glass.pbrt.
fn glass_contour() -> Vec<(f64, f64)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/martini/glass.pbrt");
    let text = std::fs::read_to_string(path).expect("glass.pbrt");
    let start = text.find("\"point2 contour\" [").expect("a contour") + 18;
    let end = start + text[start..].find(']').unwrap();
    let v: Vec<f64> = text[start..end]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    v.chunks(2).map(|c| (c[0], c[1])).collect()
}

fn scene(shape: &str) -> Scene {
    let text = format!(
        "Camera \"perspective\"\nWorldBegin\nMaterial \"dielectric\" \"float eta\" 1.5\n{shape}\n"
    );
    let desc = kiln_scene::load_str(&text, "bench.pbrt".as_ref(), ".".as_ref()).unwrap();
    Scene::build(&desc, MediaPolicy::Render).unwrap()
}

/// The contour turned into `segments` quads round per strip.
fn mesh_text(c: &[(f64, f64)], segments: usize) -> String {
    let (mut p, mut idx) = (String::new(), String::new());
    for (i, &(r, z)) in c.iter().enumerate() {
        for k in 0..segments {
            let phi = 2.0 * PI * k as f64 / segments as f64;
            write!(p, "{} {} {} ", r * libm::cos(phi), r * libm::sin(phi), z).unwrap();
        }
        if i + 1 < c.len() {
            for k in 0..segments {
                let v = |row: usize, kk: usize| row * segments + kk % segments;
                let (a, b, cc, d) = (v(i, k), v(i, k + 1), v(i + 1, k + 1), v(i + 1, k));
                write!(idx, "{a} {b} {cc} {a} {cc} {d} ").unwrap();
            }
        }
    }
    format!("Shape \"trianglemesh\" \"point3 P\" [ {p}] \"integer indices\" [ {idx}]")
}

fn resident_mib() -> f64 {
    let s = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: f64 = s
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    pages * 4096.0 / (1 << 20) as f64
}

/// Rays from a sphere round the glass towards random points of its bounding box.
fn rays(n: usize) -> Vec<Ray> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n)
        .map(|_| {
            let d = kiln_render::sampling::uniform_sphere(Vec2::new(next(), next()));
            let origin = Vec3A::new(0.0, 0.0, 1.0) + d * 4.0;
            let target = Vec3A::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.1);
            Ray::new(origin, (target - origin).normalize())
        })
        .collect()
}

fn main() {
    let n: usize = arg("--rays", 1_000_000);
    let tolerance: f64 = arg("--tolerance", 1e-4);
    let contour = glass_contour();
    let rays = rays(n);
    let points: String = contour.iter().map(|(r, z)| format!("{r} {z} ")).collect();
    // The chord of one of `s` segments round falls short of the circle by r (1 - cos(π/s)).
    let accurate = (PI / libm::acos(1.0 - tolerance)).ceil() as usize;
    println!(
        "martini glass: {} contour points; mesh accuracy {tolerance} of the radius needs {accurate} segments round",
        contour.len()
    );
    let mut hits_of = Vec::new();
    // Every scene is kept to the end, so each one's resident growth is its own.
    let mut kept = Vec::new();
    for (label, shape) in [
        (
            "revolution".to_string(),
            format!("Shape \"revolution\" \"point2 contour\" [ {points}]"),
        ),
        (format!("mesh x{accurate}"), mesh_text(&contour, accurate)),
        (
            format!("mesh x{}", accurate / 4),
            mesh_text(&contour, accurate / 4),
        ),
    ] {
        let before = resident_mib();
        let start = Instant::now();
        let scene = scene(&shape);
        let build = start.elapsed().as_secs_f64();
        let memory = resident_mib() - before;
        let start = Instant::now();
        let hits: Vec<bool> = rays
            .iter()
            .map(|r| scene.geometry.intersect(r, f32::INFINITY).is_some())
            .collect();
        let secs = start.elapsed().as_secs_f64();
        let p = &scene.geometry.prims;
        let prims = p.quadrics.len() + p.triangle_vertices.len();
        // What the primitives hold (BVH nodes not counted): a quadric record per strip
        // sector; per triangle its indices, its mesh id and its copy in BVH order, and
        // the vertices.
        let data = p.quadrics.len() * std::mem::size_of::<kiln_render::shapes::Quadric>()
            + p.positions.len() * 16
            + p.triangle_vertices.len() * (12 + 4 + 4 + 48);
        println!(
            "{label:>14}: {prims:>7} primitives, {:.2} MiB of primitive data, build {build:.3} s, +{memory:.1} MiB resident, {:.2} M rays/s on one thread ({:.1}% hit)",
            data as f64 / (1 << 20) as f64,
            n as f64 / secs / 1e6,
            100.0 * hits.iter().filter(|h| **h).count() as f64 / n as f64
        );
        hits_of.push(hits);
        kept.push(scene);
    }
    let agree = hits_of[0]
        .iter()
        .zip(&hits_of[1])
        .filter(|(a, b)| a == b)
        .count();
    println!(
        "revolution and the accurate mesh agree on hit or miss for {:.4}% of rays",
        100.0 * agree as f64 / n as f64
    );
}
