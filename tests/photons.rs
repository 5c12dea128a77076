//! Photon maps (seeds 003 and 004) against what they must equal: the stored photons of a
//! beam entering a slab against the closed form, the volume map against volumetric path
//! tracing (converging as photons grow), a point light's caustic against path tracing of a
//! small sphere light of the same power, and weight-aware Russian roulette against none.

use crate::util::{mean_and_error, render, scene, write_pfm, write_scene};
use kiln_image::RgbBuffer;
use kiln_render::integrators::photons::{PhotonMaps, Roulette, power_spread};
use kiln_render::lights::Light;
use kiln_render::{Integrator, MediaPolicy, Scene};

/// Builds `text`'s scene and its integrator's photon maps, with `roulette`.
fn photon_maps(text: &str, roulette: Roulette) -> (Scene, PhotonMaps) {
    let here = std::path::Path::new(".");
    let desc = kiln_scene::load_str(text, &here.join("photons.pbrt"), here).expect("scene loads");
    let scene = Scene::build(&desc, MediaPolicy::Render).expect("scene builds");
    let integrator = Integrator::from_description(&desc.integrator);
    let mut settings = integrator
        .photon_settings(&scene)
        .expect("the integrator asks for photons");
    settings.roulette = roulette;
    let maps = PhotonMaps::build(&scene, &settings);
    (scene, maps)
}

/// A beam straight down through a thin glass sheet (the specular event after which photons
/// are stored) into a slab of grey medium, sigma_s 1 and sigma_a 0.5, two units deep, with
/// photons ending at their first scattering (maxdepth 2). `medium` declares the slab.
fn slab_scene(medium: &str) -> String {
    format!(
        r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
Film "rgb" "integer xresolution" [ 4 ] "integer yresolution" [ 4 ]
Integrator "volpath" "integer maxdepth" [ 2 ] "integer volumephotons" [ 400000 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 0 10 ] "point3 to" [ 0 0 0 ] "rgb L" [ 1 1 1 ]
{medium}
AttributeBegin
    Material "thindielectric" "float eta" [ 1.5 ]
    Shape "bilinearmesh" "point3 P" [ -1 -1 0.01  1 -1 0.01  -1 1 0.01  1 1 0.01 ]
AttributeEnd
AttributeBegin
    MediumInterface "slab" ""
    Material "interface"
    Shape "trianglemesh" "point3 P" [ -1 -1 -2  1 -1 -2  1 1 -2  -1 1 -2  -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]
        "integer indices" [ 0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7 ]
AttributeEnd
"#
    )
}

