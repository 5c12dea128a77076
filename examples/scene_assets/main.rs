//! Writes the generated assets of the scenes in `scenes/` (their outputs are committed, so a
//! fresh clone renders without running this):
//!
//! - `scenes/molten-glass/snail.ply` and `snail-grid.csv`: the glass snail (`snail.rs`), one
//!   closed surface of 124k triangles, and the heat of its glass;
//! - `scenes/fire/density.vol`, `scenes/fire/temperature.vol`: a flame for seed 001's
//!   emissive medium, in Mitsuba's .vol format;
//! - `scenes/lily-pond/pads.pbrt`: seed 004's lily pads (thin closed discs) and their stems
//!   (circles swept along curves of sines and cosines);
//! - `scenes/martini/glass.pbrt`: a martini glass and its drink, Kiln's surfaces of
//!   revolution from seed 003's three 2D contours, sharing one boundary by priority.
//!
//! `cargo run --release --example scene_assets`

mod snail;
mod vec3;
mod workbench;

use vec3::cross;

use std::f32::consts::PI;
use std::path::Path;

/// Seed 003's martini glass as its three contours, points (r, z) about the glass's own
/// vertical z axis, in order: glass-air (the foot from the axis out, the stem, the bowl's
/// outside, the rim, the bowl's inside down to the drink's surface), glass-drink (the bowl's
/// inside from the drink's surface down to the axis) and drink-air (the surface, from the
/// glass in to the axis). `fill` is the drink's height as a fraction of the bowl's.
struct MartiniContours {
    glass_air: Vec<(f32, f32)>,
    glass_drink: Vec<(f32, f32)>,
    drink_air: Vec<(f32, f32)>,
    /// The bowl's wall thickness (horizontal).
    wall: f32,
}

fn martini_contours(fill: f32) -> MartiniContours {
    let (joint, rim_z, rim_r, wall) = (1.05f32, 2.0f32, 1.0f32, 0.025f32);
    let outer = |z: f32| 0.08 + (z - joint) * (rim_r - 0.08) / (rim_z - joint);
    let inner = |z: f32| outer(z) - wall;
    let mut glass_air = vec![(0.0, 0.0)];
    // The foot: flat underneath, a rounded edge, rising to the stem.
    let (foot_r, foot_t) = (0.62f32, 0.035f32);
    glass_air.push((foot_r - foot_t / 2.0, 0.0));
    for i in 1..8 {
        let a = -PI / 2.0 + PI * i as f32 / 8.0;
        glass_air.push((
            foot_r - foot_t / 2.0 + foot_t / 2.0 * libm::cosf(a),
            foot_t / 2.0 + foot_t / 2.0 * libm::sinf(a),
        ));
    }
    glass_air.extend([
        (foot_r - foot_t / 2.0, foot_t),
        (0.45, 0.045),
        (0.25, 0.06),
        (0.12, 0.085),
        (0.065, 0.13),
        (0.045, 0.2),
        (0.038, 0.45),
        (0.04, 0.75),
        (0.05, 0.95),
        (0.065, 1.01),
    ]);
    // The bowl's outside, a cone up to the rim.
    let n = 24;
    for i in 0..=n {
        let z = joint + (rim_z - joint) * i as f32 / n as f32;
        glass_air.push((outer(z), z));
    }
    // The rim: a half round over the wall.
    for i in 1..8 {
        let a = PI * i as f32 / 8.0;
        glass_air.push((
            rim_r - wall / 2.0 + wall / 2.0 * libm::cosf(a),
            rim_z + wall / 2.0 * libm::sinf(a),
        ));
    }
    // The inside, down to the drink.
    let bottom = joint + 0.11;
    let surface = bottom + fill * (rim_z - bottom);
    for i in 0..=n {
        let z = rim_z + (surface - rim_z) * i as f32 / n as f32;
        glass_air.push((inner(z), z));
    }
    // Below the surface: the inside down to a rounded bottom on the axis.
    let mut glass_drink = Vec::new();
    for i in 0..=n {
        let z = surface + (bottom + 0.04 - surface) * i as f32 / n as f32;
        glass_drink.push((inner(z), z));
    }
    let last = inner(bottom + 0.04);
    for i in 1..=6 {
        let a = PI / 2.0 * i as f32 / 6.0;
        glass_drink.push((
            last * libm::cosf(a),
            bottom + 0.04 * libm::powf(1.0 - libm::sinf(a), 0.7),
        ));
    }
    glass_drink.last_mut().unwrap().0 = 0.0;
    let drink_air = vec![(inner(surface), surface), (0.0, surface)];
    MartiniContours {
        glass_air,
        glass_drink,
        drink_air,
        wall,
    }
}

