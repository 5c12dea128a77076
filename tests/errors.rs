//! Bad scenes exit non-zero with a message that names the file and line.

use crate::util::{failing, kiln, render, write_scene};

/// Renders a scene file that must fail; returns kiln's stderr.
fn render_failure(scene: &std::path::Path, dir: &std::path::Path) -> String {
    let out = kiln()
        .arg("render")
        .arg(scene)
        .arg("-q")
        .arg("-o")
        .arg(dir.join("o.exr"))
        .output()
        .unwrap();
    assert!(!out.status.success(), "kiln accepted {}", scene.display());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn assert_names(stderr: &str, file: &str, line: u32, words: &str) {
    let at = format!("{file}:{line}:");
    assert!(stderr.contains(&at), "expected '{at}' in:\n{stderr}");
    assert!(stderr.contains(words), "expected '{words}' in:\n{stderr}");
}

#[test]
fn unknown_material_type() {
    let (err, _d) = failing("WorldBegin\n\nMaterial \"velvet\"\nShape \"sphere\"\n");
    assert_names(
        &err,
        "scene.pbrt",
        3,
        "unknown or unsupported material type 'velvet'",
    );
}

#[test]
fn missing_ply_file() {
    let (err, _d) =
        failing("WorldBegin\nShape \"plymesh\" \"string filename\" \"models/nope.ply\"\n");
    assert_names(&err, "scene.pbrt", 2, "nope.ply");
    // The OS's reason, once (not repeated by the chain of causes).
    assert_eq!(err.matches("os error").count(), 1, "{err}");
}

#[test]
fn malformed_number() {
    let (err, _d) = failing("WorldBegin\nShape \"sphere\"\n  \"float radius\" [ 1.2.3 ]\n");
    assert_names(&err, "scene.pbrt", 3, "malformed number '1.2.3'");
}

#[test]
fn unclosed_bracket() {
    let (err, _d) =
        failing("WorldBegin\nShape \"sphere\" \"float radius\" [ 1\nMaterial \"diffuse\"\n");
    assert_names(&err, "scene.pbrt", 2, "unclosed '['");
    let (err, _d) = failing("WorldBegin\nShape \"sphere\" \"float radius\" [ 1\n");
    assert_names(&err, "scene.pbrt", 2, "unclosed '['");
}

#[test]
fn misspelt_parameter() {
    let (err, _d) = failing("WorldBegin\nShape \"sphere\" \"float raduis\" [ 1 ]\n");
    assert_names(&err, "scene.pbrt", 2, "\"float raduis\"");
}

#[test]
fn unknown_directive_and_unterminated_string() {
    let (err, _d) = failing("WorldBegin\nShpe \"sphere\"\n");
    assert_names(&err, "scene.pbrt", 2, "unknown directive 'Shpe'");
    let (err, _d) = failing("WorldBegin\nShape \"sphere\n");
    assert_names(&err, "scene.pbrt", 2, "unterminated string");
}

#[test]
fn errors_in_included_files_name_that_file() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(
        dir.path(),
        "inner.pbrt",
        "\n\nShape \"sphere\" \"float radius\" [ \"oops\" ]\n",
    );
    let main = write_scene(
        dir.path(),
        "main.pbrt",
        "WorldBegin\nInclude \"inner.pbrt\"\n",
    );
    let err = render_failure(&main, dir.path());
    assert_names(&err, "inner.pbrt", 3, "needs numbers");
}

#[test]
fn corrupt_ply_names_the_directive_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bad.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    let main = write_scene(
        dir.path(),
        "scene.pbrt",
        "WorldBegin\n\nShape \"plymesh\" \"string filename\" \"bad.ply\"\n",
    );
    let err = render_failure(&main, dir.path());
    assert_names(&err, "scene.pbrt", 3, "refers to vertex 7");
}

