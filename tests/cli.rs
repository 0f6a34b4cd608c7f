//! The `arpa` binary end to end: a tiny render writes a sane EXR and PNG; bad arguments
//! fail with a message naming the problem, never with a panic.


use std::process::{Command, Output};

fn arpa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arpa")).args(args).output().expect("cannot run the arpa binary")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
#[cfg(feature = "cpu")]
fn tiny_render_writes_exr_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x");
    let o = arpa(&["render", "--resolution", "32x32", "--iterations", "2", "--photons", "20000", "--out", out.to_str().unwrap()]);
    let err = stderr(&o);
    assert!(o.status.success(), "arpa render failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("rendered 2 iterations"), "{err}");
    let exr = dir.path().join("x.exr");
    let png = dir.path().join("x.png");
    assert!(exr.is_file() && png.is_file(), "{err}");
    let image = arpa::image_io::read_exr(&exr).unwrap();
    assert_eq!((image.width, image.height, image.pixels.len()), (32, 32, 1024));
    assert!(image.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0), "non-finite or negative pixels");
    let mean = image.pixels.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3.0 * 1024.0);
    assert!(mean > 0.0, "black image");
    assert!(std::fs::metadata(&png).unwrap().len() > 0);
}

fn assert_fails(args: &[&str], needles: &[&str]) {
    let o = arpa(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: stderr does not mention '{n}': {err}");
    }
}

#[test]
#[cfg(feature = "cpu")] // without a backend every render fails on the default `--backend cpu`
fn bad_arguments_fail_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never");
    let out = out.to_str().unwrap();
    assert_fails(&["render", "--photons", "0", "--out", out], &["--photons", "'0'"]);
    assert_fails(&["render", "--resolution", "0x5", "--out", out], &["--resolution", "0x5"]);
    assert_fails(&["render", "--resolution", "big", "--out", out], &["--resolution", "big"]);
    assert_fails(&["render", "--backend", "quantum", "--out", out], &["unknown backend 'quantum'", "compiled backends"]);
    assert_fails(&["render", "--iterations", "1", "--time", "1", "--out", out], &["--iterations", "--time"]);
    assert_fails(&["render", "--time", "-3", "--out", out], &["--time"]);
    assert_fails(&["render", "--method", "magic", "--out", out], &["--method", "magic"]);
    assert_fails(&["render", "scenes/cornell.xml", "--out", out], &["cannot load scene file", "cornell.xml", "cannot read"]);
    assert_fails(&["render", "-D", "novalue", "--out", out], &["-D", "novalue"]);
    assert_fails(&["render", "--out", dir.path().to_str().unwrap()], &["--out"]);
    assert_fails(&["frobnicate"], &["frobnicate"]);
    assert!(!std::path::Path::new(&format!("{out}.exr")).exists());
}

#[test]
#[cfg(not(feature = "cpu"))]
fn without_backends_render_names_the_missing_feature() {
    assert_fails(&["render", "--iterations", "1"], &["backend 'cpu' is not compiled", "--features cpu"]);
}

#[test]
fn help_lists_the_render_options() {
    let o = arpa(&["render", "--help"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    for opt in ["--backend", "--method", "--photons", "--iterations", "--time", "--resolution", "--seed", "--out", "--no-direct", "--smoothing-caustic", "--smoothing-global", "--max-depth", "--exposure", "--reference", "--metrics-every", "--metrics-csv", "--checkpoint", "--checkpoint-every", "--resume"] {
        assert!(text.contains(opt), "help lacks {opt}: {text}");
    }
}

#[test]
#[cfg(feature = "cpu")]
fn rendering_against_its_own_output_gives_zero_error() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let second = dir.path().join("second");
    let csv = dir.path().join("m.csv");
    let common = ["render", "--resolution", "24x16", "--iterations", "3", "--photons", "10000", "--seed", "5"];
    let o = arpa(&[&common[..], &["--out", first.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = dir.path().join("first.exr");
    let o = arpa(&[&common[..], &["--out", second.to_str().unwrap(), "--reference", reference.to_str().unwrap(), "--metrics-csv", csv.to_str().unwrap()]].concat());
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("relMSE") && err.contains("SSIM") && err.contains("FLIP"), "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("iteration,seconds,relmse,ssim,flip"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect()).collect();
    // Powers of two (1, 2) and the end (3).
    assert_eq!(rows.iter().map(|r| r[0] as u32).collect::<Vec<_>>(), vec![1, 2, 3], "{text}");
    let last = rows.last().unwrap();
    assert!(last[1] > 0.0, "{text}");
    assert_eq!(last[2], 0.0, "relMSE of identical renders: {text}");
    assert!((last[3] - 1.0).abs() < 1e-9, "SSIM of identical renders: {text}");
    assert_eq!(last[4], 0.0, "FLIP of identical renders: {text}");
    assert!(rows[0][2] > 0.0, "an earlier checkpoint should differ from the final image: {text}");
}

#[test]
#[cfg(feature = "cpu")]
fn a_reference_of_the_wrong_size_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let o = arpa(&["render", "--resolution", "16x8", "--iterations", "1", "--photons", "1000", "--out", first.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = dir.path().join("first.exr");
    let out = dir.path().join("never");
    assert_fails(
        &["render", "--resolution", "8x8", "--iterations", "1", "--photons", "1000", "--out", out.to_str().unwrap(), "--reference", reference.to_str().unwrap()],
        &["reference image", "first.exr", "16x8", "8x8"],
    );
    assert!(!dir.path().join("never.exr").exists());
    assert_fails(&["render", "--metrics-csv", "x.csv", "--out", out.to_str().unwrap()], &["--reference"]);
}
