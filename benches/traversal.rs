//! BVH traversal alone, the part of a render the profiles put first: Kiln's closest-hit and
//! any-hit rays per second over a scene's triangles, on one thread, with no shading. The
//! triangles and rays are written to target/traversal/ so that another tracer can trace the
//! very same set (benches/embree/ does, for the physical limit the issue asks about).
//!
//! The rays: one camera ray through every pixel of a 512-pixel-wide frame (jittered within
//! the pixel), then from each point they hit one ray in a uniformly random direction, half
//! of them into the surface (for the snail's glass, the interior chords paths trace). The
//! secondary rays start 1e-4 of the scene's size off the surface, on the side they leave.
//!
//! A third scene is made here: a UV sphere of about a million triangles (`--sphere-rings
//! 500`; 0 leaves it out), for the build time and memory a large mesh costs.
//!
//! `cargo bench --bench traversal [-- --width N --repeats N --sphere-rings N]`

mod common;
use common::{arg, write_sphere_ply};
use glam::{Vec2, Vec3A};
use kiln_render::shapes::{Geometry, Primitives};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A ray as both tracers take it.
#[derive(Clone, Copy, Debug)]
struct TestRay {
    origin: Vec3A,
    dir: Vec3A,
}

/// A small deterministic generator (SplitMix64), so that every run traces the same rays.
struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let width = arg("--width", 512u32);
    let repeats = arg("--repeats", 5usize);
    let scenes = [
        (
            "cornell",
            root.join("../shared/reference-scenes/cornell-box/scene.pbrt"),
        ),
        ("snail", root.join("scenes/molten-glass/scene.pbrt")),
    ];
    let out_dir = root.join("target/traversal");
    std::fs::create_dir_all(&out_dir).expect("target/traversal can be made");
    let rings = arg("--sphere-rings", 500usize);
    let mut scenes = scenes.to_vec();
    if rings > 0 {
        write_sphere_ply(&out_dir.join("sphere.ply"), rings, 2 * rings);
        let scene = out_dir.join("sphere.pbrt");
        std::fs::write(
            &scene,
            "LookAt 0 0.5 4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 512 ] \"integer yresolution\" [ 512 ]\n\
             WorldBegin\nShape \"plymesh\" \"string filename\" \"sphere.ply\"\n",
        )
        .expect("the sphere's scene is written");
        scenes.push(("sphere", scene));
    }
    for (name, path) in scenes {
        if !path.exists() {
            println!(
                "SKIPPED {name}: {} is not present (../shared exists beside the checkout and in CI only)",
                path.display()
            );
            continue;
        }
        bench_scene(name, &path, width, repeats, &out_dir);
    }
}

