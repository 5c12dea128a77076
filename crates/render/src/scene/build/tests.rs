//! Building scenes: pbrt-v4's "power" normalisation, the shapes' geometric helpers, and
//! what a built scene holds for each kind of shape and light.

use super::quadric::revolution_is_closed;
use super::*;
use crate::lights::Light;
use crate::math::Ray;
use glam::Vec3A;
use std::f32::consts::PI;

fn build(world: &str) -> Result<Scene, BuildError> {
    let text = format!(
        "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\nCamera \"perspective\"\nWorldBegin\n{world}"
    );
    let desc = kiln_scene::load_str(&text, "build.pbrt".as_ref(), ".".as_ref()).unwrap();
    Scene::build(&desc, MediaPolicy::Render)
}

#[test]
fn power_is_lumens_over_pi_area_and_sides() {
    // Φ = π · area · sides · L: a one-sided unit area of power π has L = 1.
    assert_eq!(power_scale(Some(PI), 1.0, false, 1.0), 1.0);
    assert_eq!(power_scale(Some(PI), 1.0, true, 1.0), 0.5);
    assert_eq!(power_scale(Some(PI), 2.0, false, 1.0), 0.5);
    // An image's mean luminance stands for the radiance it scales.
    assert_eq!(power_scale(Some(PI), 1.0, false, 4.0), 0.25);
    assert_eq!(power_scale(None, 3.0, true, 2.0), 1.0);
    assert_eq!(power_scale(Some(PI), 0.0, false, 1.0), 0.0);
}

#[test]
fn similarity_scales_are_found_and_others_are_not() {
    let rotated = DMat4::from_translation(glam::DVec3::new(1.0, -2.0, 3.0))
        * DMat4::from_rotation_y(0.7)
        * DMat4::from_scale(glam::DVec3::splat(2.5));
    let s = similarity_scale(&rotated).unwrap();
    assert!((s - 2.5).abs() < 1e-12, "{s}");
    let mirrored = DMat4::from_scale(glam::DVec3::new(-3.0, 3.0, 3.0));
    assert!((similarity_scale(&mirrored).unwrap() - 3.0).abs() < 1e-12);
    assert_eq!(
        similarity_scale(&DMat4::from_scale(glam::DVec3::new(1.0, 2.0, 1.0))),
        None
    );
    let sheared = DMat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);
    assert_eq!(similarity_scale(&sheared), None);
    assert_eq!(similarity_scale(&DMat4::ZERO), None);
}

#[test]
fn a_revolution_is_closed_when_swept_round_from_axis_to_axis() {
    let revolution = |contour: Vec<[f32; 2]>, phi_max: f64| kiln_scene::RevolutionDesc {
        contour,
        normals: None,
        crease: 0.0,
        phi_max,
    };
    let tau = std::f64::consts::TAU;
    assert!(revolution_is_closed(&revolution(
        vec![[0.0, 0.0], [1.0, 0.5], [0.0, 1.0]],
        tau
    )));
    assert!(revolution_is_closed(&revolution(
        vec![[1.0, 0.0], [2.0, 0.5], [1.0, 0.0]],
        tau
    )));
    assert!(!revolution_is_closed(&revolution(
        vec![[1.0, 0.0], [1.0, 1.0]],
        tau
    )));
    assert!(!revolution_is_closed(&revolution(
        vec![[0.0, 0.0], [1.0, 0.5], [0.0, 1.0]],
        3.0
    )));
}

