//! Renders of scenes nobody at Kiln wrote, held against other renderers' means.

use crate::util::{assert_matches_pbrt, block_stats, reference_scene, render};

/// reference-scenes/README.md: Tungsten's mean of the Cornell box (Mitsuba 3 agrees to 0.1%).
/// Both render RGB, so Kiln's RGB mode is held against it.
const CORNELL_REFERENCE: [f64; 3] = [0.19625, 0.12753, 0.03610];

#[test]
fn cornell_box_matches_the_reference_mean() {
    let Some(path) = reference_scene("cornell-box") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let r = render(
        &path,
        dir.path(),
        "cornell",
        &["--resolution", "128x128", "--spp", "64", "--rgb"],
    );
    let mean = r.image.mean();
    for c in 0..3 {
        let rel = (mean[c] - CORNELL_REFERENCE[c]).abs() / CORNELL_REFERENCE[c];
        assert!(
            rel < 0.015,
            "channel {c}: kiln {} vs reference {} ({:.2}% off)",
            mean[c],
            CORNELL_REFERENCE[c],
            rel * 100.0
        );
    }
}

/// reference-scenes/README.md: pbrt-v4's spectral mean of the same Cornell box file (128x128,
/// 256 spp), up to 4% off the RGB renderers' in blue.
const CORNELL_PBRT_V4: [f64; 3] = [0.19498, 0.12673, 0.03468];

/// In spectral mode Kiln renders the Cornell box as pbrt-v4 does, within 1.2% per channel
/// (measured: 0.1%, 0.2%, 0.6% at 64 spp over three seeds), where its RGB mode is 4% bright
/// in blue (0.03612): the box's saturated walls light each other many times, and a product
/// of RGB triples is not a product of spectra.
#[test]
fn the_cornell_box_in_spectral_mode_matches_pbrt_v4() {
    let Some(path) = reference_scene("cornell-box") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let args = ["--resolution", "128x128", "--spp", "64"];
    let spectral = render(
        &path,
        dir.path(),
        "spectral",
        &[&args[..], &["--spectral"]].concat(),
    );
    let rgb = render(&path, dir.path(), "rgb", &[&args[..], &["--rgb"]].concat());
    println!(
        "spectral {:?}, RGB {:?}",
        spectral.image.mean(),
        rgb.image.mean()
    );
    assert_matches_pbrt(
        "Cornell box, spectral",
        spectral.image.mean(),
        CORNELL_PBRT_V4,
        0.012,
        3,
    );
    // The test can tell: RGB is out of the same bounds in blue.
    assert!((rgb.image.mean()[2] / CORNELL_PBRT_V4[2] - 1.0).abs() > 0.012);
}

/// pbrt-v4's SPPM render of reference-scenes/water-caustic as its file stands (Integrator
/// "sppm", radius 0.01, maxdepth 9) at 160x160 and 256 iterations, the mean of two seeds
/// (they agree to 0.2%), over the frame without the 7x7 pixels around the light itself:
/// the light is a 5x4 mm quad of radiance 5*10^5 covering 1.6% of one pixel, which
/// pbrt-v4's independent sampler hit in one seed and missed in the other.
const WATER_SPPM_PBRT: [f64; 3] = [0.231673, 0.142573, 0.034017];

/// The same renders' means of RGB over 20x20 blocks covering the water and the floor under
/// it (rows 40..160, columns 20..140): the caustic.
const WATER_SPPM_PBRT_BLOCKS: [[f64; 6]; 6] = [
    [0.09129, 0.13525, 0.13066, 0.15472, 0.16604, 0.13348],
    [0.10192, 0.11354, 0.1483, 0.12231, 0.14598, 0.11659],
    [0.09724, 0.11579, 0.10775, 0.12126, 0.1443, 0.14017],
    [0.07808, 0.10813, 0.13413, 0.13181, 0.16664, 0.15669],
    [0.07248, 0.11631, 0.11057, 0.1402, 0.14207, 0.13552],
    [0.1307, 0.19947, 0.22738, 0.23534, 0.12163, 0.07774],
];

/// Means of `img` (160x160) without the light's pixels.
fn water_means(img: &kiln_image::RgbBuffer) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    let mut n = 0.0;
    for y in 0..160 {
        for x in 0..160 {
            if (10..17).contains(&y) && (76..83).contains(&x) {
                continue;
            }
            let p = img.get(x, y);
            for c in 0..3 {
                sum[c] += p[c] as f64;
            }
            n += 1.0;
        }
    }
    sum.map(|v| v / n)
}