/// The normal of a contour at each point: to the right of its direction of travel in the
/// (r, z) plane, averaged over the point's two strips.
fn contour_normals(c: &[(f32, f32)]) -> Vec<(f32, f32)> {
    let strip = |i: usize| {
        let (a, b) = (c[i], c[i + 1]);
        let (tr, tz) = (b.0 - a.0, b.1 - a.1);
        let l = libm::hypotf(tr, tz);
        (tz / l, -tr / l)
    };
    (0..c.len())
        .map(|i| {
            let (p, q) = match i {
                0 => (strip(0), strip(0)),
                i if i == c.len() - 1 => (strip(i - 1), strip(i - 1)),
                i => (strip(i - 1), strip(i)),
            };
            let (r, z) = (p.0 + q.0, p.1 + q.1);
            let l = libm::hypotf(r, z);
            (r / l, z / l)
        })
        .collect()
}

fn contour_text(c: &[(f32, f32)]) -> String {
    let mut s = String::new();
    for (i, (r, z)) in c.iter().enumerate() {
        if i % 6 == 0 {
            s.push_str("\n    ");
        }
        s.push_str(&format!("{r:.5} {z:.5}  "));
    }
    s
}

/// A martini glass and its drink in pbrt-v4's syntax with Kiln's nested dielectrics: the
/// glass is the closed contour glass-air + glass-drink (priority 2); the drink is closed by
/// glass-drink pushed half a wall into the glass and drink-air carried out to meet it
/// (priority 1), so inside the glass the drink's own boundary is hidden and the glass-drink
/// contour is the one boundary the two share. Uses the material "glass" and the medium
/// "drink", which the including scene defines.
fn martini_pbrt(c: &MartiniContours) -> String {
    let mut glass = c.glass_air.clone();
    glass.extend_from_slice(&c.glass_drink[1..]);
    // The drink: from the axis under the glass's bottom, out and up inside the wall, and
    // back along its surface.
    let push = c.wall / 2.0;
    let normals = contour_normals(&c.glass_drink);
    let mut drink: Vec<(f32, f32)> = c
        .glass_drink
        .iter()
        .zip(&normals)
        .map(|(p, n)| ((p.0 - n.0 * push).max(0.0), p.1 - n.1 * push))
        .rev()
        .collect();
    drink[0].0 = 0.0;
    let top = drink.last().unwrap().1;
    let surface = c.drink_air[0].1;
    drink.last_mut().unwrap().1 = top.max(surface);
    drink.push((0.0, surface));
    format!(
        "# A martini glass (seed 003), written by `cargo run --release --example scene_assets`:\n\
         # three contours, glass-air, glass-drink and drink-air, made into two closed surfaces\n\
         # of revolution that share the glass-drink boundary by priority.\n\
         AttributeBegin\n\
         \x20   NamedMaterial \"glass\"\n\
         \x20   Shape \"revolution\" \"integer priority\" 2 \"point2 contour\" [{}\n    ]\n\
         AttributeEnd\n\
         AttributeBegin\n\
         \x20   MediumInterface \"drink\" \"\"\n\
         \x20   NamedMaterial \"drink\"\n\
         \x20   Shape \"revolution\" \"integer priority\" 1 \"point2 contour\" [{}\n    ]\n\
         AttributeEnd\n",
        contour_text(&glass),
        contour_text(&drink)
    )
}