#[test]
fn emitting_shapes_become_lights_of_their_power() {
    // Two triangles of a one-sided unit square of power π: each face L = 1.
    let scene = build(
        "AreaLightSource \"diffuse\" \"rgb L\" [ 5 5 5 ] \"float power\" [ 3.14159265 ]
         Shape \"trianglemesh\" \"point3 P\" [ 0 0 0  1 0 0  1 1 0  0 1 0 ] \"integer indices\" [ 0 1 2 0 2 3 ]",
    )
    .unwrap();
    assert_eq!(scene.lights.len(), 2);
    for light in &scene.lights {
        let Light::Triangle(t) = light else {
            panic!("{light:?}");
        };
        assert!((t.area - 0.5).abs() < 1e-6);
        // pbrt-v4's "power" is per shape, and each triangle of a mesh is one: L · Φ / (π ·
        // the triangle's area) = 5 · π / (π · 0.5).
        assert!(
            (t.radiance - crate::math::Color::splat(10.0))
                .abs()
                .max_element()
                < 1e-4,
            "{:?}",
            t.radiance
        );
    }
    // A sphere under a uniform scale stays a world-space sphere; under a non-uniform one it
    // is a quadric light.
    let scene = build(
        "AttributeBegin Scale 2 2 2 AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ] Shape \"sphere\" AttributeEnd
         AttributeBegin Scale 1 2 1 AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ] Shape \"sphere\" AttributeEnd",
    )
    .unwrap();
    assert!(matches!(
        scene.lights[..],
        [Light::Sphere(_), Light::Quadric(_)]
    ));
    assert_eq!(scene.geometry.prims.spheres.len(), 1);
    assert_eq!(scene.geometry.prims.quadrics.len(), 1);
}

#[test]
fn geometry_beyond_the_world_limit_is_refused_where_it_is() {
    for (world, what) in [
        (
            "Shape \"trianglemesh\" \"point3 P\" [ 0 0 0  1 0 0  2e15 1 0 ] \"integer indices\" [ 0 1 2 ]",
            "vertex 2 of this mesh",
        ),
        ("Translate 1e16 0 0 Shape \"sphere\"", "this sphere"),
        ("Scale 1e16 1 1 Shape \"disk\"", "this shape"),
    ] {
        let message = build(world).err().expect("refused").to_string();
        assert!(
            message.starts_with("build.pbrt:")
                && message.contains(what)
                && message.contains("1e15"),
            "{world}: {message}"
        );
    }
}

#[test]
fn a_volume_light_needs_a_closed_shape_and_a_smooth_dielectric() {
    let light = "AreaLightSource \"volume\" \"rgb Le\" [ 1 1 1 ] \"rgb sigma_a\" [ 1 1 1 ]";
    let ok = build(&format!(
        "Material \"dielectric\" {light} Shape \"sphere\" \"float radius\" [ 1 ]"
    ))
    .unwrap();
    assert_eq!(ok.volumes.len(), 1);
    assert!(matches!(ok.lights[..], [Light::VolumeSphere(_)]));
    let open = build(&format!("Material \"dielectric\" {light} Shape \"disk\""))
        .err()
        .unwrap()
        .to_string();
    assert!(open.contains("needs a closed shape"), "{open}");
    let diffuse = build(&format!("Material \"diffuse\" {light} Shape \"sphere\""))
        .err()
        .unwrap()
        .to_string();
    assert!(diffuse.contains("smooth \"dielectric\""), "{diffuse}");
}

/// 30,000 copies of one triangle, or of one sphere, once overflowed the BVH builder's
/// stack (obvhs's PLOC merges primitives it cannot tell apart into a chain). They are now
/// built by a median split, in the stack a production render thread has and in well
/// under the time: a camera ray sees them as one.
#[test]
fn coincident_primitives_build_in_bounded_stack_and_time() {
    let n = 30_000;
    let points = "-1 -1 0 1 -1 0 0 1 0 ".repeat(n);
    let indices: String = (0..n)
        .map(|i| format!("{} {} {} ", 3 * i, 3 * i + 1, 3 * i + 2))
        .collect();
    for world in [
        format!("Shape \"trianglemesh\" \"point3 P\" [ {points}] \"integer indices\" [ {indices}]"),
        format!(
            "Translate 0 0 3\n{}",
            "Shape \"sphere\" \"float radius\" [ 0.5 ]\n".repeat(n)
        ),
    ] {
        let start = std::time::Instant::now();
        // On a thread with a production render thread's stack (rayon's default, 2 MiB),
        // where the BVH is built.
        let scene = std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(move || build(&world).unwrap())
            .unwrap()
            .join()
            .expect("the build did not overflow its stack");
        assert!(
            start.elapsed() < std::time::Duration::from_secs(10),
            "{:?}",
            start.elapsed()
        );
        let ray = crate::math::Ray::new(Vec3A::new(0.0, 0.0, -5.0), Vec3A::Z);
        let hit = scene
            .geometry
            .intersect(&ray, f32::INFINITY)
            .expect("a hit");
        assert!(
            (hit.t - 5.0).abs() < 1e-3 || (hit.t - 7.5).abs() < 1e-3,
            "{}",
            hit.t
        );
    }
}

