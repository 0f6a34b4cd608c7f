//! Independent references: each scene of `../shared/scenes` rendered by the backend and
//! compared with the image the scenes' README names as ground truth (Mitsuba 3 `path` where
//! the scene is lit by an area light or has no caustics, LuxCore PATHCPU + PhotonGI where a
//! delta light makes caustics that a path tracer cannot find).
//!
//! ## Two sets
//!
//! * **Reduced (default, CI):** the scene at `1/downsample` of the reference's resolution
//!   with few photons and iterations; the reference is box-averaged by the same factor
//!   before comparing. Box averaging `k × k` pixels of a box-filtered image gives exactly
//!   the box-filtered image at `1/k` resolution, so this compares the same quantity with
//!   `k²` times less reference noise (the V-B and W-C references are still noisy at full
//!   size).
//! * **Full (`ARPA_CONFORMANCE_FULL=1`):** the reference's own resolution, more photons
//!   and iterations, its own (tighter) thresholds.
//!
//! ## Metrics and thresholds
//!
//! `arpa::metrics` (the same code as `arpa render --reference`): relMSE of the linear
//! images, SSIM of the sRGB luminance, mean LDR-ꟻLIP (`nv-flip`), plus the error of the
//! image's mean radiance (energy). Each limit is the value measured on the CPU backend
//! when the case was written (`Measured` in each [`RefScene`]) plus a margin stated next
//! to it; they are regression limits against independent renderers, not proofs of
//! exactness: a consistent estimator with this few photons still carries bias and noise.
//! A backend that loses a bounce, a light or a material fails them by far (the sabotage
//! test halves the image: relMSE grows by an order of magnitude, the mean by 50 %).
//!
//! `ARPA_CONFORMANCE_IMAGES=DIR` writes each render and the downsampled reference as EXR
//! (and as sRGB PNG) into `DIR` for inspection.

use std::path::{Path, PathBuf};

use arpa::metrics::{self, Metrics, downsample, mean};
use arpa_core::propagate::classify::Smoothing;
use arpa_core::render::tracer::{Image, Method, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::suite::{CaseResult, Context};

/// Environment variable selecting the full set (`1`, `true`, `yes`).
pub const FULL_ENV: &str = "ARPA_CONFORMANCE_FULL";
/// Environment variable naming a directory for the rendered and reference images.
pub const IMAGES_ENV: &str = "ARPA_CONFORMANCE_IMAGES";
/// Environment variable overriding the shared scenes directory (default
/// `<repository>/../shared/scenes`).
pub const SCENES_ENV: &str = "ARPA_SHARED_SCENES";

/// `true` when [`FULL_ENV`] asks for the full set.
pub fn full_set() -> bool {
    std::env::var(FULL_ENV).is_ok_and(|v| matches!(v.trim(), "1" | "true" | "yes"))
}

/// The shared scenes directory: [`SCENES_ENV`], else `../shared/scenes` relative to the
/// repository root.
pub fn scenes_dir() -> PathBuf {
    std::env::var_os(SCENES_ENV)
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/scenes"))
        })
}

/// Number of regions across the image for the region relMSE: the rendered image is
/// box-averaged into `REGIONS_ACROSS` columns (16 × 16 regions for the square scenes,
/// 16 × 9 for the 16:9 ones).
pub const REGIONS_ACROSS: u32 = 16;

/// Limits of one comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest relMSE of the region averages ([`REGIONS_ACROSS`]).
    pub rel_mse: f64,
    /// Smallest SSIM (at the set's resolution).
    pub ssim: f64,
    /// Largest mean LDR-ꟻLIP (at the set's resolution).
    pub flip: f64,
    /// Largest `|mean(test)/mean(reference) − 1|` of the mean over pixels and channels (%).
    pub mean_percent: f64,
}

/// A named rectangle of the reference image (reference pixels, half-open ranges; every
/// bound a multiple of 4 so that the reduced set's `/4` image has the same rectangle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// What it shows.
    pub name: &'static str,
    /// Rows `[first, end)`.
    pub rows: [u32; 2],
    /// Columns `[first, end)`.
    pub cols: [u32; 2],
    /// Largest error of its mean in the reduced set (%).
    pub reduced_percent: f64,
    /// Largest error of its mean in the full set (%).
    pub full_percent: f64,
}

fn region_mean(image: &Image, r: &Region, k: u32) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for y in r.rows[0] / k..r.rows[1] / k {
        for x in r.cols[0] / k..r.cols[1] / k {
            if let Some(p) = image.pixels.get((y * image.width + x) as usize) {
                sum += (p.x as f64 + p.y as f64 + p.z as f64) / 3.0;
                n += 1;
            }
        }
    }
    sum / n.max(1) as f64
}

