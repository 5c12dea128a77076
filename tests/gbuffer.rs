//! pbrt-v4's G-buffer film: the geometric channels beside R, G and B, against pbrt-v4's
//! render of the same file, against closed forms on a tilted plane, and the same bytes
//! through the farm as from `kiln render`, whatever the tiling.

use crate::util::{render, write_scene};
use kiln_image::RgbBuffer;

/// The mean of a channel (R, G, B or a further one) over the image.
fn channel_mean(image: &RgbBuffer, name: &str) -> f64 {
    let n = image.pixels.len() as f64;
    match name {
        "R" | "G" | "B" => {
            let c = ["R", "G", "B"].iter().position(|c| *c == name).unwrap();
            image.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / n
        }
        _ => {
            let k = image.aovs.names.len();
            let c = image
                .aovs
                .names
                .iter()
                .position(|c| c == name)
                .unwrap_or_else(|| panic!("no channel {name} in {:?}", image.aovs.names));
            image
                .aovs
                .values
                .iter()
                .skip(c)
                .step_by(k)
                .map(|v| *v as f64)
                .sum::<f64>()
                / n
        }
    }
}

pub(crate) const SCENE: &str = r#"Integrator "volpath" "integer maxdepth" [ 5 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Film "gbuffer" "integer xresolution" [ 48 ] "integer yresolution" [ 32 ]
LookAt 0.3 1.2 -3  0 0.2 0.5  0 1 0
Camera "perspective" "float fov" [ 40 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.5 0.5 0.5 ]
AttributeBegin
  Material "diffuse" "rgb reflectance" [ 0.6 0.4 0.2 ]
  Shape "bilinearmesh" "point3 P" [ -3 0 -2  3 -0.5 -2  -3 0.3 4  3 0 4 ] "point2 uv" [ 0 0 1 0 0 1 1 1 ]
AttributeEnd
AttributeBegin
  Translate 0.2 0.6 0.8
  Material "coateddiffuse" "rgb reflectance" [ 0.2 0.5 0.3 ] "float roughness" [ 0.1 ]
  Shape "sphere" "float radius" [ 0.5 ]
AttributeEnd
AttributeBegin
  Translate -0.8 0.4 0.3
  Rotate 30 0 1 0
  Material "conductor" "float roughness" [ 0.2 ]
  Shape "trianglemesh" "point3 P" [ -0.3 -0.3 0  0.3 -0.3 0  0.3 0.3 0  -0.3 0.3 0 ] "integer indices" [ 0 1 2 0 2 3 ] "point2 uv" [ 0 0 1 0 1 1 0 1 ]
AttributeEnd
"#;

/// Channel means against pbrt-v4's (5f7a606, the same file at the same 64 spp: a pixel
/// whose samples all miss has position 0 in both, so the comparison needs equal rates).
/// Albedo differs by up to 2.2% (in spectral mode too, so not by pbrt-v4's spectral round
/// trip; not yet explained); the variances are left out: pbrt-v4 takes them of its sensor's values (X, Y, Z for the
/// default sensor) under the names R, G, B, Kiln of the R, G, B it writes.
#[test]
fn gbuffer_channels_match_pbrt_v4() {
    gbuffer_against_pbrt_v4(&["--rgb"], 0.03);
}

/// [`gbuffer_channels_match_pbrt_v4`] rendered spectrally, as pbrt-v4 renders: the albedo
/// is a spectrum recorded through the film under the colour space's white, as pbrt-v4's
/// G-buffer records it. It comes out as RGB's does (measured +1.0%, +1.1%, +2.0% against
/// pbrt-v4 in both modes), so that difference is not the spectral round trip.
#[test]
fn gbuffer_channels_match_pbrt_v4_spectrally() {
    gbuffer_against_pbrt_v4(&["--spectral"], 0.03);
}

/// The G-buffer scene against pbrt-v4, rendered with `args`; albedo within `albedo`.
fn gbuffer_against_pbrt_v4(args: &[&str], albedo: f64) {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "gb.pbrt", SCENE);
    let image = render(&path, dir.path(), "gb", args).image;
    // pbrt-v4's 22 channels, and beside them the denoiser's features every render keeps.
    assert_eq!(
        image.aovs.names.len(),
        22 + kiln_render::features::FEATURE_CHANNELS.len()
    );
    // (channel, pbrt-v4's mean, relative tolerance, absolute tolerance)
    let pbrt = [
        ("R", 0.331383f64, 0.02, 0.0),
        ("G", 0.274619, 0.02, 0.0),
        ("B", 0.211309, 0.02, 0.0),
        ("Albedo.R", 0.389427, albedo, 0.0),
        ("Albedo.G", 0.272366, albedo, 0.0),
        ("Albedo.B", 0.142114, albedo, 0.0),
        ("P.X", 0.017009, 0.0, 0.01),
        ("P.Y", -0.144989, 0.0, 0.01),
        ("P.Z", 2.705507, 0.015, 0.0),
        ("N.X", 0.021937, 0.0, 0.01),
        ("N.Y", 0.596031, 0.015, 0.0),
        ("N.Z", -0.301066, 0.015, 0.0),
        ("Ns.Y", 0.596031, 0.015, 0.0),
        ("dzdx", 0.002258, 0.04, 0.0),
        ("dzdy", 0.017382, 0.04, 0.0),
        ("u", 0.369227, 0.015, 0.0),
        ("v", 0.292488, 0.015, 0.0),
    ];
    for (name, want, rel, abs) in pbrt {
        let got = channel_mean(&image, name);
        eprintln!("{args:?} {name}: Kiln {got}, pbrt-v4 {want}");
        let limit = abs + rel * want.abs();
        assert!(
            (got - want).abs() <= limit,
            "{name}: Kiln {got}, pbrt-v4 {want} (within {limit})"
        );
    }
}