#[test]
fn missing_scene_file() {
    let out = kiln()
        .args(["render", "/nonexistent/scene.pbrt", "-q"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/scene.pbrt"), "{err}");
}

/// Geometry beyond f32's range (or near it), or not a number, is an error naming the
/// Shape's file and line, never a panic inside the BVH builder.
#[test]
fn overflowing_or_nan_geometry() {
    for (p, words) in [
        ("3.5e38 0 0", "vertex 1 of this mesh"),
        ("1e308 0 0", "vertex 1 of this mesh"),
        ("1e16 0 0", "within 1e15"),
    ] {
        let text = format!(
            "WorldBegin\nLightSource \"infinite\"\n\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0 {p} 0 1 0 ]\n  \"integer indices\" [ 0 1 2 ]\n"
        );
        let (err, _d) = failing(&text);
        assert_names(&err, "scene.pbrt", 4, words);
    }
    // A transform can carry finite vertices out of range too.
    let (err, _d) = failing(
        "WorldBegin\nScale 1e30 1e30 1e30\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ]\n  \"integer indices\" [ 0 1 2 ]\n",
    );
    assert_names(&err, "scene.pbrt", 3, "world space");
    let (err, _d) = failing("WorldBegin\nShape \"sphere\" \"float radius\" [ 1e38 ]\n");
    assert_names(&err, "scene.pbrt", 2, "this sphere");
    // A NaN vertex in a binary PLY.
    let dir = tempfile::tempdir().unwrap();
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [[0.0f32, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            ply.extend(c.to_le_bytes());
        }
    }
    ply.push(3);
    for i in [0i32, 1, 2] {
        ply.extend(i.to_le_bytes());
    }
    std::fs::write(dir.path().join("nan.ply"), ply).unwrap();
    let err = crate::util::failing_in(
        dir.path(),
        "WorldBegin\nLightSource \"infinite\"\nShape \"plymesh\" \"string filename\" \"nan.ply\"\n",
    );
    assert_names(&err, "scene.pbrt", 3, "vertex 1 of this mesh");
}

/// Sizes from outside are checked before anything is allocated: a frame of 65536 x 65536
/// (51.5 GB of float RGB) is refused with a message that says so, and so is an
/// environment map whose few hundred bytes claim 100,000 x 100,000 pixels.
#[test]
fn huge_frames_and_images_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        "sky.pbrt",
        "WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n",
    );
    let out = kiln()
        .args(["render", "--resolution", "65536x65536", "-q", "-o"])
        .arg(dir.path().join("o.exr"))
        .arg(&scene)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("4294967296 pixels, 51.5 GB"), "{err}");
    // The limit is the user's to raise; below it the same scene renders.
    let out = kiln()
        .args(["render", "--resolution", "64x64", "--spp", "1", "-q", "-o"])
        .arg(dir.path().join("o.exr"))
        .args(["--max-frame-pixels", "4096"])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(out.status.success());
    std::fs::write(
        dir.path().join("huge.exr"),
        crate::util::exr_claiming(100_000, 100_000),
    )
    .unwrap();
    let err = crate::util::failing_in(
        dir.path(),
        "WorldBegin\n\nLightSource \"infinite\" \"string filename\" \"huge.exr\"\n",
    );
    assert_names(&err, "scene.pbrt", 3, "100000x100000 pixels is larger than");
}

/// A photon count whose maps could not fit in memory is refused where it is written.
#[test]
fn too_many_caustic_photons() {
    let (err, _d) =
        failing("Integrator \"volpath\" \"integer causticphotons\" [ 1000000000 ]\nWorldBegin\n");
    assert_names(&err, "scene.pbrt", 1, "causticphotons must be 0 to 5*10^7");
}