/// The photons a beam leaves in a slab follow the closed form: the power stored between
/// depths d0 and d1 is the power through the sheet times sigma_s / sigma_t times
/// (exp(-sigma_t d0) - exp(-sigma_t d1)). The same holds for a homogeneous medium (sampled
/// exactly) and for a grid of the same density (delta tracking): interaction points carry no
/// interval bias either way (seed 004).
#[test]
fn stored_photons_follow_the_closed_form_along_a_slab() {
    let homogeneous = r#"MakeNamedMedium "slab" "string type" "homogeneous" "rgb sigma_a" [ 0.5 0.5 0.5 ] "rgb sigma_s" [ 1 1 1 ]"#;
    // Forty layers a tenth of a unit thick over z -3..1, four voxels a unit wide across x
    // and y -2..2: density 1 up to the layer above the slab's top, 2 beyond, so that the
    // slab's density is exactly 1 (a grid fades to 0 in the half voxel at its edges, as
    // pbrt-v4's does, so the grid reaches beyond the slab). Free flights are then sampled by
    // delta tracking against the grid's majorants, not in closed form.
    let densities: Vec<&str> = (0..640)
        .map(|i| if i / 16 <= 30 { "1" } else { "2" })
        .collect();
    let grid = format!(
        r#"MakeNamedMedium "slab" "string type" "uniformgrid" "rgb sigma_a" [ 0.5 0.5 0.5 ] "rgb sigma_s" [ 1 1 1 ]
    "integer nx" [ 4 ] "integer ny" [ 4 ] "integer nz" [ 40 ] "point3 p0" [ -2 -2 -3 ] "point3 p1" [ 2 2 1 ]
    "float density" [ {} ]"#,
        densities.join(" ")
    );
    for (name, medium) in [("homogeneous", homogeneous), ("grid", grid.as_str())] {
        let (scene, maps) = photon_maps(&slab_scene(medium), Roulette::WeightAware);
        let Light::Distant(sun) = &scene.lights[0] else {
            panic!("the first light is the distant one");
        };
        // A thin sheet of eta 1.5 at normal incidence reflects 2R / (1 + R), R = 0.04.
        let r = 0.04f64;
        let through = 4.0 * sun.radiance.y as f64 * (1.0 - 2.0 * r / (1.0 + r));
        let (sigma_s, sigma_t) = (1.0f64, 1.5f64);
        let photons = maps.volume.photons();
        assert!(photons.len() > 50_000, "{name}: {} photons", photons.len());
        let bins = 8;
        for b in 0..bins {
            let (d0, d1) = (b as f64 * 0.25, (b + 1) as f64 * 0.25);
            let want =
                through * sigma_s / sigma_t * (libm::exp(-sigma_t * d0) - libm::exp(-sigma_t * d1));
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for ph in photons {
                let d = -ph.p.z as f64;
                if d >= d0 && d < d1 {
                    let w = ph.power.y as f64;
                    sum += w;
                    sum2 += w * w;
                }
            }
            // The stored power is a sum of independent photons: its variance is about the
            // sum of their squared powers.
            let se = sum2.sqrt();
            eprintln!(
                "slab ({name}), depth {d0:.2}..{d1:.2}: stored {sum:.5} ± {se:.5}, closed form {want:.5}"
            );
            assert!(
                (sum - want).abs() < 4.0 * se + 1e-3 * want,
                "{name}: depth {d0}..{d1}: stored power {sum} vs closed form {want} (standard error {se})"
            );
        }
        // Nothing is stored outside the slab.
        assert!(photons.iter().all(|ph| ph.p.z <= 1e-3 && ph.p.z >= -2.001));
    }
}

/// Per-channel relative error of `img` against `reference`, block by block (an 8x8 grid),
/// as a root mean square.
fn block_rms(img: &RgbBuffer, reference: &RgbBuffer) -> f64 {
    let (bw, bh) = (img.width / 8, img.height / 8);
    let mut sum = 0.0;
    let mut n = 0.0;
    for j in 0..8 {
        for i in 0..8 {
            for c in 0..3 {
                let block =
                    |im: &RgbBuffer| crate::util::block_stats(im, i * bw, j * bh, bw, bh, c).0;
                let (a, r) = (block(img), block(reference));
                sum += ((a - r) / r).powi(2);
                n += 1.0;
            }
        }
    }
    (sum / n).sqrt()
}

fn channel_means(img: &RgbBuffer) -> [(f64, f64); 3] {
    [0, 1, 2].map(|c| mean_and_error(img.pixels.iter().map(|p| p[c] as f64)))
}

/// The volume photon map (seeds 003 and 004) against volumetric path tracing on a room full
/// of bright haze, where most light has scattered many times: the image mean within 2% and
/// every block within four standard errors at 160,000 photons, and the blocks' error
/// shrinking as photons grow (10,000, 40,000, 160,000).
#[test]
fn volume_photon_map_agrees_with_volumetric_path_tracing() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("media/haze.pbrt");
    let text = std::fs::read_to_string(&path).unwrap();
    let photons = " \"integer volumephotons\" [ 100000 ] \"integer volumenearest\" [ 100 ]";
    assert!(text.contains(photons));
    let pt = render(
        &write_scene(dir.path(), "pt.pbrt", &text.replace(photons, "")),
        dir.path(),
        "pt",
        &["--spp", "1024", "--seed", "7"],
    )
    .image;
    let mut errors = Vec::new();
    let mut last = None;
    for count in [10_000, 40_000, 160_000] {
        let variant = text.replace(
            photons,
            &format!(" \"integer volumephotons\" [ {count} ] \"integer volumenearest\" [ 100 ]"),
        );
        let pm = render(
            &write_scene(dir.path(), &format!("pm{count}.pbrt"), &variant),
            dir.path(),
            &format!("pm{count}"),
            &["--spp", "256"],
        )
        .image;
        let e = block_rms(&pm, &pt);
        eprintln!(
            "haze, {count} volume photons: block rms error {:.2}%, means {:?} (path tracing {:?})",
            100.0 * e,
            channel_means(&pm),
            channel_means(&pt)
        );
        errors.push(e);
        last = Some(pm);
    }
    assert!(
        errors[1] < errors[0] && errors[2] < errors[1] && errors[2] < 0.6 * errors[0],
        "the volume map must converge as photons grow: block errors {errors:?}"
    );
    let pm = last.unwrap();
    for (c, ((a, sa), (b, _))) in channel_means(&pt)
        .into_iter()
        .zip(channel_means(&pm))
        .enumerate()
    {
        assert!(
            (b - a).abs() < 0.02 * a,
            "channel {c}: volume photon map {b} vs path tracing {a} ± {sa}"
        );
    }
    let z = crate::util::max_z_score(&pt, &pm, 4, 4);
    eprintln!("haze: largest block z-score {z:.2}");
    assert!(z < 4.0, "a block differs by {z} standard errors");
}

