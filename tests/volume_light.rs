//! The VolumeLight (seed 000): analytic chords, estimator agreement, power estimates,
//! voxel grids.

use crate::util::{assert_strategies_agree, render, render_strategies, write_scene};
use kiln_render::lights::volume::power_estimates;
use kiln_render::{MediaPolicy, Scene};
use std::path::Path;

/// A unit-Le VolumeLight seen through a tiny orthographic window at impact parameter `b`.
fn chord_scene(shape_and_material: &str, b: f64) -> String {
    format!(
        "Sampler \"zsobol\" \"integer pixelsamples\" [ 1 ]
        PixelFilter \"box\"
        Film \"rgb\" \"integer xresolution\" [ 2 ] \"integer yresolution\" [ 2 ]
        LookAt {b} 0 10  {b} 0 0  0 1 0
        Camera \"orthographic\" \"float screenwindow\" [ -0.0001 0.0001 -0.0001 0.0001 ]
        WorldBegin
        AttributeBegin
        AreaLightSource \"volume\" \"rgb Le\" [ 1 2 3 ] \"float scale\" [ 0.5 ]
        {shape_and_material}
        AttributeEnd"
    )
}

/// Through an index-matched surface a ray sees Le times the chord: 2 Le sqrt(r^2 - b^2).
/// Per RGB channel, as the closed form is: in RGB mode (spectrally, Le's round trip through
/// a spectrum and the four wavelengths' noise come on top).
#[test]
fn index_matched_sphere_shows_le_times_the_chord() {
    let dir = tempfile::tempdir().unwrap();
    let r = 1.5;
    for material in [
        "Material \"dielectric\" \"float eta\" [ 1 ]",
        "Material \"interface\"",
    ] {
        for b in [0.0, 0.5, 1.0, 1.4, 1.49] {
            let text = chord_scene(
                &format!("{material}\nShape \"sphere\" \"float radius\" [ {r} ]"),
                b,
            );
            let path = write_scene(dir.path(), "chord.pbrt", &text);
            let img = render(&path, dir.path(), "chord", &["--rgb"]).image;
            let chord = 2.0 * (r * r - b * b).sqrt();
            for (c, le) in [0.5, 1.0, 1.5].iter().enumerate() {
                let expected = le * chord;
                let got = img.mean()[c];
                assert!(
                    (got - expected).abs() <= 0.005 * expected,
                    "{material}, b = {b}: {got} vs {expected}"
                );
            }
        }
    }
    // A cube mesh seen face on: every ray's chord is the cube's side.
    let cube = "Material \"interface\"
        Shape \"trianglemesh\" \"point3 P\" [ -1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1 ]
        \"integer indices\" [ 0 2 1 0 3 2  4 5 6 4 6 7  0 1 5 0 5 4  2 3 7 2 7 6  1 2 6 1 6 5  0 4 7 0 7 3 ]";
    for b in [0.0, 0.7] {
        let path = write_scene(dir.path(), "cube.pbrt", &chord_scene(cube, b));
        let img = render(&path, dir.path(), "cube", &["--rgb"]).image;
        assert!(
            (img.mean()[1] - 2.0).abs() < 0.01,
            "cube at b = {b}: {}",
            img.mean()[1]
        );
    }
}

/// Light sampling alone, BSDF sampling alone and MIS estimate the same floor illumination
/// from a glass VolumeLight: the image means agree within three standard errors, and
/// every block within 4.5 (24 comparisons per pair).
fn glass_strategies_agree(path: &Path, args: &[&str]) {
    // Depth 4 takes paths into the glass, through internal reflections and out again.
    let images = render_strategies(path, "path", 4, 11, true, args);
    assert_strategies_agree(&path.display().to_string(), &images, 4.5, Some(3.0));
}

#[test]
fn glass_volume_light_sphere_strategies_agree() {
    glass_strategies_agree(
        &crate::util::scene("volume-light/glass-sphere.pbrt"),
        &["--spp", "128"],
    );
}

/// The same spectrally, with an interior that absorbs in colour: a VolumeLight's radiance at
/// a spectral path's wavelengths is the same function for light sampling and for paths
/// that reach its surface.
#[test]
fn glass_volume_light_sphere_strategies_agree_spectrally() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(crate::util::scene("volume-light/glass-sphere.pbrt"))
        .unwrap()
        .replace(
            "\"rgb Le\" [ 4 1.6 0.4 ]",
            "\"rgb Le\" [ 4 1.6 0.4 ] \"rgb sigma_a\" [ 0.2 0.9 1.5 ]",
        );
    assert!(text.contains("sigma_a"));
    let path = write_scene(dir.path(), "absorbing.pbrt", &text);
    glass_strategies_agree(&path, &["--spp", "128", "--spectral"]);
}

