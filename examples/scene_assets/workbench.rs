//! The headline frame's setting (seed 000): a glassblower's bench before the furnace, with
//! the glass snail on a steel marver, the tools of the trade around it, a gather glowing on
//! its blowpipe, and the glory hole burning behind. Written as a pbrt-v4 scene
//! (`scenes/molten-glass/scene.pbrt`) with its wood texture (`wood.png`).

use crate::vec3::{cross, sub};
use std::f32::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// What a reader may change.
#[derive(Clone, Copy, Debug)]
pub struct WorkbenchParams {
    pub resolution: (u32, u32),
    pub spp: u32,
    /// The glass's emission (linear RGB) before the heat grid scales it.
    pub glass_le: [f32; 3],
    /// The glory hole's radiance.
    pub furnace_l: [f32; 3],
    /// The cool fill light's radiance (a window to the front left).
    pub fill_l: [f32; 3],
    /// The lens's radius (depth of field; the focus is on the snail).
    pub lens_radius: f32,
}

impl Default for WorkbenchParams {
    fn default() -> Self {
        WorkbenchParams {
            resolution: (2880, 1920),
            spp: 2048,
            glass_le: [1.2, 0.36, 0.07],
            furnace_l: [4.0, 1.5, 0.35],
            fill_l: [4.5, 6.0, 9.5],
            lens_radius: 0.035,
        }
    }
}

/// A box from `lo` to `hi` as a pbrt-v4 triangle mesh, faces outward.
fn cuboid(lo: [f32; 3], hi: [f32; 3]) -> String {
    // Corners numbered x + 2y + 4z.
    let corner = |i: usize| [0, 1, 2].map(|a| if (i >> a) & 1 == 1 { hi[a] } else { lo[a] });
    let mut idx = Vec::new();
    for axis in 0..3 {
        for side in 0..2 {
            // The face's four corners, in order around it.
            let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
            let quad =
                [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(a, b)| (side << axis) | (a << u) | (b << w));
            for t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                // pbrt-v4 faces a triangle by (p0 - p2) x (p1 - p2): flip it if that points in.
                let [p0, p1, p2] = t.map(corner);
                let n = cross(sub(p0, p2), sub(p1, p2));
                let out = if side == 1 {
                    n[axis] > 0.0
                } else {
                    n[axis] < 0.0
                };
                idx.extend(if out { t } else { [t[0], t[2], t[1]] });
            }
        }
    }
    let p: Vec<String> = (0..8)
        .map(|i| {
            let c = corner(i);
            format!("{} {} {}", c[0], c[1], c[2])
        })
        .collect();
    let i: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
    format!(
        "Shape \"trianglemesh\" \"point3 P\" [ {} ]\n    \"integer indices\" [ {} ]\n",
        p.join("  "),
        i.join(" ")
    )
}

/// A closed cylinder of radius `r` from `a` to `b`: pbrt-v4's open cylinder and two disks,
/// placed by a transform.
fn rod(a: [f32; 3], b: [f32; 3], r: f32) -> String {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    // Rotate z onto d: about z x d by the angle between them.
    let axis = [-d[1], d[0], 0.0];
    let angle = libm::acosf((d[2] / l).clamp(-1.0, 1.0)) * 180.0 / PI;
    let rotate = if axis[0] == 0.0 && axis[1] == 0.0 {
        if d[2] < 0.0 {
            "Rotate 180 1 0 0\n".to_string()
        } else {
            String::new()
        }
    } else {
        format!("Rotate {angle} {} {} 0\n", axis[0], axis[1])
    };
    format!(
        "AttributeBegin\nTranslate {} {} {}\n{rotate}Shape \"cylinder\" \"float radius\" [ {r} ] \"float zmin\" [ 0 ] \"float zmax\" [ {l} ]\nShape \"disk\" \"float radius\" [ {r} ] \"float height\" [ {l} ]\nReverseOrientation\nShape \"disk\" \"float radius\" [ {r} ]\nAttributeEnd\n",
        a[0], a[1], a[2]
    )
}

