//! `arpa bench` end to end on the reduced config (`bench/smoke.toml`: two shared scenes at a
//! quarter of their film size, 2 s per run, no peers): every output exists and parses.
//! Timings are never asserted. Without the shared scenes the tests skip loudly, except under
//! `CI`, where they fail.
#![cfg(feature = "cpu")]

use std::path::{Path, PathBuf};
use std::process::Command;

fn shared_scenes() -> Option<PathBuf> {
    let dir = std::env::var_os("ARPA_SHARED_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"));
    if dir.join("cornell-caustic/scene.xml").is_file() {
        return Some(dir);
    }
    assert!(std::env::var_os("CI").is_none(), "CI is set but the shared scenes are missing at {}", dir.display());
    eprintln!("SKIPPED: the shared scenes are not at {} (set ARPA_SHARED_SCENES)", dir.display());
    None
}

fn bench(config: &Path, out: &Path, extra: &[&str]) -> (bool, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_arpa"))
        .arg("bench")
        .arg(config)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .expect("cannot run the arpa binary");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!err.contains("panicked"), "{err}");
    (o.status.success(), err)
}

/// The CSV rows (not the `#` header) as fields, after checking the header and columns.
fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    for key in ["# bench:", "# machine:", "# cpu:", "# threads:", "# devices:", "# commit:", "# config sha256:"] {
        assert!(text.lines().any(|l| l.starts_with(key)), "runs.csv has no '{key}' line");
    }
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let columns: Vec<&str> = lines.next().expect("no column line").split(',').collect();
    assert_eq!(columns.len(), 37, "{columns:?}");
    assert_eq!(columns[12..22], ["camera_ms", "photon_ms", "build_ms", "gather_ms", "accumulate_ms", "camera_device_ms", "photon_device_ms", "build_device_ms", "gather_device_ms", "accumulate_device_ms"]);
    assert_eq!(columns[26..32], ["region_relmse", "caustic_records_per_photon", "global_records_per_photon", "caustic_pass_photons", "global_pass_photons", "caustic_records_per_second"]);
    assert_eq!(columns[32..], ["scale0_share", "scale1_share", "scale2_share", "scale3_share", "scale4_share"]);
    lines.map(|l| l.split(',').map(str::to_owned).collect::<Vec<_>>()).inspect(|f| assert_eq!(f.len(), 37, "{f:?}")).collect()
}

