//! pbrt-v4's quadrics (disks, cylinders, partial and transformed spheres) and curves against
//! closed forms, between Kiln's estimators, and against pbrt-v4's renders of the same files.

use crate::util::{
    assert_matches_pbrt, assert_strategies_agree, block_stats, failing, render, render_strategies,
    scene, write_scene,
};
use std::f64::consts::PI;

/// The radiance a white-ish diffuse floor (reflectance 0.5) sends up from the origin, lit
/// by `lights` alone (one bounce), estimated with `strategy`; returns the mean over 8 x 8
/// pixels that all see the origin, and its standard error.
fn floor_radiance(dir: &std::path::Path, lights: &str, strategy: &str) -> (f64, f64) {
    let text = format!(
        r#"Integrator "path" "integer maxdepth" [ 1 ] "string strategy" "{strategy}"
Sampler "halton" "integer pixelsamples" [ 1024 ]
Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
LookAt 0 0 1  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -0.0001 0.0001 -0.0001 0.0001 ]
WorldBegin
AttributeBegin
{lights}
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "disk" "float radius" [ 20 ]
"#
    );
    let path = write_scene(dir, "floor.pbrt", &text);
    let img = render(&path, dir, "floor", &[]).image;
    block_stats(&img, 0, 0, 8, 8, 1)
}

/// Asserts every direct-lighting strategy finds `want` at the floor under `lights`.
fn assert_floor_radiance(lights: &str, want: f64) {
    let dir = tempfile::tempdir().unwrap();
    for strategy in ["light", "bsdf", "mis"] {
        let (got, se) = floor_radiance(dir.path(), lights, strategy);
        eprintln!("{strategy:>5}: {got:.6} ± {se:.6} (want {want:.6}) for {lights}");
        assert!(
            se < 0.01 * want,
            "{strategy}: too noisy to tell ({se}) for {lights}"
        );
        assert!(
            (got - want).abs() < 4.0 * se + 1e-4 * want,
            "{strategy}: {got} ± {se}, want {want}, for {lights}"
        );
    }
}

/// On its axis, a disk of radius r at height h (an annulus: less the inner disk) gives a
/// point facing it the irradiance E = Lπ r²/(r² + h²); cut to half its angle, half that.
/// pbrt-v4's "power" divides by the object-space area, whatever the transform.
#[test]
fn a_disk_light_gives_the_closed_form_irradiance_on_its_axis() {
    let annulus = 0.5 * (1.0 / 5.0 - 0.25 / 4.25);
    let lights = [
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "disk" "float height" [ 2 ] "float radius" [ 1 ] "float innerradius" [ 0.5 ]"#,
            annulus,
        ),
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "disk" "float height" [ 2 ] "float radius" [ 1 ] "float innerradius" [ 0.5 ] "float phimax" [ 180 ]"#,
            annulus / 2.0,
        ),
        // The same annulus, drawn small and scaled up non-uniformly.
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Scale 2 2 0.5
Shape "disk" "float height" [ 4 ] "float radius" [ 0.5 ] "float innerradius" [ 0.25 ]"#,
            annulus,
        ),
        // Power 3 over the object-space area π/4: L = 3 / (π · π/4).
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "float power" [ 3 ]
ReverseOrientation
Scale 2 2 2
Shape "disk" "float height" [ 1 ] "float radius" [ 0.5 ]"#,
            0.5 * 3.0 / (PI * PI / 4.0) / 5.0,
        ),
    ];
    for (light, want) in lights {
        assert_floor_radiance(light, want);
    }
}