/// The same spectrally: photons fly at four wavelengths of their own and are stored with the
/// RGB the film would record of them, which a gathering path takes as light of that colour.
/// On the haze's red and green walls (light that changes colour before it is stored) the
/// volume map at 160,000 photons still agrees with spectral volumetric path tracing: means
/// within 2% per channel, every block within four standard errors.
#[test]
fn volume_photon_map_agrees_with_volumetric_path_tracing_spectrally() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene("media/haze.pbrt")).unwrap();
    let photons = " \"integer volumephotons\" [ 100000 ] \"integer volumenearest\" [ 100 ]";
    assert!(text.contains(photons));
    let pt = render(
        &write_scene(dir.path(), "pt.pbrt", &text.replace(photons, "")),
        dir.path(),
        "pt",
        &["--spp", "1024", "--seed", "7", "--spectral"],
    )
    .image;
    let more = " \"integer volumephotons\" [ 160000 ] \"integer volumenearest\" [ 100 ]";
    let pm = render(
        &write_scene(dir.path(), "pm.pbrt", &text.replace(photons, more)),
        dir.path(),
        "pm",
        &["--spp", "256", "--spectral"],
    )
    .image;
    let (a, b) = (channel_means(&pt), channel_means(&pm));
    eprintln!("haze, spectral: volume photon map {b:?}, path tracing {a:?}");
    for c in 0..3 {
        assert!(
            (b[c].0 - a[c].0).abs() < 0.02 * a[c].0,
            "channel {c}: volume photon map {:?} vs path tracing {:?}",
            b[c],
            a[c]
        );
    }
    let z = crate::util::max_z_score(&pt, &pm, 4, 4);
    eprintln!("haze, spectral: largest block z-score {z:.2}");
    assert!(z < 4.0, "a block differs by {z} standard errors");
}

/// Weight-aware Russian roulette (seed 004) makes stored photons' powers nearly equal (the
/// coefficient of variation of their luminance drops) without changing the estimate.
#[test]
fn weight_aware_roulette_evens_photon_powers_and_keeps_the_estimate() {
    let text = std::fs::read_to_string(scene("media/haze.pbrt")).unwrap();
    let (_, before) = photon_maps(&text, Roulette::Off);
    let (_, after) = photon_maps(&text, Roulette::WeightAware);
    let (cv_before, cv_after) = (
        power_spread(before.volume.photons()),
        power_spread(after.volume.photons()),
    );
    eprintln!(
        "haze volume map: power spread (CV) without roulette {cv_before:.3} ({} photons), weight-aware {cv_after:.3} ({} photons)",
        before.volume.len(),
        after.volume.len()
    );
    assert!(cv_after < 0.5 * cv_before, "{cv_after} vs {cv_before}");
    // The two maps' estimates of the same image.
    let dir = tempfile::tempdir().unwrap();
    let none = text.replace(
        "\"integer volumenearest\" [ 100 ]",
        "\"integer volumenearest\" [ 100 ] \"string photonroulette\" \"none\"",
    );
    let a = render(
        &write_scene(dir.path(), "none.pbrt", &none),
        dir.path(),
        "none",
        &["--spp", "64"],
    )
    .image;
    let b = render(
        &scene("media/haze.pbrt"),
        dir.path(),
        "weight",
        &["--spp", "64"],
    )
    .image;
    for (c, ((ma, _), (mb, _))) in channel_means(&a)
        .into_iter()
        .zip(channel_means(&b))
        .enumerate()
    {
        eprintln!("haze channel {c}: no roulette {ma:.5}, weight-aware {mb:.5}");
        assert!((ma - mb).abs() < 0.015 * ma, "channel {c}: {ma} vs {mb}");
    }
}

