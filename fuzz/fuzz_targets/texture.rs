//! libFuzzer target: [`arpa::scene_file::fuzzing::texture`] must return `Ok` or an error
//! naming a file, never panic, hang or exhaust memory, whatever image it is given.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = arpa::scene_file::fuzzing::texture(data) {
        assert!(arpa::scene_file::fuzzing::error_names_file(&e), "the error names no file: {e}");
    }
});