/// A point at the centre of an open cylinder's base, the wall lit inwards, sees the wall in
/// every upward direction but the top opening's: E = Lπ − L·P(opening), where P is the
/// opening's projected solid angle, H²/(R² + H²)·π for a circle of radius R at height H,
/// and for an ellipse ∫ ½ (1 − H²/(R(φ)² + H²)) dφ.
#[test]
fn a_cylinder_light_around_a_point_gives_the_closed_form_irradiance() {
    // Radius 1, height 2: the opening subtends π/5.
    let circle = 0.5 * (1.0 - 1.0 / 5.0);
    // Semi-axes 2 and 1 at height 2, by a fine midpoint rule in φ.
    let n = 100_000;
    let opening: f64 = (0..n)
        .map(|i| {
            let phi = (i as f64 + 0.5) / n as f64 * 2.0 * PI;
            let r2 = 1.0 / ((libm::cos(phi) / 2.0).powi(2) + libm::sin(phi).powi(2));
            0.5 * (1.0 - 4.0 / (r2 + 4.0)) * 2.0 * PI / n as f64
        })
        .sum();
    let ellipse = 0.5 * (1.0 - opening / PI);
    let lights = [
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "cylinder" "float radius" [ 1 ] "float zmin" [ 0 ] "float zmax" [ 2 ]"#,
            circle,
        ),
        // Half the wall, seen from its axis: half the irradiance.
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "cylinder" "float radius" [ 1 ] "float zmin" [ 0 ] "float zmax" [ 2 ] "float phimax" [ 180 ]"#,
            circle / 2.0,
        ),
        // An elliptic cylinder: the area scale varies around the wall.
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Scale 2 1 4
Shape "cylinder" "float radius" [ 1 ] "float zmin" [ 0 ] "float zmax" [ 0.5 ]"#,
            ellipse,
        ),
    ];
    for (light, want) in lights {
        assert_floor_radiance(light, want);
    }
}

/// Under a dome lit inwards a point sees L in every upward direction: E = Lπ, whatever the
/// dome's shape (a stretched one too); a cap down to polar angle θ gives Lπ sin²θ; a
/// quarter of the dome, a quarter of Lπ.
#[test]
fn a_spherical_dome_light_gives_the_closed_form_irradiance() {
    let lights = [
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "sphere" "float radius" [ 3 ] "float zmin" [ 0 ]"#,
            0.5,
        ),
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Scale 1 0.5 2
Shape "sphere" "float radius" [ 3 ] "float zmin" [ 0 ]"#,
            0.5,
        ),
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "sphere" "float radius" [ 3 ] "float zmin" [ 1.5 ]"#,
            0.5 * 0.75,
        ),
        (
            r#"AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
ReverseOrientation
Shape "sphere" "float radius" [ 3 ] "float zmin" [ 0 ] "float phimax" [ 90 ]"#,
            0.5 / 4.0,
        ),
    ];
    for (light, want) in lights {
        assert_floor_radiance(light, want);
    }
}

/// Light sampling (by area through the transform), BSDF sampling and MIS agree on a scene
/// of quadric lights and surfaces: a cut annulus, a stretched sphere, a two-sided tube.
#[test]
fn quadric_lights_agree_by_light_and_bsdf_sampling() {
    let images = render_strategies(
        &scene("shapes/scene.pbrt"),
        "volpath",
        3,
        11,
        false,
        &["--spp", "256", "--resolution", "48x32"],
    );
    assert_strategies_agree("shapes", &images, 4.5, Some(4.5));
}

/// The quadrics scene as pbrt-v4 renders it (96x64, 1024 spp), with the stretched lamp
/// replaced by a round one of radius 0.15: pbrt-v4 samples a transformed quadric light by
/// its object-space size (a sphere by the cone of its object-space radius, a disk by
/// 1/object area), so it renders scaled quadric lights wrongly, and warns ("Scaling
/// detected in rendering to light space transformation"). Kiln's closed-form tests above
/// cover scaled lights.
#[test]
fn the_quadrics_scene_matches_pbrt_v4() {
    let text = std::fs::read_to_string(scene("shapes/scene.pbrt")).unwrap();
    let stretched = "  Scale 1 0.3 0.4\n  Shape \"sphere\" \"float radius\" [ 0.4 ]";
    assert!(
        text.contains(stretched),
        "the scene still has its stretched lamp"
    );
    let text = text.replace(stretched, "  Shape \"sphere\" \"float radius\" [ 0.15 ]");
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), "round-lamp.pbrt", &text);
    let kiln = render(&path, dir.path(), "round-lamp", &["--spp", "64"])
        .image
        .mean();
    assert_matches_pbrt(
        "quadrics",
        kiln,
        [0.144247483, 0.121323582, 0.127593051],
        0.02,
        3,
    );
}