/// Seed 001's flame: density and temperature on a 40x64x40 grid.
fn fire() -> (kiln_scene::VoxelGrid, kiln_scene::VoxelGrid) {
    let (nx, ny, nz) = (40usize, 64usize, 40usize);
    let mut density = Vec::new();
    let mut temperature = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let u = (x as f32 + 0.5) / nx as f32 * 2.0 - 1.0;
                let v = (y as f32 + 0.5) / ny as f32;
                let w = (z as f32 + 0.5) / nz as f32 * 2.0 - 1.0;
                // Tongues: the radius wobbles with height and angle.
                let angle = libm::atan2f(w, u);
                let wobble = 1.0 + 0.25 * libm::sinf(5.0 * angle + 11.0 * v) * v;
                let sway = 0.15 * libm::sinf(6.0 * v) * v;
                let r =
                    libm::hypotf(u - sway, w) / ((0.8 * libm::powf(1.0 - v, 0.7) + 0.03) * wobble);
                let d = (1.0 - r * r).max(0.0) * (1.0 - 0.5 * v);
                density.push(d);
                temperature.push(if d > 0.0 {
                    800.0 + 1800.0 * (1.0 - r).max(0.0) * (1.0 - 0.55 * v)
                } else {
                    300.0
                });
            }
        }
    }
    let grid = |values| kiln_scene::VoxelGrid { nx, ny, nz, values };
    (grid(density), grid(temperature))
}