/// reference-scenes/water-caustic with "sppm", as its file asks (SPPM is where its caustic
/// converges): Kiln's SPPM against pbrt-v4's. Red and green within 3%, every caustic block
/// within 5%. Blue is 7.5% brighter in Kiln: the light is saturated orange and the walls red
/// and green, and Kiln multiplies RGB where pbrt-v4 multiplies spectra; with direct light
/// only (maxdepth 1) the two differ by the same 7.6% in blue under the water, and with a
/// white light and grey walls SPPM agrees to 0.2% in every channel (the next test).
///
/// That blue excess lifts the caustic blocks (means of R, G and B) by 1.9% on average, and
/// blocks scatter by 1.5% (one standard deviation) from one render's noise to another's,
/// so in RGB each block is compared after dividing out the blocks' common level: the
/// caustic's shape within 5%, its level held by the channel means above. (Error-bounded
/// ray offsets changed the blocks by a factor of 1.0011 ± 0.0083, noise, and took one
/// block from +4.1% to +5.7% of pbrt-v4's in absolute terms.)
#[test]
fn water_caustic_sppm_matches_pbrt() {
    water_caustic_sppm_against_pbrt(&["--rgb"], [0.03, 0.03, 0.10], Blocks::Shape(0.05));
}

/// [`water_caustic_sppm_matches_pbrt`] rendered spectrally, as pbrt-v4 renders: each
/// iteration's camera paths and photons share its wavelengths, and the orange light on red
/// and green walls multiplies spectra. Every channel within 2%, every caustic block within 5%.
#[test]
fn water_caustic_sppm_matches_pbrt_spectrally() {
    water_caustic_sppm_against_pbrt(&["--spectral"], [0.02; 3], Blocks::Absolute(0.05));
}

/// How the caustic's blocks are compared with pbrt-v4's.
enum Blocks {
    /// Each block's mean within this fraction of pbrt-v4's.
    Absolute(f64),
    /// Each block's mean within this fraction of pbrt-v4's times the blocks' mean ratio
    /// to pbrt-v4's: the caustic's shape, whatever its level.
    Shape(f64),
}

/// The water caustic under SPPM against pbrt-v4's, rendered with `args`: each channel's
/// mean within `within`, each caustic block as `blocks` says.
fn water_caustic_sppm_against_pbrt(args: &[&str], within: [f64; 3], blocks: Blocks) {
    let Some(path) = reference_scene("water-caustic") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let r = render(
        &path,
        dir.path(),
        "water",
        &[&["--resolution", "160x160", "--spp", "128"], args].concat(),
    );
    let stderr = String::from_utf8_lossy(&r.output.stderr);
    assert!(stderr.contains("103487 triangles"), "{stderr}");
    let mean = water_means(&r.image);
    eprintln!("water-caustic sppm {args:?}: kiln {mean:.5?}, pbrt-v4 {WATER_SPPM_PBRT:?}");
    for (c, tolerance) in within.into_iter().enumerate() {
        let rel = mean[c] / WATER_SPPM_PBRT[c] - 1.0;
        assert!(
            rel.abs() < tolerance,
            "channel {c}: kiln {} vs pbrt-v4 {} ({:+.2}%)",
            mean[c],
            WATER_SPPM_PBRT[c],
            rel * 100.0
        );
    }
    let got: Vec<Vec<f64>> = (0..6)
        .map(|j| {
            (0..6)
                .map(|i| {
                    let (x0, y0) = (20 + 20 * i as u32, 40 + 20 * j as u32);
                    (0..3)
                        .map(|c| block_stats(&r.image, x0, y0, 20, 20, c).0)
                        .sum::<f64>()
                        / 3.0
                })
                .collect()
        })
        .collect();
    let ratios = || (0..36).map(|k| got[k / 6][k % 6] / WATER_SPPM_PBRT_BLOCKS[k / 6][k % 6]);
    let (level, tolerance) = match blocks {
        Blocks::Absolute(t) => (1.0, t),
        Blocks::Shape(t) => (ratios().sum::<f64>() / 36.0, t),
    };
    eprintln!(
        "water-caustic sppm {args:?}: blocks' mean ratio to pbrt-v4 {:.4}",
        ratios().sum::<f64>() / 36.0
    );
    for (j, row) in WATER_SPPM_PBRT_BLOCKS.iter().enumerate() {
        for (i, &want) in row.iter().enumerate() {
            let (x0, y0) = (20 + 20 * i, 40 + 20 * j);
            let got = got[j][i];
            assert!(
                (got / (want * level) - 1.0).abs() < tolerance,
                "caustic block at {x0}, {y0}: kiln {got} vs pbrt-v4 {want} (times the level {level:.4})"
            );
        }
    }
}