/// Size of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Reference resolution divided by this (exactly; the reference is box-averaged by it).
    pub downsample: u32,
    /// Photons per iteration.
    pub photons: u32,
    /// Iterations.
    pub iterations: u32,
    /// The limits for this budget.
    pub limits: Limits,
}

/// One shared scene and its ground-truth reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefScene {
    /// Directory under the shared scenes directory.
    pub dir: &'static str,
    /// File of the ground-truth reference in `<dir>/reference/`.
    pub reference: &'static str,
    /// ARPA's smoothing factors for the scene (the paper's `S_c`, `S_g`; 1 where it gives none).
    pub smoothing: Smoothing,
    /// Regions whose means are compared (caustics, surfaces seen through glass, lit and
    /// indirectly lit areas).
    pub regions: &'static [Region],
    /// The reduced (CI) set.
    pub reduced: Budget,
    /// The full set.
    pub full: Budget,
}

fn scene_file(spec: &RefScene) -> PathBuf {
    scenes_dir().join(spec.dir).join("scene.xml")
}

fn reference_file(spec: &RefScene) -> PathBuf {
    scenes_dir()
        .join(spec.dir)
        .join("reference")
        .join(spec.reference)
}

/// `Err(what is missing)` unless the scene file and its reference exist.
pub fn data_present(spec: &RefScene) -> Result<(), String> {
    for p in [scene_file(spec), reference_file(spec)] {
        if !p.is_file() {
            return Err(format!(
                "{} is absent (the shared scenes are expected at ../shared/scenes beside the repository, or in ${SCENES_ENV})",
                p.display()
            ));
        }
    }
    Ok(())
}


fn write_images(dir: &Path, name: &str, test: &Image, reference: &Image) {
    let _ = std::fs::create_dir_all(dir);
    for (suffix, img) in [("arpa", test), ("reference", reference)] {
        let stem = dir.join(format!("{name}_{suffix}_{}x{}", img.width, img.height));
        let exr = arpa::image_io::write_exr(&stem.with_extension("exr"), img).err();
        let png = arpa::image_io::write_png(&stem.with_extension("png"), img, 1.0).err();
        for e in exr.into_iter().chain(png) {
            eprintln!("conformance: {e}");
        }
    }
}

/// Renders `spec` with ARPA under the selected set's budget and compares it with the
/// reference; every limit of the budget must hold.
pub fn compare_with_reference(t: &mut dyn DynTracer, spec: &RefScene) -> CaseResult {
    let (budget, set) = if full_set() {
        (spec.full, "full")
    } else {
        (spec.reduced, "reduced")
    };
    let reference = arpa::image_io::read_exr(&reference_file(spec)).map_err(|e| e.to_string())?;
    let reference = downsample(&reference, budget.downsample)?;
    let mut loaded =
        arpa::scene_file::load_scene(&scene_file(spec), &[]).map_err(|e| e.to_string())?;
    loaded.set_resolution(reference.width, reference.height);
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: budget.photons,
        seed: 1,
        // The file's integrator depth (the reference renderer's), as `arpa render` does.
        max_depth: loaded.max_depth.unwrap_or(16),
        smoothing: spec.smoothing,
        ..RenderSettings::default()
    };
    t.upload_scene(&loaded.scene, &settings)
        .ctx("upload_scene")?;
    for _ in 0..budget.iterations {
        t.iterate().ctx("iterate")?;
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("non-finite pixel".into());
    }
    if let Some(dir) = std::env::var_os(IMAGES_ENV).filter(|d| !d.is_empty()) {
        write_images(Path::new(&dir), spec.dir, &image, &reference);
    }
    let Metrics {
        rel_mse: pixel_rel_mse,
        ssim,
        flip,
    } = metrics::compare_images(&image, &reference).map_err(|e| e.to_string())?;
    // Region averages: blocks of the image, REGIONS_ACROSS of them across.
    let block = image.width / REGIONS_ACROSS;
    let (coarse, coarse_ref) = (downsample(&image, block)?, downsample(&reference, block)?);
    let rel_mse = metrics::rel_mse(
        &coarse.pixels,
        &coarse_ref.pixels,
        coarse.width,
        coarse.height,
    )
    .map_err(|e| e.to_string())?;
    let mean_percent = (mean(&image) / mean(&reference) - 1.0) * 100.0;
    let mut regions_ok = true;
    let region_list = spec
        .regions
        .iter()
        .map(|r| {
            let k = budget.downsample;
            let e = (region_mean(&image, r, k) / region_mean(&reference, r, k) - 1.0) * 100.0;
            let tol = if full_set() {
                r.full_percent
            } else {
                r.reduced_percent
            };
            regions_ok &= e.abs() <= tol;
            format!("{} {e:+.1}% (±{tol}%)", r.name)
        })
        .collect::<Vec<_>>()
        .join(", ");
    let l = budget.limits;
    let msg = format!(
        "{set} set {}x{} (reference /{}), {}×{} photons: region relMSE {rel_mse:.2e} (≤ {:.0e}; {}x{} regions), SSIM {ssim:.3} (≥ {}), FLIP {flip:.3} (≤ {}), mean {mean_percent:+.1}% (±{}%), regions: {region_list}; pixel relMSE {pixel_rel_mse:.3}",
        image.width,
        image.height,
        budget.downsample,
        budget.iterations,
        budget.photons,
        l.rel_mse,
        coarse.width,
        coarse.height,
        l.ssim,
        l.flip,
        l.mean_percent,
    );
    if rel_mse <= l.rel_mse
        && ssim >= l.ssim
        && flip <= l.flip
        && mean_percent.abs() <= l.mean_percent
        && regions_ok
    {
        Ok(msg)
    } else {
        Err(msg)
    }
}