/// pbrt-v4 (5f7a606, CPU, built here) renders a checkerboard sphere turned -90 degrees about
/// x, under a white sky (64x64, 64 spp): the mean of each 8x8 block of pixels, rows from
/// the top. pbrt-v4 parametrises a sphere in its object space, so the turned sphere shows
/// its pole to the camera and its meridians as a pie; Kiln, which once took (u, v) from
/// world coordinates and showed columns (0.58 off in the worst block), must agree within
/// 0.02 in every block and channel.
#[test]
fn a_turned_textured_sphere_matches_pbrt_v4() {
    // Measured figures: one of them is near pi/4 by chance.
    #[rustfmt::skip]
    #[allow(clippy::approx_constant)]
    const PBRT: [[f32; 3]; 64] = [
    [0.9999, 1.0, 0.9994], [1.0, 0.9998, 1.001], [1.0, 1.0, 1.0], [0.9819, 0.9865, 0.9923], [0.9943, 0.9876, 0.9843], [1.0, 1.0, 1.0], [0.9996, 1.0, 0.9995], [1.0, 0.9998, 1.0],
    [1.0, 0.9998, 1.001], [0.9757, 0.9736, 0.9759], [0.5314, 0.6279, 0.7849], [0.4603, 0.4585, 0.5537], [0.573, 0.4772, 0.4786], [0.8375, 0.6787, 0.5829], [0.9759, 0.973, 0.9777], [0.9994, 1.0, 0.9995],
    [0.9998, 1.0, 0.9991], [0.837, 0.6775, 0.5827], [0.4993, 0.4499, 0.5016], [0.7882, 0.4979, 0.3074], [0.2124, 0.4021, 0.6918], [0.4993, 0.4498, 0.5002], [0.5339, 0.6289, 0.7854], [1.0, 1.0, 1.002],
    [0.9949, 0.9879, 0.985], [0.5728, 0.4774, 0.4767], [0.2122, 0.402, 0.6917], [0.5004, 0.4502, 0.4989], [0.4998, 0.4501, 0.4998], [0.7881, 0.498, 0.3079], [0.4596, 0.4581, 0.555], [0.9808, 0.9855, 0.9918],
    [0.981, 0.9855, 0.9932], [0.4614, 0.4589, 0.5529], [0.788, 0.498, 0.3084], [0.5004, 0.4501, 0.4988], [0.4994, 0.4498, 0.5006], [0.2127, 0.4018, 0.6934], [0.5721, 0.4779, 0.4778], [0.9938, 0.9876, 0.983],
    [1.0, 0.9999, 0.9997], [0.5332, 0.6286, 0.7891], [0.5, 0.4499, 0.5001], [0.2121, 0.4019, 0.6928], [0.7875, 0.4978, 0.3083], [0.4986, 0.45, 0.4993], [0.8359, 0.6781, 0.58], [1.0, 0.9999, 0.9994],
    [1.0, 1.0, 0.9994], [0.9749, 0.9727, 0.9754], [0.8384, 0.6794, 0.585], [0.5716, 0.4766, 0.4779], [0.4613, 0.4594, 0.5544], [0.529, 0.626, 0.7864], [0.9748, 0.9727, 0.977], [1.0, 1.0, 0.9993],
    [0.9996, 1.0, 0.9999], [1.0, 1.0, 1.001], [0.9999, 1.0, 1.001], [0.9945, 0.9878, 0.9831], [0.982, 0.9863, 0.9918], [1.0, 1.0, 1.0], [0.9999, 1.0, 0.9988], [1.0, 0.9998, 1.001],
    ];
    let dir = tempfile::tempdir().unwrap();
    let text = r#"LookAt 0 -5 0  0 0 0  0 0 1
Camera "perspective" "float fov" [ 30 ]
Sampler "halton" "integer pixelsamples" [ 64 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Texture "checks" "spectrum" "checkerboard" "float uscale" [ 8 ] "float vscale" [ 4 ] "rgb tex1" [ 0.8 0.5 0.3 ] "rgb tex2" [ 0.2 0.4 0.7 ]
Material "diffuse" "texture reflectance" "checks"
Rotate -90 1 0 0
Shape "sphere"
"#;
    let path = write_scene(dir.path(), "turned.pbrt", text);
    let img = render(&path, dir.path(), "turned", &[]).image;
    for (k, want) in PBRT.iter().enumerate() {
        let (bx, by) = (k as u32 % 8, k as u32 / 8);
        for (c, &w) in want.iter().enumerate() {
            let (got, _) = block_stats(&img, bx * 8, by * 8, 8, 8, c);
            assert!(
                (got - f64::from(w)).abs() < 0.02,
                "block ({bx}, {by}), channel {c}: Kiln {got:.4}, pbrt-v4 {w}"
            );
        }
    }
}

/// Bad quadric and curve parameters are errors that name the line.
#[test]
fn bad_quadrics_and_curves_are_errors_that_say_where() {
    let (err, _dir) = failing("WorldBegin\n\nShape \"disk\" \"float radius\" [ -1 ]\n");
    assert!(
        err.contains("scene.pbrt:3") && err.contains("radius"),
        "{err}"
    );
    let (err, _dir) = failing(
        "WorldBegin\nAttributeBegin\nMaterial \"dielectric\"\nAreaLightSource \"volume\" \"rgb Le\" [ 1 1 1 ]\nShape \"cylinder\"\nAttributeEnd\n",
    );
    assert!(
        err.contains("scene.pbrt:5") && err.contains("closed shape"),
        "{err}"
    );
    for (text, says) in [
        (
            "Shape \"curve\" \"point3 P\" [ 0 0 0 1 0 0 2 0 0 3 0 0 4 0 0 ]",
            "control points",
        ),
        (
            "Shape \"curve\" \"point3 P\" [ 0 0 0 1 0 0 2 0 0 3 0 0 ] \"string type\" \"ribbon\"",
            "normals",
        ),
        (
            "Shape \"curve\" \"point3 P\" [ 0 0 0 1 0 0 2 0 0 3 0 0 ] \"string basis\" \"hermite\"",
            "basis",
        ),
        (
            "AreaLightSource \"diffuse\"\nShape \"curve\" \"point3 P\" [ 0 0 0 1 0 0 2 0 0 3 0 0 ]",
            "area light",
        ),
    ] {
        let (err, _dir) = failing(&format!("WorldBegin\n{text}\n"));
        assert!(
            err.contains("scene.pbrt:") && err.contains(says),
            "{says}: {err}"
        );
    }
}

/// A white curve seen square-on, lit by a distant light from the camera (L = π): a flat
/// curve faces the light, so every pixel it covers is its reflectance 0.5 and the rest is
/// black; the image mean is 0.5 × the curve's area over the view's, and a straight curve of
/// length ℓ tapering from w0 to w1 covers ℓ (w0 + w1) / 2. A cylinder-shaded curve turns
/// its normal from −90° to 90° across its width: on average cos = 2/π of that.
#[test]
fn a_curve_covers_its_width() {
    let dir = tempfile::tempdir().unwrap();
    let pi = std::f64::consts::PI;
    for (kind, w0, w1, shade) in [
        ("flat", 0.2, 0.2, 1.0),
        ("flat", 0.3, 0.1, 1.0),
        ("cylinder", 0.25, 0.25, 2.0 / pi),
    ] {
        let text = format!(
            r#"Integrator "path" "integer maxdepth" [ 1 ]
Sampler "halton" "integer pixelsamples" [ 64 ]
PixelFilter "box"
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 0 5 ] "point3 to" [ 0 0 0 ] "rgb L" [ {pi} {pi} {pi} ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "curve" "point3 P" [ -0.8 0 0  -0.3 0 0  0.3 0 0  0.8 0 0 ] "float width0" [ {w0} ] "float width1" [ {w1} ] "string type" "{kind}"
"#
        );
        let path = write_scene(dir.path(), "curve.pbrt", &text);
        let got = render(&path, dir.path(), "curve", &[]).image.mean()[1];
        let want = 0.5 * shade * 1.6 * (w0 + w1) / 2.0 / 4.0;
        assert!(
            (got / want - 1.0).abs() < 0.01,
            "{kind} {w0}..{w1}: {got} vs {want}"
        );
    }
}

/// The curves scene as pbrt-v4 renders it (128x96, 256 spp): a tapering flat curve, a
/// cylinder-shaded b-spline, a quadratic ribbon. Within 1% (measured within 0.15%). With
/// curves ten times as wide, the ribbon's shadow on the flat curve differed: pbrt-v4 starts
/// a curve's shadow rays a whole width off the curve, Kiln at the point hit.
#[test]
fn the_curves_scene_matches_pbrt_v4() {
    let dir = tempfile::tempdir().unwrap();
    let kiln = render(
        &scene("shapes/curves.pbrt"),
        dir.path(),
        "curves",
        &["--spp", "64"],
    )
    .image
    .mean();
    assert_matches_pbrt(
        "curves",
        kiln,
        [0.369063284, 0.368392268, 0.419577545],
        0.01,
        3,
    );
}

/// A thick hair fibre (a cylinder-type curve) seen square-on under a distant light, against
/// pbrt-v4's renders of the same file (32x32, 1024 spp): grey absorption within 0.5%,
/// melanin within 1%, rendered spectrally (the default) as pbrt-v4 does. (In RGB mode,
/// measured: within 0.01% and +0.6%, +0.3%, +0.5%, Kiln absorbing per RGB channel.)
#[test]
fn a_hair_fibre_scatters_as_in_pbrt_v4() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            r#""rgb sigma_a" [ 0.3 0.3 0.3 ] "float beta_m" [ 0.2 ] "float beta_n" [ 0.5 ]"#,
            [0.0212537049, 0.0212538791, 0.0212537438],
            0.005,
        ),
        (
            r#""float eumelanin" [ 0.5 ] "float alpha" [ 4 ]"#,
            [0.0280456363, 0.0255919864, 0.0228839045],
            0.01,
        ),
    ];
    for (material, pbrt, within) in cases {
        let text = format!(
            r#"Integrator "path" "integer maxdepth" [ 30 ]
Sampler "halton" "integer pixelsamples" [ 1024 ]
PixelFilter "box"
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
LightSource "distant" "point3 from" [ 1 2 3 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material "hair" {material}
Shape "curve" "point3 P" [ -1.2 -0.3 0  -0.4 0.3 0  0.4 -0.3 0  1.2 0.3 0 ] "float width" [ 1.2 ] "string type" "cylinder"
"#
        );
        let path = write_scene(dir.path(), "fibre.pbrt", &text);
        let kiln = render(&path, dir.path(), "fibre", &[]).image.mean();
        assert_matches_pbrt(material, kiln, pbrt, within, 3);
    }
}