/// The same with a triangle mesh, where every face is its own light chosen by estimated power.
#[test]
fn glass_volume_light_mesh_strategies_agree() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(crate::util::scene("volume-light/glass-sphere.pbrt"))
        .unwrap()
        .replace(
            "Shape \"sphere\" \"float radius\" [ 1 ]",
            &format!("Shape \"trianglemesh\" {}", uv_sphere(1.0, 24, 48)),
        );
    let path = write_scene(dir.path(), "mesh.pbrt", &text);
    glass_strategies_agree(&path, &["--spp", "128", "--resolution", "72x48", "--rgb"]);
}

/// A UV sphere as trianglemesh parameters (with smooth normals), `2 * rings * segments` faces
/// less the degenerate ones at the poles.
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> String {
    let mut p = Vec::new();
    let mut n = Vec::new();
    for i in 0..=rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            let v = [
                libm::sin(theta) * libm::cos(phi),
                libm::cos(theta),
                libm::sin(theta) * libm::sin(phi),
            ];
            p.push(format!("{} {} {}", r * v[0], r * v[1], r * v[2]));
            n.push(format!("{} {} {}", v[0], v[1], v[2]));
        }
    }
    let mut idx = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            // Outward-facing winding (pbrt's normal is (p0 - p2) x (p1 - p2)).
            if i != 0 {
                idx.push(format!("{a} {b} {c}"));
            }
            if i != rings - 1 {
                idx.push(format!("{b} {d} {c}"));
            }
        }
    }
    format!(
        "\"point3 P\" [ {} ] \"normal N\" [ {} ] \"integer indices\" [ {} ]",
        p.join(" "),
        n.join(" "),
        idx.join(" ")
    )
}

/// Mesh volume by the divergence theorem.
fn mesh_volume(positions: &[[f32; 3]], indices: &[u32]) -> f64 {
    indices
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize].map(|v| v as f64));
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0
        })
        .sum::<f64>()
        .abs()
}

/// The summed face powers of a uniformly emitting sphere mesh equal the emitted power,
/// 4 pi Le V (per unit Le of luminance); per-face estimates hardly move with the seed.
#[test]
fn face_powers_sum_to_the_analytic_power() {
    let text = format!(
        "WorldBegin
        AttributeBegin
        AreaLightSource \"volume\" \"rgb Le\" [ 2 2 2 ]
        Material \"dielectric\" \"float eta\" [ 1.5 ]
        Shape \"trianglemesh\" {}
        AttributeEnd",
        uv_sphere(1.3, 24, 48)
    );
    let desc = kiln_scene::load_str(&text, Path::new("power.pbrt"), Path::new(".")).unwrap();
    let kiln_scene::ShapeKind::Mesh(mesh) = &desc.shapes[0].kind else {
        panic!()
    };
    let faces = mesh.indices.len() / 3;
    assert!(faces >= 1000, "{faces} faces");
    let scene = Scene::build(&desc, MediaPolicy::Ignore).unwrap();
    let analytic = 4.0 * std::f64::consts::PI * 2.0 * mesh_volume(&mesh.positions, &mesh.indices);
    let a: Vec<f64> = power_estimates(&scene.lights, &scene.light_context(), 1)
        .into_iter()
        .flatten()
        .map(|p| p as f64)
        .collect();
    let b: Vec<f64> = power_estimates(&scene.lights, &scene.light_context(), 2)
        .into_iter()
        .flatten()
        .map(|p| p as f64)
        .collect();
    assert_eq!(a.len(), faces);
    for est in [&a, &b] {
        let total: f64 = est.iter().sum();
        assert!(
            (total - analytic).abs() < 0.03 * analytic,
            "summed power {total} vs analytic {analytic}"
        );
    }
    let mut rel: Vec<f64> = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs() / x.max(*y))
        .collect();
    rel.sort_by(f64::total_cmp);
    assert!(
        rel[rel.len() / 2] < 0.05,
        "median per-face change across seeds: {}",
        rel[rel.len() / 2]
    );
    // The scene's own estimates are what its light sampler uses.
    let used: f64 = scene
        .lights
        .iter()
        .map(|l| l.power(scene.radius) as f64)
        .sum();
    assert!((used - analytic).abs() < 0.03 * analytic);
}

