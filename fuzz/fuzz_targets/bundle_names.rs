//! A bundle whose entry names are the input's lines (any depth, length or characters, a
//! name repeated, a file that is also a folder), each entry one byte: read and unpacked as
//! the coordinator does. Deep and long names must be refused in time linear in their
//! length, never overflow a stack or fill the disk.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let files: Vec<(String, Vec<u8>)> = String::from_utf8_lossy(data)
        .split('\n')
        .filter(|n| n.len() <= u16::MAX as usize)
        .take(1 << 16)
        .map(|n| (n.to_string(), vec![b'x']))
        .collect();
    if files.is_empty() {
        return;
    }
    let bundle = kiln_farm::bundle::encode(&files);
    if kiln_farm::bundle::entries(&bundle.bytes).is_ok() {
        let dir = tempfile::tempdir().unwrap();
        let _ = kiln_farm::bundle::unpack_into_cache(
            kiln_farm::bundle::Source::Bytes(&bundle.bytes),
            &bundle.digest,
            dir.path(),
            true,
        );
    }
});
