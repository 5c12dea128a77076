//! Spectral rendering (the default; `--spectral`, `Option "kiln.spectral"`): a white
//! furnace stays white, scenes render as in RGB within noise where colours do not multiply
//! many times, the bytes do not depend on tiles or threads, the option and the flags agree,
//! and spectral inputs (coated layers, metals, named illuminants) match pbrt-v4.

use crate::util::{block_stats, max_z_score, render, render_with_env, scene, write_scene};

/// Asserts that every channel of `image` averages 1 within `within` and four standard errors.
fn assert_white(name: &str, image: &kiln_image::RgbBuffer, within: f64) {
    for c in 0..3 {
        let (mean, err) = block_stats(image, 0, 0, image.width, image.height, c);
        println!("{name}, channel {c}: {mean:.5} ± {err:.5}");
        assert!(
            (mean - 1.0).abs() < within + 4.0 * err,
            "{name} channel {c}: {mean} ± {err}"
        );
    }
}

/// A white furnace (a white diffuse sphere inside uniform white light) is white at every
/// pixel's mean, on every channel, though each sample sees four wavelengths of a light whose
/// spectrum (D65) is not flat.
#[test]
fn a_white_furnace_stays_white_in_spectral_mode() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(
        &scene("furnace/scene.pbrt"),
        dir.path(),
        "furnace",
        &["--spectral", "--resolution", "48x32", "--spp", "64"],
    );
    assert_white("furnace", &r.image, 3e-3);
}

/// A grey box (grey walls, a grey ball, a glass ball, white light, eight bounces).
const GREY_BOX: &str = r#"Integrator "path" "integer maxdepth" [ 8 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 36 ]
LookAt 0 1 -3.5  0 1 0  0 1 0
Camera "perspective" "float fov" [ 50 ]
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 8 8 8 ] "bool twosided" true
  Shape "trianglemesh" "point3 P" [ -0.3 1.95 -0.3  0.3 1.95 -0.3  0.3 1.95 0.3  -0.3 1.95 0.3 ]
    "integer indices" [ 0 1 2  0 2 3 ]
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "trianglemesh"
  "point3 P" [ -1 0 -1  1 0 -1  1 0 1  -1 0 1  -1 2 -1  1 2 -1  1 2 1  -1 2 1 ]
  "integer indices" [ 0 1 2  0 2 3  4 6 5  4 7 6  3 2 6  3 6 7  0 3 7  0 7 4  1 5 6  1 6 2 ]
AttributeBegin
  Material "diffuse" "rgb reflectance" [ 0.25 0.25 0.25 ]
  Translate -0.4 0.4 0.2
  Shape "sphere" "float radius" 0.4
AttributeEnd
AttributeBegin
  Material "dielectric" "float eta" 1.5
  Translate 0.45 0.35 -0.2
  Shape "sphere" "float radius" 0.35
AttributeEnd
"#;