/// An orthographic camera on a plane z = 3 + x/2 (camera space is world space here): every
/// sample lies on the plane, so each pixel's mean position does too; the normal faces the
/// camera; a Lambertian's albedo is its reflectance; u follows x; and the depth derivative
/// is pbrt-v4's: the slope times the pixel's width times the ray-differential scale
/// (1/sqrt(16) = 1/4), across x and nothing across y.
#[test]
fn gbuffer_channels_of_a_tilted_plane_are_exact() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"Sampler "independent" "integer pixelsamples" [ 16 ]
Film "gbuffer" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
LookAt 0 0 0  0 0 1  0 1 0
Camera "orthographic"
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.25 0.125 ]
Shape "bilinearmesh" "point3 P" [ -4 -4 1  4 -4 5  -4 4 1  4 4 5 ] "point2 uv" [ 0 0 1 0 0 1 1 1 ]
"#;
    let path = write_scene(dir.path(), "plane.pbrt", text);
    // In RGB, where the albedo is exact; a spectral sample's albedo is its four
    // wavelengths' estimate (noisy, as pbrt-v4's).
    let image = render(&path, dir.path(), "plane", &["--rgb"]).image;
    let names = &image.aovs.names;
    let at = |i: usize, n: &str| {
        image.aovs.values[i * names.len() + names.iter().position(|c| c == n).unwrap()] as f64
    };
    let n = [0.5f64, 0.0, -1.0].map(|v| v / 1.25f64.sqrt());
    for i in 0..image.pixels.len() {
        let (x, z) = (at(i, "P.X"), at(i, "P.Z"));
        assert!(
            (z - (3.0 + 0.5 * x)).abs() < 1e-4,
            "pixel {i}: P.Z {z} for P.X {x}"
        );
        assert!((at(i, "u") - (x + 4.0) / 8.0).abs() < 1e-4);
        for (c, want) in ["N.X", "N.Y", "N.Z"].iter().zip(n) {
            assert!((at(i, c) - want).abs() < 1e-5, "{c} {}", at(i, c));
            assert!((at(i, &c.replace("N.", "Ns.")) - want).abs() < 1e-5);
        }
        for (c, want) in [("Albedo.R", 0.5), ("Albedo.G", 0.25), ("Albedo.B", 0.125)] {
            assert!((at(i, c) - want).abs() < 1e-5, "{c} {}", at(i, c));
        }
        // The screen window is [-1, 1] over 32 pixels.
        assert!(
            (at(i, "dzdx") - 0.5 * (2.0 / 32.0) * 0.25).abs() < 1e-6,
            "dzdx {}",
            at(i, "dzdx")
        );
        assert!(at(i, "dzdy").abs() < 1e-6);
    }
    // Raster x grows with camera x.
    assert!(at(31, "P.X") > at(0, "P.X"));
}

/// The farm's merged G-buffer is `kiln render`'s, byte for byte, for other tile sizes,
/// worker counts and thread counts: every channel of a pixel comes from its own samples.
#[test]
fn gbuffer_is_the_same_bytes_through_the_farm() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "gb.pbrt", SCENE);
    let args = ["--spp", "4", "--tile", "16", "--threads", "1"];
    let direct = render(&path, dir.path(), "direct", &args);
    assert_eq!(
        direct.image.aovs.names.len(),
        22 + kiln_render::features::FEATURE_CHANNELS.len()
    );
    assert!(channel_mean(&direct.image, "P.Z") > 1.0);
    let other = render(&path, dir.path(), "other", &["--spp", "4", "--tile", "7"]);
    assert!(other.bytes == direct.bytes, "tiling changed the G-buffer");
    let merged = crate::farm::farm(
        &path,
        dir.path(),
        "farm",
        &[
            "--spp",
            "4",
            "--tile",
            "11",
            "--workers",
            "2",
            "--threads-per-worker",
            "1",
        ],
    );
    assert!(
        merged == direct.bytes,
        "the farm's G-buffer differs from kiln render's"
    );
}
