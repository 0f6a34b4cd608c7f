//! The outputs of `arpa bench`: CSV, the Table 2 Markdown, error-against-time plots, final
//! images and relMSE heat maps, all in one directory and all under the same [`Header`].

use super::config::LoadedConfig;
use super::results::{BenchRow, Header, RunKind, RunResult, budget_label};
use crate::image_io;
use crate::metrics;
use anyhow::{Context, anyhow};
use arpa_core::render::tracer::{DeviceTimes, Image};
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Plot size (pixels).
const PLOT_SIZE: (u32, u32) = (960, 640);
/// Heat-map range: relMSE per pixel from `10^LOG_MIN` to `10^LOG_MAX`, log scale.
const HEAT_LOG_MIN: f64 = -4.0;
const HEAT_LOG_MAX: f64 = 1.0;

/// `images/SCENE-STEM` (without extension).
fn image_stem(out: &Path, scene: &str, kind: &RunKind) -> PathBuf {
    out.join("images").join(format!("{scene}-{}", kind.stem()))
}

/// Writes a run's final image (EXR, PNG) and its per-pixel relMSE heat map
/// (`…-relmse.png`: viridis, log scale from 1e-4 to 10, like the paper's Figure 5).
pub fn write_run_images(out: &Path, scene: &str, kind: &RunKind, image: &Image, reference: &Image) -> anyhow::Result<()> {
    let stem = image_stem(out, scene, kind);
    std::fs::create_dir_all(stem.parent().unwrap_or(out)).with_context(|| format!("cannot create '{}'", out.display()))?;
    image_io::write_exr(&stem.with_extension("exr"), image)?;
    image_io::write_png(&stem.with_extension("png"), image, 1.0)?;
    let per_pixel = metrics::rel_mse_per_pixel(&image.pixels, &reference.pixels, image.width, image.height)?;
    let rgb: Vec<u8> = per_pixel
        .iter()
        .flat_map(|&e| {
            let t = ((e.max(1e-30).log10() - HEAT_LOG_MIN) / (HEAT_LOG_MAX - HEAT_LOG_MIN)).clamp(0.0, 1.0);
            let c = ViridisRGB::get_color(t as f32);
            [c.0, c.1, c.2]
        })
        .collect();
    let path = PathBuf::from(format!("{}-relmse.png", stem.display()));
    image::save_buffer(&path, &rgb, image.width, image.height, image::ExtendedColorType::Rgb8).with_context(|| format!("cannot write '{}'", path.display()))
}

/// Writes `runs.csv`, `table.md`, `plots/SCENE.png` and, for a scene with a caustic region,
/// `plots/SCENE-region.png` for `results`.
pub fn write_all(out: &Path, header: &Header, cfg: &LoadedConfig, results: &[RunResult]) -> anyhow::Result<()> {
    let csv = out.join("runs.csv");
    std::fs::write(&csv, csv_text(header, results)).with_context(|| format!("cannot write '{}'", csv.display()))?;
    let md = out.join("table.md");
    std::fs::write(&md, table_text(header, cfg, results)).with_context(|| format!("cannot write '{}'", md.display()))?;
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots).with_context(|| format!("cannot create '{}'", plots.display()))?;
    for scene in &cfg.config.scenes {
        let runs: Vec<&RunResult> = results.iter().filter(|r| r.scene == scene.name).collect();
        plot_scene(&plots.join(format!("{}.png", scene.name)), header, &scene.name, &runs, "relMSE", |r| Some(r.rel_mse))?;
        if scene.region().is_some() {
            plot_scene(&plots.join(format!("{}-region.png", scene.name)), header, &scene.name, &runs, "caustic-region relMSE", |r| r.region_rel_mse)?;
        }
    }
    Ok(())
}