/// A fibre that absorbs nothing, under a uniform white sky, disappears: every path ends in
/// the sky with nothing lost or gained, so every pixel, fibre or not, is 1 (the white
/// furnace). A wide fibre covers 40% of the view.
#[test]
fn a_clear_hair_vanishes_in_a_white_furnace() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"Integrator "path" "integer maxdepth" [ 50 ]
Sampler "halton" "integer pixelsamples" [ 256 ]
PixelFilter "box"
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "hair" "rgb sigma_a" [ 0 0 0 ] "float beta_m" [ 0.3 ] "float beta_n" [ 0.4 ]
Shape "curve" "point3 P" [ -1.2 -0.2 0  -0.4 0.3 0  0.4 -0.3 0.2  1.2 0.2 0 ] "float width" [ 0.8 ] "string type" "cylinder"
"#;
    let path = write_scene(dir.path(), "furnace.pbrt", text);
    let img = render(&path, dir.path(), "furnace", &[]).image;
    let mean = img.mean();
    assert!((mean[1] - 1.0).abs() < 0.003, "{mean:?}");
    // The fibre's own pixels: the middle band, where it lies.
    let (band, se) = crate::util::block_stats(&img, 4, 12, 24, 8, 1);
    assert!((band - 1.0).abs() < 0.005 + 4.0 * se, "{band} ± {se}");
}

