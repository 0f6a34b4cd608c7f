//! The picture of a per-pixel bandwidth choice (`arpa render --scale-map`): the scale of
//! the footprint ladder each pixel uses ([`arpa_core::accumulate::bandwidth`]), as a colour map with a
//! legend under it.

use anyhow::{anyhow, Context as _};
use arpa_core::gather::scales::{scale, SCALES};
use plotters::prelude::*;
use std::path::Path;

/// Colours of the ladder's scales, from the stored footprints (0, dark blue) to the
/// smallest (yellow); a fractional index is interpolated between its two scales.
const STOPS: [[f64; 3]; SCALES] = [[68.0, 1.0, 84.0], [59.0, 82.0, 139.0], [33.0, 145.0, 140.0], [94.0, 201.0, 98.0], [253.0, 231.0, 37.0]];

/// The colour of fractional scale index `c` (clamped to the ladder).
pub fn colour(c: f32) -> [u8; 3] {
    let c = f64::from(c).clamp(0.0, (SCALES - 1) as f64);
    let k = (c as usize).min(SCALES - 2);
    let t = c - k as f64;
    core::array::from_fn(|i| (STOPS[k][i] * (1.0 - t) + STOPS[k + 1][i] * t).round() as u8)
}

/// Writes `path` (PNG): the `width × height` map of `scale` (fractional scale index per
/// pixel, row-major, as [`arpa_core::accumulate::bandwidth::Selection::scale`]) enlarged to at least
/// 512 pixels across, and a legend naming each scale's size relative to the stored
/// footprints.
pub fn write_scale_map(path: &Path, width: u32, height: u32, scale_index: &[f32]) -> anyhow::Result<()> {
    if width == 0 || height == 0 || scale_index.len() != width as usize * height as usize {
        return Err(anyhow!("cannot write scale map '{}': {} values for {width}x{height} pixels", path.display(), scale_index.len()));
    }
    crate::bench::report::register_font()?;
    let zoom = 512u32.div_ceil(width).clamp(1, 8);
    let (w, legend) = ((width * zoom).max(420), 56u32);
    let h = height * zoom + legend;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    for y in 0..height * zoom {
        for x in 0..width * zoom {
            let c = colour(scale_index[(y / zoom * width + x / zoom) as usize]);
            let at = ((y * w + x) * 3) as usize;
            buf[at..at + 3].copy_from_slice(&c);
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let fail = |e: &dyn std::fmt::Display| anyhow!("cannot draw scale map '{}': {e}", path.display());
        let top = (height * zoom) as i32 + 8;
        root.draw(&Text::new("footprint scale per pixel (relative to the stored ellipse)", (8, top), ("sans-serif", 13))).map_err(|e| fail(&e))?;
        let step = (w as i32 - 16) / SCALES as i32;
        for k in 0..SCALES {
            let x = 8 + k as i32 * step;
            let [r, g, b] = colour(k as f32);
            root.draw(&Rectangle::new([(x, top + 20), (x + 22, top + 40)], RGBColor(r, g, b).filled())).map_err(|e| fail(&e))?;
            root.draw(&Text::new(format!("{:.2}", scale(k)), (x + 28, top + 23), ("sans-serif", 13))).map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    image::save_buffer(path, &buf, w, h, image::ExtendedColorType::Rgb8).with_context(|| format!("cannot write scale map '{}'", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_interpolate_between_the_stops() {
        assert_eq!(colour(0.0), [68, 1, 84]);
        assert_eq!(colour(4.0), [253, 231, 37]);
        assert_eq!(colour(9.0), colour(4.0));
        let mid = colour(0.5);
        assert!(mid[0] > 59 && mid[0] < 68 && mid[2] > 84 && mid[2] < 139, "{mid:?}");
    }

    #[test]
    fn writes_a_png_and_refuses_a_wrong_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.scale.png");
        write_scale_map(&path, 4, 3, &[0.0, 1.0, 2.0, 3.0, 4.0, 0.5, 1.5, 2.5, 3.5, 0.0, 0.0, 0.0]).unwrap();
        let img = image::open(&path).unwrap();
        assert!(img.width() >= 420 && img.height() == 3 * 8 + 56, "{}x{}", img.width(), img.height());
        let e = write_scale_map(&path, 4, 4, &[0.0; 3]).unwrap_err();
        assert!(e.to_string().contains("s.scale.png"), "{e}");
    }
}
