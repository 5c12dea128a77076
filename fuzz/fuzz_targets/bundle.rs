//! A scene bundle, read and unpacked into a cache folder as the coordinator does.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if kiln_farm::bundle::entries(data).is_ok() {
        let dir = tempfile::tempdir().unwrap();
        let digest = kiln_farm::bundle::digest_of(data);
        let _ = kiln_farm::bundle::unpack_into_cache(
            kiln_farm::bundle::Source::Bytes(data),
            &digest,
            dir.path(),
            true,
        );
    }
});