/// Photon-map and SPPM parameters out of range name the Integrator's line and what is
/// allowed.
#[test]
fn photon_and_sppm_parameters_are_checked() {
    for (text, message) in [
        (
            "Integrator \"photonmap\" \"integer volumenearest\" [ -3 ]\nWorldBegin\n",
            "volumenearest must be 0 (a fixed radius) to 10000, not -3",
        ),
        (
            "Integrator \"volpath\" \"float volumeradius\" [ -1 ]\nWorldBegin\n",
            "volumeradius must be 0 (automatic) or a positive distance",
        ),
        (
            "Integrator \"volpath\" \"string photonroulette\" \"russian\"\nWorldBegin\n",
            "photonroulette 'russian' is unknown (weight or none)",
        ),
        (
            "Integrator \"sppm\" \"integer photonsperiteration\" [ 0 ]\nWorldBegin\n",
            "photonsperiteration must be -1 (one per pixel) or 1 to 5*10^7, not 0",
        ),
        (
            "Integrator \"sppm\" \"float radius\" [ 0 ]\nWorldBegin\n",
            "radius must be a positive distance, not 0",
        ),
    ] {
        let (err, _d) = failing(text);
        assert_names(&err, "scene.pbrt", 1, message);
    }
}

#[test]
fn adaptive_sampling_parameters_are_checked() {
    for (text, message) in [
        (
            "Sampler \"zsobol\" \"float noisethreshold\" [ 0 ]\nWorldBegin\n",
            "\"float noisethreshold\" must be above 0, not 0",
        ),
        (
            "Sampler \"zsobol\" \"float noisethreshold\" [ -0.5 ]\nWorldBegin\n",
            "must be above 0, not -0.5",
        ),
        (
            "Sampler \"zsobol\" \"integer minsamples\" [ 0 ]\nWorldBegin\n",
            "\"integer minsamples\" is out of range (1 to 65536): 0",
        ),
    ] {
        let (err, _d) = failing(text);
        assert_names(&err, "scene.pbrt", 1, message);
    }
    // kiln render's override is checked too.
    let dir = tempfile::tempdir().unwrap();
    let path = crate::util::write_scene(dir.path(), "s.pbrt", "WorldBegin\n");
    let out = crate::util::kiln()
        .args(["render", "--quiet", "--noise-threshold", "-1"])
        .arg(&path)
        .arg("-o")
        .arg(dir.path().join("o.exr"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("noise threshold is a number from 0 (off) up, not -1"),
        "{said}"
    );
}

/// pbrt-v4 reads `.gz` meshes and includes decompressed; a gzip bomb or a corrupt file is an
/// error that names the file.
#[test]
fn gzipped_meshes_and_includes_load() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gz = |name: &str, bytes: &[u8]| {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(bytes).unwrap();
        std::fs::write(d.join(name), enc.finish().unwrap()).unwrap();
    };
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    gz("tri.ply.gz", ply.as_bytes());
    gz(
        "shapes.pbrt.gz",
        b"Shape \"plymesh\" \"string filename\" \"tri.ply.gz\"\n",
    );
    let path =
        crate::util::write_scene(d, "scene.pbrt", "WorldBegin\nInclude \"shapes.pbrt.gz\"\n");
    let desc = kiln_scene::load_file(&path).unwrap();
    assert_eq!(desc.shapes.len(), 1);
    std::fs::write(d.join("broken.ply.gz"), b"\x1f\x8b\x08\x00garbage").unwrap();
    let err = crate::util::failing_in(
        d,
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"broken.ply.gz\"\n",
    );
    assert!(
        err.contains("scene.pbrt:2:") && err.contains("not a valid gzip file"),
        "{err}"
    );
    // 2 GB of zeros in about 2 MB of gzip.
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    let zeros = vec![0u8; 1 << 24];
    for _ in 0..(2u64 << 30) / zeros.len() as u64 {
        enc.write_all(&zeros).unwrap();
    }
    std::fs::write(d.join("bomb.ply.gz"), enc.finish().unwrap()).unwrap();
    let err = crate::util::failing_in(
        d,
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"bomb.ply.gz\"\n",
    );
    assert!(err.contains("decompresses to more than"), "{err}");
}