/// The furnace's front wall: a square from (x0, y0) to (x1, y1) at depth z with a round
/// hole of radius `r` centred at (cx, cy), facing +z.
fn wall_with_hole(x: (f32, f32), y: (f32, f32), z: f32, c: (f32, f32), r: f32) -> String {
    let n = 64;
    let mut p = Vec::new();
    let mut idx = Vec::new();
    for i in 0..n {
        let a = 2.0 * PI * i as f32 / n as f32;
        let (s, co) = libm::sincosf(a);
        // The hole's edge, and where the same ray from the centre meets the square.
        let t = [
            (x.1 - c.0) / co,
            (x.0 - c.0) / co,
            (y.1 - c.1) / s,
            (y.0 - c.1) / s,
        ]
        .into_iter()
        .filter(|t| *t > 0.0)
        .fold(f32::INFINITY, f32::min);
        p.push([c.0 + r * co, c.1 + r * s, z]);
        p.push([c.0 + t * co, c.1 + t * s, z]);
    }
    for i in 0..n {
        let (a, b) = (2 * i, 2 * ((i + 1) % n));
        // Counterclockwise seen from +z: outward along +z.
        idx.extend([a, a + 1, b + 1, a, b + 1, b]);
    }
    // The square's corners, fanned to the ring's outer points nearest them.
    let points: Vec<String> = p
        .iter()
        .map(|v| format!("{} {} {}", v[0], v[1], v[2]))
        .collect();
    let indices: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
    format!(
        "Shape \"trianglemesh\" \"point3 P\" [ {} ]\n    \"integer indices\" [ {} ]\n",
        points.join("  "),
        indices.join(" ")
    )
}