/// The hair scene as pbrt-v4 renders it (96x64, 1024 spp), within 1% over the frame
/// (measured within 0.2%). Its coloured strands differ by up to 5% where they are (Kiln's
/// RGB absorption against pbrt-v4's spectral; with grey absorption each strand agrees
/// within 1%).
#[test]
fn the_hair_scene_matches_pbrt_v4() {
    let dir = tempfile::tempdir().unwrap();
    let kiln = render(
        &scene("shapes/hair.pbrt"),
        dir.path(),
        "hair",
        &["--spp", "64"],
    )
    .image
    .mean();
    assert_matches_pbrt("hair", kiln, [0.42005087, 0.430094602, 0.47993944], 0.01, 3);
}

/// pbrt-v4's spherical camera, both mappings, on the quadrics scene (round lamp) from its
/// place: each quadrant's green mean within 2% of pbrt-v4's render (64x64, 1024 spp), which
/// an image turned or mirrored would miss.
#[test]
fn spherical_cameras_see_as_pbrt_v4_does() {
    let text = std::fs::read_to_string(scene("shapes/scene.pbrt")).unwrap();
    let text = text.replace(
        "  Scale 1 0.3 0.4\n  Shape \"sphere\" \"float radius\" [ 0.4 ]",
        "  Shape \"sphere\" \"float radius\" [ 0.15 ]",
    );
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("equalarea", [[0.049983, 0.049983], [0.058156, 0.059133]]),
        (
            "equirectangular",
            [[0.053181, 0.049983], [0.057939, 0.049983]],
        ),
    ];
    for (mapping, pbrt) in cases {
        let camera = format!("Camera \"spherical\" \"string mapping\" \"{mapping}\"");
        let t = text.replace("Camera \"perspective\" \"float fov\" [ 40 ]", &camera);
        assert!(t.contains(&camera));
        let path = write_scene(dir.path(), "spherical.pbrt", &t);
        let img = render(
            &path,
            dir.path(),
            "spherical",
            &["--resolution", "64x64", "--spp", "128"],
        )
        .image;
        for (j, row) in pbrt.iter().enumerate() {
            for (i, &want) in row.iter().enumerate() {
                let got = block_stats(&img, 32 * i as u32, 32 * j as u32, 32, 32, 1).0;
                assert!(
                    (got / want - 1.0).abs() < 0.02,
                    "{mapping}, quadrant ({i}, {j}): Kiln {got} vs pbrt-v4 {want}"
                );
            }
        }
    }
}

