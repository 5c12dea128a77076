//! Nested dielectrics by priority (Kiln's "integer priority"): a shared boundary against the
//! same geometry built from explicit relative-index interfaces, a slab stack against its
//! closed form, and a shape hidden inside a higher-priority one.

use crate::util::{block_stats, max_z_score, render, write_scene};

/// A lit, checkered room for a glass to stand in: the image shows refraction everywhere.
const ROOM: &str = r#"Integrator "volpath" "integer maxdepth" [ 32 ]
Sampler "zsobol" "integer pixelsamples" [ 32 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ]
LookAt 0 -5 2.2  0 0 0.9  0 0 1
Camera "perspective" "float fov" [ 32 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.3 0.3 0.3 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 6 6 6 ]
Translate 2 -2 5
Shape "sphere" "float radius" 0.6
AttributeEnd
Texture "checks" "spectrum" "checkerboard" "float uscale" 8 "float vscale" 8
    "rgb tex1" [0.8 0.8 0.8] "rgb tex2" [0.1 0.1 0.1]
Material "diffuse" "texture reflectance" "checks"
Shape "bilinearmesh" "point3 P" [ -4 -4 0  4 -4 0  -4 4 0  4 4 0 ] "point2 uv" [0 0 1 0 0 1 1 1]
Shape "bilinearmesh" "point3 P" [ -4 3 0  4 3 0  -4 3 5  4 3 5 ] "point2 uv" [0 0 1 0 0 1 1 1]
MakeNamedMedium "water" "string type" "homogeneous" "rgb sigma_a" [ 0.05 0.6 0.9 ] "rgb sigma_s" [ 0 0 0 ]
"#;

/// A glass cup (eta 1.5) of water (eta 1.33, absorbing) as two closed shapes with priorities:
/// the water reaches halfway into the glass wall and floor, and the glass outranks it.
const NESTED_CUP: &str = r#"AttributeBegin
Material "dielectric" "float eta" 1.5
Shape "revolution" "point2 contour" [ 0 0  1 0  1 2  0.9 2  0.9 0.2  0 0.2 ] "integer priority" 2
AttributeEnd
AttributeBegin
MediumInterface "water" ""
Material "dielectric" "float eta" 1.33
Shape "revolution" "point2 contour" [ 0 0.1  0.95 0.1  0.95 1.5  0 1.5 ] "integer priority" 1
AttributeEnd
"#;

/// The same cup as seed 003 builds it: three open surfaces, glass-air, glass-water (relative
/// eta 1.5 / 1.33, glass on its inner side) and water-air, each with its own media.
const EXPLICIT_CUP: &str = r#"AttributeBegin
Material "dielectric" "float eta" 1.5
Shape "revolution" "point2 contour" [ 0 0  1 0  1 2  0.9 2  0.9 1.5 ]
AttributeEnd
AttributeBegin
MediumInterface "" "water"
Material "dielectric" "float eta" 1.1278195488721805
Shape "revolution" "point2 contour" [ 0.9 1.5  0.9 0.2  0 0.2 ]
AttributeEnd
AttributeBegin
MediumInterface "water" ""
Material "dielectric" "float eta" 1.33
Shape "revolution" "point2 contour" [ 0.9 1.5  0 1.5 ]
AttributeEnd
"#;

/// The water in the glass, one shared boundary by priority, renders as the three explicit
/// interfaces do: the same image within noise (independent seeds, block by block).
#[test]
fn a_shared_boundary_renders_as_explicit_relative_indices() {
    let dir = tempfile::tempdir().unwrap();
    let nested = write_scene(dir.path(), "nested.pbrt", &format!("{ROOM}{NESTED_CUP}"));
    let explicit = write_scene(
        dir.path(),
        "explicit.pbrt",
        &format!("{ROOM}{EXPLICIT_CUP}"),
    );
    let a = render(&nested, dir.path(), "nested", &["--seed", "1"]).image;
    let b = render(&explicit, dir.path(), "explicit", &["--seed", "2"]).image;
    let z = max_z_score(&a, &b, 4, 4);
    eprintln!("cup: largest block z-score {z:.2}");
    assert!(z < 4.0, "a block differs by {z} standard errors");
    // The water is there: without it (glass alone) the cup's middle is another colour.
    let glass = write_scene(
        dir.path(),
        "glass.pbrt",
        &format!(
            "{ROOM}{}",
            &NESTED_CUP[..NESTED_CUP.find("AttributeEnd").unwrap() + 13]
        ),
    );
    let c = render(&glass, dir.path(), "glass", &["--seed", "3"]).image;
    let z_empty = max_z_score(&a, &c, 4, 4);
    assert!(z_empty > 10.0, "the water changes nothing ({z_empty})");
}

/// Incoherent transmittance of a stack at normal incidence: interfaces between the indices
/// `n` (air at both ends) with the internal transmittance `t[i]` of layer i between
/// interfaces i and i + 1, every internal reflection summed (the adding method).
fn stack_transmittance(n: &[f64], t: &[f64]) -> f64 {
    let fresnel = |a: f64, b: f64| ((a - b) / (a + b)).powi(2);
    // Front reflectance, back reflectance and transmittance of the stack so far, built from
    // the bottom up; reciprocity makes transmittance the same both ways.
    let last = n.len() - 1;
    let r = fresnel(n[last - 1], n[last]);
    let (mut rf, mut rb, mut tt) = (r, r, 1.0 - r);
    for i in (0..last - 1).rev() {
        let r = fresnel(n[i], n[i + 1]);
        let (r1, t1) = (r, 1.0 - r);
        let a = t[i] * t[i];
        let denom = 1.0 - r1 * rf * a;
        let new_tt = t1 * t[i] * tt / denom;
        let new_rf = r1 + t1 * t1 * rf * a / denom;
        let new_rb = rb + tt * tt * r1 * a / denom;
        (rf, rb, tt) = (new_rf, new_rb, new_tt);
    }
    let _ = rb;
    tt
}