#[test]
fn smoke_config_writes_every_output() {
    let Some(scenes) = shared_scenes() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("smoke");
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/smoke.toml");
    let cmd = Command::new(env!("CARGO_BIN_EXE_arpa"))
        .env("ARPA_SHARED_SCENES", &scenes)
        .arg("bench")
        .arg(&config)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&cmd.stderr);
    assert!(cmd.status.success(), "arpa bench failed: {err}");
    // One progress line per run, with the ETA of the sweep.
    assert_eq!(err.lines().filter(|l| l.contains("ETA")).count(), 16, "{err}");

    let rows = csv_rows(&out.join("runs.csv"));
    for scene in ["cornell-caustic", "caustic-glass"] {
        for run in ["arpa E-20K", "arpa E-50K", "arpa-auto E-20K", "arpa-auto E-50K", "arpa-pp E-20K", "arpa-pp E-50K", "rtpm E-20K", "rtpm E-50K"] {
            let mine: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == scene && r[1] == run).collect();
            assert!(!mine.is_empty(), "no rows for {scene} {run}");
            let mut last_iteration = 0;
            for r in &mine {
                assert_eq!(r[5], "ok");
                let iteration: u32 = r[6].parse().unwrap();
                assert!(iteration > last_iteration, "checkpoints go forward: {r:?}");
                last_iteration = iteration;
                let num = |i: usize| r[i].parse::<f64>().unwrap_or_else(|_| panic!("column {i} of {r:?}"));
                assert!(num(7) > 0.0 && num(8) >= 0.0 && (-1.0..=1.0).contains(&num(9)) && (0.0..=1.0).contains(&num(10)));
                // The whole-image mean is near the reference's (a wrong image is far off).
                assert!((0.8..1.25).contains(&num(11)), "mean ratio {r:?}");
                assert!((12..17).all(|i| num(i) >= 0.0));
                // No device columns on the cpu backend (its host time is its device time).
                assert!(r[17..22].iter().all(String::is_empty), "device ms on cpu: {r:?}");
                assert!((22..26).all(|i| num(i) >= 0.0));
                // Gather candidates and contributions per query point (RTPM: photons only).
                assert!(num(22) >= num(23) && num(24) >= num(25) && num(24) > 0.0, "gather counts {r:?}");
                // The region relMSE only where the config sets a caustic region.
                if scene == "cornell-caustic" {
                    assert!(num(26) >= 0.0, "region relMSE {r:?}");
                } else {
                    assert_eq!(r[26], "", "no region: {r:?}");
                }
                // Records per photon, photons per pass and caustic records per second.
                assert!((27..32).all(|i| num(i) >= 0.0), "photon rates {r:?}");
                // The share of pixels per scale: for the per-pixel runs only, summing to 1.
                if run.starts_with("arpa-pp") {
                    let total: f64 = (32..37).map(num).sum();
                    assert!((32..37).all(|i| num(i) >= 0.0) && (total - 1.0).abs() < 1e-3, "scale shares {r:?}");
                } else {
                    assert!(r[32..].iter().all(String::is_empty), "no scale shares: {r:?}");
                }
            }
            let stem = format!("{scene}-{}-cpu", run.replace(' ', "-").replace("-E-", "-E"));
            let exr = arpa::image_io::read_exr(&out.join("images").join(format!("{stem}.exr"))).unwrap();
            let size = if scene == "cornell-caustic" { (64, 64) } else { (80, 45) };
            assert_eq!((exr.width, exr.height), size);
            for png in [format!("{stem}.png"), format!("{stem}-relmse.png")] {
                let img = image::open(out.join("images").join(&png)).unwrap_or_else(|e| panic!("{png}: {e}"));
                assert_eq!((img.width(), img.height()), size, "{png}");
            }
        }
        let plot = image::open(out.join("plots").join(format!("{scene}.png"))).unwrap();
        assert!(plot.width() > 100 && plot.height() > 100);
    }
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(table.contains("## Table 2 (cpu)") && table.contains("| E-20K SSIM | NI | ATI (ms) |"), "{table}");
    assert!(table.contains("| cornell-caustic | ARPA |") && table.contains("| cornell-caustic | ARPA auto |") && table.contains("| caustic-glass | RTPM |"), "{table}");
    assert!(table.contains("- config sha256:"), "{table}");
    assert!(table.contains("| region relMSE |") && table.contains("Caustic regions") && table.contains("## Photon passes"), "{table}");
    let region_plot = image::open(out.join("plots").join("cornell-caustic-region.png")).unwrap();
    assert!(region_plot.width() > 100 && region_plot.height() > 100);
    assert!(!out.join("plots").join("caustic-glass-region.png").exists());
}