/// pbrt-v4's SPPM of the water-caustic file with a white light (rgb L 4*10^5 each) and grey
/// walls (0.5; floor, ceiling, back wall and boxes 0.7), 160x160, 256 iterations, without
/// the light's pixels.
const WATER_GREY_SPPM_PBRT: [f64; 3] = [0.187388, 0.187454, 0.187816];

/// The water caustic with colour taken out (white light, grey walls): Kiln's SPPM agrees
/// with pbrt-v4's to 2% in every channel (0.2% measured), so what differs in the coloured
/// file is spectral.
#[test]
fn water_caustic_sppm_in_grey_matches_pbrt() {
    let Some(path) = reference_scene("water-caustic") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let grey = text
        .replace(
            "\"rgb L\" [ 541126.75 381971.8 127323.94 ]",
            "\"rgb L\" [ 400000 400000 400000 ]",
        )
        .replace(
            "\"rgb reflectance\" [ 0.63 0.065 0.05 ]",
            "\"rgb reflectance\" [ 0.5 0.5 0.5 ]",
        )
        .replace(
            "\"rgb reflectance\" [ 0.14 0.45 0.091 ]",
            "\"rgb reflectance\" [ 0.5 0.5 0.5 ]",
        )
        .replace(
            "\"rgb reflectance\" [ 0.725 0.71 0.68 ]",
            "\"rgb reflectance\" [ 0.7 0.7 0.7 ]",
        );
    assert_eq!(
        grey.matches("0.5 0.5 0.5").count(),
        2,
        "the file's walls changed"
    );
    assert!(
        grey.contains("400000 400000 400000"),
        "the file's light changed"
    );
    std::os::unix::fs::symlink(
        path.parent().unwrap().join("models"),
        dir.path().join("models"),
    )
    .unwrap();
    let grey_path = crate::util::write_scene(dir.path(), "grey.pbrt", &grey);
    let r = render(
        &grey_path,
        dir.path(),
        "grey",
        &["--resolution", "160x160", "--spp", "64"],
    );
    let mean = water_means(&r.image);
    eprintln!("water-caustic sppm, grey: kiln {mean:.5?}, pbrt-v4 {WATER_GREY_SPPM_PBRT:?}");
    for c in 0..3 {
        let rel = mean[c] / WATER_GREY_SPPM_PBRT[c] - 1.0;
        assert!(
            rel.abs() < 0.02,
            "channel {c}: kiln {} vs pbrt-v4 {} ({:+.2}%)",
            mean[c],
            WATER_GREY_SPPM_PBRT[c],
            rel * 100.0
        );
    }
}

/// reference-scenes/README.md: pbrt-v4's own mean for this file at 160x90 (both render
/// spectrally, Kiln by default).
const VEACH_PBRT: [f64; 3] = [1.10834, 0.89611, 0.83308];

#[test]
fn veach_mis_matches_pbrt_mean() {
    let Some(path) = reference_scene("veach-mis") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let r = render(
        &path,
        dir.path(),
        "veach",
        &["--resolution", "160x90", "--spp", "256"],
    );
    let mean = r.image.mean();
    for c in 0..3 {
        let rel = (mean[c] - VEACH_PBRT[c]).abs() / VEACH_PBRT[c];
        assert!(
            rel < 0.03,
            "channel {c}: kiln {} vs pbrt-v4 {} ({:.2}% off)",
            mean[c],
            VEACH_PBRT[c],
            rel * 100.0
        );
    }
}

/// Mitsuba 3's estimate of the volumetric-caustic scene (`benches/mitsuba/volumetric_caustic.py`:
/// the file rebuilt in Mitsuba, `llvm_ad_rgb` volpath, 60 independent renders of 32x32 at 4096
/// spp): the mean over the frame without the block of pixels around the 5x4 mm light, whose
/// sliver camera samples hit or miss whole. Standard error 0.0089 0.0062 0.0020.
const VOLUMETRIC_CAUSTIC_MITSUBA: [f64; 3] = [0.52952, 0.35102, 0.10564];
/// pbrt-v4's mean of one render at 128x128, 256 spp (reference-scenes/README.md). The
/// scene's caustic (a tiny light focused by a glass ball into gas) reaches a path tracer as
/// rare fireflies worth about 0.1 to 0.3 of the image mean each, and the light itself as whole
/// camera-sample hits: single renders of 4 million samples spread from 0.55 to 0.95 in
/// Mitsuba (60 of them), so one such render is not a reference to 4%. Printed, not tested.
const VOLUMETRIC_CAUSTIC_PBRT: [f64; 3] = [1.05356, 0.73717, 0.25214];