/// A wood-grain image: long grain along u, the growth rings' stripes bent by slow noise.
pub fn wood_png(path: &Path) {
    let (w, h) = (1024u32, 256u32);
    let noise = |x: f32, y: f32| {
        // Smooth value noise from a few sines (enough for grain that never repeats in view).
        libm::sinf(x * 1.7 + libm::sinf(y * 2.3)) * 0.5
            + libm::sinf(x * 0.61 + y * 3.7 + libm::sinf(x * 0.23) * 2.0) * 0.35
            + libm::sinf(x * 5.3 - y * 1.1) * 0.15
    };
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for j in 0..h {
        for i in 0..w {
            let (x, y) = (i as f32 / w as f32 * 12.0, j as f32 / h as f32 * 3.0);
            let ring = (y * 9.0 + 0.9 * noise(x * 0.5, y)).fract();
            // Late wood (a narrow dark band) in each ring, and a little fine streaking.
            let late = libm::powf(((ring - 0.78) / 0.22).clamp(0.0, 1.0), 0.7);
            let streak = 0.5 + 0.5 * libm::sinf(x * 40.0 + noise(x * 3.0, y * 20.0) * 6.0);
            let t = 0.75 * late + 0.12 * streak;
            let light = [0.55f32, 0.36, 0.19];
            let dark = [0.25f32, 0.13, 0.06];
            for c in 0..3 {
                let v = light[c] + (dark[c] - light[c]) * t;
                // sRGB encoding, as the imagemap's default decodes it.
                let s = if v <= 0.003_130_8 {
                    12.92 * v
                } else {
                    1.055 * libm::powf(v, 1.0 / 2.4) - 0.055
                };
                rgb.push((s * 255.0).round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    let file = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.write_header().unwrap().write_image_data(&rgb).unwrap();
    println!("wrote {}", path.display());
}

/// The scene file.
pub fn scene(p: &WorkbenchParams) -> String {
    let v = |c: [f32; 3]| format!("{} {} {}", c[0], c[1], c[2]);
    let mut s = String::new();
    let (w, h) = p.resolution;
    writeln!(
        s,
        r#"# Kiln's headline frame (seed 000): a glassblower's bench before the furnace, the glass
# snail still glowing on the steel marver, the tools around it, a gather on its blowpipe,
# and the glory hole burning behind. Written by `cargo run --release --example scene_assets`
# (examples/scene_assets/workbench.rs) from parameters a reader can change there.
# The snail (snail.ply, one closed surface) is one VolumeLight under a dielectric surface;
# snail-grid.csv is the heat of its glass, hottest at the foot and where it is thick.
Option "kiln.spectral" false  # Kiln's own scene, measured in RGB; --spectral renders it as pbrt-v4 would
Integrator "volpath" "integer maxdepth" [ 8 ] "string lightsampler" [ "power" ]
Sampler "zsobol" "integer pixelsamples" [ {spp} ] "float noisethreshold" [ 0.01 ] "integer minsamples" [ 256 ]
PixelFilter "gaussian"
Film "rgb" "integer xresolution" [ {w} ] "integer yresolution" [ {h} ] "string filename" [ "molten-glass.exr" ]
LookAt 0.9 2.0 6.4   0.05 0.62 0   0 1 0
Camera "perspective" "float fov" [ 29 ] "float lensradius" [ {lens} ] "float focaldistance" [ 6.45 ]
WorldBegin
"#,
        spp = p.spp,
        lens = p.lens_radius
    )
    .unwrap();
    writeln!(
        s,
        r#"# The snail.
AttributeBegin
    AreaLightSource "volume" "rgb Le" [ {} ] "string grid" "snail-grid.csv" "integer steps" [ 8 ] "integer powersamples" [ 16 ]
    Material "dielectric" "float eta" [ 1.5 ]
    Shape "plymesh" "string filename" "snail.ply"
AttributeEnd
"#,
        v(p.glass_le)
    )
    .unwrap();
    // The bench: a thick wooden top (the grain runs along x), with a polished steel marver
    // let into it under the snail; the floor far below.
    writeln!(
        s,
        r#"# The bench: wood, and the steel marver the snail stands on.
Texture "wood" "spectrum" "imagemap" "string filename" "wood.png" "float uscale" [ 2 ] "float vscale" [ 4 ]
AttributeBegin
    Material "coateddiffuse" "texture reflectance" "wood" "float roughness" [ 0.25 ]
    Shape "bilinearmesh" "point3 P" [ -7 -0.06 -5  7 -0.06 -5  -7 -0.06 3  7 -0.06 3 ]
        "point2 uv" [ 0 0  1 0  0 1  1 1 ]
    Material "diffuse" "texture reflectance" "wood"
    {}AttributeEnd
AttributeBegin
    Texture "marver-wear" "float" "fbm" "integer octaves" [ 5 ] "float roughness" [ 0.6 ]
    Texture "marver-rough" "float" "mix" "float tex1" [ 0.04 ] "float tex2" [ 0.22 ] "texture amount" "marver-wear"
    Material "conductor" "spectrum eta" "metal-Al-eta" "spectrum k" "metal-Al-k" "texture roughness" "marver-rough"
    {}AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.08 0.08 0.08 ]
Shape "bilinearmesh" "point3 P" [ -40 -3 -40  40 -3 -40  -40 -3 40  40 -3 40 ]
"#,
        cuboid([-7.0, -0.4, -5.0], [7.0, -0.0601, 3.0]),
        cuboid([-2.7, -0.06, -1.7], [2.9, 0.0, 1.5]),
    )
    .unwrap();
    // The tools, resting on the bench.
    let steel = r#"Material "conductor" "spectrum eta" "metal-Al-eta" "spectrum k" "metal-Al-k" "float uroughness" [ 0.3 ] "float vroughness" [ 0.08 ]"#;
    writeln!(
        s,
        "# Jacks: two steel blades sprung from one handle, lying on the bench."
    )
    .unwrap();
    writeln!(
        s,
        "AttributeBegin\n{steel}\nTranslate 1.2 -0.06 1.95\nRotate 172 0 1 0"
    )
    .unwrap();
    s += &rod([-1.6, 0.05, 0.0], [-0.2, 0.05, 0.0], 0.05);
    for side in [-1.0f32, 1.0] {
        writeln!(s, "AttributeBegin\nRotate {} 0 1 0", 4.0 * side).unwrap();
        s += &cuboid(
            [-0.2, 0.0, -0.035 + 0.09 * side],
            [1.9, 0.04, 0.035 + 0.09 * side],
        );
        writeln!(s, "AttributeEnd").unwrap();
    }
    writeln!(s, "AttributeEnd").unwrap();
    writeln!(s, "# Tweezers, on the marver before the snail's head.").unwrap();
    writeln!(
        s,
        "AttributeBegin\n{steel}\nTranslate 2.5 0 1.15\nRotate 160 0 1 0"
    )
    .unwrap();
    for side in [-1.0f32, 1.0] {
        writeln!(s, "AttributeBegin\nRotate {} 0 1 0", 3.0 * side).unwrap();
        s += &cuboid([0.0, 0.0, -0.018], [1.25, 0.025, 0.018]);
        writeln!(s, "AttributeEnd").unwrap();
    }
    writeln!(s, "AttributeEnd").unwrap();
    writeln!(
        s,
        "# A wooden paddle, charred along its blade, on the marver's far corner; its handle\n# overhangs the bench."
    )
    .unwrap();
    writeln!(
        s,
        "AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [ 0.07 0.05 0.04 ]"
    )
    .unwrap();
    s += &cuboid([-2.6, 0.0, -1.55], [-1.3, 0.07, -0.95]);
    writeln!(s, "Material \"diffuse\" \"texture reflectance\" \"wood\"").unwrap();
    s += &rod([-2.6, 0.05, -1.25], [-4.4, 0.05, -1.25], 0.05);
    writeln!(s, "AttributeEnd").unwrap();
    // The blowpipe: resting in a yoke on a post at the bench's far side, its gather (a
    // second, smaller VolumeLight) hanging out beyond the yoke, its other end on the bench.
    writeln!(
        s,
        "# The blowpipe in its yoke, the gather glowing at its end."
    )
    .unwrap();
    let yoke = [-3.5f32, 0.85, -2.2];
    let end = [-7.0f32, -0.02, -3.6];
    let dir = {
        let d = [yoke[0] - end[0], yoke[1] - end[1], yoke[2] - end[2]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        d.map(|c| c / l)
    };
    let tip = [0, 1, 2].map(|i| yoke[i] + dir[i] * 0.75);
    writeln!(s, "AttributeBegin\n{steel}").unwrap();
    s += &rod(end, tip, 0.035);
    // The yoke: a post, and two arms in a V that the pipe lies in.
    s += &rod(
        [yoke[0], -0.06, yoke[2]],
        [yoke[0], yoke[1] - 0.16, yoke[2]],
        0.05,
    );
    for side in [-1.0f32, 1.0] {
        s += &rod(
            [yoke[0], yoke[1] - 0.16, yoke[2]],
            [
                yoke[0] + 0.16 * side * dir[2],
                yoke[1] + 0.06,
                yoke[2] - 0.16 * side * dir[0],
            ],
            0.025,
        );
    }
    writeln!(s, "AttributeEnd").unwrap();
    let gather = [0, 1, 2].map(|i| tip[i] + dir[i] * 0.2);
    writeln!(
        s,
        "AttributeBegin\n    AreaLightSource \"volume\" \"rgb Le\" [ {} ] \"integer steps\" [ 8 ]\n    Material \"dielectric\" \"float eta\" [ 1.5 ]\n    Translate {}\n    Shape \"sphere\" \"float radius\" [ 0.26 ]\nAttributeEnd",
        v(p.glass_le.map(|c| c * 2.5)),
        v(gather)
    )
    .unwrap();
    // Marbles, cold glass, resting on the marver.
    writeln!(
        s,
        "# Two marbles of cold glass on the marver.\nMaterial \"dielectric\" \"float eta\" [ 1.5 ]\nAttributeBegin\n    Translate -2.05 0.2 0.75\n    Shape \"sphere\" \"float radius\" [ 0.2 ]\nAttributeEnd\nAttributeBegin\n    Translate -1.6 0.13 1.2\n    Shape \"sphere\" \"float radius\" [ 0.13 ]\nAttributeEnd"
    )
    .unwrap();
    // The furnace behind the bench: a refractory front with the round glory hole, its
    // tunnel and back wall burning.
    // In the furnace's own frame the glory hole is centred at the origin on the front wall,
    // its tunnel running back along -z; the furnace stands turned so that the camera looks
    // into the tunnel from one side.
    let (centre, turn, hr, deep) = ([-5.6f32, 1.55, -9.0], -28.0f32, 0.75f32, 1.8f32);
    writeln!(
        s,
        "# The furnace: its front wall, the steel collar of the glory hole, and the fire inside.\nAttributeBegin\n    Translate {}\n    Rotate {turn} 0 1 0\n    Texture \"brick-grain\" \"float\" \"fbm\" \"integer octaves\" [ 4 ]\n    Texture \"refractory\" \"spectrum\" \"mix\" \"rgb tex1\" [ 0.28 0.16 0.11 ] \"rgb tex2\" [ 0.12 0.08 0.06 ] \"texture amount\" \"brick-grain\"\n    Material \"diffuse\" \"texture reflectance\" \"refractory\"",
        v(centre)
    )
    .unwrap();
    s += &wall_with_hole((-4.0, 4.0), (-5.0, 4.0), 0.0, (0.0, 0.0), hr + 0.14);
    s += &cuboid([-4.2, -5.0, -3.5], [-4.0, 4.0, 0.0]);
    s += &cuboid([4.0, -5.0, -3.5], [4.2, 4.0, 0.0]);
    writeln!(
        s,
        "    Material \"conductor\" \"spectrum eta\" \"metal-Al-eta\" \"spectrum k\" \"metal-Al-k\" \"float roughness\" [ 0.35 ]\n    Shape \"cylinder\" \"float radius\" [ {} ] \"float zmin\" [ 0 ] \"float zmax\" [ 0.3 ]\n    Shape \"disk\" \"float radius\" [ {} ] \"float innerradius\" [ {hr} ] \"float height\" [ 0.3 ]\n    AttributeBegin\n        AreaLightSource \"diffuse\" \"rgb L\" [ {} ]\n        Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.3 0.2 ]\n        ReverseOrientation\n        Shape \"cylinder\" \"float radius\" [ {hr} ] \"float zmin\" [ -{deep} ] \"float zmax\" [ 0.3 ]\n    AttributeEnd\n    AttributeBegin\n        AreaLightSource \"diffuse\" \"rgb L\" [ {} ]\n        Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.3 0.2 ]\n        Shape \"disk\" \"float radius\" [ {hr} ] \"float height\" [ -{deep} ]\n    AttributeEnd\nAttributeEnd",
        hr + 0.14,
        hr + 0.14,
        v(p.furnace_l.map(|c| c * 0.35)),
        v(p.furnace_l)
    )
    .unwrap();
    // The cool fill: a window's light from the front left, off the frame.
    writeln!(
        s,
        "# The cool fill: daylight from a window to the front left, off the frame.\nAttributeBegin\n    AreaLightSource \"diffuse\" \"rgb L\" [ {} ]\n    Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n    Translate 9 3.5 5\n    Rotate -120 0 1 0\n    Shape \"bilinearmesh\" \"point3 P\" [ -1.5 -1.2 0  1.5 -1.2 0  -1.5 1.2 0  1.5 1.2 0 ]\nAttributeEnd",
        v(p.fill_l)
    )
    .unwrap();
    s
}