#[test]
fn a_peer_that_cannot_run_is_a_skipped_row() {
    let Some(scenes) = shared_scenes() else { return };
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("peer.toml");
    std::fs::write(
        &config,
        format!(
            "name = \"peer\"\nseconds = 0.2\nthreads = 1\nphotons = [2000]\nmethods = [\"rtpm\"]\npeers = [\"ptracer\"]\nscenes_dir = {:?}\ndownscale = 8\n\
             [[scene]]\nname = \"cornell-caustic\"\nfile = \"cornell-caustic/scene.xml\"\n\
             reference = \"cornell-caustic/reference/cornell-caustic_mitsuba-path_256x256_4096spp_143s.exr\"\n",
            scenes.display().to_string()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let (ok, err) = bench(&config, &out, &["--python", "/nonexistent/python3"]);
    assert!(ok, "{err}");
    assert!(err.contains("SKIPPED") && err.contains("1 run(s) skipped"), "{err}");
    let rows = csv_rows(&out.join("runs.csv"));
    let peer: Vec<&Vec<String>> = rows.iter().filter(|r| r[1] == "mitsuba ptracer").collect();
    assert_eq!(peer.len(), 1);
    assert!(peer[0][5].starts_with("\"skipped: cannot run"), "{:?}", peer[0]);
    assert!(peer[0][6..].iter().all(String::is_empty), "{:?}", peer[0]);
    assert!(std::fs::read_to_string(out.join("table.md")).unwrap().contains("| cornell-caustic | ptracer | skipped: cannot run"));
}

#[test]
fn a_caustic_region_outside_the_film_names_the_file_and_the_field() {
    let Some(scenes) = shared_scenes() else { return };
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("region.toml");
    std::fs::write(
        &config,
        format!(
            "name = \"region\"\nseconds = 0.2\nthreads = 1\nphotons = [2000]\nmethods = [\"rtpm\"]\nscenes_dir = {:?}\ndownscale = 8\n\
             [[scene]]\nname = \"cornell-caustic\"\nfile = \"cornell-caustic/scene.xml\"\n\
             reference = \"cornell-caustic/reference/cornell-caustic_mitsuba-path_256x256_4096spp_143s.exr\"\ncaustic_region = [200, 10, 257, 20]\n",
            scenes.display().to_string()
        ),
    )
    .unwrap();
    let (ok, err) = bench(&config, &dir.path().join("out"), &[]);
    assert!(!ok);
    assert!(err.contains("region.toml") && err.contains("caustic_region [200, 10, 257, 20]") && err.contains("256x256"), "{err}");
}

#[test]
fn a_bad_config_names_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "name = \"x\"\nphotons = [0]\n[[scene]]\nname = \"a\"\nfile = \"a.xml\"\nreference = \"a.exr\"\n").unwrap();
    let (ok, err) = bench(&config, &dir.path().join("out"), &[]);
    assert!(!ok);
    assert!(err.contains("bad.toml") && err.contains("photons"), "{err}");
}

/// `bench/table2-gpu.toml` (the paper-size GPU sweep) at a small size on whatever adapter
/// is present (lavapipe in CI): every run of both GPU backends writes rows whose device
/// columns hold each stage's device time, each within the run's host time, and table.md
/// has the device-time table. Timings are never asserted beyond that.
#[cfg(all(feature = "wgpu", feature = "vk"))]
#[test]
fn gpu_table2_config_reports_device_time_per_stage() {
    let Some(scenes) = shared_scenes() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gpu");
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/table2-gpu.toml");
    let cmd = Command::new(env!("CARGO_BIN_EXE_arpa"))
        .env("ARPA_SHARED_SCENES", &scenes)
        .args(["bench", config.to_str().unwrap(), "--out", out.to_str().unwrap(), "--downscale", "4", "--photons", "20000", "--seconds", "0.2"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&cmd.stderr);
    assert!(cmd.status.success(), "arpa bench failed: {err}");
    let rows = csv_rows(&out.join("runs.csv"));
    for scene in ["caustic-glass", "veach-bidir", "water-caustic", "crytek-sponza"] {
        for backend in ["vk", "wgpu"] {
            let mine: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == scene && r[2] == backend).collect();
            assert!(!mine.is_empty(), "no rows for {scene} on {backend}");
            for r in mine {
                let num = |i: usize| r[i].parse::<f64>().unwrap_or_else(|_| panic!("column {i} of {r:?}"));
                let (host, device): (f64, f64) = ((12..17).map(num).sum(), (17..22).map(num).sum());
                assert!((17..22).all(|i| num(i).is_finite() && num(i) >= 0.0), "device ms {r:?}");
                assert!(num(17) > 0.0 && num(18) > 0.0 && num(21) >= 0.0, "camera and photon passes take device time: {r:?}");
                // The CSV rounds each column to 1 µs.
                assert!(device <= host * 1.01 + 0.01, "device {device} ms over host {host} ms: {r:?}");
            }
        }
    }
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(table.contains("## Table 2 (vk)") && table.contains("## Table 2 (wgpu)") && table.contains("## Device time by stage"), "{table}");
}
