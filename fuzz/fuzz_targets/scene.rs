//! A scene file: parsed (confined to its folder, so a fuzzed Include cannot read the
//! machine's files) and, when it parses, built into a scene (BVHs, lights, media).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.pbrt");
    std::fs::write(&path, data).unwrap();
    if let Ok(desc) = kiln_scene::load_file_within(&path, dir.path()) {
        let _ = kiln_render::Scene::build(&desc, kiln_render::MediaPolicy::Render);
    }
});
