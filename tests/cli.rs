//! What `kiln render` writes and prints.

use crate::util::{kiln, render, scene, write_scene};

#[test]
fn crop_window_sets_the_data_window_inside_the_display_window() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene("furnace/scene.pbrt"))
        .unwrap()
        .replace(
            "\"string filename\" [ \"furnace.exr\" ]",
            "\"string filename\" [ \"furnace.exr\" ] \"float cropwindow\" [ 0.25 0.75 0.5 1 ]",
        );
    let path = write_scene(dir.path(), "crop.pbrt", &text);
    let r = render(&path, dir.path(), "crop", &["--spp", "8"]);
    let img = &r.image;
    assert_eq!((img.frame_width, img.frame_height), (32, 32));
    assert_eq!((img.x0, img.y0, img.width, img.height), (8, 16, 16, 16));
    assert!((img.mean()[0] - 1.0).abs() < 0.02);
    // The same crop at another resolution keeps its fractions.
    let r = render(
        &path,
        dir.path(),
        "crop64",
        &["--spp", "1", "--resolution", "64x64"],
    );
    assert_eq!(
        (r.image.x0, r.image.y0, r.image.width, r.image.height),
        (16, 32, 32, 32)
    );
}

#[test]
fn preview_summary_and_defaults_from_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("preview.png");
    let r = render(
        &scene("furnace/scene.pbrt"),
        dir.path(),
        "out",
        &["--preview", png.to_str().unwrap(), "--exposure", "-1"],
    );
    // The Film's resolution and the Sampler's pixelsamples are the defaults.
    assert_eq!((r.image.width, r.image.height), (32, 32));
    let stderr = String::from_utf8_lossy(&r.output.stderr);
    assert!(stderr.contains("64 spp"), "{stderr}");
    assert!(
        stderr.contains("M samples/s") && stderr.contains("M rays/s"),
        "{stderr}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
}

#[test]
fn fallback_integrator_and_unknown_harmless_parameters_are_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(
        dir.path(),
        "warn.pbrt",
        "Integrator \"bdpt\" \"integer maxdepth\" [ 3 ]\nFilm \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ] \"bool savefp16\" [ true ]\nWorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n",
    );
    // In RGB, where one sample of a white sky is exactly white (a spectral sample's four
    // wavelengths estimate it).
    let r = render(&path, dir.path(), "warn", &["--spp", "1", "--rgb"]);
    let stderr = String::from_utf8_lossy(&r.output.stderr);
    assert!(
        stderr.contains("warn.pbrt:1: warning: Integrator 'bdpt'"),
        "{stderr}"
    );
    assert!(
        stderr.contains("warn.pbrt:2: warning:") && stderr.contains("savefp16"),
        "{stderr}"
    );
    assert!(r.image.pixels.iter().all(|p| *p == [1.0, 1.0, 1.0]));
}

#[test]
fn bad_flags_are_refused() {
    let out = kiln()
        .args(["render", "x.pbrt", "--resolution", "12by4"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("WIDTHxHEIGHT"));
    let out = kiln()
        .args(["render"])
        .arg(scene("furnace/scene.pbrt"))
        .args(["--tile", "0", "-q"])
        .output()
        .unwrap();
    assert!(!out.status.success());
}

/// Kiln's "objmesh" shape reads OBJ files (through tobj): a quad floor from an OBJ file
/// under a uniform sky reflects half the light, as the same floor written inline does.
#[test]
fn obj_meshes_load_and_shade_like_inline_meshes() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("floor.obj"),
        "# a quad\nv -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10\nvn 0 1 0\nf 1//1 2//1 3//1 4//1\n",
    )
    .unwrap();
    let path = write_scene(
        dir.path(),
        "obj.pbrt",
        "Integrator \"path\" \"integer maxdepth\" [ 1 ]
        Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]
        LookAt 0 3 0.01  0 0 0  0 1 0
        Camera \"perspective\" \"float fov\" [ 20 ]
        WorldBegin
        LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]
        Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]
        Shape \"objmesh\" \"string filename\" \"floor.obj\"",
    );
    let r = render(&path, dir.path(), "obj", &["--spp", "64"]);
    assert!(
        (r.image.mean()[0] - 0.5).abs() < 0.003,
        "{:?}",
        r.image.mean()
    );
    std::fs::write(dir.path().join("floor.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let out = kiln()
        .arg("render")
        .arg(&path)
        .arg("-q")
        .arg("-o")
        .arg(dir.path().join("x.exr"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("obj.pbrt:8:"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every scene in scenes/ loads and renders, at a tiny size and one sample, with no warning.
#[test]
fn every_scene_in_the_repository_renders_without_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let mut scenes = Vec::new();
    let mut stack = vec![crate::util::repo().join("scenes")];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "pbrt")
                // A fragment that scenes Include (martini/glass.pbrt) is not a scene.
                && std::fs::read_to_string(&p).unwrap().contains("WorldBegin")
            {
                scenes.push(p);
            }
        }
    }
    scenes.sort();
    assert!(scenes.len() >= 8, "found only {scenes:?}");
    for (i, path) in scenes.iter().enumerate() {
        let r = render(
            path,
            dir.path(),
            &format!("smoke{i}"),
            &["--spp", "1", "--resolution", "16x12"],
        );
        let stderr = String::from_utf8_lossy(&r.output.stderr);
        assert!(!stderr.contains("warning"), "{}: {stderr}", path.display());
    }
}

/// An output named other than .exr is refused before rendering, with the way to a PNG.
#[test]
fn an_output_not_named_exr_is_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("frame.png");
    let out = kiln()
        .arg("render")
        .arg(crate::util::scene("furnace/scene.pbrt"))
        .arg("-q")
        .arg("-o")
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("name it .exr") && stderr.contains("--preview"),
        "{stderr}"
    );
    assert!(!png.exists());
}
