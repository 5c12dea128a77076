//! pbrt-v4's "subsurface" material, rendered by random walk: a dielectric boundary around
//! a scattering interior that the volumetric path tracer walks through.

use crate::util::{block_stats, max_z_score, render, write_scene};

/// Chandrasekhar's H-function for isotropic scattering of single-scattering albedo `w`, at
/// `mu`, from its iteration 1/H(μ) = √(1 − w) + (w/2) ∫₀¹ μ' H(μ') / (μ + μ') dμ' on a
/// midpoint grid.
fn h_function(w: f64, mu: f64) -> f64 {
    let n = 2000;
    let grid: Vec<f64> = (0..n).map(|i| (i as f64 + 0.5) / n as f64).collect();
    let root = (1.0 - w).sqrt();
    let integral = |m: f64, h: &[f64]| {
        grid.iter()
            .zip(h)
            .map(|(mp, hp)| mp * hp / (m + mp))
            .sum::<f64>()
            / n as f64
    };
    let mut h = vec![1.0; n];
    for _ in 0..200 {
        h = grid
            .iter()
            .map(|&m| 1.0 / (root + w / 2.0 * integral(m, &h)))
            .collect();
    }
    1.0 / (root + w / 2.0 * integral(mu, &h))
}

/// A semi-infinite, index-matched (eta 1) random-walk medium of isotropic scattering under a
/// uniform sky of radiance 1 sends back, straight up, its plane albedo 1 − H(1) √(1 − w):
/// for single-scattering albedos 0.5, 0.9 and 0.97 (one per channel, the same extinction)
/// within 1% and four standard errors. The walk is one bounce, whatever its length: with
/// maxdepth 1 too.
#[test]
fn a_semi_infinite_walk_reflects_the_exact_plane_albedo() {
    for max_depth in [1000, 1] {
        semi_infinite_walk(max_depth);
    }
}