/// The CSV columns. `camera_ms` … `accumulate_ms` are the host's mean wall-clock time per
/// iteration of each stage, `camera_device_ms` … `accumulate_device_ms` the device's own
/// time of the same stages from timestamp queries (empty for the cpu backend, whose host
/// time is its device time, for the peers, and where the adapter has no timestamps);
/// host minus device is the host's share. `region_relmse` is the relMSE inside the scene's
/// caustic region (empty without one). The last five are the photon passes' sums up to the checkpoint (empty for
/// peers): records stored per photon emitted in the caustic and the global map, mean
/// photons emitted per iteration by the caustic and the global pass, and caustic-map
/// records stored per second of render time.
pub const CSV_COLUMNS: &str = "scene,run,backend,method,photons,status,iteration,seconds,relmse,ssim,flip,mean_ratio,camera_ms,photon_ms,build_ms,gather_ms,accumulate_ms,camera_device_ms,photon_device_ms,build_device_ms,gather_device_ms,accumulate_device_ms,caustic_candidates_per_query,caustic_contributions_per_query,global_candidates_per_query,global_contributions_per_query,region_relmse,caustic_records_per_photon,global_records_per_photon,caustic_pass_photons,global_pass_photons,caustic_records_per_second,scale0_share,scale1_share,scale2_share,scale3_share,scale4_share";

/// `{:.9e}` of a value, or nothing.
fn optional_sci(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:.9e}"))
}

/// `# header` lines, then one row per checkpoint (a skipped run is one `skipped: …` row).
pub fn csv_text(header: &Header, results: &[RunResult]) -> String {
    let mut s = String::new();
    for l in header.lines() {
        let _ = writeln!(s, "# {l}");
    }
    let _ = writeln!(s, "{CSV_COLUMNS}");
    for r in results {
        let (backend, method, photons) = match &r.kind {
            RunKind::Arpa { backend, method, photons } => (backend.clone(), method.name().to_string(), photons.to_string()),
            RunKind::Peer { integrator } => ("mitsuba".into(), integrator.clone(), String::new()),
        };
        let run = r.kind.label();
        if let Some(why) = &r.skipped {
            let empty = ",".repeat(CSV_COLUMNS.split(',').count() - 6);
            let _ = writeln!(s, "{},{run},{backend},{method},{photons},\"skipped: {}\"{empty}", r.scene, why.replace('"', "'"));
            continue;
        }
        for row in &r.rows {
            let t = &row.times;
            let rates = row.photons.map_or_else(
                || ",,,,".to_string(),
                |p| {
                    format!(
                        "{:.6},{:.6},{:.1},{:.1},{:.1}",
                        p.records_per_photon[0], p.records_per_photon[1], p.emitted_per_iteration[0], p.emitted_per_iteration[1], p.caustic_records_per_second
                    )
                },
            );
            // Per-scale share of the pixels (per-pixel bandwidth runs; empty otherwise).
            let shares = row.scale_share.map_or_else(|| ",".repeat(arpa_core::gather::scales::SCALES - 1), |sh| sh.map(|v| format!("{v:.4}")).join(","));
            let device = row.device_times.measured().map_or_else(
                || ",,,,".to_string(),
                |d| format!("{:.3},{:.3},{:.3},{:.3},{:.3}", d.camera * 1e3, d.photon * 1e3, d.build * 1e3, d.gather * 1e3, d.accumulate * 1e3),
            );
            let _ = writeln!(
                s,
                "{},{run},{backend},{method},{photons},ok,{},{:.6},{:.9e},{:.9},{:.9},{:.6},{:.3},{:.3},{:.3},{:.3},{:.3},{device},{:.3},{:.3},{:.3},{:.3},{},{rates},{shares}",
                r.scene,
                row.iteration,
                row.seconds,
                row.rel_mse,
                row.ssim,
                row.flip,
                row.mean_ratio,
                t.camera * 1e3,
                t.photon * 1e3,
                t.build * 1e3,
                t.gather * 1e3,
                t.accumulate * 1e3,
                row.candidates_per_query[0],
                row.contributions_per_query[0],
                row.candidates_per_query[1],
                row.contributions_per_query[1],
                optional_sci(row.region_rel_mse)
            );
        }
    }
    s
}