/// Grey scenes render as in RGB within noise: grey spectra are flat, so their products
/// are too, and the white light is white: a grey box, and fog (a grey homogeneous medium
/// that scatters and absorbs, lit by a sphere light) and the same as a grid medium, and a
/// VolumeLight whose interior glows and absorbs. Block by block (4 x 3) and channel by channel,
/// independent renders (different seeds) differ by under 5 standard errors.
#[test]
fn a_grey_scene_renders_alike_in_spectral_and_rgb_modes() {
    let dir = tempfile::tempdir().unwrap();
    let fog = std::fs::read_to_string(scene("media/fog.pbrt"))
        .unwrap()
        .replace(
            "\"rgb sigma_a\" [ 0.05 0.05 0.08 ] \"rgb sigma_s\" [ 0.35 0.3 0.25 ]",
            "\"rgb sigma_a\" [ 0.06 0.06 0.06 ] \"rgb sigma_s\" [ 0.3 0.3 0.3 ]",
        )
        .replace("\"rgb L\" [ 20 16 12 ]", "\"rgb L\" [ 16 16 16 ]");
    assert!(fog.contains("[ 0.3 0.3 0.3 ]") && fog.contains("[ 16 16 16 ]"));
    // The same fog as a grid medium, denser towards +x and +y.
    let smoke = fog.replace(
        "\"homogeneous\" \"rgb sigma_a\" [ 0.06 0.06 0.06 ] \"rgb sigma_s\" [ 0.3 0.3 0.3 ]",
        "\"uniformgrid\" \"point3 p0\" [ -3 0 -3 ] \"point3 p1\" [ 3 4 3 ] \"integer nx\" 2 \"integer ny\" 2 \"integer nz\" 1 \"float density\" [ 0.5 1 1.5 2 ] \"rgb sigma_a\" [ 0.04 0.04 0.04 ] \"rgb sigma_s\" [ 0.2 0.2 0.2 ]",
    );
    assert!(smoke.contains("uniformgrid"));
    // A VolumeLight glowing grey through its glass, absorbing inside.
    let glow = std::fs::read_to_string(scene("volume-light/glass-sphere.pbrt"))
        .unwrap()
        .replace(
            "\"rgb Le\" [ 4 1.6 0.4 ]",
            "\"rgb Le\" [ 2 2 2 ] \"rgb sigma_a\" [ 0.7 0.7 0.7 ]",
        );
    assert!(glow.contains("[ 0.7 0.7 0.7 ]"));
    for (name, text, spp) in [
        ("grey box", GREY_BOX, "128"),
        ("grey fog", fog.as_str(), "64"),
        ("grey smoke (a grid medium)", smoke.as_str(), "64"),
        ("grey VolumeLight", glow.as_str(), "64"),
    ] {
        let path = write_scene(dir.path(), "grey.pbrt", text);
        let args = |mode: &'static str, seed: &'static str| {
            vec![mode, "--spp", spp, "--seed", seed, "--resolution", "48x32"]
        };
        let rgb = render(&path, dir.path(), "rgb", &args("--rgb", "1"));
        let spectral = render(&path, dir.path(), "spectral", &args("--spectral", "2"));
        let z = max_z_score(&rgb.image, &spectral.image, 4, 3);
        println!(
            "{name}: RGB {:?}, spectral {:?}, largest |z| {z:.2}",
            rgb.image.mean(),
            spectral.image.mean()
        );
        assert!(z < 5.0, "{name}: largest |z| {z}");
    }
}

/// Coloured scenes differ between the modes where colours multiply (that is what spectral
/// rendering is for), but little where light meets colour once or twice: the image means
/// of the textures and materials scenes agree within 2% on every channel.
#[test]
fn coloured_scenes_stay_close_to_their_rgb_renders() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["textures/scene.pbrt", "materials/scene.pbrt"] {
        let args = |mode: &'static str| vec![mode, "--resolution", "64x48", "--spp", "64"];
        let rgb = render(&scene(name), dir.path(), "rgb", &args("--rgb"));
        let spectral = render(&scene(name), dir.path(), "spectral", &args("--spectral"));
        println!(
            "{name}: RGB {:?}, spectral {:?}",
            rgb.image.mean(),
            spectral.image.mean()
        );
        for c in 0..3 {
            let (a, b) = (rgb.image.mean()[c], spectral.image.mean()[c]);
            assert!((a - b).abs() < 0.02 * a, "{name} channel {c}: {a} vs {b}");
        }
    }
}