/// A semi-infinite, index-matched random-walk medium (its top at z = 0) under a uniform sky
/// of radiance 1, seen straight down at `spp` samples and `res` pixels square.
fn semi_infinite(
    integrator: &str,
    spp: u32,
    res: u32,
    sigma_a: [f64; 3],
    sigma_s: [f64; 3],
) -> String {
    let v = |c: [f64; 3]| format!("{} {} {}", c[0], c[1], c[2]);
    format!(
        r#"Integrator "volpath" {integrator}
Sampler "zsobol" "integer pixelsamples" [ {spp} ]
Film "rgb" "integer xresolution" [ {res} ] "integer yresolution" [ {res} ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "subsurface" "float eta" 1 "rgb sigma_a" [ {} ] "rgb sigma_s" [ {} ]
Shape "revolution" "point2 contour" [ 0 -2000  2000 -2000  2000 0  0 0 ]
"#,
        v(sigma_a),
        v(sigma_s)
    )
}

fn semi_infinite_walk(max_depth: u32) {
    let dir = tempfile::tempdir().unwrap();
    let text = semi_infinite(
        &format!("\"integer maxdepth\" [ {max_depth} ]"),
        128,
        48,
        [0.5, 0.1, 0.03],
        [0.5, 0.9, 0.97],
    );
    let path = write_scene(dir.path(), "semi.pbrt", &text);
    // The exact albedo is per RGB channel: in RGB mode (spectrally each wavelength has
    // an albedo of its own between the channels').
    let img = render(&path, dir.path(), "semi", &["--rgb"]).image;
    for (c, w) in [0.5f64, 0.9, 0.97].into_iter().enumerate() {
        let want = 1.0 - h_function(w, 1.0) * (1.0 - w).sqrt();
        let (got, se) = block_stats(&img, 0, 0, 48, 48, c);
        eprintln!("maxdepth {max_depth}, albedo {w}: {got:.5} ± {se:.5}, exact {want:.5}");
        assert!(se < 0.003 * want, "too noisy to tell: ± {se}");
        assert!(
            (got - want).abs() < 0.01 * want && (got - want).abs() < 4.0 * se + 1e-4,
            "maxdepth {max_depth}, albedo {w}: {got} ± {se} against the exact {want}"
        );
    }
}

/// The Integrator's "walkdepth" caps a walk's events: cut off after 3, the walks in the
/// semi-infinite medium of albedo 0.97 send back well under the exact plane albedo.
#[test]
fn walkdepth_cuts_subsurface_walks_off() {
    let dir = tempfile::tempdir().unwrap();
    let text = semi_infinite(
        "\"integer maxdepth\" [ 5 ] \"integer walkdepth\" [ 3 ]",
        16,
        16,
        [0.03; 3],
        [0.97; 3],
    );
    let path = write_scene(dir.path(), "cut.pbrt", &text);
    let img = render(&path, dir.path(), "cut", &[]).image;
    let exact = 1.0 - h_function(0.97, 1.0) * (1.0 - 0.97f64).sqrt();
    let (got, _) = block_stats(&img, 0, 0, 16, 16, 0);
    eprintln!("walkdepth 3: {got:.4}, exact without a cap {exact:.4}");
    assert!(got > 0.05 && got < 0.8 * exact, "{got} against {exact}");
}

/// The subsurface material is the same thing as a dielectric of its eta with its
/// interior as a MediumInterface: the same image within noise (a sphere of skin-like
/// stuff, eta 1.33, rough and smooth, under an area light).
#[test]
fn subsurface_is_a_dielectric_around_its_medium() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |body: &str| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 64 ]
Sampler "zsobol" "integer pixelsamples" [ 32 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
LookAt 0 -4 1  0 0 0  0 0 1
Camera "perspective" "float fov" [ 35 ]
WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 8 8 8 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Translate 1.5 -1 3
Shape "sphere" "float radius" 0.5
AttributeEnd
LightSource "infinite" "rgb L" [ 0.1 0.1 0.1 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "bilinearmesh" "point3 P" [ -5 -5 -1  5 -5 -1  -5 5 -1  5 5 -1 ]
{body}
"#
        )
    };
    for roughness in [0.0, 0.3] {
        let sss = scene(&format!(
            "Material \"subsurface\" \"float eta\" 1.33 \"float roughness\" {roughness} \"float g\" 0.3 \"rgb sigma_a\" [ 0.3 0.8 1.5 ] \"rgb sigma_s\" [ 6 5 4 ] \"float scale\" 2\nShape \"sphere\""
        ));
        let explicit = scene(&format!(
            "MakeNamedMedium \"inside\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [ 0.6 1.6 3 ] \"rgb sigma_s\" [ 12 10 8 ] \"float g\" 0.3\nMediumInterface \"inside\" \"\"\nMaterial \"dielectric\" \"float eta\" 1.33 \"float roughness\" {roughness}\nShape \"sphere\""
        ));
        let a = write_scene(dir.path(), "sss.pbrt", &sss);
        let b = write_scene(dir.path(), "explicit.pbrt", &explicit);
        let a = render(&a, dir.path(), "sss", &["--seed", "1"]).image;
        let b = render(&b, dir.path(), "explicit", &["--seed", "2"]).image;
        let z = max_z_score(&a, &b, 4, 4);
        eprintln!("roughness {roughness}: subsurface vs medium in dielectric, largest z {z:.2}");
        assert!(
            z < 4.0,
            "roughness {roughness}: a block differs by {z} standard errors"
        );
        // The interior shows: without it the sphere is clear glass, another image.
        let glass = write_scene(
            dir.path(),
            "glass.pbrt",
            &scene(&format!(
                "Material \"dielectric\" \"float eta\" 1.33 \"float roughness\" {roughness}\nShape \"sphere\""
            )),
        );
        let c = render(&glass, dir.path(), "glass", &["--seed", "3"]).image;
        assert!(max_z_score(&a, &c, 4, 4) > 10.0);
    }
}

/// A measured medium by name (pbrt-v4's sssdragon asks for "Skin1") is its table's
/// coefficients times `scale`: the same image as those coefficients written out.
#[test]
fn a_named_measured_medium_is_its_coefficients() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |material: &str| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 32 ]
Sampler "zsobol" "integer pixelsamples" [ 8 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 24 ]
LookAt 0 -4 1  0 0 0  0 0 1
Camera "perspective" "float fov" [ 35 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
{material}
Shape "sphere"
"#
        )
    };
    let named = write_scene(
        dir.path(),
        "named.pbrt",
        &scene(
            "Material \"subsurface\" \"string name\" \"Skin1\" \"float scale\" 10 \"float eta\" 1.5",
        ),
    );
    let written = write_scene(
        dir.path(),
        "written.pbrt",
        &scene(
            "Material \"subsurface\" \"rgb sigma_a\" [ 0.032 0.17 0.48 ] \"rgb sigma_s\" [ 0.74 0.88 1.01 ] \"float scale\" 10 \"float eta\" 1.5",
        ),
    );
    let a = render(&named, dir.path(), "named", &[]);
    let b = render(&written, dir.path(), "written", &[]);
    assert_eq!(a.bytes, b.bytes);
}