/// The volumetric caustic, rendered by Kiln with caustic photon maps (the file unchanged
/// but for `"integer causticphotons"` on its Integrator line), against Mitsuba 3's converged
/// estimate: within 4% in every channel.
#[test]
fn volumetric_caustic_matches_an_independent_estimate() {
    let Some(path) = reference_scene("volumetric-caustic") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let line = "\nIntegrator \"volpath\"\n";
    assert_eq!(
        text.matches(line).count(),
        1,
        "the file's Integrator line moved"
    );
    let dir = tempfile::tempdir().unwrap();
    let variant = crate::util::write_scene(
        dir.path(),
        "caustic.pbrt",
        &text.replace(
            line,
            "\nIntegrator \"volpath\" \"integer causticphotons\" [ 2000000 ]\n",
        ),
    );
    let img = render(
        &variant,
        dir.path(),
        "caustic",
        // In RGB, as Mitsuba's llvm_ad_rgb rendered its reference.
        &["--resolution", "32x32", "--spp", "1024", "--rgb"],
    )
    .image;
    let mut masked = [0.0f64; 3];
    let mut n = 0.0;
    for y in 0..32 {
        for x in 0..32 {
            if (1..6).contains(&y) && (13..19).contains(&x) {
                continue;
            }
            let p = img.get(x, y);
            for c in 0..3 {
                masked[c] += p[c] as f64;
            }
            n += 1.0;
        }
    }
    let mean = img.mean();
    eprintln!(
        "volumetric-caustic: kiln mean {mean:.4?} (pbrt-v4's one render: {VOLUMETRIC_CAUSTIC_PBRT:?})"
    );
    for c in 0..3 {
        let m = masked[c] / n;
        let rel = (m - VOLUMETRIC_CAUSTIC_MITSUBA[c]).abs() / VOLUMETRIC_CAUSTIC_MITSUBA[c];
        eprintln!(
            "volumetric-caustic channel {c}: kiln {m:.5} vs Mitsuba {} ({:.2}% off), the light's pixels left out",
            VOLUMETRIC_CAUSTIC_MITSUBA[c],
            rel * 100.0
        );
        assert!(
            rel < 0.04,
            "channel {c}: kiln {m} vs Mitsuba {}",
            VOLUMETRIC_CAUSTIC_MITSUBA[c]
        );
    }
}