/// A 3x3x3 grid with one hot voxel on the +x side renders its hot spot there: with this
/// camera (pbrt's LookAt, left-handed) world +x is the image's left.
#[test]
fn hot_voxel_renders_where_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("# 3x3x3, x fastest\n3, 3, 3\n");
    for z in 0..3 {
        for y in 0..3 {
            let row: Vec<&str> = (0..3)
                .map(|x| if (x, y, z) == (2, 1, 1) { "20" } else { "1" })
                .collect();
            csv.push_str(&row.join(", "));
            csv.push('\n');
        }
    }
    std::fs::write(dir.path().join("hot.csv"), csv).unwrap();
    let text = "Sampler \"zsobol\" \"integer pixelsamples\" [ 4 ]
        Film \"rgb\" \"integer xresolution\" [ 30 ] \"integer yresolution\" [ 30 ]
        LookAt 0 0 10  0 0 0  0 1 0
        Camera \"orthographic\" \"float screenwindow\" [ -1 1 -1 1 ]
        WorldBegin
        AreaLightSource \"volume\" \"rgb Le\" [ 1 1 1 ] \"string grid\" \"hot.csv\" \"integer steps\" [ 64 ]
        Material \"interface\"
        Shape \"sphere\" \"float radius\" [ 1 ]";
    let path = write_scene(dir.path(), "grid.pbrt", text);
    let img = render(&path, dir.path(), "grid", &[]).image;
    let third = |x0: u32, y0: u32| crate::util::block_stats(&img, x0, y0, 10, 10, 0).0;
    let left = third(0, 10);
    let right = third(20, 10);
    let centre = third(10, 10);
    assert!(left > 3.0 * right, "hot side {left}, cold side {right}");
    assert!(
        third(0, 0) < 0.5 * left && third(0, 20) < 0.5 * left,
        "the hot spot is in the middle row"
    );
    assert!(
        centre > right,
        "the centre, nearer the hot voxel, outshines the cold side"
    );
}

#[test]
fn volume_light_errors_name_their_place() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.csv"), "2,2,1\n1,1\n1\n").unwrap();
    let cases = [
        (
            "WorldBegin\nMaterial \"dielectric\"\nAreaLightSource \"volume\"\nScale 1 2 1\nShape \"sphere\"\n",
            "scene.pbrt:5:",
            "non-uniform scale",
        ),
        (
            "WorldBegin\nAreaLightSource \"volume\" \"string grid\" \"bad.csv\"\nShape \"sphere\"\n",
            "scene.pbrt:2:",
            "bad.csv', line 3",
        ),
        (
            "WorldBegin\nAreaLightSource \"volume\"\nMaterial \"diffuse\"\nShape \"sphere\"\n",
            "scene.pbrt:4:",
            "needs a smooth \"dielectric\"",
        ),
        (
            "WorldBegin\nAreaLightSource \"volume\" \"integer steps\" [ 0 ]\n",
            "scene.pbrt:2:",
            "steps 0",
        ),
    ];
    for (text, at, what) in cases {
        let err = crate::util::failing_in(dir.path(), text);
        assert!(
            err.contains(at) && err.contains(what),
            "expected {at} and {what} in {err}"
        );
    }
}

/// The headline snail (scenes/molten-glass/snail.ply) is one connected closed surface, consistently
/// oriented and facing out: every edge is shared by exactly two faces that run along it in
/// opposite directions, no face is degenerate, the enclosed volume is positive, and the
/// vertex normals (which pbrt-v4's geometric normals follow) agree with the winding. Its
/// VolumeLight has the seed's 120,000 or more emitting faces.
#[test]
fn the_headline_snail_is_one_closed_outward_surface() {
    let path = crate::util::scene("molten-glass/snail.ply");
    let mesh = kiln_scene::files::ply::read_ply(&path, &kiln_scene::Loc::synthetic("snail"))
        .unwrap_or_else(|e| panic!("{e}"));
    let faces: Vec<[u32; 3]> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    assert!(faces.len() >= 120_000, "{} faces", faces.len());
    assert!(mesh.quads.is_empty());
    let mut directed = std::collections::HashMap::<(u32, u32), u32>::new();
    for f in &faces {
        for k in 0..3 {
            *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "edge {a}-{b} runs the same way in {n} faces");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge {a}-{b} has no face running back along it: the surface is open there"
        );
    }
    let p = |i: u32| glam::DVec3::from(mesh.positions[i as usize].map(f64::from));
    let normals = mesh.normals.as_ref().expect("the snail has vertex normals");
    let n = |i: u32| glam::DVec3::from(normals[i as usize].map(f64::from));
    let (mut volume, mut disagree) = (0.0, 0);
    for f in &faces {
        let [a, b, c] = f.map(p);
        let face = (a - c).cross(b - c);
        assert!(face.length() > 0.0, "a degenerate face {f:?}");
        volume += a.dot(b.cross(c)) / 6.0;
        if face.dot(n(f[0]) + n(f[1]) + n(f[2])) < 0.0 {
            disagree += 1;
        }
    }
    assert!(volume > 0.5, "enclosed volume {volume}");
    assert_eq!(
        disagree, 0,
        "faces whose winding disagrees with their normals"
    );
    // One surface, not several closed pieces that touch (the coiled tube, body and
    // feelers the snail was before were four): every face reaches every other by edges.
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn root(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for f in &faces {
        for k in 0..2 {
            let (a, b) = (root(&mut parent, f[k]), root(&mut parent, f[k + 1]));
            parent[a as usize] = b;
        }
    }
    let pieces: std::collections::HashSet<u32> =
        faces.iter().map(|f| root(&mut parent, f[0])).collect();
    assert_eq!(
        pieces.len(),
        1,
        "the snail is {} separate surfaces",
        pieces.len()
    );
}