/// pbrt-v4's bilinear patches, non-planar: a textured saddle, a one-sided glowing saddle
/// (ReverseOrientation) and a mirror-like saddle with shading normals, against pbrt-v4's
/// render of the same file (512 spp; the numbers are pbrt-v4's). The image mean within 1%
/// and, where the patches' curvature shows, four 8x8 blocks within 4% (measured within 2%;
/// the same saddles split into two triangles each, as Kiln drew them before, are 10% to 23%
/// off there). Light, BSDF and MIS sampling of the glowing saddle agree (it is sampled by
/// pbrt-v4's bilinear warp of its corners' area densities, which must match its pdf).
#[test]
fn bilinear_patches_match_pbrt_v4() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"Integrator "volpath" "integer maxdepth" [ 5 ]
Sampler "independent" "integer pixelsamples" [ 512 ]
Film "rgb" "integer xresolution" [ 96 ] "integer yresolution" [ 64 ]
LookAt 0 3 6  0 0.5 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.2 0.2 0.25 ]
Texture "checks" "spectrum" "checkerboard" "float uscale" [ 6 ] "float vscale" [ 6 ] "rgb tex1" [ 0.9 0.2 0.1 ] "rgb tex2" [ 0.1 0.3 0.9 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "bilinearmesh" "point3 P" [ -6 0 -6  6 0 -6  -6 0 6  6 0 6 ]
AttributeBegin
Translate -1.6 0.2 0
Material "diffuse" "texture reflectance" "checks"
Shape "bilinearmesh" "point3 P" [ -1 0 -1  1 1.5 -1  -1 1.5 1  1 0 1 ]
  "point2 uv" [ 0 0  1 0  0 1  1 1 ]
AttributeEnd
AttributeBegin
Translate 1.6 1.8 0
ReverseOrientation
AreaLightSource "diffuse" "rgb L" [ 4 3 2 ]
Shape "bilinearmesh" "point3 P" [ -0.6 0 -0.6  0.6 0.6 -0.6  -0.6 0.6 0.6  0.6 0 0.6 ]
AttributeEnd
AttributeBegin
Translate 0.2 0.4 1.5
Material "conductor" "float roughness" [ 0.05 ]
Shape "bilinearmesh" "point3 P" [ -0.7 0 -0.5  0.7 0.5 -0.5  -0.7 0.5 0.5  0.7 0 0.5 ]
  "normal N" [ -0.3 1 0.3  0.3 1 -0.3  -0.3 1 -0.3  0.3 1 0.3 ]
AttributeEnd
"#;
    let path = write_scene(dir.path(), "saddles.pbrt", text);
    let img = render(&path, dir.path(), "saddles", &[]).image;
    assert_matches_pbrt(
        "saddles",
        img.mean(),
        [0.160458, 0.148080, 0.172994],
        0.01,
        3,
    );
    let blocks: [((u32, u32), [f64; 3]); 4] = [
        ((7, 4), [0.08384, 0.04613, 0.10685]),
        ((8, 3), [0.09954, 0.05705, 0.12071]),
        ((7, 3), [0.10378, 0.04602, 0.11214]),
        ((8, 4), [0.06730, 0.04901, 0.07523]),
    ];
    for ((bx, by), pbrt) in blocks {
        let kiln: [f64; 3] = std::array::from_fn(|c| block_stats(&img, bx * 8, by * 8, 8, 8, c).0);
        eprintln!("block ({bx}, {by}): Kiln {kiln:?}, pbrt-v4 {pbrt:?}");
        assert_matches_pbrt(&format!("block ({bx}, {by})"), kiln, pbrt, 0.04, 3);
    }
    let images = render_strategies(
        &path,
        "path",
        1,
        7,
        false,
        &["--spp", "256", "--resolution", "48x32"],
    );
    assert_strategies_agree("saddles", &images, 4.5, Some(3.0));
}