/// The five shared scenes, their regions and limits.
///
/// ## How the limits were set
///
/// Measured on the CPU backend (2 threads, AMD EPYC) with ARPA at the paper's `S_c`, `S_g`:
/// the reduced set with seeds 1–5 (the spread is our own Monte Carlo noise; other backends
/// use the same random streams but may diverge on individual photons), the full set with
/// seed 1. `conformance --case reference` prints every value again.
///
/// * **Reduced set:** region relMSE ≤ 2 × the worst of the five seeds; SSIM ≥ worst − 0.04;
///   FLIP ≤ worst + 0.02; image mean and each region mean within 2 × the worst seed's
///   error, at least 3 % (the independent renderers agree to 0.2–0.9 % on means: the
///   scenes README and [`cross-checks`](self#cross-checks)). Caustic regions are small and
///   hit by few photons at 8 × 100k, so their limits are wide (35–46 %); they still catch
///   a missing (−100 %) or misplaced caustic.
/// * **Full set:** 20 × the photons: the standard deviation of a region mean falls by
///   √20 ≈ 4.5, so each region and the image mean get the reduced limit / 4 (at least
///   2 %); region relMSE (a variance) the reduced limit / 10; SSIM ≥ measured − 0.03; FLIP ≤
///   measured + 0.01.
///
/// ## Cross-checks
///
/// The second renderer against the ground truth, same regions and metrics at the
/// reference resolution (`LuxCore` vs Mitsuba `path` unless named): cornell-caustic region
/// relMSE 2.8e-5, SSIM 0.870, FLIP 0.036, mean +0.2 %, regions +0.4 / +0.6 / +0.1 / +0.3 %;
/// veach-bidir 1.2e-3, 0.322, 0.125, −0.6 %, regions −0.6 / +5.5 / +0.4 / +1.5 %;
/// sponza-standin 2.9e-4, 0.947, 0.040, +0.9 %, regions +0.4 / +1.9 / +2.4 %; caustic-glass
/// (Mitsuba `ptracer`, glass black by construction, vs LuxCore) regions +0.0 / −0.0 /
/// −0.6 %.
pub mod scenes {
    use super::*;

    const fn limits(rel_mse: f64, ssim: f64, flip: f64, mean_percent: f64) -> Limits {
        Limits {
            rel_mse,
            ssim,
            flip,
            mean_percent,
        }
    }

    const fn region(
        name: &'static str,
        rows: [u32; 2],
        cols: [u32; 2],
        reduced_percent: f64,
        full_percent: f64,
    ) -> Region {
        Region {
            name,
            rows,
            cols,
            reduced_percent,
            full_percent,
        }
    }

    const REDUCED_PHOTONS: u32 = 100_000;
    const REDUCED_ITERATIONS: u32 = 8;
    const FULL_PHOTONS: u32 = 250_000;
    const FULL_ITERATIONS: u32 = 64;

    const fn reduced(limits: Limits) -> Budget {
        Budget {
            downsample: 4,
            photons: REDUCED_PHOTONS,
            iterations: REDUCED_ITERATIONS,
            limits,
        }
    }