/// A spectral render is the same bytes for any tile size and thread count, and the scene's
/// option gives what the flag gives; `--rgb` overrides the option.
#[test]
fn spectral_renders_are_deterministic_and_the_option_is_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let base = ["--resolution", "40x28", "--spp", "8"];
    let materials = scene("materials/scene.pbrt");
    let with = |extra: &[&'static str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        a
    };
    let one = render(
        &materials,
        dir.path(),
        "one",
        &with(&["--spectral", "--tile", "40", "--threads", "1"]),
    );
    let many = render(
        &materials,
        dir.path(),
        "many",
        &with(&["--spectral", "--tile", "8", "--threads", "2"]),
    );
    assert!(
        one.bytes == many.bytes,
        "tile split or threads changed the bytes"
    );
    // And through a grid medium, a temperature grid's emission sampled as a light; and the
    // headline frame's VolumeLight, seen through its glass.
    for name in ["fire/scene.pbrt", "molten-glass/scene.pbrt"] {
        let split = |tile: &'static str, threads: &'static str| {
            render(
                &scene(name),
                dir.path(),
                &format!("split-{tile}"),
                &with(&["--spectral", "--tile", tile, "--threads", threads]),
            )
            .bytes
        };
        assert!(
            split("40", "1") == split("8", "2"),
            "tile split or threads changed {name}'s bytes"
        );
    }
    // Kiln's own scene asks for RGB; without that line it is a pbrt-v4 user's scene, which
    // renders spectrally by default.
    let text = std::fs::read_to_string(&materials).unwrap();
    let option = "Option \"kiln.spectral\" false";
    assert!(
        text.contains(option),
        "scenes/materials no longer asks for RGB"
    );
    let unmarked: String = text
        .lines()
        .filter(|l| !l.starts_with(option))
        .map(|l| format!("{l}\n"))
        .collect();
    let users = write_scene(dir.path(), "users.pbrt", &unmarked);
    let opted = write_scene(
        dir.path(),
        "opted.pbrt",
        &format!("Option \"kiln.spectral\" true\n{unmarked}"),
    );
    let by_default = render(&users, dir.path(), "default", &base);
    let by_option = render(&opted, dir.path(), "option", &base);
    let rgb_anyway = render(&opted, dir.path(), "rgb", &with(&["--rgb"]));
    let rgb_flag = render(&users, dir.path(), "rgb-flag", &with(&["--rgb"]));
    let rgb = render(&materials, dir.path(), "own", &base);
    let spectral_anyway = render(
        &materials,
        dir.path(),
        "own-spectral",
        &with(&["--spectral"]),
    );
    assert!(
        by_default.bytes == one.bytes,
        "a scene without the option is not spectral by default"
    );
    assert!(
        by_option.bytes == one.bytes,
        "the option differs from --spectral"
    );
    assert!(
        spectral_anyway.bytes == one.bytes,
        "--spectral did not override the option"
    );
    assert!(
        rgb_anyway.bytes == rgb.bytes && rgb_flag.bytes == rgb.bytes,
        "--rgb did not override the option or the default"
    );
    assert!(rgb.bytes != one.bytes);
}

/// Dispersive glass conserves energy: in a white furnace (uniform white light all round) a
/// lossless glass sphere is invisible, whatever its index, so the image stays white on every
/// channel though each path through the glass keeps its hero wavelength alone (four times
/// over) from its first glass hit on. Both a named glass (BK7, by its Sellmeier index) and
/// an inline spectrum of strong dispersion (1.60 at 400 nm to 1.45 at 700 nm).
#[test]
fn dispersive_glass_in_a_white_furnace_stays_white() {
    let dir = tempfile::tempdir().unwrap();
    for (name, eta) in [
        ("bk7", "\"glass-BK7\""),
        ("inline", "[ 400 1.60 700 1.45 ]"),
    ] {
        let text = format!(
            "Integrator \"volpath\" \"integer maxdepth\" [ 100 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
             LookAt 0 0 5  0 0 0  0 1 0\n\
             Camera \"perspective\" \"float fov\" [ 28 ]\n\
             WorldBegin\n\
             LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
             Material \"dielectric\" \"spectrum eta\" {eta}\n\
             Shape \"sphere\" \"float radius\" 1\n"
        );
        let path = write_scene(dir.path(), &format!("{name}.pbrt"), &text);
        let r = render(&path, dir.path(), name, &["--spectral", "--spp", "256"]);
        assert_white(name, &r.image, 5e-3);
    }
}

