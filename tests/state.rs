//! State files end to end through the `arpa` binary (cpu backend): a render killed with
//! SIGKILL at random moments and resumed each time ends with the uninterrupted render's
//! image bit for bit; three parts merged give the single run's image bit for bit; and
//! states of other renders, overlapping or missing parts and damaged files are refused with
//! an error that names the file and the problem.

use arpa::image_io::read_exr;
use arpa::state_file::StateFile;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const ARPA: &str = env!("CARGO_BIN_EXE_arpa");

/// The embedded scene, small: 40×40 pixels, 20 000 photons per iteration, seed 5.
fn render_args() -> Vec<String> {
    ["render", "--resolution", "40x40", "--photons", "20000", "--seed", "5"].map(String::from).to_vec()
}

fn arpa(args: &[String]) -> Output {
    Command::new(ARPA).args(args).output().expect("run arpa")
}

fn ok(args: &[String]) -> Output {
    let out = arpa(args);
    assert!(out.status.success(), "arpa {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    out
}

fn failed(args: &[String]) -> String {
    let out = arpa(args);
    assert!(!out.status.success(), "arpa {args:?} succeeded but should have been refused");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn args(extra: &[&str]) -> Vec<String> {
    let mut a = render_args();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// The pixels' bits of an EXR.
fn bits(path: &Path) -> Vec<[u32; 3]> {
    let image = read_exr(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(image.pixels.iter().filter(|p| p.max_element() > 0.0).count() * 2 > image.pixels.len(), "{}: mostly black", path.display());
    image.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The uninterrupted render of `iterations` iterations, as pixel bits.
fn uninterrupted(dir: &Path, iterations: u32) -> Vec<[u32; 3]> {
    let out = dir.join(format!("full{iterations}"));
    ok(&args(&["--iterations", &iterations.to_string(), "--out", s(&out)]));
    bits(&out.with_extension("exr"))
}

#[test]
fn killed_at_random_moments_and_resumed_ends_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let iterations = 24;
    let reference = uninterrupted(dir.path(), iterations);
    let state = dir.path().join("render.state");
    let out = dir.path().join("resumed");
    let mut run_args = args(&["--iterations", &iterations.to_string(), "--out", s(&out), "--checkpoint", s(&state), "--checkpoint-every", "1"]);
    // A fixed sequence of pseudo-random kill delays (an LCG), so a failure reproduces.
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut kills = 0;
    let deadline = Instant::now() + Duration::from_secs(240);
    loop {
        assert!(Instant::now() < deadline, "the render did not finish within the test's time after {kills} kills");
        let mut a = run_args.clone();
        if state.exists() {
            // Whatever moment the last kill hit, the state file must be whole.
            let st = StateFile::read(&state).unwrap_or_else(|e| panic!("after kill {kills}: {e}"));
            assert!(st.accumulation.end() <= u64::from(iterations));
            a.extend(["--resume".to_string(), s(&state).to_string()]);
        }
        let mut child = Command::new(ARPA).args(&a).stderr(std::process::Stdio::piped()).stdout(std::process::Stdio::null()).spawn().expect("spawn arpa");
        x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        let delay = Duration::from_millis(30 + (x >> 33) % 400);
        let start = Instant::now();
        let finished = loop {
            if let Some(status) = child.try_wait().expect("wait") {
                break Some(status);
            }
            if start.elapsed() >= delay {
                break None;
            }
            std::thread::sleep(Duration::from_millis(2));
        };
        match finished {
            Some(status) => {
                let mut err = String::new();
                std::io::Read::read_to_string(child.stderr.as_mut().expect("stderr"), &mut err).ok();
                assert!(status.success(), "resumed render failed after {kills} kills:\n{err}");
                break;
            }
            None if kills < 8 => {
                child.kill().expect("SIGKILL");
                child.wait().expect("reap");
                kills += 1;
            }
            // Enough kills: let this run finish.
            None => {
                let output = child.wait_with_output().expect("wait");
                assert!(output.status.success(), "resumed render failed:\n{}", String::from_utf8_lossy(&output.stderr));
                break;
            }
        }
        run_args = args(&["--iterations", &iterations.to_string(), "--out", s(&out), "--checkpoint", s(&state), "--checkpoint-every", "1"]);
    }
    assert!(kills >= 1, "no run was killed: the test proves nothing");
    assert_eq!(bits(&out.with_extension("exr")), reference, "resumed after {kills} kills: the image differs from the uninterrupted render");
    // No temporary files are left behind by the kills... except the one a kill may
    // interrupt mid-write, which the next save replaces; none survives a finished run.
    // (The file names only: the temporary directory's own name starts with ".tmp".)
    let leftovers: Vec<PathBuf> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().path()).filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().contains(".tmp"))).collect();
    assert!(leftovers.len() <= kills, "{leftovers:?}");
}

#[test]
fn three_parts_merge_into_the_single_run() {
    let dir = tempfile::tempdir().unwrap();
    let reference = uninterrupted(dir.path(), 9);
    let parts = ["0..3", "3..7", "7..9"];
    for r in parts {
        ok(&args(&["--iterations", r, "--out", s(&dir.path().join(format!("part{r}")))]));
    }
    let state = |r: &str| dir.path().join(format!("part{r}.arpastate"));
    let merged = dir.path().join("merged");
    // Any order.
    let out = ok(&["merge", s(&state("7..9")), s(&state("0..3")), s(&state("3..7")), "-o", s(&merged)].map(String::from));
    assert!(String::from_utf8_lossy(&out.stderr).contains("iterations 0..9"));
    assert_eq!(bits(&merged.with_extension("exr")), reference, "merged parts differ from the single run");

    // A missing part, an overlap, a part of another seed: refused, naming the problem.
    let e = failed(&["merge", s(&state("0..3")), s(&state("7..9")), "-o", s(&merged)].map(String::from));
    assert!(e.contains("iterations 3..7 are missing"), "{e}");
    ok(&args(&["--iterations", "2..5", "--out", s(&dir.path().join("overlap"))]));
    let e = failed(&["merge", s(&state("0..3")), s(&dir.path().join("overlap.arpastate")), "-o", s(&merged)].map(String::from));
    assert!(e.contains("covered twice"), "{e}");
    let mut other_seed = args(&["--iterations", "3..7", "--out", s(&dir.path().join("seed9"))]);
    other_seed[6] = "9".into();
    ok(&other_seed);
    let e = failed(&["merge", s(&state("0..3")), s(&dir.path().join("seed9.arpastate")), "-o", s(&merged)].map(String::from));
    assert!(e.contains("different seed") && e.contains("seed9.arpastate"), "{e}");
}

#[test]
fn states_of_other_renders_and_damaged_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let state = dir.path().join("s.state");
    let out = dir.path().join("o");
    ok(&args(&["--iterations", "2", "--out", s(&out), "--checkpoint", s(&state)]));
    // Other settings, another scene (resolution), more iterations than the state's end.
    let e = failed(&args(&["--iterations", "4", "--out", s(&out), "--resume", s(&state), "--max-depth", "3"]));
    assert!(e.contains("different settings") && e.contains("s.state"), "{e}");
    let mut other_scene = args(&["--iterations", "4", "--out", s(&out), "--resume", s(&state)]);
    other_scene[2] = "41x40".into();
    let e = failed(&other_scene);
    assert!(e.contains("different scene"), "{e}");
    let e = failed(&args(&["--iterations", "1", "--out", s(&out), "--resume", s(&state)]));
    assert!(e.contains("beyond --iterations 1"), "{e}");
    // Truncated and modified files.
    let bytes = std::fs::read(&state).unwrap();
    std::fs::write(&state, &bytes[..bytes.len() / 2]).unwrap();
    let e = failed(&args(&["--iterations", "4", "--out", s(&out), "--resume", s(&state)]));
    assert!(e.contains("is damaged") && e.contains("s.state"), "{e}");
    let mut modified = bytes.clone();
    modified[bytes.len() / 2] ^= 4;
    std::fs::write(&state, &modified).unwrap();
    let e = failed(&args(&["--iterations", "4", "--out", s(&out), "--resume", s(&state)]));
    assert!(e.contains("checksum"), "{e}");
}
