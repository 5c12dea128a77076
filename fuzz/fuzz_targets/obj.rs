//! An OBJ mesh.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let loc = kiln_scene::Loc::synthetic("fuzz");
    let _ = kiln_scene::files::obj::parse_obj(data, std::path::Path::new("m.obj"), &loc);
});