/// Dispersive glass under SPPM: a camera path and a photon that each keep their hero
/// wavelength alone weigh it four times, once (not sixteen times when both did). The glass
/// ball's caustic with BK7 (dispersive) and with BK7's index at 550 nm (not) gives the same
/// image means within 2% per channel, the caustic's colours spread but not its energy, and
/// the floor seen through the ball within 5% (measured +1.4%, -0.9%, -2.3%; weighing such
/// photons sixteen times gives +8.5% to +11%); under a white sky alone the dispersive ball
/// vanishes under SPPM as under path tracing.
#[test]
fn dispersive_glass_under_sppm_keeps_its_energy() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene("photons/ball.pbrt")).unwrap();
    let plain = "Material \"dielectric\" \"float eta\" [ 1.5 ]";
    assert!(text.contains(plain));
    let means = |eta: &str, name: &str| {
        let variant = text.replace(plain, &format!("Material \"dielectric\" {eta}"));
        let path = write_scene(dir.path(), &format!("{name}.pbrt"), &variant);
        let args = ["--spectral", "--spp", "256", "--resolution", "32x32"];
        let image = render(&path, dir.path(), name, &args).image;
        // The floor seen through the ball: camera paths that refracted gather there.
        let through = [0, 1, 2].map(|c| block_stats(&image, 10, 12, 12, 12, c).0);
        (image.mean(), through)
    };
    let (dispersive, through_d) = means("\"spectrum eta\" \"glass-BK7\"", "dispersive");
    let (plain, through_p) = means("\"float eta\" [ 1.5185 ]", "plain");
    println!(
        "SPPM ball: dispersive {dispersive:?} ({through_d:?} through the ball), plain {plain:?} ({through_p:?})"
    );
    for c in 0..3 {
        assert!(
            (dispersive[c] / plain[c] - 1.0).abs() < 0.02,
            "channel {c}: dispersive {dispersive:?} vs plain {plain:?}"
        );
        assert!(
            (through_d[c] / through_p[c] - 1.0).abs() < 0.05,
            "channel {c} through the ball: dispersive {through_d:?} vs plain {through_p:?}"
        );
    }
    let furnace = "Integrator \"sppm\" \"integer maxdepth\" [ 100 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
         LookAt 0 0 5  0 0 0  0 1 0\n\
         Camera \"perspective\" \"float fov\" [ 28 ]\n\
         WorldBegin\n\
         LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
         Material \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n\
         Shape \"sphere\" \"float radius\" 1\n";
    let path = write_scene(dir.path(), "furnace.pbrt", furnace);
    let r = render(
        &path,
        dir.path(),
        "furnace",
        &["--spectral", "--spp", "256"],
    );
    assert_white("sppm furnace", &r.image, 5e-3);
}

/// A scene of a sphere of `material` under a uniform white sky (64x64, 256 spp).
fn sphere_under_sky(material: &str) -> String {
    format!(
        "Film \"rgb\" \"integer xresolution\" [ 64 ] \"integer yresolution\" [ 64 ]\n\
         Sampler \"zsobol\" \"integer pixelsamples\" [ 256 ]\n\
         Integrator \"volpath\" \"integer maxdepth\" [ 50 ]\n\
         LookAt 0 0 5  0 0 0  0 1 0\n\
         Camera \"perspective\" \"float fov\" [ 30 ]\n\
         WorldBegin\n\
         LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
         {material}\n\
         Shape \"sphere\" \"float radius\" 1\n"
    )
}

/// Coated materials render as pbrt-v4 renders them spectrally: a sphere under a white sky,
/// the mean of its centre (20 x 20 pixels), against pbrt-v4's (5f7a606, 1024 spp) within 1.5%
/// per channel (measured: within 0.3%). A saturated coated diffuse is where RGB rendering
/// drifts: its light crosses the colour many times between the coat and the base, and RGB
/// mode is 7.5% bright in red there (checked, so that the test can tell).
#[test]
fn coated_materials_match_pbrt_v4_spectrally() {
    let dir = tempfile::tempdir().unwrap();
    let mut cases = vec![
        (
            "coated diffuse",
            "Material \"coateddiffuse\" \"rgb reflectance\" [ 0.8 0.3 0.1 ] \"float roughness\" [ 0 ]".to_string(),
            [0.54401, 0.17534, 0.07603],
        ),
        (
            "rough coated diffuse",
            "Material \"coateddiffuse\" \"rgb reflectance\" [ 0.2 0.5 0.8 ] \"float roughness\" [ 0.2 ]".to_string(),
            [0.10287, 0.24545, 0.41540],
        ),
    ];
    match crate::util::reference_scene("killeroo-coated-gold") {
        Some(scene) => {
            let spds = scene.parent().unwrap().join("spds");
            let gold = |rough: f32| {
                format!(
                    "Material \"coatedconductor\" \"spectrum conductor.k\" [ \"{}\" ] \"spectrum conductor.eta\" [ \"{}\" ] \"float interface.roughness\" [ {rough} ] \"float conductor.roughness\" [ {} ]",
                    spds.join("Au.k.spd").display(),
                    spds.join("Au.eta.spd").display(),
                    if rough < 0.1 { 0.002 } else { rough }
                )
            };
            cases.push(("coated gold", gold(0.02), [0.92858, 0.67866, 0.23748]));
            cases.push(("rough coated gold", gold(0.3), [0.30568, 0.22281, 0.08341]));
        }
        None => println!("SKIPPED: the coated gold cases (../shared/reference-scenes is not here)"),
    }
    for (i, (what, material, pbrt)) in cases.iter().enumerate() {
        let path = write_scene(
            dir.path(),
            &format!("{i}.pbrt"),
            &sphere_under_sky(material),
        );
        let r = render(&path, dir.path(), &format!("{i}"), &["--spectral"]);
        let centre = [0, 1, 2].map(|c| block_stats(&r.image, 22, 22, 20, 20, c).0);
        println!("{what}: Kiln {centre:?}, pbrt-v4 {pbrt:?}");
        crate::util::assert_matches_pbrt(what, centre, *pbrt, 0.015, 3);
        if i == 0 {
            let rgb = render(&path, dir.path(), "rgb", &["--rgb"]).image;
            let red = block_stats(&rgb, 22, 22, 20, 20, 0).0;
            assert!(red / pbrt[0] > 1.05, "RGB mode's red {red}");
        }
    }
}