/// A glass ball over a floor, lit by `light`; the camera sees the floor under the ball, not
/// the ball (whose highlights would show a sphere light but never a point light).
fn ball_scene(light: &str, integrator: &str) -> String {
    format!(
        r#"Integrator "volpath" "integer maxdepth" [ 5 ] {integrator}
Sampler "zsobol" "integer pixelsamples" [ 64 ]
Film "rgb" "integer xresolution" [ 40 ] "integer yresolution" [ 40 ]
    "float cropwindow" [ 0.3 0.7 0.55 0.9 ] "string filename" [ "ball.exr" ]
LookAt 0 0.9 3   0 0.3 0   0 1 0
Camera "perspective" "float fov" [ 30 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
Shape "bilinearmesh" "point3 P" [ -2 0 -2  2 0 -2  -2 0 2  2 0 2 ]
AttributeBegin
    Material "dielectric" "float eta" [ 1.5 ]
    Translate 0 0.6 0
    Shape "sphere" "float radius" [ 0.3 ]
AttributeEnd
{light}
"#
    )
}

/// Point lights shoot photons: the caustic a point light casts through a glass ball (which
/// a path tracer cannot find at all) agrees with path tracing of the same scene lit by a
/// small sphere light of the same power (radiance I / (pi r^2)), over the floor around the
/// caustic and over its brightest part, within four standard errors and 4%.
#[test]
fn a_point_lights_caustic_agrees_with_path_tracing_a_small_sphere_light() {
    let dir = tempfile::tempdir().unwrap();
    let point = ball_scene(
        r#"LightSource "point" "point3 from" [ 0 1.4 0 ] "rgb I" [ 1 1 1 ]"#,
        r#""integer causticphotons" [ 400000 ]"#,
    );
    let r = 0.03f64;
    let sphere = ball_scene(
        &format!(
            r#"AttributeBegin
    Translate 0 1.4 0
    AreaLightSource "diffuse" "rgb L" [ {l} {l} {l} ]
    Material "diffuse" "rgb reflectance" [ 0 0 0 ]
    Shape "sphere" "float radius" [ {r} ]
AttributeEnd"#,
            l = 1.0 / (std::f64::consts::PI * r * r)
        ),
        "",
    );
    let pm = render(
        &write_scene(dir.path(), "point.pbrt", &point),
        dir.path(),
        "point",
        &["--spp", "256", "--rgb"],
    )
    .image;
    let pt = render(
        &write_scene(dir.path(), "sphere.pbrt", &sphere),
        dir.path(),
        "sphere",
        // Path tracing's error here is its rare fireflies: it takes this many samples for
        // its mean to settle (at 8192 it was 5% low in the caustic, 2.1 standard errors).
        &["--spp", "32768", "--seed", "2", "--rgb"],
    )
    .image;
    assert_eq!((pm.width, pm.height), (16, 14));
    // The whole crop, then the caustic's core (the middle of the floor under the ball).
    // Differences pixel by pixel take the caustic's own shape out of the error estimate.
    for (name, x0, y0, w, h) in [("floor", 0, 0, 16, 14), ("caustic", 3, 2, 10, 8)] {
        let (a, _) = crate::util::block_stats(&pt, x0, y0, w, h, 1);
        let (b, _) = crate::util::block_stats(&pm, x0, y0, w, h, 1);
        let (_, se) = mean_and_error(
            (y0..y0 + h)
                .flat_map(|y| (x0..x0 + w).map(move |x| (x, y)))
                .map(|(x, y)| pt.get(x, y)[1] as f64 - pm.get(x, y)[1] as f64),
        );
        eprintln!(
            "ball {name}: point light with photons {b:.5}, sphere light path traced {a:.5}, difference's standard error {se:.5}"
        );
        assert!(
            (a - b).abs() < 4.0 * se && (a - b).abs() < 0.04 * a,
            "{name}: point light's photons {b} vs path-traced sphere light {a} (standard error {se})"
        );
    }
    // Without photons the point light casts no caustic: the core is much darker.
    let bare = render(
        &write_scene(
            dir.path(),
            "bare.pbrt",
            &point.replace(r#""integer causticphotons" [ 400000 ]"#, ""),
        ),
        dir.path(),
        "bare",
        &["--spp", "16", "--rgb"],
    )
    .image;
    let (dark, _) = crate::util::block_stats(&bare, 3, 2, 10, 8, 1);
    let (lit, _) = crate::util::block_stats(&pm, 3, 2, 10, 8, 1);
    assert!(dark < 0.5 * lit, "{dark} vs {lit}");
    // Spectral photons carry the same caustic: a white light through clear glass onto a
    // grey floor renders as in RGB, channel by channel, within 2% in the caustic's core.
    let spectral = render(
        &write_scene(dir.path(), "point.pbrt", &point),
        dir.path(),
        "spectral",
        &["--spp", "256", "--spectral"],
    )
    .image;
    for c in 0..3 {
        let (s, _) = crate::util::block_stats(&spectral, 3, 2, 10, 8, c);
        let (r, _) = crate::util::block_stats(&pm, 3, 2, 10, 8, c);
        assert!(
            (s / r - 1.0).abs() < 0.02,
            "channel {c}: spectral {s} vs RGB {r}"
        );
    }
}

/// pbrt-v4's stochastic progressive photon mapping ("sppm") converges to the image path
/// tracing gives: a glass ball's caustic in a small box, lit by a light large enough for
/// path tracing to converge too. The means within 1.5%, every block of an 8x8 grid within
/// four standard errors, and the blocks' error shrinking from 16 to 256 iterations.
#[test]
fn sppm_converges_to_path_tracing() {
    let dir = tempfile::tempdir().unwrap();
    let path = scene("photons/ball.pbrt");
    let text = std::fs::read_to_string(&path).unwrap();
    let sppm_line = "Integrator \"sppm\" \"integer maxdepth\" [ 8 ] \"float radius\" [ 0.03 ] \"integer photonsperiteration\" [ 20000 ]";
    assert!(text.contains(sppm_line));
    let pt_text = text.replace(
        sppm_line,
        "Integrator \"volpath\" \"integer maxdepth\" [ 8 ]",
    );
    let args = |spp: &'static str| ["--resolution", "32x32", "--spp", spp];
    let pt = render(
        &write_scene(dir.path(), "pt.pbrt", &pt_text),
        dir.path(),
        "pt",
        &args("4096"),
    )
    .image;
    let mut errors = Vec::new();
    let mut last = None;
    for iterations in ["16", "256"] {
        let img = render(
            &path,
            dir.path(),
            &format!("sppm{iterations}"),
            &args(iterations),
        )
        .image;
        let e = block_rms(&img, &pt);
        eprintln!(
            "ball, sppm {iterations} iterations: block rms error {:.2}%, means {:?} (path tracing {:?})",
            100.0 * e,
            channel_means(&img),
            channel_means(&pt)
        );
        errors.push(e);
        last = Some(img);
    }
    assert!(
        errors[1] < errors[0],
        "SPPM must converge: block errors {errors:?}"
    );
    let sppm = last.unwrap();
    for (c, ((a, sa), (b, _))) in channel_means(&pt)
        .into_iter()
        .zip(channel_means(&sppm))
        .enumerate()
    {
        assert!(
            (b - a).abs() < 0.015 * a,
            "channel {c}: SPPM {b} vs path tracing {a} ± {sa}"
        );
    }
    let z = crate::util::max_z_score(&pt, &sppm, 8, 8);
    eprintln!("ball: largest block z-score, SPPM against path tracing, {z:.2}");
    assert!(z < 4.0, "a block differs by {z} standard errors");
}

/// The luminance of the power leaving a glass VolumeLight sphere of `radius` whose interior
/// glows uniformly: over its area 4 pi R^2, the radiance arriving from inside along chords of
/// length 2 R cos(theta), times the Fresnel transmittance out, times cos(theta) dw, inside the
/// critical angle (the 1/eta^2 of radiance leaving glass and the wider solid angle outside
/// cancel).
fn volume_sphere_exitant_power(interior: &kiln_render::lights::VolumeInterior, radius: f32) -> f64 {
    use kiln_render::bsdfs::fresnel_dielectric;
    let eta = interior.eta as f64;
    let steps = 20_000;
    let mut sum = [0.0f64; 3];
    for i in 0..steps {
        let theta = (i as f64 + 0.5) / steps as f64 * std::f64::consts::FRAC_PI_2;
        let (sin_i, cos_i) = libm::sincos(theta);
        let sin_o = eta * sin_i;
        if sin_o >= 1.0 {
            break;
        }
        let cos_o = (1.0 - sin_o * sin_o).sqrt();
        let t = 1.0 - fresnel_dielectric(cos_o as f32, eta as f32) as f64;
        let chord = 2.0 * radius as f64 * cos_i;
        for (c, total) in sum.iter_mut().enumerate() {
            let (le, sigma) = (interior.le[c] as f64, interior.sigma_a[c] as f64);
            let along = if sigma > 0.0 {
                le * (1.0 - libm::exp(-sigma * chord)) / sigma
            } else {
                le * chord
            };
            *total += t * along * cos_i * sin_i * (std::f64::consts::FRAC_PI_2 / steps as f64);
        }
    }
    let scale = 4.0 * std::f64::consts::PI * (radius as f64).powi(2) * 2.0 * std::f64::consts::PI;
    let rgb = sum.map(|v| v * scale);
    luminance_f64(rgb)
}

/// 4 pi times the integral of a grid medium's source term (sigma_a Le) over its box, in
/// luminance, by the midpoint rule on a 96^3 lattice (the box is axis-aligned here).
fn grid_emitted_power(medium: &kiln_render::media::Medium) -> f64 {
    let kiln_render::media::Medium::Grid(g) = medium else {
        panic!("an emissive grid");
    };
    let (lo, hi) = medium.bounds().expect("a grid has a box");
    let n = 96;
    let mut sum = 0.0f64;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let f = glam::Vec3A::new(x as f32, y as f32, z as f32) + 0.5;
                let p = lo + (hi - lo) * f / n as f32;
                sum += kiln_render::math::luminance(g.source_at(g.to_box(p), None)) as f64;
            }
        }
    }
    let volume = ((hi - lo).x * (hi - lo).y * (hi - lo).z) as f64;
    4.0 * std::f64::consts::PI * sum * volume / (n * n * n) as f64
}

