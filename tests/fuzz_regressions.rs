//! Replays on stable every input kept from fuzzing the scene-file loaders
//! (`scripts/fuzz.sh`): the minimal seed corpus `fuzz/corpus/<target>/` must load, and
//! every reproducer in `fuzz/regressions/<target>/` (an input that once made the loader
//! panic, hang or exhaust memory) must give `Ok` or an error naming the file, through the
//! same entry points as the fuzz targets (`arpa::scene_file::fuzzing`).

use arpa::scene_file::fuzzing;
use arpa::scene_file::{LoadedScene, SceneFileError};
use std::path::{Path, PathBuf};

type Entry = fn(&[u8]) -> Result<LoadedScene, SceneFileError>;

const TARGETS: [(&str, Entry); 6] =
    [("scene_xml", fuzzing::scene_xml), ("ply", fuzzing::ply), ("obj", fuzzing::obj), ("serialized", fuzzing::serialized), ("texture", fuzzing::texture), ("gltf", fuzzing::gltf)];

fn files(dir_kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz").join(dir_kind).join(target);
    // A target without reproducers has no regressions/<target>/ directory (git keeps no
    // empty directories).
    let entries = match std::fs::read_dir(&dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && dir_kind == "regressions" => return Vec::new(),
        r => r.unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display())),
    };
    let mut out: Vec<PathBuf> = entries
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    out
}

#[test]
fn seed_corpus_loads() {
    for (target, run) in TARGETS {
        let seeds = files("corpus", target);
        assert!(!seeds.is_empty(), "fuzz/corpus/{target}/ is empty");
        for f in seeds {
            let bytes = std::fs::read(&f).unwrap();
            if let Err(e) = run(&bytes) {
                panic!("seed {} does not load: {e}", f.display());
            }
        }
    }
}

#[test]
fn regressions_give_ok_or_an_error_naming_the_file() {
    let mut count = 0;
    for (target, run) in TARGETS {
        for f in files("regressions", target) {
            let bytes = std::fs::read(&f).unwrap();
            if let Err(e) = run(&bytes) {
                assert!(fuzzing::error_names_file(&e), "{}: the error names no file: {e}", f.display());
            }
            count += 1;
        }
    }
    assert!(count > 0, "no reproducers in fuzz/regressions/");
}

/// Each reproducer fuzzing found, with what its error must say.
#[test]
fn known_reproducers_give_their_errors() {
    let cases: [(&str, Entry, &str, &[&str]); 7] = [
        // gltf's reader subtracted 1 from an accessor count of 0 (overflow).
        ("gltf/accessor-count-zero", fuzzing::gltf, fuzzing::GLTF_PATH, &["count 0"]),
        // gltf's reader asserted an accessor's element size it never checked (debug panic).
        ("gltf/position-accessor-of-another-type", fuzzing::gltf, fuzzing::GLTF_PATH, &["accessor"]),
        // gltf's GLB reader subtracted the header size from a shorter length (overflow).
        ("gltf/glb-length-below-header", fuzzing::gltf, fuzzing::GLTF_PATH, &["GLB header"]),
        // gltf's Image::source unwrapped a buffer view image's missing MIME type (panic).
        ("gltf/image-view-without-mime-type", fuzzing::gltf, fuzzing::GLTF_PATH, &["image"]),
        // gltf-json's validation indexed a primitive's POSITION accessor before checking it (panic).
        ("gltf/position-accessor-out-of-range", fuzzing::gltf, fuzzing::GLTF_PATH, &["accessor", "does not exist"]),
        // tobj multiplied an out-of-range relative texture coordinate index (overflow).
        ("obj/relative_texcoord_index_overflow.obj", fuzzing::obj, fuzzing::OBJ_PATH, &["line 11", "relative texture coordinate index -4", "only 1 precede"]),
        // ply-rs unwrapped a header number too large for a u64 (panic).
        ("ply/element_count_overflows_u64.ply", fuzzing::ply, fuzzing::PLY_PATH, &["header line 11", "too large"]),
    ];
    for (file, run, path, needles) in cases {
        let bytes = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions").join(file)).unwrap();
        let e = run(&bytes).err().unwrap_or_else(|| panic!("{file} loaded"));
        let text = e.to_string();
        assert!(text.contains(path), "{file}: {text}");
        for n in needles {
            assert!(text.contains(n), "{file}: expected '{n}' in: {text}");
        }
    }
}