/// A near-specular coated gold (the killeroo's: interface roughness 0.02, conductor 0.002)
/// lit by a small sphere light: Kiln's light sampling (which evaluates the layered BSDF's
/// stochastic f) and its BSDF sampling (its random walk) give the same image, within 3% over
/// the sphere's centre. pbrt-v4 (5f7a606, 1024 spp, two seeds: 0.3253-0.3273 in red) is 9%
/// above both, while under a uniform sky, where BSDF sampling carries the image, it agrees
/// with Kiln within 0.1% (`coated_materials_match_pbrt_v4_spectrally`). The likely cause:
/// where pbrt-v4's `LayeredBxDF::f` weighs light that a reflection off the non-exit
/// interface sends out through the exit interface, it takes the exit's transmission density
/// as PDF(-w, wi), the reverse of the direction its other strategy samples (Kiln takes
/// pdf(wi, -w)), so the two MIS weights need not sum to one. Kiln keeps its answer; this is
/// the killeroo-coated-gold body's 4% (README, "Where it stands").
#[test]
fn a_near_specular_coated_gold_is_the_same_by_light_and_by_bsdf_sampling() {
    let Some(scene) = crate::util::reference_scene("killeroo-coated-gold") else {
        println!("SKIPPED: ../shared/reference-scenes is not here (the gold's .spd files)");
        return;
    };
    let spds = scene.parent().unwrap().join("spds");
    let dir = tempfile::tempdir().unwrap();
    let mut means = Vec::new();
    for strategy in ["light", "bsdf"] {
        let text = format!(
            "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n\
             Sampler \"zsobol\" \"integer pixelsamples\" [ 1024 ]\n\
             Integrator \"volpath\" \"integer maxdepth\" [ 50 ] \"string strategy\" \"{strategy}\"\n\
             LookAt 0 0 5  0 0 0  0 1 0\n\
             Camera \"perspective\" \"float fov\" [ 30 ]\n\
             WorldBegin\n\
             AttributeBegin\n\
             AreaLightSource \"diffuse\" \"rgb L\" [ 30 30 30 ]\n\
             Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n\
             Translate 0 0.9 5\n\
             Shape \"sphere\" \"float radius\" 0.4\n\
             AttributeEnd\n\
             Material \"coatedconductor\" \"spectrum conductor.k\" [ \"{}\" ] \"spectrum conductor.eta\" [ \"{}\" ] \"float interface.roughness\" [ 0.02 ] \"float conductor.roughness\" [ 0.002 ]\n\
             Shape \"sphere\" \"float radius\" 1\n",
            spds.join("Au.k.spd").display(),
            spds.join("Au.eta.spd").display()
        );
        let path = write_scene(dir.path(), &format!("{strategy}.pbrt"), &text);
        let img = render(&path, dir.path(), strategy, &["--spectral"]).image;
        means.push([0, 1, 2].map(|c| block_stats(&img, 11, 11, 10, 10, c).0));
    }
    println!(
        "light sampling {:?}, BSDF sampling {:?}",
        means[0], means[1]
    );
    for c in 0..3 {
        assert!(
            (means[0][c] / means[1][c] - 1.0).abs() < 0.03,
            "channel {c}: light {:?} vs BSDF {:?}",
            means[0],
            means[1]
        );
    }
}