    const fn full(limits: Limits) -> Budget {
        Budget {
            downsample: 1,
            photons: FULL_PHOTONS,
            iterations: FULL_ITERATIONS,
            limits,
        }
    }

    /// cornell-caustic against Mitsuba `path` (4096 spp; area light, so unbiased, caustics
    /// included: the README's ground truth).
    ///
    /// Measured, reduced (seeds 1–5): region relMSE 0.0038–0.040, SSIM 0.870–0.881, FLIP
    /// 0.057–0.061, mean −3.5…+2.0 %, caustic −11.5…+17.5 %, floor through the sphere
    /// −1.9…+1.4 %, back wall ≤ 0.4 %, mirror box ≤ 0.9 %. Full (seed 1): 1.0e-4, 0.880,
    /// 0.041, −0.0 %, regions −1.7 / +0.1 / +0.1 / −0.1 %, pixel relMSE 0.0044.
    pub const CORNELL_CAUSTIC: RefScene = RefScene {
        dir: "cornell-caustic",
        reference: "cornell-caustic_mitsuba-path_256x256_4096spp_143s.exr",
        smoothing: Smoothing {
            caustic: 1.0,
            global: 1.0,
        },
        regions: &[
            region("caustic under the sphere", [236, 248], [48, 92], 35.0, 9.0),
            region(
                "floor seen through the sphere",
                [180, 220],
                [56, 100],
                4.0,
                2.0,
            ),
            region("back wall", [60, 120], [60, 200], 3.0, 2.0),
            region("mirror box", [120, 200], [180, 204], 3.0, 2.0),
        ],
        reduced: reduced(limits(0.08, 0.83, 0.08, 7.0)),
        full: full(limits(0.008, 0.85, 0.05, 2.0)),
    };

    /// caustic-glass against LuxCore PATHCPU + PhotonGI (the README's ground truth: the
    /// caustic of the delta spot and the floor seen through the glass). Regions as in the
    /// README's own cross-check table.
    ///
    /// Measured, reduced: region relMSE 0.0025–0.0050, SSIM 0.776–0.813, FLIP 0.061–0.071,
    /// mean −2.2…−0.3 %, lit floor left ≤ 0.5 %, right −2.7…−0.2 %, caustic −18.0…+6.5 %.
    /// Full: 4e-5, 0.827, 0.034, +0.2 %, regions −0.1 / +0.1 / +0.9 %, pixel relMSE 0.011.
    pub const CAUSTIC_GLASS: RefScene = RefScene {
        dir: "caustic-glass",
        reference: "caustic-glass_luxcore-pathcpu-photongi1_320x180_333spp_368s.exr",
        smoothing: Smoothing {
            caustic: 0.55,
            global: 1.0,
        },
        regions: &[
            region("lit floor left", [120, 180], [0, 100], 3.0, 2.0),
            region("lit floor right", [100, 180], [252, 320], 6.0, 2.0),
            region("caustic under the glass", [88, 132], [140, 200], 36.0, 9.0),
        ],
        reduced: reduced(limits(0.01, 0.74, 0.09, 5.0)),
        full: full(limits(0.001, 0.80, 0.045, 2.0)),
    };

    /// water-caustic against LuxCore PATHCPU + PhotonGI (the only image with the
    /// under-water caustics; slightly noisy, hence region means).
    ///
    /// Measured, reduced: region relMSE 0.0083–0.011, SSIM 0.557–0.582, FLIP 0.124–0.129,
    /// mean −1.1…−0.0 %, ceiling −1.2…+6.9 %, under-water back wall −1.5…+2.2 %, pool floor
    /// −11.2…−1.9 %. Full: 3e-4, 0.756, 0.074, −0.4 %, regions +0.5 / −0.1 / −0.1 %, pixel
    /// relMSE 0.018.
    pub const WATER_CAUSTIC: RefScene = RefScene {
        dir: "water-caustic",
        reference: "water-caustic_luxcore-pathcpu-photongi1_256x256_294spp_902s.exr",
        smoothing: Smoothing {
            caustic: 0.50,
            global: 0.77,
        },
        regions: &[
            region("ceiling", [0, 24], [40, 216], 14.0, 3.5),
            region("under-water back wall", [100, 200], [100, 160], 5.0, 2.0),
            region("pool floor", [236, 252], [100, 160], 22.0, 5.5),
        ],
        reduced: reduced(limits(0.022, 0.52, 0.15, 3.0)),
        full: full(limits(0.0022, 0.73, 0.085, 2.0)),
    };

