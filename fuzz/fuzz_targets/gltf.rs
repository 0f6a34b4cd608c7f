//! libFuzzer target: [`arpa::scene_file::fuzzing::gltf`] (a glTF JSON or GLB file) must
//! return `Ok` or an error naming a file, never panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = arpa::scene_file::fuzzing::gltf(data) {
        assert!(arpa::scene_file::fuzzing::error_names_file(&e), "the error names no file: {e}");
    }
});