/// The total transmittance of a plane-parallel slab (thickness 1, extinction 2, albedo
/// 0.8, isotropic, index-matched) for light arriving along its normal, by an independent
/// one-dimensional random walk written here: the chance a walker leaves by the far side.
fn slab_transmittance_by_walk(walkers: u32) -> (f64, f64) {
    let (sigma_t, albedo, depth) = (2.0f64, 0.8f64, 1.0f64);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut through = 0u32;
    for _ in 0..walkers {
        // Depth into the slab and the direction's cosine with the inward normal.
        let (mut z, mut mu) = (0.0f64, 1.0f64);
        loop {
            z += -libm::log(uniform()) / sigma_t * mu;
            if z >= depth {
                through += 1;
                break;
            }
            if z < 0.0 || uniform() >= albedo {
                break;
            }
            mu = 2.0 * uniform() - 1.0;
        }
    }
    let t = f64::from(through) / f64::from(walkers);
    (t, (t * (1.0 - t) / f64::from(walkers)).sqrt())
}

/// A thin subsurface slab seen from above against a uniform emitter below shows its total
/// transmittance for light along the view (reciprocity): the same as the independent walk,
/// within 1% and four standard errors. Scattering carries light through that the
/// unscattered exp(-2) alone would not.
#[test]
fn a_thin_slab_transmits_what_an_independent_walk_finds() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"Integrator "volpath" "integer maxdepth" [ 1000 ]
Sampler "zsobol" "integer pixelsamples" [ 128 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Translate 0 0 -1.5
Shape "disk" "float radius" 3000
AttributeEnd
Material "subsurface" "float eta" 1 "rgb sigma_a" [ 0.4 0.4 0.4 ] "rgb sigma_s" [ 1.6 1.6 1.6 ]
Shape "revolution" "point2 contour" [ 0 -1  500 -1  500 0  0 0 ]
"#;
    let path = write_scene(dir.path(), "slab.pbrt", text);
    let img = render(&path, dir.path(), "slab", &[]).image;
    let (want, want_se) = slab_transmittance_by_walk(2_000_000);
    let (got, se) = block_stats(&img, 0, 0, 48, 48, 1);
    eprintln!("slab: {got:.5} ± {se:.5}, independent walk {want:.5} ± {want_se:.5}");
    let both = (se * se + want_se * want_se).sqrt();
    assert!(both < 0.003 * want, "too noisy to tell: ± {both}");
    assert!(
        (got - want).abs() < 0.01 * want && (got - want).abs() < 4.0 * both,
        "slab transmittance {got} ± {se}, independent walk {want} ± {want_se}"
    );
    assert!(
        want > 1.5 * libm::exp(-2.0f64),
        "the walk adds little to exp(-2)"
    );
}

/// A unit sphere of `material` at the origin under a spherical area light up and to the
/// left and a dim sky, seen from the front at 96x96: the scene both subsurface spheres
/// below were rendered in by pbrt-v4.
fn lit_sphere(spp: u32, max_depth: u32, material: &str) -> String {
    format!(
        r#"LookAt 0 -5 1.2  0 0 0.2  0 0 1
Camera "perspective" "float fov" [ 30 ]
Sampler "halton" "integer pixelsamples" [ {spp} ]
Film "rgb" "integer xresolution" [ 96 ] "integer yresolution" [ 96 ]
Integrator "volpath" "integer maxdepth" [ {max_depth} ]
WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 10 10 10 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Translate 2 -2 3
Shape "sphere" "float radius" 0.6
AttributeEnd
LightSource "infinite" "rgb L" [ 0.05 0.05 0.05 ]
{material}
Shape "sphere"
"#
    )
}