/// A coated diffuse lit by a constant environment map is what it is under a uniform sky of
/// the same radiance: the map is found by light sampling and the sky by BSDF sampling alone,
/// so the two estimators must agree. Kiln's do (0.12324 and 0.12325, 32x32, 1024 spp).
/// pbrt-v4's do not: 0.125181 with the map against 0.123146 under the sky (5f7a606, the
/// same files), +1.65%, from its layered BSDF's weighting of light samples (docs: the
/// killeroo-coated-gold figures). Kiln is held to pbrt-v4's sky, which pbrt-v4 computes
/// without light sampling; the survey's coffee and sssdragon floors differ by this.
#[test]
fn a_coated_diffuse_under_a_constant_map_is_as_under_a_uniform_sky() {
    const PBRT_SKY: f64 = 0.123146;
    let dir = tempfile::tempdir().unwrap();
    crate::util::write_pfm(&dir.path().join("grey.pfm"), 4, 4, &[[0.5; 3]; 16]);
    let lit = |name: &str, light: &str| {
        let text = format!(
            "LookAt 0 0 5  0 0 0  0 1 0\n\
             Camera \"orthographic\" \"float screenwindow\" [ -1 1 -1 1 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n\
             Sampler \"halton\" \"integer pixelsamples\" [ 1024 ]\n\
             PixelFilter \"box\"\n\
             Integrator \"volpath\" \"integer maxdepth\" [ 5 ]\n\
             WorldBegin\n\
             {light}\n\
             Material \"coateddiffuse\" \"float roughness\" [ 0.2 ]\n\
             Shape \"bilinearmesh\" \"point3 P\" [ -1 -1 0  1 -1 0  -1 1 0  1 1 0 ]\n"
        );
        let path = write_scene(dir.path(), &format!("{name}.pbrt"), &text);
        render(&path, dir.path(), name, &["--spectral"])
            .image
            .mean()
    };
    let sky = lit("sky", r#"LightSource "infinite" "rgb L" [ 0.5 0.5 0.5 ]"#);
    let map = lit(
        "map",
        r#"LightSource "infinite" "string filename" "grey.pfm""#,
    );
    println!("sky {sky:?}, map {map:?}, pbrt-v4's sky {PBRT_SKY}");
    for c in 0..3 {
        assert!(
            (map[c] / sky[c] - 1.0).abs() < 0.003,
            "map {map:?}, sky {sky:?}"
        );
        assert!((sky[c] / PBRT_SKY - 1.0).abs() < 0.005, "sky {sky:?}");
    }
}

/// pbrt-v4's named illuminants light a spectral path as their CIE tables: a red surface
/// under a sky of fluorescent F11 (three narrow bands) against pbrt-v4's render of the same
/// file (32x32, 1024 spp) within 2% per channel (measured -0.1%, +0.1%, -1.5%). Light of the
/// illuminant's RGB, upsampled as before, is 8.6% bright in red on the same surface.
#[test]
fn a_named_illuminant_is_its_cie_table() {
    const PBRT: [f64; 3] = [0.59926, 0.135072, 0.028206];
    let dir = tempfile::tempdir().unwrap();
    let lit = |light: &str| {
        let text = format!(
            "Integrator \"volpath\" \"integer maxdepth\" [ 5 ]\n\
             Sampler \"halton\" \"integer pixelsamples\" [ 1024 ]\n\
             PixelFilter \"box\"\n\
             Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n\
             LookAt 0 0 5  0 0 0  0 1 0\n\
             Camera \"orthographic\" \"float screenwindow\" [ -0.5 0.5 -0.5 0.5 ]\n\
             WorldBegin\n\
             {light}\n\
             Material \"diffuse\" \"rgb reflectance\" [ 0.7 0.2 0.1 ]\n\
             Shape \"bilinearmesh\" \"point3 P\" [ -1 -1 0  1 -1 0  -1 1 0  1 1 0 ]\n"
        );
        let path = write_scene(dir.path(), "f11.pbrt", &text);
        render(&path, dir.path(), "f11", &["--spectral"])
            .image
            .mean()
    };
    let table = lit(r#"LightSource "infinite" "spectrum L" "stdillum-F11" "float scale" [ 0.7 ]"#);
    crate::util::assert_matches_pbrt("F11 on red", table, PBRT, 0.02, 3);
    // The same light's RGB (stdillum-F11's, times 0.7), upsampled: the test can tell.
    let upsampled = lit(r#"LightSource "infinite" "rgb L" [ 0.98714 0.64776 0.37143 ]"#);
    println!("F11 table {table:?}, its RGB upsampled {upsampled:?}, pbrt-v4 {PBRT:?}");
    assert!(upsampled[0] / PBRT[0] - 1.0 > 0.05, "{upsampled:?}");
}

/// A named spectrum the user measured, in the folder KILN_SPECTRUM_DATA names, is read as
/// its table: a smooth gold-like conductor named `metal-Au-eta` / `metal-Au-k` renders the
/// same bytes as the same tables given inline (their end values carried on to 360 and
/// 830 nm, as pbrt-v4 carries its named spectra's), and not the bytes of Kiln's own colour
/// of gold; a conductor given no eta and k is copper's tables there. A broken file there is
/// an error naming it, its line and the scene's line.
#[test]
fn a_measured_named_spectrum_is_read_as_its_table() {
    let data = tempfile::tempdir().unwrap();
    let eta = "400 1.6\n450 1.5\n500 0.9\n550 0.35\n600 0.22\n700 0.16\n";
    let k = "# k\n400 1.95\n450 1.88\n500 1.89\n550 2.7\n600 3.0\n700 3.96\n";
    // Copper's files hold the same tables: a conductor given no eta and k is copper.
    for metal in ["Au", "Cu"] {
        std::fs::write(data.path().join(format!("metal-{metal}-eta.spd")), eta).unwrap();
        std::fs::write(data.path().join(format!("metal-{metal}-k.spd")), k).unwrap();
    }
    let inline = |table: &str| {
        let nums: Vec<&str> = table
            .lines()
            .filter(|l| !l.starts_with('#'))
            .flat_map(|l| l.split_whitespace())
            .collect();
        let (first, last) = (nums[1], nums[nums.len() - 1]);
        format!("[ 360 {first} {} 830 {last} ]", nums.join(" "))
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = |name: &str, material: String| {
        let text = sphere_under_sky(&material).replace("[ 256 ]", "[ 16 ]");
        write_scene(dir.path(), name, &text)
    };
    let named = scene(
        "named.pbrt",
        r#"Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0"#.into(),
    );
    let tables = scene(
        "inline.pbrt",
        format!(
            r#"Material "conductor" "spectrum eta" {} "spectrum k" {} "float roughness" 0"#,
            inline(eta),
            inline(k)
        ),
    );
    let env = [("KILN_SPECTRUM_DATA", data.path().to_str().unwrap())];
    let measured = render_with_env(&named, dir.path(), "measured", &["--spectral"], &env);
    let given = render(&tables, dir.path(), "given", &["--spectral"]);
    let own = render(&named, dir.path(), "own", &["--spectral"]);
    assert!(
        measured.bytes == given.bytes,
        "the measured tables were not used"
    );
    assert!(
        own.bytes != given.bytes,
        "the test cannot tell the tables from the colour"
    );
    let copper = scene(
        "copper.pbrt",
        r#"Material "conductor" "float roughness" 0"#.into(),
    );
    let default = render_with_env(&copper, dir.path(), "copper", &["--spectral"], &env);
    assert!(
        default.bytes == given.bytes,
        "copper's measured tables were not the default"
    );

    std::fs::write(data.path().join("metal-Au-k.spd"), "400 1.9\n500 x\n").unwrap();
    let out = crate::util::kiln()
        .env("KILN_SPECTRUM_DATA", data.path())
        .arg("render")
        .arg(&named)
        .arg("-o")
        .arg(dir.path().join("broken.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("named.pbrt:8:") && err.contains("metal-Au-k.spd', line 2: 'x'"),
        "{err}"
    );
}