/// The gold killeroos as pbrt-v4 renders them (reference-scenes/README.md: 200x150, 1024
/// spp): a disk light, loopsubdiv, an image texture scaled by another, and gold from .spd
/// files. The frame outside the body within 1.5% (its mean follows from pbrt-v4's means of
/// the whole frame and of the body); the plain gold body within 1.5% per channel, which
/// the spectral Fresnel table makes possible (with the Fresnel of RGB eta and k its red
/// was 3.5% low). The coated body stays within 6%: it is 3-4% dark in RGB and in spectral
/// mode alike (256 spp, spectral: −4.1%, −3.7%, −1.8%), and the difference is pbrt-v4's:
/// Kiln's light and BSDF sampling of a near-specular coated gold agree with each other,
/// pbrt-v4's light sampling is 9% above them (spectral.rs,
/// `a_near_specular_coated_gold_is_the_same_by_light_and_by_bsdf_sampling`). At the test's
/// 32 spp the layered BSDF's stochastic estimates move the region's green by 1.5% from seed
/// to seed.
#[test]
fn killeroos_in_gold_match_pbrt_v4() {
    let cases = [
        (
            "killeroo-gold",
            [0.407560, 0.377244, 0.322936],
            [0.494213, 0.403287, 0.240001],
            0.015,
        ),
        (
            "killeroo-coated-gold",
            [0.386782, 0.355710, 0.305895],
            [0.434794, 0.341642, 0.190303],
            0.06,
        ),
    ];
    for (name, whole, body, body_within) in cases {
        let Some(path) = reference_scene(name) else {
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let img = render(
            &path,
            dir.path(),
            name,
            &["--resolution", "200x150", "--spp", "32"],
        )
        .image;
        // The body is 80x80 of the 200x150 frame.
        let (n, m) = (200.0 * 150.0, 80.0 * 80.0);
        let region = [0, 1, 2].map(|c| block_stats(&img, 60, 30, 80, 80, c).0);
        let mean = img.mean();
        let outside = |whole: [f64; 3], body: [f64; 3]| {
            [0, 1, 2].map(|c| (whole[c] * n - body[c] * m) / (n - m))
        };
        assert_matches_pbrt(
            &format!("{name}, around the body"),
            outside(mean, region),
            outside(whole, body),
            0.015,
            3,
        );
        assert_matches_pbrt(&format!("{name}, body"), region, body, body_within, 3);
    }
}

/// A smooth gold mirror (eta and k from the killeroo scene's .spd files) reflecting a white
/// sky, seen at 0°, 60° and 80°, against pbrt-v4's spectral renders of the same files: the
/// Fresnel reflectance within 1% per channel (pbrt-v4's red passes 1: the spectral
/// reflectance's RGB does). The Fresnel of the RGB-projected eta and k was 4.6% low in red.
#[test]
fn a_gold_mirror_reflects_as_pbrt_v4_renders_it_spectrally() {
    let Some(killeroo) = reference_scene("killeroo-gold") else {
        return;
    };
    let spds = killeroo.parent().unwrap().join("spds");
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (0, [1.02201059, 0.781886525, 0.341836349]),
        (60, [1.00672112, 0.786899041, 0.378505714]),
        (80, [0.984899931, 0.863839515, 0.580678249]),
    ];
    for (tilt, pbrt) in cases {
        let text = format!(
            r#"Integrator "path" "integer maxdepth" [ 1 ]
Sampler "halton" "integer pixelsamples" [ 16 ]
Film "rgb" "integer xresolution" [ 4 ] "integer yresolution" [ 4 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -0.01 0.01 -0.01 0.01 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "conductor" "spectrum k" [ "{k}" ] "spectrum eta" [ "{eta}" ] "float roughness" [ 0 ]
Rotate {tilt} 1 0 0
Shape "trianglemesh" "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ] "integer indices" [ 0 1 2 0 2 3 ]
"#,
            k = spds.join("Au.k.spd").display(),
            eta = spds.join("Au.eta.spd").display(),
        );
        let path = crate::util::write_scene(dir.path(), "gold.pbrt", &text);
        let kiln = render(&path, dir.path(), "gold", &[]).image.mean();
        assert_matches_pbrt(&format!("gold at {tilt}°"), kiln, pbrt, 0.01, 3);
    }
}

/// One blonde hair as pbrt-v4 renders it (reference-scenes/README.md: 192x160, 4096 spp):
/// a cylinder-type b-spline curve with the hair BSDF (eumelanin 0.2), a distant light and
/// an equal-area .pfm sky, maxdepth 65. The strand's region within 2% per channel
/// (measured at 1024 spp: −0.5%, −0.4%, −0.6%), and the frame's mean too.
#[test]
fn a_hair_matches_pbrt_v4() {
    hair_against_pbrt_v4(&["--rgb"]);
}

/// [`a_hair_matches_pbrt_v4`] rendered spectrally, as pbrt-v4 renders: the melanin's
/// absorption is an unbounded spectrum, and the lobes are chosen by their attenuation over
/// the path's four wavelengths.
#[test]
fn a_hair_matches_pbrt_v4_spectrally() {
    hair_against_pbrt_v4(&["--spectral"]);
}

fn hair_against_pbrt_v4(args: &[&str]) {
    let Some(path) = reference_scene("hair-curl") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let img = render(
        &path,
        dir.path(),
        "hair",
        &[&["--resolution", "192x160", "--spp", "256"], args].concat(),
    )
    .image;
    eprintln!(
        "hair-curl {args:?}: mean {:?}, strand {:?}",
        img.mean(),
        [0, 1, 2].map(|c| block_stats(&img, 150, 0, 42, 160, c).0)
    );
    assert_matches_pbrt(
        "hair-curl",
        img.mean(),
        [0.002667, 0.002613, 0.002299],
        0.02,
        3,
    );
    let strand = [0, 1, 2].map(|c| block_stats(&img, 150, 0, 42, 160, c).0);
    assert_matches_pbrt(
        "hair-curl, strand",
        strand,
        [0.012192, 0.011946, 0.010508],
        0.02,
        3,
    );
}