fn final_of<'a>(results: &'a [RunResult], scene: &str, pick: impl Fn(&RunKind) -> bool) -> Vec<(&'a RunResult, Option<&'a BenchRow>)> {
    results.iter().filter(|r| r.scene == scene && pick(&r.kind)).map(|r| (r, r.last())).collect()
}

/// ATI: mean milliseconds per iteration (sum of the stage means).
fn ati_ms(row: &BenchRow) -> f64 {
    let t = &row.times;
    (t.camera + t.photon + t.build + t.gather + t.accumulate) * 1e3
}

/// The Markdown report: the header, Table 2 (SSIM, NI, ATI per scene × method × budget),
/// the peers at equal time, the final relMSE/region relMSE/FLIP/mean ratio of every run,
/// the ATI split by stage, and the photon passes' rates.
pub fn table_text(header: &Header, cfg: &LoadedConfig, results: &[RunResult]) -> String {
    let c = &cfg.config;
    let mut s = String::new();
    let _ = writeln!(s, "# arpa bench: {}\n", c.name);
    for l in header.lines() {
        let _ = writeln!(s, "- {l}");
    }
    let _ = writeln!(
        s,
        "\nSSIM of the sRGB-encoded luminance (clamped to [0, 1], 11×11 Gaussian window, σ = 1.5 px); NI: iterations in the budget; ATI: mean ms per iteration. Reference: each scene's independent reference{}.\n",
        if c.downscale > 1 {
            format!(", box-averaged {0}×{0} (renders at 1/{0} of the film size)", c.downscale)
        } else if c.upscale > 1 {
            format!(" (renders at {0}× the film size, compared box-averaged {0}×{0}; images at the reference's size)", c.upscale)
        } else {
            String::new()
        }
    );
    for &backend in &cfg.backends {
        let _ = writeln!(s, "## Table 2 ({backend})\n");
        let mut head = String::from("| scene | method |");
        let mut rule = String::from("|---|---|");
        for &p in &c.photons {
            let _ = write!(head, " E-{} SSIM | NI | ATI (ms) |", budget_label(p));
            rule += "---|---|---|";
        }
        let _ = writeln!(s, "{head}\n{rule}");
        for scene in &c.scenes {
            for &method in &cfg.methods {
                let _ = write!(s, "| {} | {} |", scene.name, method.title());
                for &p in &c.photons {
                    let row = final_of(results, &scene.name, |k| matches!(k, RunKind::Arpa { backend: b, method: m, photons } if b == backend.name() && *m == method && *photons == p));
                    match row.first().and_then(|(_, r)| *r) {
                        Some(r) => {
                            let _ = write!(s, " {:.3} | {} | {:.1} |", r.ssim, r.iteration, ati_ms(r));
                        }
                        None => s += " – | – | – |",
                    }
                }
                s += "\n";
            }
        }
        s += "\n";
    }
    if !c.peers.is_empty() {
        let _ = writeln!(s, "## Equal-time peers (Mitsuba 3, {} s, {} threads)\n", header.seconds, header.threads);
        let _ = writeln!(s, "| scene | integrator | SSIM | relMSE | region relMSE | FLIP | mean / ref | passes | ms per pass |\n|---|---|---|---|---|---|---|---|---|");
        for scene in &c.scenes {
            for (r, last) in final_of(results, &scene.name, |k| matches!(k, RunKind::Peer { .. })) {
                let RunKind::Peer { integrator } = &r.kind else { continue };
                match (&r.skipped, last) {
                    (Some(why), _) => {
                        let _ = writeln!(s, "| {} | {integrator} | skipped: {why} | | | | | | |", scene.name);
                    }
                    (None, Some(l)) => {
                        let _ = writeln!(
                            s,
                            "| {} | {integrator} | {:.3} | {:.4e} | {} | {:.4} | {:.3} | {} | {:.1} |",
                            scene.name,
                            l.ssim,
                            l.rel_mse,
                            region_cell(l),
                            l.flip,
                            l.mean_ratio,
                            l.iteration,
                            l.seconds * 1e3 / l.iteration.max(1) as f64
                        );
                    }
                    (None, None) => {}
                }
            }
        }
        s += "\n";
    }
    let regions: Vec<String> = c.scenes.iter().filter_map(|e| e.region().map(|r| format!("{} {r}", e.name))).collect();
    if !regions.is_empty() {
        let _ = writeln!(s, "Caustic regions (pixels [x0, y0, x1, y1] of the full-size film, half-open; region relMSE is relMSE over them): {}.\n", regions.join(", "));
    }
    let _ = writeln!(s, "## Final errors of every run\n\n| scene | run | backend | relMSE | region relMSE | FLIP | SSIM | mean / ref | NI | seconds |\n|---|---|---|---|---|---|---|---|---|---|");
    for r in results {
        let backend = match &r.kind {
            RunKind::Arpa { backend, .. } => backend.as_str(),
            RunKind::Peer { .. } => "mitsuba",
        };
        match r.last() {
            Some(l) => {
                let _ = writeln!(
                    s,
                    "| {} | {} | {backend} | {:.4e} | {} | {:.4} | {:.3} | {:.3} | {} | {:.2} |",
                    r.scene,
                    r.kind.label(),
                    l.rel_mse,
                    region_cell(l),
                    l.flip,
                    l.ssim,
                    l.mean_ratio,
                    l.iteration,
                    l.seconds
                );
            }
            None => {
                let _ = writeln!(s, "| {} | {} | {backend} | {} | | | | | | |", r.scene, r.kind.label(), r.skipped.as_deref().unwrap_or("no result"));
            }
        }
    }
    let _ = writeln!(s, "\n## ATI by stage (ms per iteration)\n\n| scene | run | backend | camera | photons | AS build | gather | accumulate | total |\n|---|---|---|---|---|---|---|---|---|");
    for r in results {
        let (RunKind::Arpa { backend, .. }, Some(l)) = (&r.kind, r.last()) else { continue };
        let t = &l.times;
        let _ = writeln!(
            s,
            "| {} | {} | {backend} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            r.scene,
            r.kind.label(),
            t.camera * 1e3,
            t.photon * 1e3,
            t.build * 1e3,
            t.gather * 1e3,
            t.accumulate * 1e3,
            ati_ms(l)
        );
    }
    let gpu_runs: Vec<(&RunResult, &str, &BenchRow)> = results
        .iter()
        .filter_map(|r| match (&r.kind, r.last()) {
            (RunKind::Arpa { backend, .. }, Some(l)) if l.device_times != DeviceTimes::Host => Some((r, backend.as_str(), l)),
            _ => None,
        })
        .collect();
    if !gpu_runs.is_empty() {
        let _ = writeln!(
            s,
            "\n## Device time by stage (ms per iteration, from timestamp queries; host share = ATI − device total)\n\n| scene | run | backend | camera | photons | AS build | gather | accumulate | device total | ATI | host share |\n|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for (r, backend, l) in gpu_runs {
            match l.device_times.measured() {
                Some(d) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {backend} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
                        r.scene,
                        r.kind.label(),
                        d.camera * 1e3,
                        d.photon * 1e3,
                        d.build * 1e3,
                        d.gather * 1e3,
                        d.accumulate * 1e3,
                        d.total() * 1e3,
                        ati_ms(l),
                        ati_ms(l) - d.total() * 1e3
                    );
                }
                None => {
                    let _ = writeln!(s, "| {} | {} | {backend} | device time: not available on this adapter | | | | | | {:.1} | |", r.scene, r.kind.label(), ati_ms(l));
                }
            }
        }
    }
    let _ = writeln!(
        s,
        "\n## Photon passes (sums over each run)\n\n| scene | run | backend | caustic-pass photons / it | global-pass photons / it | caustic records / photon | global records / photon | caustic records / s |\n|---|---|---|---|---|---|---|---|"
    );
    for r in results {
        let (RunKind::Arpa { backend, .. }, Some(l)) = (&r.kind, r.last()) else { continue };
        let Some(p) = l.photons else { continue };
        let _ = writeln!(
            s,
            "| {} | {} | {backend} | {:.0} | {:.0} | {:.4} | {:.4} | {:.4e} |",
            r.scene,
            r.kind.label(),
            p.emitted_per_iteration[0],
            p.emitted_per_iteration[1],
            p.records_per_photon[0],
            p.records_per_photon[1],
            p.caustic_records_per_second
        );
    }
    s
}