/// Kiln's luminance of linear sRGB.
fn luminance_f64(rgb: [f64; 3]) -> f64 {
    let c = kiln_render::math::rgb3(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32);
    kiln_render::math::luminance(c) as f64
}

/// Every kind of light shoots photons that carry its power: the mean luminance of the flux
/// its emitted rays carry is the power the light sampler chooses it by, within 2% (for a
/// VolumeLight, the power that leaves its surface, in closed form). Point, spot, goniometric,
/// projection, distant, uniform, image and dome lights at infinity, triangle, sphere and
/// disk area lights (one- and two-sided), a VolumeLight sphere and an emissive grid.
#[test]
fn every_light_kind_emits_photons_carrying_its_power() {
    use kiln_render::lights::SceneSphere;
    use kiln_render::math::luminance;
    use kiln_render::sampling::TrackingRng;
    let dir = tempfile::tempdir().unwrap();
    let n = 16;
    let gradient: Vec<[f32; 3]> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
            [0.2 + x, 0.5 + y * y, 1.0 - 0.5 * x * y]
        })
        .collect();
    write_pfm(&dir.path().join("image.pfm"), n, n, &gradient);
    let text = r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
Film "rgb" "integer xresolution" [ 4 ] "integer yresolution" [ 4 ]
WorldBegin
LightSource "point" "point3 from" [ 0 1 0 ] "rgb I" [ 1 2 3 ]
LightSource "spot" "point3 from" [ 0 2 0 ] "point3 to" [ 0 0 0 ] "rgb I" [ 3 2 1 ] "float coneangle" [ 40 ] "float conedeltaangle" [ 15 ]
AttributeBegin
    Translate 0.5 0.5 0
    Rotate 30 1 0 0
    LightSource "goniometric" "string filename" "image.pfm" "rgb I" [ 2 1.5 1 ]