    /// veach-bidir against Mitsuba `path` (8192 spp, unbiased, still with fireflies from
    /// the egg caustic: region means are the robust comparison; LuxCore itself differs from
    /// it by +5.5 % on the table top).
    ///
    /// Measured, reduced: region relMSE 0.022–0.033, SSIM 0.309–0.322, FLIP 0.158–0.166,
    /// mean −0.5…+2.4 %, ceiling −6.3…+6.1 %, table top −20.9…+6.5 %, back wall
    /// −22.9…−6.4 %, floor +2.4…+13.0 %. Full: 2.7e-3, 0.448, 0.094, +1.7 %, regions
    /// +1.0 / +6.1 / −6.4 / +1.9 %, pixel relMSE 0.091, with the lamp (GGX α 0.25) read as a
    /// mirror. The loader's roughness cut-off (`ROUGHNESS_CUTOFF` of `arpa::scene_file`)
    /// reads it as diffuse, which is closer to the reference on the ceiling and the lamp.
    pub const VEACH_BIDIR: RefScene = RefScene {
        dir: "veach-bidir",
        reference: "veach-bidir_mitsuba-path_256x256_8192spp_304s.exr",
        smoothing: Smoothing {
            caustic: 0.26,
            global: 0.66,
        },
        regions: &[
            region("ceiling above the lamp", [16, 56], [24, 136], 13.0, 3.3),
            region(
                "table top (egg caustic)",
                [168, 180],
                [100, 208],
                42.0,
                10.5,
            ),
            region("back wall", [100, 148], [148, 184], 46.0, 11.5),
            region("floor", [216, 248], [100, 200], 26.0, 6.5),
        ],
        reduced: reduced(limits(0.07, 0.27, 0.19, 5.0)),
        full: full(limits(0.007, 0.42, 0.105, 2.0)),
    };

    /// sponza-standin against Mitsuba `path` (diffuse only, point light).
    ///
    /// Limits set by the rules above from the reduced set rendered with diffuse surfaces
    /// shaded by their face normals: region relMSE 0.032–0.039, SSIM 0.364–0.374, FLIP
    /// 0.198–0.206, atrium floor −0.0…+5.2 %, far arches −1.4…+15.7 %, foreground arch (lit
    /// indirectly) +8.3…+20.6 %; the mean limit is the noise-derived 3 %, which face normals
    /// (mean +7.1…+8.9 %) fail. With diffuse shading normals ([`arpa_core::propagate::lambertian`]),
    /// seed 1: reduced 0.019, 0.413, 0.180, mean +0.9 %, regions −0.7 / +7.2 / +7.3 %; full
    /// 6.2e-4, 0.554, 0.106, mean +0.2 %, regions +0.3 / +1.0 / **−2.8 %** (the foreground
    /// arch, within its 3 % full-set limit; its remaining deficit is the light Mitsuba lets
    /// through open sheets under tilted shading normals, which arpa does not, see
    /// `arpa_core::propagate::lambertian`).
    pub const SPONZA_STANDIN: RefScene = RefScene {
        dir: "sponza-standin",
        reference: "sponza-standin_mitsuba-path_320x180_1024spp_81s.exr",
        smoothing: Smoothing {
            caustic: 1.0,
            global: 0.87,
        },
        regions: &[
            region("atrium floor", [140, 176], [120, 200], 6.0, 2.0),
            region("far arches", [100, 132], [140, 180], 17.0, 4.3),
            region("foreground arch (indirect)", [20, 100], [0, 40], 12.0, 3.0),
        ],
        reduced: reduced(limits(0.08, 0.32, 0.23, 3.0)),
        full: full(limits(0.008, 0.46, 0.18, 2.0)),
    };
}

macro_rules! reference_case {
    ($run:ident, $needs:ident, $spec:path) => {
        /// The reference comparison of this scene ([`compare_with_reference`]).
        pub fn $run(t: &mut dyn DynTracer) -> CaseResult {
            compare_with_reference(t, &$spec)
        }
        /// Whether this scene's data is present ([`data_present`]).
        pub fn $needs() -> Result<(), String> {
            data_present(&$spec)
        }
    };
}

reference_case!(
    cornell_caustic,
    cornell_caustic_data,
    scenes::CORNELL_CAUSTIC
);
reference_case!(caustic_glass, caustic_glass_data, scenes::CAUSTIC_GLASS);
reference_case!(water_caustic, water_caustic_data, scenes::WATER_CAUSTIC);
reference_case!(veach_bidir, veach_bidir_data, scenes::VEACH_BIDIR);
reference_case!(sponza_standin, sponza_standin_data, scenes::SPONZA_STANDIN);