/// A whole sphere is traced in world space but parametrised in its object space, as pbrt-v4
/// parametrises it: under any rotation (and a mirroring) its (u, v), dp/du, dp/dv and
/// normals are those of the same sphere traced as a quadric in object space (made so by a
/// sweep a hair short of 360 degrees).
#[test]
fn a_whole_sphere_is_parametrised_in_its_object_space() {
    let transforms = [
        "Rotate -90 1 0 0",
        "Translate 0.5 -1 2 Rotate 37 0.3 1 0.2 Scale 2 2 2",
        "Rotate 120 0 1 1 Scale -1.5 1.5 1.5",
    ];
    for transform in transforms {
        let whole = build(&format!("{transform} Shape \"sphere\"")).unwrap();
        let quadric = build(&format!(
            "{transform} Shape \"sphere\" \"float phimax\" [ 359.9999 ]"
        ))
        .unwrap();
        assert_eq!(whole.geometry.prims.spheres.len(), 1, "{transform}");
        assert_eq!(quadric.geometry.prims.spheres.len(), 0, "{transform}");
        let center = whole.geometry.prims.spheres[0].center;
        let mut compared = 0;
        for k in 0..64 {
            let from = Vec3A::new(
                libm::sinf(k as f32 * 0.7) * 6.0,
                libm::cosf(k as f32 * 1.3) * 6.0,
                libm::sinf(k as f32 * 2.1 + 0.4) * 6.0,
            ) + center;
            let ray = Ray::new(from, (center - from).normalize());
            let (Some(a), Some(b)) = (
                whole.geometry.intersect(&ray, f32::INFINITY),
                quadric.geometry.intersect(&ray, f32::INFINITY),
            ) else {
                panic!("{transform}: ray {k} misses");
            };
            // Away from the seam, where u wraps from 1 to 0.
            if a.uv.x.min(1.0 - a.uv.x) < 0.01 {
                continue;
            }
            let close = |x: Vec3A, y: Vec3A| (x - y).length() <= 1e-3 * (1.0 + y.length());
            assert!(
                (a.uv - b.uv).abs().max_element() < 1e-4,
                "{transform}: uv {} vs {}",
                a.uv,
                b.uv
            );
            assert!(
                close(a.dpdu, b.dpdu),
                "{transform}: dpdu {} vs {}",
                a.dpdu,
                b.dpdu
            );
            assert!(
                close(a.dpdv, b.dpdv),
                "{transform}: dpdv {} vs {}",
                a.dpdv,
                b.dpdv
            );
            assert!(close(a.ng, b.ng), "{transform}: ng {} vs {}", a.ng, b.ng);
            compared += 1;
        }
        assert!(compared > 50, "{transform}: {compared} hits compared");
    }
    // Turned -90 degrees about x, the sphere's pole faces up, so the point facing the
    // camera on +z is on its equator, a quarter turn before its seam.
    let turned = build("Rotate -90 1 0 0 Shape \"sphere\"").unwrap();
    let ray = Ray::new(Vec3A::new(0.0, 0.0, 5.0), -Vec3A::Z);
    let hit = turned.geometry.intersect(&ray, f32::INFINITY).unwrap();
    assert!(
        (hit.uv - glam::Vec2::new(0.75, 0.5)).abs().max_element() < 1e-5,
        "{}",
        hit.uv
    );
}
