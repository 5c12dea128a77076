//! An RGL measured BRDF (.bsdf tensor file), parsed and, when it parses, turned into the
//! renderer's sampling tables and evaluated.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(brdf) = kiln_scene::files::measured::parse_measured(data)
        && let Ok(tables) = kiln_render::bsdfs::MeasuredTables::new(&brdf)
    {
        let b = kiln_render::bsdfs::MeasuredBxdf { tables: &tables };
        let wo = glam::Vec3A::new(0.3, 0.2, 0.93).normalize();
        let _ = b.sample(wo, 0.5, glam::Vec2::new(0.3, 0.7));
        let _ = b.f(wo, glam::Vec3A::new(-0.1, 0.4, 0.91).normalize());
    }
});
