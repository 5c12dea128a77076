//! Participating media (issue 5, first part): homogeneous media behind interface
//! boundaries, scattering, emission, and estimators that must agree through them.

use crate::util::{assert_strategies_agree, render, render_strategies, scene, write_scene};

/// pbrt-v4's convention: the source term is sigma_a * Le, so a ray through the centre of a
/// non-scattering emissive sphere sees Le (1 - exp(-2 r sigma_a)); off centre, the chord.
#[test]
fn emissive_sphere_of_medium_matches_the_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    let (r, sigma_a) = (1.5f64, 0.8f64);
    for b in [0.0, 0.9, 1.4] {
        let text = format!(
            "Sampler \"zsobol\" \"integer pixelsamples\" [ 4 ]
            Film \"rgb\" \"integer xresolution\" [ 4 ] \"integer yresolution\" [ 4 ]
            LookAt {b} 0 10  {b} 0 0  0 1 0
            Camera \"orthographic\" \"float screenwindow\" [ -0.0001 0.0001 -0.0001 0.0001 ]
            WorldBegin
            MakeNamedMedium \"glow\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [ {sigma_a} {sigma_a} {sigma_a} ] \"rgb sigma_s\" [ 0 0 0 ] \"rgb Le\" [ 2 1 0.5 ]
            AttributeBegin
              MediumInterface \"glow\" \"\"
              Material \"interface\"
              Shape \"sphere\" \"float radius\" [ {r} ]
            AttributeEnd"
        );
        let path = write_scene(dir.path(), "glow.pbrt", &text);
        let img = render(&path, dir.path(), "glow", &[]).image;
        let chord = 2.0 * (r * r - b * b).sqrt();
        for (c, le) in [2.0, 1.0, 0.5].iter().enumerate() {
            let expected = le * (1.0 - (-chord * sigma_a).exp());
            let got = img.mean()[c];
            assert!(
                (got - expected).abs() <= 0.005 * expected,
                "b = {b}, channel {c}: {got} vs {expected}"
            );
        }
    }
}

/// Inside a closed surface that emits 1 (and reflects nothing), a purely scattering medium
/// leaves radiance 1 everywhere: scattering only redistributes a uniform field. With
/// absorption it must come out darker, and with emission Le = 1 restoring it, 1 again.
#[test]
fn scattering_furnace_stays_uniform() {
    let dir = tempfile::tempdir().unwrap();
    for (sigma_a, le, expected) in [
        ("0 0 0", "0 0 0", Some(1.0)),
        ("0.5 0.5 0.5", "0 0 0", None),
        ("0.5 0.5 0.5", "1 1 1", Some(1.0)),
    ] {
        let text = format!(
            "Integrator \"volpath\" \"integer maxdepth\" [ 200 ]
            Sampler \"zsobol\" \"integer pixelsamples\" [ 64 ]
            Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]
            MakeNamedMedium \"gas\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [ {sigma_a} ] \"rgb sigma_s\" [ 1 1 1 ] \"rgb Le\" [ {le} ] \"float g\" [ 0.5 ]
            MediumInterface \"gas\" \"gas\"
            LookAt 0 0 0  0 0 1  0 1 0
            Camera \"perspective\" \"float fov\" [ 60 ]
            WorldBegin
            AttributeBegin
              MediumInterface \"gas\" \"\"
              AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ] \"bool twosided\" true
              Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]
              Shape \"sphere\" \"float radius\" [ 2 ]
            AttributeEnd"
        );
        let path = write_scene(dir.path(), "furnace.pbrt", &text);
        let m = render(&path, dir.path(), "furnace", &[]).image.mean()[0];
        match expected {
            Some(e) => assert!((m - e).abs() < 0.01, "sigma_a {sigma_a}, Le {le}: {m}"),
            None => assert!(m < 0.5, "an absorbing medium must darken the furnace: {m}"),
        }
    }
}

/// Light sampling alone, phase/BSDF sampling alone and MIS estimate the same image of a
/// light and a floor in coloured, forward-scattering fog.
#[test]
fn light_and_phase_sampling_agree_through_fog() {
    let images = render_strategies(
        &scene("media/fog.pbrt"),
        "volpath",
        3,
        21,
        false,
        &["--spp", "128"],
    );
    assert_strategies_agree("fog", &images, 4.5, Some(3.0));
}

#[test]
fn medium_errors_name_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "WorldBegin\nMediumInterface \"smoke\" \"\"\n",
            "scene.pbrt:2:",
            "no medium named 'smoke'",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\"\n",
            "scene.pbrt:2:",
            "not supported yet",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"float g\" [ 1 ]\n",
            "scene.pbrt:2:",
            "strictly between -1 and 1",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\"\n",
            "scene.pbrt:2:",
            "no \"string type\"",
        ),
    ];
    for (text, at, what) in cases {
        let path = write_scene(dir.path(), "scene.pbrt", text);
        let out = crate::util::kiln()
            .arg("render")
            .arg(&path)
            .arg("-q")
            .arg("-o")
            .arg(dir.path().join("o.exr"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{text}");
        assert!(
            err.contains(at) && err.contains(what),
            "expected {at} and {what} in {err}"
        );
    }
}