/// ReverseOrientation turns a mesh's per-vertex normals round, as pbrt-v4's meshes do, and
/// the geometric normal follows them: a one-sided light whose normals face the camera goes
/// dark when reversed, and lights again with its normals given the other way. (Kiln kept
/// the given normals, so reversing did nothing: Bitterli's car, whose ReverseOrientation
/// glass then reflected the whole sky where pbrt-v4 shows the cabin, was 8% bright.)
#[test]
fn reverse_orientation_turns_mesh_normals_round() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |reverse: bool, nz: f32| {
        format!(
            r#"Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
Sampler "independent" "integer pixelsamples" [ 4 ]
LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" [ 20 ]
WorldBegin
AttributeBegin
{}AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
Shape "trianglemesh" "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ] "integer indices" [ 0 1 2 0 2 3 ]
  "normal N" [ 0 0 {nz}  0 0 {nz}  0 0 {nz}  0 0 {nz} ]
AttributeEnd
"#,
            if reverse { "ReverseOrientation\n" } else { "" }
        )
    };
    let mean = |reverse, nz| {
        let path = write_scene(dir.path(), "l.pbrt", &scene(reverse, nz));
        render(&path, dir.path(), "l", &[]).image.mean()[1]
    };
    assert!((mean(false, -1.0) - 1.0).abs() < 1e-3, "facing the camera");
    assert!(mean(true, -1.0) < 1e-6, "reversed: facing away");
    assert!((mean(true, 1.0) - 1.0).abs() < 1e-3, "reversed twice");
    assert!(mean(false, 1.0) < 1e-6, "normals facing away");
}
