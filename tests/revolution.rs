//! Kiln's surface of revolution ("revolution"): against the sphere it traces, against its
//! own fine tessellation, closed against leaks, and as an area light and a VolumeLight whose
//! light and BSDF sampling agree.

use crate::util::{assert_strategies_agree, max_z_score, render, render_strategies, write_scene};
use std::f64::consts::PI;
use std::fmt::Write;

/// A unit sphere's contour, `n` strips from the south pole to the north pole.
fn sphere_contour(n: usize) -> String {
    let mut s = String::new();
    for i in 0..=n {
        let t = PI * i as f64 / n as f64;
        write!(s, "{:.9} {:.9}  ", libm::sin(t).max(0.0), -libm::cos(t)).unwrap();
    }
    s
}

/// A vase: a closed contour with every kind of strip (flat annuli, cylinders, cones widening
/// and narrowing, points on the axis at both ends) and sharp and smooth turns.
const VASE: &str =
    "0 0  1 0  1 0.5  0.6 0.5  0.6 1  0.8 1.2  1.2 1.5  1.2 2  0.9 2.1  0.3 2.2  0 2.2";

/// A diffuse and a glass object under a distant light and a sky, seen from above a floor.
fn stage(material: &str, shape: &str) -> String {
    format!(
        r#"Integrator "volpath" "integer maxdepth" [ 8 ]
Sampler "zsobol" "integer pixelsamples" [ 32 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]
LookAt 0 -4 1.5  0 0 0  0 0 1
Camera "perspective" "float fov" [ 40 ]
WorldBegin
LightSource "distant" "point3 from" [ 1 -1 2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
LightSource "infinite" "rgb L" [ 0.2 0.2 0.25 ]
Texture "checks" "spectrum" "checkerboard" "float uscale" 8 "float vscale" 8
    "rgb tex1" [0.8 0.8 0.8] "rgb tex2" [0.2 0.2 0.2]
Material "diffuse" "texture reflectance" "checks"
Shape "bilinearmesh" "point3 P" [ -10 -10 -1  10 -10 -1  -10 10 -1  10 10 -1 ] "point2 uv" [0 0 1 0 0 1 1 1]
{material}
{shape}
"#
    )
}

/// A contour that traces a sphere renders as `Shape "sphere"` does, diffuse and glass,
/// within noise (independent seeds, block by block).
#[test]
fn a_sphere_contour_renders_as_a_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let contour = format!(
        "Shape \"revolution\" \"point2 contour\" [ {} ]",
        sphere_contour(64)
    );
    for material in [
        "Material \"diffuse\" \"rgb reflectance\" [ 0.7 0.5 0.3 ]",
        "Material \"dielectric\" \"float eta\" 1.5",
    ] {
        let a = write_scene(dir.path(), "a.pbrt", &stage(material, &contour));
        let b = write_scene(
            dir.path(),
            "b.pbrt",
            &stage(material, "Shape \"sphere\" \"float radius\" 1"),
        );
        let a = render(&a, dir.path(), "a", &["--seed", "1"]).image;
        let b = render(&b, dir.path(), "b", &["--seed", "2"]).image;
        let z = max_z_score(&a, &b, 4, 4);
        eprintln!("{material}: contour vs sphere, largest block z-score {z:.2}");
        assert!(
            z < 4.0,
            "{material}: a block differs by {z} standard errors"
        );
    }
}

/// The vase turned into triangles: `segments` round, every strip one quad (two triangles),
/// with the contour's smooth normals at the vertices (the ones Kiln derives: crease 30°).
fn vase_mesh(segments: usize) -> String {
    let pts: Vec<(f64, f64)> = VASE
        .split_whitespace()
        .map(|v| v.parse::<f64>().unwrap())
        .collect::<Vec<_>>()
        .chunks(2)
        .map(|c| (c[0], c[1]))
        .collect();
    let face = |i: usize| {
        let (a, b) = (pts[i], pts[i + 1]);
        let (tr, tz) = (b.0 - a.0, b.1 - a.1);
        let l = libm::hypot(tr, tz);
        (tz / l, -tr / l)
    };
    let crease = libm::cos(30f64.to_radians());
    // Each strip's ends get their own vertices, so creases stay sharp.
    let (mut p, mut n, mut idx) = (String::new(), String::new(), String::new());
    let mut count = 0usize;
    for i in 0..pts.len() - 1 {
        let own = face(i);
        let normal_at = |j: usize| -> (f64, f64) {
            if j == 0 || j == pts.len() - 1 {
                return if pts[j].0 == 0.0 {
                    (0.0, own.1.signum())
                } else {
                    own
                };
            }
            let (a, b) = (face(j - 1), face(j));
            if a.0 * b.0 + a.1 * b.1 >= crease {
                let (r, z) = (a.0 + b.0, a.1 + b.1);
                let l = libm::hypot(r, z);
                (r / l, z / l)
            } else {
                own
            }
        };
        let ends = [(pts[i], normal_at(i)), (pts[i + 1], normal_at(i + 1))];
        for k in 0..=segments {
            let phi = 2.0 * PI * k as f64 / segments as f64;
            for ((r, z), (nr, nz)) in ends {
                write!(p, "{} {} {} ", r * libm::cos(phi), r * libm::sin(phi), z).unwrap();
                write!(n, "{} {} {} ", nr * libm::cos(phi), nr * libm::sin(phi), nz).unwrap();
            }
        }
        for k in 0..segments {
            let v = |kk: usize, e: usize| count + kk * 2 + e;
            // Counterclockwise seen from the contour's normal side.
            write!(
                idx,
                "{} {} {} {} {} {} ",
                v(k, 0),
                v(k + 1, 0),
                v(k + 1, 1),
                v(k, 0),
                v(k + 1, 1),
                v(k, 1)
            )
            .unwrap();
        }
        count += (segments + 1) * 2;
    }
    format!(
        "Shape \"trianglemesh\" \"point3 P\" [ {p}] \"normal N\" [ {n}] \"integer indices\" [ {idx}]"
    )
}