/// pbrt-v4 (5f7a606, CPU, built here) on the same grey subsurface sphere under an area light
/// (96x96, 256 spp halton, the sphere's disk of pixels): its volumetric path tracer with the
/// medium inside a dielectric, the ground truth, gave 0.06673; its `subsurface` material,
/// a tabulated BSSRDF, 0.05827 (12.7% dark). Kiln's random walk must agree with the ground
/// truth within 3%, and be nearer to it than pbrt-v4's BSSRDF is.
#[test]
fn a_subsurface_sphere_matches_pbrt_v4s_volumetric_ground_truth() {
    const PBRT_VOLUMETRIC: f64 = 0.06673;
    const PBRT_BSSRDF: f64 = 0.05827;
    let dir = tempfile::tempdir().unwrap();
    let text = lit_sphere(
        256,
        256,
        r#"Material "subsurface" "float eta" 1.33 "rgb sigma_a" [ 1 1 1 ] "rgb sigma_s" [ 7 7 7 ]"#,
    );
    let path = write_scene(dir.path(), "sphere.pbrt", &text);
    let img = render(&path, dir.path(), "sphere", &[]).image;
    let (mut sum, mut n) = (0.0f64, 0u32);
    for y in 0..96u32 {
        for x in 0..96u32 {
            let (dx, dy) = (x as f64 - 48.0, y as f64 - 43.0);
            if dx * dx + dy * dy < 26.88 * 26.88 {
                sum += f64::from(img.get(x, y)[1]);
                n += 1;
            }
        }
    }
    let kiln = sum / f64::from(n);
    eprintln!(
        "subsurface sphere: Kiln {kiln:.5}, pbrt-v4 volumetric {PBRT_VOLUMETRIC}, pbrt-v4 BSSRDF {PBRT_BSSRDF}"
    );
    assert!(
        (kiln - PBRT_VOLUMETRIC).abs() < 0.03 * PBRT_VOLUMETRIC,
        "Kiln {kiln} against pbrt-v4's volumetric {PBRT_VOLUMETRIC}"
    );
    assert!((kiln - PBRT_VOLUMETRIC).abs() < (PBRT_BSSRDF - PBRT_VOLUMETRIC).abs());
}

/// pbrt-v4 (5f7a606, CPU, built here) on a coloured, high-albedo subsurface sphere (sigma_s
/// 8 7 6, sigma_a 0.08 0.2 0.5, eta 1.33) under an area light to the left (96x96, 1024 spp
/// halton, volpath maxdepth 1000; over the sphere's disk, centre (48, 55.1) and radius 34
/// pixels, and its lit and shadowed halves): its volumetric path tracer with the medium
/// inside a dielectric, the ground truth, and its tabulated-BSSRDF `subsurface` material,
/// 13-18% dark on the lit side and 20-26% on the shadowed side. Kiln's random walk must
/// agree with the ground truth per channel (within 2% lit, 3% over the disk, 5% on the dim
/// shadowed side, where pbrt-v4's spectral rendering and the noise weigh most) and be nearer
/// to it than pbrt-v4's BSSRDF everywhere.
#[test]
fn a_coloured_subsurface_sphere_matches_pbrt_v4s_volumetric_ground_truth() {
    // (disk, lit half, shadowed half) x RGB.
    const VOLUMETRIC: [[f64; 3]; 3] = [
        [0.12438, 0.10262, 0.07212],
        [0.15646, 0.12966, 0.09221],
        [0.09231, 0.07558, 0.05204],
    ];
    const BSSRDF: [[f64; 3]; 3] = [
        [0.10464, 0.08345, 0.05708],
        [0.13542, 0.10893, 0.0757],
        [0.07386, 0.05796, 0.03846],
    ];
    const WITHIN: [f64; 3] = [0.03, 0.02, 0.05];
    let dir = tempfile::tempdir().unwrap();
    let text = lit_sphere(
        512,
        1000,
        r#"Material "subsurface" "float eta" 1.33 "rgb sigma_a" [ 0.08 0.2 0.5 ] "rgb sigma_s" [ 8 7 6 ]"#,
    );
    let path = write_scene(dir.path(), "coloured.pbrt", &text);
    // In RGB mode: spectrally, at 512 spp the four wavelengths' noise (1.6% per 64-spp
    // image over the disk, against RGB's 1.2%) and pbrt-v4's own leave too little margin;
    // at 4096 spp spectral Kiln is within 1.5% of the ground truth everywhere (the
    // closing note of issue 37).
    let img = render(&path, dir.path(), "coloured", &["--rgb"]).image;
    let mut sums = [[0.0f64; 3]; 3];
    let mut counts = [0u32; 3];
    for y in 0..96u32 {
        for x in 0..96u32 {
            let (dx, dy) = (x as f64 + 0.5 - 48.0, y as f64 + 0.5 - 55.109);
            if dx * dx + dy * dy >= 34.0 * 34.0 {
                continue;
            }
            // The light is to the left: the image's left half is the lit one.
            let pixel = img.get(x, y);
            for region in [0, if x < 48 { 1 } else { 2 }] {
                for (sum, v) in sums[region].iter_mut().zip(pixel) {
                    *sum += f64::from(v);
                }
                counts[region] += 1;
            }
        }
    }
    for (region, name) in ["disk", "lit half", "shadowed half"].iter().enumerate() {
        let kiln: [f64; 3] = std::array::from_fn(|c| sums[region][c] / f64::from(counts[region]));
        eprintln!(
            "coloured subsurface sphere, {name}: Kiln {kiln:.5?}, pbrt-v4 volumetric {:?}, BSSRDF {:?}",
            VOLUMETRIC[region], BSSRDF[region]
        );
        for c in 0..3 {
            let (want, bssrdf) = (VOLUMETRIC[region][c], BSSRDF[region][c]);
            assert!(
                (kiln[c] / want - 1.0).abs() < WITHIN[region],
                "{name}, channel {c}: Kiln {} against pbrt-v4's volumetric {want}",
                kiln[c]
            );
            assert!(
                (kiln[c] - want).abs() < (bssrdf - want).abs(),
                "{name}, channel {c}"
            );
        }
    }
}