/// pbrt-v4 reads a spectrum given as a file name (`"spectrum eta" "Au.eta.spd"`): the same
/// pairs inline or in a file make the same material; a malformed file names itself.
#[test]
fn spectra_read_from_files_equal_the_same_spectra_inline() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pairs = "400 0.2  500 0.9\n# a comment\n600 1.1 700 1.3\n";
    std::fs::write(d.join("eta.spd"), pairs).unwrap();
    let inline = pairs.replace("# a comment", "");
    let material = |eta: &str| {
        let path = write_scene(
            d,
            "scene.pbrt",
            &format!(
                "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" {eta} \"spectrum k\" \"metal-Au-k\"\nShape \"sphere\"\n"
            ),
        );
        let desc = kiln_scene::load_file(&path).unwrap();
        desc.materials.last().unwrap().kind.clone()
    };
    assert_eq!(material("\"eta.spd\""), material(&format!("[ {inline} ]")));
    std::fs::write(d.join("bad.spd"), "400 0.2 500").unwrap();
    let err = crate::util::failing_in(
        d,
        "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"bad.spd\"\nShape \"sphere\"\n",
    );
    assert!(
        err.contains("scene.pbrt:2:") && err.contains("'bad.spd' holds 3 numbers"),
        "{err}"
    );
    let err = crate::util::failing_in(
        d,
        "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"nowhere.spd\"\nShape \"sphere\"\n",
    );
    assert!(
        err.contains("scene.pbrt:2:") && err.contains("nowhere.spd"),
        "{err}"
    );
}

/// The film's sensor parameters that pbrt-v4 rejects, and a camera sensor without camera
/// data, are errors naming the line.
#[test]
fn film_sensor_errors_name_the_line() {
    for (text, line, says) in [
        (
            "Film \"rgb\"\n  \"float exposuretime\" [ 2 ]\nWorldBegin\n",
            2,
            "not a pbrt-v4 Film parameter",
        ),
        (
            "Film \"rgb\" \"string sensor\" \"canon_eos_100d\"\nWorldBegin\n",
            1,
            "sensor 'canon_eos_100d' is a camera's measured spectral response, which Kiln does not ship: set KILN_SENSOR_DATA",
        ),
        (
            "Film \"rgb\" \"float iso\" [ -5 ]\nWorldBegin\n",
            1,
            "\"iso\" must be positive",
        ),
        (
            "Film \"rgb\" \"float whitebalance\" [ 50 ]\nWorldBegin\n",
            1,
            "daylight temperature",
        ),
        (
            "Camera \"perspective\" \"float shutteropen\" [ 1 ] \"float shutterclose\" [ 1 ]\nWorldBegin\n",
            1,
            "never opens",
        ),
    ] {
        let (err, _d) = failing(text);
        assert_names(&err, "scene.pbrt", line, says);
    }
}

/// Camera data that is missing or broken is an error naming the Film's line and the file,
/// and a sensor name cannot reach outside the data folder.
#[test]
fn camera_sensor_data_errors_name_the_line_and_the_file() {
    let data = tempfile::tempdir().unwrap();
    std::fs::write(data.path().join("broken.json"), "{\"spectral_data\": 3}").unwrap();
    std::fs::write(
        data.path().join("flat.json"),
        r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [1,1,1], "700": [1,1,1]}}}}"#,
    )
    .unwrap();
    std::fs::write(data.path().join("Nikon_D850_380_780_5.json"), "not json").unwrap();
    for (sensor, says) in [
        ("broken", "broken.json': no \"spectral_data.index.main\""),
        ("flat", "not independent"),
        ("nikon_d850", "Nikon_D850_380_780_5.json': not valid JSON"),
        ("sony_ilce_9", "no response file for sensor 'sony_ilce_9'"),
        ("leica", "neither a camera pbrt-v4 knows"),
        ("../../etc/passwd", "not a camera name"),
    ] {
        assert_names(&sensor_error(data.path(), sensor), "scene.pbrt", 3, says);
    }
}