/// A row's region relMSE as a table cell (`–` without a region).
fn region_cell(row: &BenchRow) -> String {
    row.region_rel_mse.map_or_else(|| "–".to_string(), |e| format!("{e:.4e}"))
}

/// `0.30000000000000004` -> `0.3`: three significant digits, trailing zeros dropped.
fn short_number(v: f64) -> String {
    let digits = (2 - v.abs().max(1e-300).log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}


/// Registers the embedded DejaVu Sans as the plots' font (once).
pub(crate) fn register_font() -> anyhow::Result<()> {
    static ONCE: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    ONCE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular()).map_err(|_| "the embedded DejaVu Sans font is invalid".to_string()))
        .clone()
        .map_err(|e| anyhow!(e))
}

/// Log-log error (`metric`, named `what`) against render time of every run of one scene,
/// one line each; the caption carries the header's commit and config hash.
fn plot_scene(path: &Path, header: &Header, scene: &str, runs: &[&RunResult], what: &str, metric: fn(&BenchRow) -> Option<f64>) -> anyhow::Result<()> {
    register_font()?;
    let (w, h) = PLOT_SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let series_of = |r: &RunResult| -> Vec<(f64, f64)> { r.rows.iter().filter_map(|p| metric(p).map(|e| (p.seconds, e))).filter(|(t, e)| *t > 0.0 && *e > 0.0).collect() };
    let points: Vec<(f64, f64)> = runs.iter().flat_map(|r| series_of(r)).collect();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let fail = |e: &dyn std::fmt::Display| anyhow!("cannot draw plot '{}': {e}", path.display());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in &points {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if points.is_empty() {
            (x0, x1, y0, y1) = (0.1, 10.0, 1e-4, 1.0);
        }
        let caption = format!("{scene}: {what} against time ({}, {} threads)", header.name, header.threads);
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d((x0 * 0.8..x1 * 1.25).log_scale(), (y0 * 0.8..y1 * 1.25).log_scale())
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("render time (s)")
            .y_desc(what)
            .x_label_formatter(&|v| short_number(*v))
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| fail(&e))?;
        for (i, r) in runs.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let series = series_of(r);
            if series.is_empty() {
                continue;
            }
            let label = match &r.kind {
                RunKind::Arpa { backend, .. } => format!("{} ({backend})", r.kind.label()),
                RunKind::Peer { .. } => r.kind.label(),
            };
            chart
                .draw_series(LineSeries::new(series.clone(), colour.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            chart.draw_series(series.into_iter().map(|p| Circle::new(p, 3, colour.filled()))).map_err(|e| fail(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| fail(&e))?;
        root.draw(&Text::new(format!("commit {}  config {}", header.commit, &header.config_hash[..12.min(header.config_hash.len())]), (12, h as i32 - 18), ("sans-serif", 12)))
            .map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
    }
    image::save_buffer(path, &buf, w, h, image::ExtendedColorType::Rgb8).with_context(|| format!("cannot write plot '{}'", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_numbers_are_short() {
        assert_eq!(short_number(0.30000000000000004), "0.3");
        assert_eq!(short_number(2.0), "2");
        assert_eq!(short_number(0.0125), "0.0125");
        assert_eq!(short_number(150.0), "150");
        assert_eq!(super::super::results::budget_label(1_000_000), "1000K");
        assert_eq!(super::super::results::budget_label(12_345), "12345");
    }
}