/// Photon maps leave subsurface walks alone: with a volume and a caustic photon map, a scene
/// with a subsurface sphere lit by a sky and a small lamp shows the floor around the sphere
/// as plain path tracing does. Photons stored inside the sphere once ended every walk at its
/// first scattering with a gather far wider than the walk. And a walk ends a caustic chain
/// for camera paths as it does for photons: a path that gathered caustics on the floor and
/// then walked through the sphere once left out the light it found after the walk, which no
/// photon had brought either (the floor's front rows 5-8% dark in red).
#[test]
fn photon_maps_do_not_cut_subsurface_walks_short() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |maps: &str| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 64 ] {maps}
Sampler "zsobol" "integer pixelsamples" [ 256 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
LookAt 0 -4 1  0 0 0  0 0 1
Camera "perspective" "float fov" [ 35 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.5 0.5 0.5 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 40 40 40 ]
Translate 2 -2 4
Shape "sphere" "float radius" [ 0.3 ]
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "bilinearmesh" "point3 P" [ -5 -5 -1  5 -5 -1  -5 5 -1  5 5 -1 ]
Material "subsurface" "float eta" 1.33 "rgb sigma_a" [ 0.3 0.8 1.5 ] "rgb sigma_s" [ 12 10 8 ]
Shape "sphere"
"#
        )
    };
    let plain = write_scene(dir.path(), "plain.pbrt", &scene(""));
    let photons = write_scene(
        dir.path(),
        "photons.pbrt",
        &scene(r#""integer volumephotons" [ 20000 ] "integer causticphotons" [ 20000 ]"#),
    );
    let a = render(&plain, dir.path(), "plain", &[]).image;
    let b = render(&photons, dir.path(), "photons", &[]).image;
    // The floor's front rows, before the sphere; measured 256 spp: red -0.3%, green -0.2%
    // (blue +2%: the photons' colour is an RGB estimate, met again as a spectrum), and
    // -7.9%, -5.5% with the walk not ending the chain.
    for c in 0..2 {
        let (pa, pb) = (
            block_stats(&a, 0, 40, 48, 8, c).0,
            block_stats(&b, 0, 40, 48, 8, c).0,
        );
        eprintln!("channel {c}: path tracing {pa:.5}, with photon maps {pb:.5}");
        assert!(
            (pb / pa - 1.0).abs() < 0.03,
            "channel {c}: photon maps change the floor by {:.1}%",
            (pb / pa - 1.0) * 100.0
        );
    }
}