/// Three slabs stacked by priority (each reaching into its neighbour, the higher priority
/// cutting the lower) transmit what Fresnel at each true interface and Beer-Lambert in the
/// absorbing one give, every internal reflection included: within 0.5%.
#[test]
fn a_slab_stack_transmits_its_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    // Top to bottom: glass 1.5 (z 1..2), absorbing water 1.33 (z 0.05..1, sigma_a 0.3),
    // flint 1.7 (z -0.5..0.05). The water's own slab is z 0..1.1: both of its faces lie
    // inside higher-priority slabs and are hidden.
    let slab = |z0: f64, z1: f64| format!("[ 0 {z0}  50 {z0}  50 {z1}  0 {z1} ]");
    let text = format!(
        r#"Integrator "volpath" "integer maxdepth" [ 100 ]
Sampler "zsobol" "integer pixelsamples" [ 64 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 64 ]
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [ -1 1 -1 1 ]
WorldBegin
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Translate 0 0 -1
Shape "disk" "float radius" 40
AttributeEnd
MakeNamedMedium "ink" "string type" "homogeneous" "rgb sigma_a" [ 0.3 0.3 0.3 ] "rgb sigma_s" [ 0 0 0 ]
AttributeBegin
Material "dielectric" "float eta" 1.5
Shape "revolution" "point2 contour" {glass} "integer priority" 3
AttributeEnd
AttributeBegin
MediumInterface "ink" ""
Material "dielectric" "float eta" 1.33
Shape "revolution" "point2 contour" {water} "integer priority" 2
AttributeEnd
AttributeBegin
Material "dielectric" "float eta" 1.7
Shape "revolution" "point2 contour" {flint} "integer priority" 3
AttributeEnd
"#,
        glass = slab(1.0, 2.0),
        water = slab(0.0, 1.1),
        flint = slab(-0.5, 0.05),
    );
    let path = write_scene(dir.path(), "stack.pbrt", &text);
    let img = render(&path, dir.path(), "stack", &[]).image;
    let want = stack_transmittance(
        &[1.0, 1.5, 1.33, 1.7, 1.0],
        &[1.0, libm::exp(-0.3f64 * 0.95), 1.0],
    );
    let (got, se) = block_stats(&img, 0, 0, 64, 64, 1);
    eprintln!("slab stack: {got:.5} ± {se:.5}, closed form {want:.5}");
    assert!(se < 0.0015 * want, "too noisy to tell: ± {se}");
    assert!(
        (got - want).abs() < 0.005 * want,
        "transmittance {got} ± {se}, closed form {want}"
    );
    // Had the hidden faces been there, the water's own faces would reflect too: the closed
    // form with them differs by more than the tolerance, so the test can tell.
    let with_hidden = stack_transmittance(
        &[1.0, 1.5, 1.33, 1.5, 1.33, 1.7, 1.33, 1.7, 1.0],
        &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
    );
    assert!((with_hidden - want).abs() > 0.02 * want);
}

/// A sphere of another index lying wholly inside a higher-priority block is not there: the
/// image equals the block's alone within noise. With the priorities swapped it shows.
#[test]
fn a_shape_inside_a_higher_priority_one_is_invisible() {
    let dir = tempfile::tempdir().unwrap();
    let block = r#"AttributeBegin
Material "dielectric" "float eta" 1.5
Shape "revolution" "point2 contour" [ 0 0  1.2 0  1.2 1.8  0 1.8 ] "integer priority" 5
AttributeEnd
"#;
    let sphere = |priority: u32| {
        format!(
            r#"AttributeBegin
Material "dielectric" "float eta" 2.2
Translate 0 0 0.9
Shape "sphere" "float radius" 0.5 "integer priority" {priority}
AttributeEnd
"#
        )
    };
    let alone = write_scene(dir.path(), "alone.pbrt", &format!("{ROOM}{block}"));
    let hidden = write_scene(
        dir.path(),
        "hidden.pbrt",
        &format!("{ROOM}{block}{}", sphere(1)),
    );
    let shown = write_scene(
        dir.path(),
        "shown.pbrt",
        &format!("{ROOM}{block}{}", sphere(9)),
    );
    let a = render(&alone, dir.path(), "alone", &["--seed", "1"]).image;
    let b = render(&hidden, dir.path(), "hidden", &["--seed", "2"]).image;
    let c = render(&shown, dir.path(), "shown", &["--seed", "3"]).image;
    let z = max_z_score(&a, &b, 4, 4);
    eprintln!("hidden sphere: largest block z-score {z:.2}");
    assert!(z < 4.0, "the hidden sphere shows: {z} standard errors");
    let z_shown = max_z_score(&a, &c, 4, 4);
    assert!(
        z_shown > 10.0,
        "the outranking sphere does not show ({z_shown})"
    );
}

/// A scene without priorities renders exactly as before nesting existed: the same bytes with
/// "integer priority" 0 written out as without it.
#[test]
fn priority_zero_is_pbrt_v4s_behaviour_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let plain = write_scene(dir.path(), "plain.pbrt", &format!("{ROOM}{EXPLICIT_CUP}"));
    let zero = write_scene(
        dir.path(),
        "zero.pbrt",
        &format!(
            "{ROOM}{}",
            EXPLICIT_CUP.replace(
                "Shape \"revolution\"",
                "Shape \"revolution\" \"integer priority\" 0"
            )
        ),
    );
    let a = render(&plain, dir.path(), "plain", &[]);
    let b = render(&zero, dir.path(), "zero", &[]);
    assert_eq!(a.bytes, b.bytes);
}