fn bench_scene(name: &str, path: &Path, width: u32, repeats: usize, out_dir: &Path) {
    let mut desc = kiln_scene::load_file(path).expect("the scene loads");
    let (xres, yres) = (desc.film.xresolution, desc.film.yresolution);
    let height = (width as f32 * yres as f32 / xres as f32).round() as u32;
    desc.film.xresolution = width;
    desc.film.yresolution = height;
    desc.film.pixel_bounds = [0, width, 0, height];
    let renderer = kiln_render::Renderer::build(&desc).expect("the scene builds");
    let scene = renderer.scene();
    let prims = &scene.geometry.prims;
    // The triangles alone, in their own BVH: what Embree is given too.
    let start = Instant::now();
    let geometry = Geometry::new(Primitives {
        positions: prims.positions.clone(),
        triangle_vertices: prims.triangle_vertices.clone(),
        ..Primitives::default()
    });
    let build_s = start.elapsed().as_secs_f64();
    let (lo, hi) = geometry.bounds();
    let eps = 1e-4 * (hi - lo).max_element();

    let mut rng = Rng(0x6b69_6c6e);
    let mut rays = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let film = Vec2::new(x as f32 + rng.f(), y as f32 + rng.f());
            let r = scene.camera.generate_ray(film, Vec2::splat(0.5));
            rays.push(TestRay {
                origin: r.origin,
                dir: r.dir,
            });
        }
    }
    let primary = rays.len();
    for i in 0..primary {
        let r = rays[i];
        let ray = kiln_render::math::Ray::new(r.origin, r.dir);
        let Some(hit) = scene.geometry.intersect(&ray, f32::INFINITY) else {
            continue;
        };
        let z = 1.0 - 2.0 * rng.f();
        let phi = std::f32::consts::TAU * rng.f();
        let s = (1.0 - z * z).max(0.0).sqrt();
        let dir = Vec3A::new(s * libm::cosf(phi), s * libm::sinf(phi), z);
        let side = if dir.dot(hit.ng) >= 0.0 { 1.0 } else { -1.0 };
        rays.push(TestRay {
            origin: hit.p + hit.ng * (side * eps),
            dir,
        });
    }

    // Closest hits, then any hit, each timed over the whole set on this thread.
    let closest = |geometry: &Geometry| {
        let (mut hits, mut t_sum) = (0u64, 0f64);
        for r in &rays {
            let ray = kiln_render::math::Ray::new(r.origin, r.dir);
            if let Some(t) = geometry.hit_distance(&ray, f32::INFINITY) {
                hits += 1;
                t_sum += t as f64;
            }
        }
        (hits, t_sum)
    };
    let any = || {
        rays.iter()
            .filter(|r| !geometry.unoccluded(r.origin, r.dir, f32::INFINITY, 0.0))
            .count()
    };
    let best = |f: &dyn Fn() -> f64| {
        (0..repeats)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(f());
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let (hits, t_sum) = closest(&geometry);
    let blocked = any();
    let closest_s = best(&|| closest(&geometry).1);
    let any_s = best(&|| any() as f64);
    // The design before Kiln's wide BVH, over the same triangles, for comparison: obvhs's
    // compressed 8-wide BVH, walked nearest child first for closest hits and by obvhs's own
    // walk for any hit.
    let triangles = geometry.triangle_count();
    let tris: Vec<obvhs::triangle::Triangle> = prims
        .triangle_vertices
        .iter()
        .map(|v| obvhs::triangle::Triangle {
            v0: prims.positions[v[0] as usize],
            v1: prims.positions[v[1] as usize],
            v2: prims.positions[v[2] as usize],
        })
        .collect();
    let params = obvhs::BvhBuildParams {
        pre_split: true,
        ..obvhs::BvhBuildParams::medium_build()
    };
    let cw_start = Instant::now();
    let cw = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &tris,
        params,
        &mut std::time::Duration::default(),
    );
    let cw_build_s = cw_start.elapsed().as_secs_f64();
    let rt: Vec<obvhs::rt_triangle::RtTriangle> = cw
        .primitive_indices
        .iter()
        .map(|&i| obvhs::rt_triangle::RtTriangle::from(&tris[i as usize]))
        .collect();
    let cw_closest = || {
        let (mut hits, mut t_sum) = (0u64, 0f64);
        for r in &rays {
            let ray = obvhs::ray::Ray::new(r.origin, r.dir + Vec3A::ZERO, 0.0, f32::INFINITY);
            if let Some((t, _)) =
                kiln_render::shapes::traverse::closest(&cw, ray, |r, slot| rt[slot].intersect(r))
            {
                hits += 1;
                t_sum += t as f64;
            }
        }
        (hits, t_sum)
    };
    let cw_any = || {
        rays.iter()
            .filter(|r| {
                let ray = obvhs::ray::Ray::new(r.origin, r.dir + Vec3A::ZERO, 0.0, f32::INFINITY);
                !cw.ray_traverse_miss(ray, |r, slot| rt[slot].intersect(r))
            })
            .count()
    };
    // The two differ only where the CWBVH cannot see: obvhs clamps a box's entry to 1e-4,
    // so it misses hits nearer than that (rays leaving a corner of the Cornell box for the
    // wall beside it); the wide BVH finds every hit the triangle test gives.
    // Where the two differ, the wide BVH's hit is the nearer: obvhs clamps a box's entry to
    // 1e-4, so the CWBVH misses hits nearer than that (rays leaving a corner of the Cornell
    // box for the wall beside it), and of two triangles a ray meets at a shared edge it keeps
    // the one it tested first, where the wide BVH keeps the nearer.
    let (mut only_ours, mut nearer) = (0, 0);
    for r in &rays {
        let ray = obvhs::ray::Ray::new(r.origin, r.dir + Vec3A::ZERO, 0.0, f32::INFINITY);
        let theirs =
            kiln_render::shapes::traverse::closest(&cw, ray, |r, slot| rt[slot].intersect(r));
        let ours =
            geometry.hit_distance(&kiln_render::math::Ray::new(r.origin, r.dir), f32::INFINITY);
        match (theirs.map(|h| h.0), ours) {
            (a, b) if a == b => {}
            (None, Some(t)) if t < 1e-4 => only_ours += 1,
            (Some(a), Some(b)) if b < a => nearer += 1,
            (a, b) => panic!("ray {r:?}: the CWBVH finds {a:?}, the wide BVH {b:?}"),
        }
    }
    let (cw_hits, cw_t_sum) = cw_closest();

    let cw_blocked = cw_any();
    let cw_closest_s = best(&|| cw_closest().1);
    let cw_any_s = best(&|| cw_any() as f64);
    let wide_bytes = geometry.bvh_bytes();
    let cw_bytes = cw.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
        + rt.len() * (std::mem::size_of::<obvhs::rt_triangle::RtTriangle>() + 4);
    println!(
        "traversal scene={name} triangles={} rays={} primary={primary} build_s={build_s:.3} cwbvh_build_s={cw_build_s:.3} \
         closest_hits={hits} closest_t_sum={t_sum:.6} cwbvh_closest_hits={cw_hits} \
         hits_only_within_1e-4={only_ours} nearer_at_shared_edges={nearer} \
         cwbvh_closest_t_sum={cw_t_sum:.6} blocked={blocked} cwbvh_blocked={cw_blocked} closest_rays_per_s={:.0} any_rays_per_s={:.0} \
         cwbvh_closest_rays_per_s={:.0} cwbvh_any_rays_per_s={:.0} \
         bytes_per_triangle={:.1} cwbvh_bytes_per_triangle={:.1}",
        triangles,
        rays.len(),
        rays.len() as f64 / closest_s,
        rays.len() as f64 / any_s,
        rays.len() as f64 / cw_closest_s,
        rays.len() as f64 / cw_any_s,
        wide_bytes as f64 / triangles as f64,
        cw_bytes as f64 / triangles as f64,
    );

    // For benches/embree: u32 count then f32 v0 v1 v2 per triangle; u32 count then
    // f32 origin, direction, tmin, tmax per ray (little-endian).
    let mut mesh = Vec::new();
    mesh.extend((prims.triangle_vertices.len() as u32).to_le_bytes());
    for tri in &prims.triangle_vertices {
        for &v in tri {
            for c in prims.positions[v as usize].to_array() {
                mesh.extend(c.to_le_bytes());
            }
        }
    }
    let mut ray_bytes = Vec::new();
    ray_bytes.extend((rays.len() as u32).to_le_bytes());
    for r in &rays {
        for c in r.origin.to_array().into_iter().chain(r.dir.to_array()) {
            ray_bytes.extend(c.to_le_bytes());
        }
        ray_bytes.extend(0f32.to_le_bytes());
        ray_bytes.extend(f32::INFINITY.to_le_bytes());
    }
    for (ext, bytes) in [("mesh", &mesh), ("rays", &ray_bytes)] {
        let p = out_dir.join(format!("{name}.{ext}"));
        std::fs::File::create(&p)
            .and_then(|mut f| f.write_all(bytes))
            .unwrap_or_else(|e| panic!("writing {}: {e}", p.display()));
    }
}