/// A textured reflectance (pbrt-v4's head scene gives one) sets each walk's coefficients
/// where it enters: a deep slab whose reflectance is a checkerboard of 0.8 and 0.3, with a
/// mean free path far below a square's size, shows in each square what a slab of that
/// square's constant reflectance shows (within four standard errors of the difference),
/// and the two squares differ.
#[test]
fn a_textured_reflectance_sets_each_walk_where_it_enters() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |reflectance: &str| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 1000 ]
Sampler "zsobol" "integer pixelsamples" [ 64 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -2 2 -2 2 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Texture "checks" "spectrum" "checkerboard" "float uscale" 2 "float vscale" 2
    "rgb tex1" [ 0.8 0.8 0.8 ] "rgb tex2" [ 0.3 0.3 0.3 ]
Material "subsurface" "float eta" 1 {reflectance} "rgb mfp" [ 0.01 0.01 0.01 ]
Shape "trianglemesh"
    "point3 P" [ -2 -2 0  2 -2 0  2 2 0  -2 2 0  -2 -2 -1  2 -2 -1  2 2 -1  -2 2 -1 ]
    "point2 uv" [ 0 0  1 0  1 1  0 1  0 0  1 0  1 1  0 1 ]
    "integer indices" [ 0 1 2  0 2 3  4 6 5  4 7 6  0 4 5  0 5 1  1 5 6  1 6 2
                        2 6 7  2 7 3  3 7 4  3 4 0 ]
"#
        )
    };
    let render_with = |name: &str, reflectance: &str| {
        let path = write_scene(dir.path(), &format!("{name}.pbrt"), &scene(reflectance));
        render(&path, dir.path(), name, &[]).image
    };
    let textured = render_with("textured", "\"texture reflectance\" \"checks\"");
    let light = render_with("light", "\"rgb reflectance\" [ 0.8 0.8 0.8 ]");
    let dark = render_with("dark", "\"rgb reflectance\" [ 0.3 0.3 0.3 ]");
    // The squares' interiors, 4 pixels in from every edge. pbrt-v4's camera space is
    // left-handed: looking down from +z with y up, the image's x runs along world -x, so u
    // runs right to left and v bottom to top; checkerboard's tex1 is where both are below
    // 0.5, the bottom right square.
    let squares = [(4, 28, 0.3), (28, 28, 0.8), (4, 4, 0.8), (28, 4, 0.3)];
    let mut seen = Vec::new();
    for (x0, y0, a) in squares {
        let reference = if a > 0.5 { &light } else { &dark };
        let (got, se) = block_stats(&textured, x0, y0, 16, 16, 1);
        let (want, se_want) = block_stats(reference, x0, y0, 16, 16, 1);
        let err = (se * se + se_want * se_want).sqrt();
        eprintln!(
            "square at ({x0}, {y0}), reflectance {a}: {got:.4} ± {se:.4}, constant {want:.4} ± {se_want:.4}"
        );
        assert!(
            (got - want).abs() < 4.0 * err + 1e-4,
            "square at ({x0}, {y0}): {got} ± {se}, against {want} ± {se_want} for a constant {a}"
        );
        seen.push(got);
    }
    assert!(
        seen[1] > 1.5 * seen[0] && seen[2] > 1.5 * seen[3],
        "{seen:?}"
    );
}

/// Walks take no light samples (their shape's surface blocks every shadow ray) unless a
/// light at a point might lie inside: lights inside a subsurface sphere, an emitting sphere
/// or a point light, light it as they light the same medium inside a dielectric, where paths
/// sample lights at every scattering (the same image within noise).
#[test]
fn lights_inside_a_subsurface_shape_are_found() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |light: &str, body: &str| {
        format!(
            r#"Integrator "volpath" "integer maxdepth" [ 100 ]
Sampler "zsobol" "integer pixelsamples" [ 32 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
LookAt 0 -4 0  0 0 0  0 0 1
Camera "perspective" "float fov" [ 35 ]
WorldBegin
{light}
{body}
Shape "sphere"
"#
        )
    };
    let lights = [
        "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\nMaterial \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\nShape \"sphere\" \"float radius\" 0.3\nAttributeEnd",
        "LightSource \"point\" \"rgb I\" [ 3 3 3 ]",
    ];
    for (i, light) in lights.into_iter().enumerate() {
        let sss = write_scene(
            dir.path(),
            "sss.pbrt",
            &scene(
                light,
                "Material \"subsurface\" \"float eta\" 1.33 \"rgb sigma_a\" [ 0.2 0.4 0.8 ] \"rgb sigma_s\" [ 2 2 2 ]",
            ),
        );
        let explicit = write_scene(
            dir.path(),
            "explicit.pbrt",
            &scene(
                light,
                "MakeNamedMedium \"inside\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [ 0.2 0.4 0.8 ] \"rgb sigma_s\" [ 2 2 2 ]\nMediumInterface \"inside\" \"\"\nMaterial \"dielectric\" \"float eta\" 1.33",
            ),
        );
        let a = render(&sss, dir.path(), "sss", &["--seed", "1"]).image;
        let b = render(&explicit, dir.path(), "explicit", &["--seed", "2"]).image;
        let z = max_z_score(&a, &b, 4, 4);
        let mean = block_stats(&a, 0, 0, 32, 32, 0).0;
        eprintln!("light {i}: largest z {z:.2}, mean red {mean:.4}");
        assert!(mean > 0.01, "light {i}: the sphere is dark");
        assert!(z < 4.0, "light {i}: a block differs by {z} standard errors");
    }
}