AttributeEnd
AttributeBegin
    Translate 0 0 3
    Rotate 180 1 0 0
    LightSource "projection" "string filename" "image.pfm" "float fov" [ 50 ] "float scale" [ 2 ]
AttributeEnd
LightSource "distant" "point3 from" [ 1 3 2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 0.5 0.6 0.7 ]
LightSource "infinite" "rgb L" [ 0.1 0.2 0.3 ]
LightSource "infinite" "string filename" "image.pfm" "float scale" [ 0.3 ]
LightSource "dome" "rgb L" [ 0.2 0.2 0.1 ]
AttributeBegin
    AreaLightSource "diffuse" "rgb L" [ 4 3 2 ]
    Shape "trianglemesh" "point3 P" [ -1 -1 -1  1 -1 -1  0 -1 1 ] "integer indices" [ 0 1 2 ]
AttributeEnd
AttributeBegin
    AreaLightSource "diffuse" "rgb L" [ 1 2 1 ] "bool twosided" true
    Translate 1 0 0
    Shape "sphere" "float radius" [ 0.2 ]
AttributeEnd
AttributeBegin
    AreaLightSource "diffuse" "rgb L" [ 2 2 5 ]
    Translate -1 0 0
    Rotate 70 0 1 0
    Shape "disk" "float radius" [ 0.3 ]
