//! A shared pre-pass's name against a job's prefix, as the coordinator checks uploads and
//! claims: any input is an answer, and an accepted name is the job's prefix followed by
//! one of the names a job shares.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let (prefix, name) = text.split_once('\n').unwrap_or(("0123456789abcdef", &text));
    if kiln_farm::api::is_prepass_of(name, prefix) {
        let rest = &name[prefix.len()..];
        assert!(rest == "-photon-maps" || rest.starts_with("-sppm-pass-"), "{name}");
    }
});
