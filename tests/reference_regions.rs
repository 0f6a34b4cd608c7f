//! Region means of short renders against the independent Mitsuba references in
//! `shared/scenes/*/reference`: region means separate bias from noise, so a few
//! iterations decide which reading of a scene is right.
//!
//! veach-bidir's lamp (rough conductor, GGX alpha 0.25, Falcor roughness 0.51 in the scene
//! RTPM rendered) is diffuse under RTPM's roughness rule as the loader applies it; the
//! Mitsuba `path` reference (8192 spp) agrees with that reading and not with the mirror
//! reading, which sends the light of the lamp's shade to the ceiling as a sharp caustic
//! (ceiling about +7 %) and shows a dark mirror image on the lamp's pole (about −24 %).

#![cfg(feature = "cpu")]

use arpa::session::{Budget, render};
use arpa::core::render::tracer::{Image, Method, RenderSettings};
use arpa::scene_file::load_scene;
use std::path::Path;

mod common;
use common::shared_scenes;

/// Mean of the three channels over rows `r0..r1`, columns `c0..c1`.
fn region_mean(img: &Image, (r0, r1): (usize, usize), (c0, c1): (usize, usize)) -> f64 {
    let mut s = 0.0;
    for r in r0..r1 {
        for c in c0..c1 {
            let p = img.pixels[r * img.width as usize + c];
            s += (p.x + p.y + p.z) as f64 / 3.0;
        }
    }
    s / ((r1 - r0) * (c1 - c0)) as f64
}

/// Renders veach-bidir at its 256x256 film with `roughness_cutoff` (None: the loader's),
/// photons only for the indirect light as in the CLI defaults.
fn render_veach(dir: &Path, roughness_cutoff: Option<f32>) -> Image {
    let mut loaded = load_scene(&dir.join("veach-bidir/scene.xml"), &[]).unwrap();
    if let Some(c) = roughness_cutoff {
        loaded.scene.roughness_cutoff = c;
    }
    let settings = RenderSettings { method: Method::Rtpm, photons_per_iteration: 100_000, max_depth: 15, seed: 7, ..RenderSettings::default() };
    let mut tracer = arpa::cpu::CpuTracer::new().unwrap();
    render(&mut tracer, &loaded.scene, &settings, Budget::Iterations(8)).unwrap().image
}

#[test]
fn veach_bidir_lamp_is_diffuse_as_the_reference_shows() {
    let Some(dir) = shared_scenes() else { return };
    let reference = arpa::image_io::read_exr(&dir.join("veach-bidir/reference/veach-bidir_mitsuba-path_256x256_8192spp_304s.exr")).unwrap();
    // Ceiling lit by Light0 and by what the lamp's shade reflects; the lamp's pole.
    let ceiling = ((0, 30), (20, 130));
    let pole = ((90, 200), (68, 75));
    let ratio = |img: &Image, region: ((usize, usize), (usize, usize))| region_mean(img, region.0, region.1) / region_mean(&reference, region.0, region.1);

    let diffuse = render_veach(&dir, None);
    let (c, p) = (ratio(&diffuse, ceiling), ratio(&diffuse, pole));
    eprintln!("lamp diffuse (loader's rule): ceiling {c:.4}, pole {p:.4} of the Mitsuba reference");
    assert!((c - 1.0).abs() < 0.03, "ceiling {c}");
    assert!((p - 1.0).abs() < 0.08, "pole {p}");

    // The other reading (alpha 0.25 below a cut-off of 0.5: a perfect mirror) fails both.
    let mirror = render_veach(&dir, Some(0.5));
    let (c, p) = (ratio(&mirror, ceiling), ratio(&mirror, pole));
    eprintln!("lamp mirror: ceiling {c:.4}, pole {p:.4} of the Mitsuba reference");
    assert!(c > 1.04 && p < 0.85, "the mirror reading should be visibly off: ceiling {c}, pole {p}");
}