/// What `kiln render` of a scene whose Film names `sensor`, with the camera data folder
/// `data`, says on failing (it must fail with status 1, not panic).
fn sensor_error(data: &std::path::Path, sensor: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        "scene.pbrt",
        &format!(
            "Sampler \"halton\"\nFilm \"rgb\"\n  \"string sensor\" \"{sensor}\"\nWorldBegin\n"
        ),
    );
    let out = kiln()
        .env("KILN_SENSOR_DATA", data)
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("out.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{sensor}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// A training chart beside the camera data that cannot be read is an error naming the
/// Film's line, the chart and its line; it is not silently replaced by Kiln's own spectra.
#[test]
fn a_broken_training_chart_names_the_film_the_file_and_its_line() {
    let data = tempfile::tempdir().unwrap();
    std::fs::write(
        data.path().join("three.json"),
        r#"{"spectral_data": {"index": {"main": ["R","G","B"]}, "data": {"main": {"400": [0,0.1,1], "550": [0.1,1,0.1], "700": [1,0.1,0]}}}}"#,
    )
    .unwrap();
    std::fs::write(
        data.path().join("training-chart.csv"),
        "wavelength,a,b,c\n400,0.1,0.2,0.3\n410,0.1,oops,0.3\n",
    )
    .unwrap();
    assert_names(
        &sensor_error(data.path(), "three"),
        "scene.pbrt",
        3,
        "training-chart.csv': line 3, patch 2: \"oops\"",
    );
}

/// A Loop subdivision Kiln cannot make is an error naming the line.
#[test]
fn loop_subdivision_errors_name_the_line() {
    for (shape, says) in [
        (
            "Shape \"loopsubdiv\" \"integer levels\" [ 40 ] \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ]",
            "\"levels\" must be 0 to 12",
        ),
        (
            "Shape \"loopsubdiv\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  0 -1 0  0 0 1 ]\n  \"integer indices\" [ 0 1 2 1 0 3 0 1 4 ]",
            "shared by 3 faces",
        ),
    ] {
        let (err, _d) = failing(&format!("WorldBegin\n{shape}\n"));
        assert_names(&err, "scene.pbrt", 2, says);
    }
}

/// A moving area light is an error naming its line (pbrt-v4 refuses it too), not a still
/// image of the start; a moving LightSource stays at its start transform with a warning,
/// as pbrt-v4 keeps it, and renders the same bytes as the still light; a transform that
/// ends where it starts is no motion and renders.
#[test]
fn motion_kiln_cannot_blur_is_an_error_not_a_still() {
    let dir = tempfile::tempdir().unwrap();
    let film = "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\nShape \"sphere\"\n";
    let light = "LightSource \"point\" \"point3 from\" [ 0 0 4 ]\n";
    let moving = write_scene(
        dir.path(),
        "moving.pbrt",
        &format!(
            "{film}AttributeBegin\nActiveTransform EndTime\nTranslate 1 0 0\nActiveTransform All\n{light}AttributeEnd\n"
        ),
    );
    let still = write_scene(dir.path(), "still.pbrt", &format!("{film}{light}"));
    let a = render(&moving, dir.path(), "moving", &[]);
    let b = render(&still, dir.path(), "still", &[]);
    let stderr = String::from_utf8_lossy(&a.output.stderr);
    assert!(stderr.contains("stays at its start transform"), "{stderr}");
    assert_eq!(a.image.pixels, b.image.pixels);
    let (err, _d) = failing(
        "WorldBegin\nAttributeBegin\nActiveTransform EndTime\nTranslate 1 0 0\nActiveTransform All\nAreaLightSource \"diffuse\"\nShape \"sphere\"\nAttributeEnd\n",
    );
    assert_names(&err, "scene.pbrt", 7, "moving area light");
    let still = write_scene(
        dir.path(),
        "still.pbrt",
        // TransformBegin/End restores both transforms, as AttributeBegin/End does.
        "Film \"rgb\" \"integer xresolution\" [ 4 ] \"integer yresolution\" [ 4 ]\nWorldBegin\nActiveTransform EndTime\nTranslate 1 0 0\nTranslate -1 0 0\nActiveTransform All\nShape \"sphere\"\nTransformBegin\nTransform [ 1 0 0 0 0 1 0 0 0 0 1 0 0 2 0 1 ]\nShape \"sphere\"\nTransformEnd\nShape \"sphere\" \"float radius\" [ 0.5 ]\n",
    );
    // Renders (util::render panics with kiln's stderr if it fails).
    render(&still, dir.path(), "still", &[]);
}

/// A nanovdb medium's file problems are errors naming the directive's line, the file and
/// what is wrong: missing, not NanoVDB, truncated, Blosc, a grid that is not there (the
/// grids that are listed), a level set.
#[test]
fn nanovdb_errors_name_the_line() {
    use kiln_scene::files::nanovdb::{CLASS_FOG_VOLUME, GridToWrite, write_nanovdb};
    let dir = tempfile::tempdir().unwrap();
    let values = vec![0.5f32; 10 * 10 * 10];
    let grid = |class| GridToWrite {
        name: "density",
        class,
        voxel_size: [0.1; 3],
        origin: [0.0; 3],
        lo: [0, 0, 0],
        dims: [10, 10, 10],
        values: &values,
    };
    let good = write_nanovdb(&[grid(CLASS_FOG_VOLUME)], false);
    std::fs::write(dir.path().join("good.nvdb"), &good).unwrap();
    std::fs::write(dir.path().join("cut.nvdb"), &good[..good.len() / 2]).unwrap();
    std::fs::write(dir.path().join("text.nvdb"), b"density 1 2 3\n").unwrap();
    let mut blosc = good.clone();
    blosc[14] = 2;
    std::fs::write(dir.path().join("blosc.nvdb"), &blosc).unwrap();
    std::fs::write(
        dir.path().join("sdf.nvdb"),
        write_nanovdb(&[grid(1)], false),
    )
    .unwrap();
    for (file, extra, says) in [
        ("missing.nvdb", "", "missing.nvdb"),
        ("text.nvdb", "", "not a NanoVDB file"),
        ("cut.nvdb", "", "truncated"),
        ("blosc.nvdb", "", "Blosc-compressed"),
        (
            "good.nvdb",
            "\"string gridname\" \"smoke\"",
            "no grid named 'smoke' (it has density)",
        ),
        ("sdf.nvdb", "", "is not a fog volume"),
    ] {
        let err = crate::util::failing_in(
            dir.path(),
            &format!(
                "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\"\n  \"string filename\" \"{file}\" {extra}\n"
            ),
        );
        assert!(
            err.contains("scene.pbrt:2:") || err.contains("scene.pbrt:3:"),
            "{file}: expected the line in:\n{err}"
        );
        assert!(err.contains(says), "{file}: expected '{says}' in:\n{err}");
    }
}

/// A bad surface of revolution or nested-dielectric priority names its line and says what
/// is wrong.
#[test]
fn revolution_and_priority_errors_say_what_is_wrong() {
    let head = "WorldBegin\n";
    for (shape, line, message) in [
        (
            "Shape \"revolution\"\n",
            2,
            "revolution: \"point2 contour\" [r z ...] is required",
        ),
        (
            "Shape \"revolution\" \"point2 contour\" [ 0 0 ]\n",
            2,
            "the contour has 1 point(s); it needs two or more",
        ),
        (
            "Shape \"revolution\" \"point2 contour\" [ 0 0  -1 1 ]\n",
            2,
            "contour point 1 is (-1, 1); every point needs a finite radius r >= 0",
        ),
        (
            "Shape \"revolution\" \"point2 contour\" [ 0 0  1 1 ] \"vector2 normals\" [ 1 0 ]\n",
            2,
            "1 normals for 2 contour points; give one per point",
        ),
        (
            "Shape \"revolution\" \"point2 contour\" [ 0 0  0 1 ]\n",
            2,
            "the contour sweeps no area",
        ),
        (
            "Shape \"sphere\" \"integer priority\" -2\n",
            2,
            "\"priority\" is -2; nested dielectric priorities run from 0",
        ),
        (
            "Material \"diffuse\"\nShape \"sphere\" \"integer priority\" 2\n",
            3,
            "\"priority\" (nested dielectrics) applies to shapes with a \"dielectric\" or \"interface\" material",
        ),
        (
            "Material \"dielectric\"\nAreaLightSource \"volume\" \"rgb Le\" [1 1 1]\nShape \"revolution\" \"point2 contour\" [ 0 1  1 0  0 -1 ]\n",
            4,
            "a VolumeLight revolution must face outwards",
        ),
    ] {
        let (err, _d) = failing(&format!("{head}{shape}"));
        assert_names(&err, "scene.pbrt", line, message);
    }
}

/// The subsurface material's parameters are checked where Kiln cannot honour them.
#[test]
fn subsurface_parameters_are_checked() {
    for (material, message) in [
        (
            "Material \"subsurface\" \"rgb sigma_a\" [ 1 1 1 ]",
            "subsurface: give both sigma_a and sigma_s, or neither",
        ),
        (
            "Material \"subsurface\" \"string name\" \"Skin9\"",
            "no measured medium named 'Skin9' (Kiln knows Jensen et al. 2001's: Apple,",
        ),
        (
            "Material \"subsurface\" \"float g\" 1",
            "\"g\" is 1; it must lie strictly between -1 and 1",
        ),
        (
            "Material \"subsurface\" \"rgb sigma_a\" [ 1 -1 1 ] \"rgb sigma_s\" [ 1 1 1 ]",
            "sigma_a and sigma_s must not be negative",
        ),
        (
            "Texture \"t\" \"spectrum\" \"checkerboard\"\nMaterial \"subsurface\" \"texture sigma_a\" \"t\" \"rgb sigma_s\" [ 1 1 1 ]",
            "a textured \"sigma_a\" is not supported",
        ),
        (
            "Texture \"t\" \"spectrum\" \"checkerboard\"\nMaterial \"subsurface\" \"texture reflectance\" \"t\" \"texture mfp\" \"t\"",
            "a textured \"mfp\" is not supported",
        ),
    ] {
        let (err, _d) = failing(&format!("WorldBegin\n{material}\n"));
        assert!(
            err.contains("scene.pbrt:") && err.contains(message),
            "{material}: {err}"
        );
    }
    let (err, _d) = failing("Integrator \"volpath\" \"integer walkdepth\" 0\nWorldBegin\n");
    assert!(
        err.contains("scene.pbrt:1") && err.contains("walkdepth 0 is out of range"),
        "{err}"
    );
}

/// A gzipped include that decompresses to more than the process may hold (here under a
/// 400 MB address-space limit, standing in for a machine's memory) is said to be out of
/// memory, with the file and line, not "not a valid gzip file: out of memory".
#[cfg(target_os = "linux")]
#[test]
fn a_gzip_too_big_for_memory_is_said_to_be() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = std::fs::File::create(d.join("big.pbrt.gz")).unwrap();
    let mut gz = flate2::write::GzEncoder::new(file, flate2::Compression::fast());
    let lines = vec![b'\n'; 1 << 20];
    for _ in 0..600 {
        gz.write_all(&lines).unwrap();
    }
    gz.finish().unwrap();
    let scene = write_scene(d, "scene.pbrt", "WorldBegin\nInclude \"big.pbrt.gz\"\n");
    let out = std::process::Command::new("bash")
        .args([
            "-c",
            "ulimit -v 400000 && exec \"$0\" render \"$1\" -q -o \"$2\"",
        ])
        .arg(env!("CARGO_BIN_EXE_kiln"))
        .arg(&scene)
        .arg(d.join("o.exr"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("scene.pbrt:2:")
            && stderr.contains("does not fit in this process's memory once decompressed"),
        "{stderr}"
    );
}