/// The contour and its fine tessellation (1024 segments round, shading normals from the
/// same contour) render the same image within noise: same shape, same shading.
#[test]
fn a_contour_renders_as_its_fine_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let contour = format!(
        "Scale 0.7 0.7 0.7 Translate 0 0 -1.2 Shape \"revolution\" \"point2 contour\" [ {VASE} ]"
    );
    let mesh = format!("Scale 0.7 0.7 0.7 Translate 0 0 -1.2 {}", vase_mesh(1024));
    for material in [
        "Material \"diffuse\" \"rgb reflectance\" [ 0.7 0.5 0.3 ]",
        "Material \"dielectric\" \"float eta\" 1.5",
    ] {
        let a = write_scene(dir.path(), "a.pbrt", &stage(material, &contour));
        let b = write_scene(dir.path(), "b.pbrt", &stage(material, &mesh));
        let a = render(&a, dir.path(), "a", &["--seed", "1"]).image;
        let b = render(&b, dir.path(), "b", &["--seed", "2"]).image;
        let z = max_z_score(&a, &b, 4, 4);
        eprintln!("{material}: contour vs mesh, largest block z-score {z:.2}");
        assert!(
            z < 4.0,
            "{material}: a block differs by {z} standard errors"
        );
    }
}

/// No leaks: a spherical camera inside the closed vase, on its axis (rays straight along
/// the axis meet the flat ends at their centres) and off it, sees the two-sided emitting
/// surface in every direction: every pixel exactly 1. A ray slipping between two strips or
/// two sectors would escape to black.
#[test]
fn a_closed_contour_does_not_leak() {
    let dir = tempfile::tempdir().unwrap();
    for (x, z) in [(0.0, 1.0), (0.0, 0.25), (0.35, 1.7), (0.95, 1.75)] {
        let text = format!(
            r#"Integrator "path" "integer maxdepth" [ 1 ]
Sampler "independent" "integer pixelsamples" [ 4 ]
Film "rgb" "integer xresolution" [ 256 ] "integer yresolution" [ 128 ]
LookAt {x} 0 {z}  {x} 1 {z}  0 0 1
Camera "spherical" "string mapping" "equirectangular"
WorldBegin
AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "bool twosided" true
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Shape "revolution" "point2 contour" [ {VASE} ] "float creaseangle" 0
"#
        );
        let path = write_scene(dir.path(), "inside.pbrt", &text);
        // In RGB, where a white emitter's sample is exactly 1 (a spectral one is four
        // wavelengths' estimate).
        let img = render(&path, dir.path(), "inside", &["--rgb"]).image;
        let mut worst = 1.0f32;
        for y in 0..img.height {
            for xx in 0..img.width {
                worst = worst.min(img.get(xx, y)[1]);
            }
        }
        assert!(
            (worst - 1.0).abs() < 1e-5,
            "from ({x}, {z}) some pixel sees {worst}: a leak"
        );
    }
}

/// A contour as a diffuse area light and as a VolumeLight (a glass vase with a glowing
/// inside): light sampling, BSDF sampling and MIS agree.
#[test]
fn contour_lights_agree_between_strategies() {
    let dir = tempfile::tempdir().unwrap();
    let lights = [
        (
            "area",
            format!(
                "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 2 1.5 1 ]\nTranslate 0 0 -0.5 Scale 0.6 0.6 0.6\nShape \"revolution\" \"point2 contour\" [ {VASE} ]\nAttributeEnd"
            ),
        ),
        (
            "volume",
            format!(
                "AttributeBegin\nAreaLightSource \"volume\" \"rgb Le\" [ 3 2 1 ]\nMaterial \"dielectric\" \"float eta\" 1.5\nTranslate 0 0 -0.5 Scale 0.6 0.6 0.6\nShape \"revolution\" \"point2 contour\" [ {VASE} ]\nAttributeEnd"
            ),
        ),
    ];
    for (what, light) in lights {
        let text = format!(
            r#"Integrator "volpath" "integer maxdepth" [ 3 ]
Sampler "zsobol" "integer pixelsamples" [ 64 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 32 ]
LookAt 0 -4 2  0 0 0  0 0 1
Camera "perspective" "float fov" [ 45 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "bilinearmesh" "point3 P" [ -6 -6 -1  6 -6 -1  -6 6 -1  6 6 -1 ]
{light}
"#
        );
        let path = write_scene(dir.path(), &format!("{what}.pbrt"), &text);
        // In RGB: the strategies' densities over the contour are what is tested, and they
        // do not depend on the mode; a spectral render's four-wavelength noise in blue is
        // skewed, which the z-scores' normal approximation does not describe at 64 spp.
        let images = render_strategies(&path, "volpath", 3, 10, false, &["--rgb"]);
        assert_strategies_agree(what, &images, 4.5, Some(3.0));
    }
}