/// Seed 004's lily pads and their stems, in pbrt-v4's syntax: `count` pads scattered on the
/// water (y = 0), each a thin closed disc with its notch, its edge curling up a little, and
/// under each a stem: a circle swept along a curve of sines and cosines down to the pond's
/// floor (pbrt-v4's `curve` of type cylinder, a b-spline). The including scene defines the
/// materials "pad" and "stem".
fn lily_pads(count: usize) -> String {
    let mut out = String::from(
        "# Lily pads and stems (seed 004), written by `cargo run --release --example scene_assets`.\n",
    );
    // A fixed little generator, so the pond is the same on every run.
    let mut state = 0x1234_5678_9abc_def1u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut placed: Vec<(f32, f32, f32)> = Vec::new();
    while placed.len() < count {
        let (x, z) = (uniform() * 6.0 - 3.0, uniform() * 5.0 - 3.5);
        let r = 0.3 + 0.3 * uniform();
        if placed
            .iter()
            .all(|&(px, pz, pr)| libm::hypotf(x - px, z - pz) > (r + pr) * 1.02)
        {
            placed.push((x, z, r));
        }
    }
    for (k, &(cx, cz, radius)) in placed.iter().enumerate() {
        let turn = uniform() * 2.0 * PI;
        let notch = 0.35f32;
        let n = 40;
        let thick = 0.012f32;
        // The outline: the centre, then the rim from one side of the notch to the other.
        let mut p: Vec<[f32; 3]> = Vec::new();
        let mut idx: Vec<[usize; 3]> = Vec::new();
        // The pad floats a hair above the water's surface (coincident surfaces would leave
        // which one a ray meets to rounding).
        let lift = |r: f32| 0.004 + 0.04 * (r / radius).powi(4);
        let rim = |i: usize, y: f32| -> [f32; 3] {
            let a = turn + notch / 2.0 + (2.0 * PI - notch) * i as f32 / n as f32;
            [
                cx + radius * libm::cosf(a),
                y + lift(radius),
                cz + radius * libm::sinf(a),
            ]
        };
        // Top (0..=n, centre n+1), bottom (n+2..=2n+2, centre 2n+3).
        for i in 0..=n {
            p.push(rim(i, thick));
        }
        p.push([cx, thick + lift(0.0), cz]);
        for i in 0..=n {
            p.push(rim(i, 0.0));
        }
        p.push([cx, lift(0.0), cz]);
        let (top_c, bot0, bot_c) = (n + 1, n + 2, 2 * n + 3);
        let mut face = |a: usize, b: usize, c: usize, out_dir: [f32; 3], p: &[[f32; 3]]| {
            // Kiln (as pbrt-v4) faces a triangle by (p0 - p2) x (p1 - p2).
            let u = [p[a][0] - p[c][0], p[a][1] - p[c][1], p[a][2] - p[c][2]];
            let v = [p[b][0] - p[c][0], p[b][1] - p[c][1], p[b][2] - p[c][2]];
            let nrm = cross(u, v);
            let d = nrm[0] * out_dir[0] + nrm[1] * out_dir[1] + nrm[2] * out_dir[2];
            idx.push(if d >= 0.0 { [a, b, c] } else { [a, c, b] });
        };
        for i in 0..n {
            face(top_c, i, i + 1, [0.0, 1.0, 0.0], &p);
            face(bot_c, bot0 + i, bot0 + i + 1, [0.0, -1.0, 0.0], &p);
            // The rim, facing out from the centre.
            let a = rim(i, 0.0);
            let out_dir = [a[0] - cx, 0.0, a[2] - cz];
            face(i, i + 1, bot0 + i + 1, out_dir, &p);
            face(i, bot0 + i + 1, bot0 + i, out_dir, &p);
        }
        // The notch's two cut faces and its point at the centre.
        for (i, side) in [(0usize, -1.0f32), (n, 1.0)] {
            let a = rim(i, 0.0);
            let (dx, dz) = (a[0] - cx, a[2] - cz);
            // Perpendicular to the cut, pointing into the notch.
            let out_dir = [-dz * side, 0.0, dx * side];
            face(i, top_c, bot_c, out_dir, &p);
            face(i, bot_c, bot0 + i, out_dir, &p);
        }
        let points: String = p
            .iter()
            .map(|v| format!("{:.5} {:.5} {:.5}  ", v[0], v[1], v[2]))
            .collect();
        let indices: String = idx
            .iter()
            .map(|t| format!("{} {} {}  ", t[0], t[1], t[2]))
            .collect();
        out.push_str(&format!(
            "# pad {k}\nAttributeBegin\n    NamedMaterial \"pad\"\n    Shape \"trianglemesh\" \"point3 P\" [ {points}]\n        \"integer indices\" [ {indices}]\nAttributeEnd\n"
        ));
        // The stem: from under the pad's centre down to the floor, swaying.
        let phase = uniform() * 2.0 * PI;
        let stem: String = (0..10)
            .map(|i| {
                let t = i as f32 / 9.0;
                let x = cx + 0.18 * libm::sinf(3.0 * t + phase) * t;
                let z = cz + 0.14 * libm::cosf(2.0 * t + phase) * t - 0.14 * libm::cosf(phase) * t;
                format!("{x:.4} {:.4} {z:.4}  ", -0.02 - 1.9 * t)
            })
            .collect();
        out.push_str(&format!(
            "AttributeBegin\n    NamedMaterial \"stem\"\n    Shape \"curve\" \"string basis\" \"bspline\" \"string type\" \"cylinder\" \"float width\" [ 0.05 ]\n        \"point3 P\" [ {stem}]\nAttributeEnd\n"
        ));
    }
    out
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let snail = snail::Snail::new(snail::SnailParams::default());
    let mesh = snail::mesh(&snail);
    mesh.write_ply(&root.join("molten-glass/snail.ply"));
    let bench = workbench::WorkbenchParams::default();
    let scene = root.join("molten-glass/scene.pbrt");
    std::fs::write(&scene, workbench::scene(&bench)).unwrap();
    println!("wrote {}", scene.display());
    workbench::wood_png(&root.join("molten-glass/wood.png"));
    let grid = root.join("molten-glass/snail-grid.csv");
    std::fs::write(&grid, snail::heat_grid(&snail, &mesh, [32, 24, 20])).unwrap();
    println!("wrote {}", grid.display());
    let glass = root.join("martini/glass.pbrt");
    std::fs::write(&glass, martini_pbrt(&martini_contours(0.72))).unwrap();
    println!("wrote {}", glass.display());
    let pads = root.join("lily-pond/pads.pbrt");
    std::fs::create_dir_all(pads.parent().unwrap()).unwrap();
    std::fs::write(&pads, lily_pads(9)).unwrap();
    println!("wrote {}", pads.display());
    let (density, temperature) = fire();
    let bbox = ([-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]);
    for (name, grid) in [("density.vol", &density), ("temperature.vol", &temperature)] {
        let path = root.join("fire").join(name);
        std::fs::write(&path, kiln_scene::files::vol::write_vol(grid, bbox)).unwrap();
        println!("wrote {}", path.display());
    }
}