AttributeEnd
AttributeBegin
    AreaLightSource "volume" "rgb Le" [ 4 1.6 0.4 ]
    Material "dielectric" "float eta" [ 1.5 ]
    Translate 0 -0.5 1
    Shape "sphere" "float radius" [ 0.4 ]
AttributeEnd
MakeNamedMedium "glow" "string type" "uniformgrid" "integer nx" [ 2 ] "integer ny" [ 2 ] "integer nz" [ 2 ]
    "float density" [ 1 2 3 4 1 2 3 4 ] "rgb Le" [ 1 0.5 0.2 ] "float Lescale" [ 3 ]
    "rgb sigma_a" [ 1 1 1 ] "rgb sigma_s" [ 0 0 0 ] "point3 p0" [ -0.5 0.5 -0.5 ] "point3 p1" [ 0.5 1.5 0.5 ]
AttributeBegin
    MediumInterface "glow" ""
    Material "interface"
    Translate 0 1 0
    Shape "sphere" "float radius" [ 0.45 ]
AttributeEnd
"#;
    let path = write_scene(dir.path(), "lights.pbrt", text);
    let desc = kiln_scene::load_file(&path).expect("scene loads");
    let scene = Scene::build(&desc, MediaPolicy::Render).expect("scene builds");
    let (lo, hi) = scene.geometry.bounds();
    let sphere = SceneSphere {
        center: (lo + hi) * 0.5,
        radius: scene.radius,
    };
    let ctx = scene.light_context();
    let mut kinds = std::collections::BTreeMap::new();
    for light in &scene.lights {
        let kind = format!("{light:?}");
        let kind = kind.split('(').next().unwrap().to_string();
        let power = match light {
            // A VolumeLight chooses itself by the emission that reaches its surface from
            // inside; what leaves is less (total internal reflection, Fresnel): the exitant
            // power in closed form for a uniformly glowing sphere.
            Light::VolumeSphere(v) => {
                volume_sphere_exitant_power(&scene.volumes[v.volume as usize], v.radius)
            }
            // An emissive grid chooses itself by a coarse estimate (each voxel's source from
            // nine lookups); its photons carry the integral of the source over the grid's
            // box, here by the midpoint rule.
            Light::Medium(m) => grid_emitted_power(&scene.media[m.medium as usize]),
            _ => light.power(scene.radius) as f64,
        };
        let count = 200_000;
        let mut rng = TrackingRng::new(17);
        let mut sum = 0.0f64;
        for _ in 0..count {
            let u = [
                glam::Vec2::new(rng.next_f32(), rng.next_f32()),
                glam::Vec2::new(rng.next_f32(), rng.next_f32()),
            ];
            if let (Some(ray), _) = light.emit(&ctx, sphere, u, rng.next_f32()) {
                sum += luminance(ray.flux) as f64;
            }
        }
        let mean = sum / count as f64;
        eprintln!("{kind}: photons carry {mean:.5}, power {power:.5}");
        assert!(
            (mean / power - 1.0).abs() < 0.02,
            "{kind}: photons carry {mean} on average, its power is {power}"
        );
        *kinds.entry(kind).or_insert(0) += 1;
    }
    // Every kind was there (a triangle light per face of the mesh).
    for kind in [
        "Point",
        "Spot",
        "Goniometric",
        "Projection",
        "Distant",
        "UniformInfinite",
        "ImageInfinite",
        "Dome",
        "Triangle",
        "Sphere",
        "Quadric",
        "VolumeSphere",
        "Medium",
    ] {
        assert!(kinds.contains_key(kind), "no {kind} light in {kinds:?}");
    }
}
