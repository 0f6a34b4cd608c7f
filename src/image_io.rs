//! Writing and reading images of linear radiance.
//!
//! * OpenEXR ([`write_exr`], [`read_exr`]): three `f32` channels R, G, B, linear, unscaled
//!   (the renderer's radiance in W/(m²·sr)), lossless compression.
//! * PNG ([`write_png`]): 8-bit sRGB: each channel is multiplied by the exposure, clamped
//!   to `[0, 1]` and encoded with the sRGB transfer function ([`srgb_encode`]).
//!
//! Nothing non-finite is ever written: NaN and ±∞ become 0 and are counted in the
//! returned [`WriteReport`]. Every error names the file.

use arpa_core::glam::Vec3;
use arpa_core::render::tracer::Image;
use std::path::{Path, PathBuf};

/// Why an image could not be written or read. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageIoError {
    /// The OpenEXR encoder or the file system failed.
    #[error("cannot write OpenEXR file '{}': {source}", path.display())]
    WriteExr {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: exr::error::Error,
    },
    /// The PNG encoder or the file system failed.
    #[error("cannot write PNG file '{}': {source}", path.display())]
    WritePng {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: image::ImageError,
    },
    /// The file is not a readable RGB OpenEXR image.
    #[error("cannot read OpenEXR file '{}': {source}", path.display())]
    ReadExr {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: exr::error::Error,
    },
    /// The image's pixel count does not match its size, or the size is zero or too large.
    #[error("cannot write '{}': image is {width}x{height} but has {pixels} pixels", path.display())]
    BadImage {
        /// The file.
        path: PathBuf,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Pixels given.
        pixels: usize,
    },
    /// A non-finite exposure.
    #[error("cannot write '{}': exposure {exposure} is not a finite non-negative number", path.display())]
    BadExposure {
        /// The file.
        path: PathBuf,
        /// The exposure given.
        exposure: f32,
    },
}

/// What writing an image did besides writing it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteReport {
    /// Channel values that were NaN or infinite and were written as 0.
    pub non_finite_replaced: usize,
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in `[0, 1]`; values
/// outside are clamped, NaN gives 0.
pub fn srgb_encode(linear: f32) -> f32 {
    let x = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    if x <= 0.003_130_8 {
        12.92 * x
    } else if x >= 1.0 {
        1.0
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

fn check(path: &Path, image: &Image) -> Result<(), ImageIoError> {
    let expected = (image.width as u64).checked_mul(image.height as u64);
    if image.width == 0 || image.height == 0 || expected != Some(image.pixels.len() as u64) {
        return Err(ImageIoError::BadImage { path: path.to_path_buf(), width: image.width, height: image.height, pixels: image.pixels.len() });
    }
    Ok(())
}

/// Copies the pixels with NaN/∞ channels replaced by 0; returns them and the count.
fn sanitized(image: &Image) -> (Vec<Vec3>, usize) {
    let mut replaced = 0;
    let pixels = image
        .pixels
        .iter()
        .map(|p| {
            let mut q = p.to_array();
            for c in &mut q {
                if !c.is_finite() {
                    *c = 0.0;
                    replaced += 1;
                }
            }
            Vec3::from_array(q)
        })
        .collect();
    (pixels, replaced)
}

/// Writes `image` as an RGB `f32` OpenEXR file (linear radiance, no exposure applied).
/// The same image always gives the same bytes.
pub fn write_exr(path: &Path, image: &Image) -> Result<WriteReport, ImageIoError> {
    check(path, image)?;
    let (pixels, replaced) = sanitized(image);
    let w = image.width as usize;
    // Compressed on one thread: the parallel writer stores blocks in the order they finish,
    // so the same image would give files that differ byte for byte from run to run.
    let channels = exr::prelude::SpecificChannels::rgb(|exr::prelude::Vec2(x, y)| {
        let p: Vec3 = pixels[y * w + x];
        (p.x, p.y, p.z)
    });
    use exr::prelude::WritableImage;
    let exr_image = exr::prelude::Image::from_channels((w, image.height as usize), channels);
    exr_image
        .write()
        .non_parallel()
        .to_file(path)
        .map_err(|source| ImageIoError::WriteExr { path: path.to_path_buf(), source })?;
    Ok(WriteReport { non_finite_replaced: replaced })
}

/// Writes `image` as an 8-bit sRGB PNG: `srgb_encode(clamp(exposure · radiance, 0, 1))`.
pub fn write_png(path: &Path, image: &Image, exposure: f32) -> Result<WriteReport, ImageIoError> {
    check(path, image)?;
    if !(exposure.is_finite() && exposure >= 0.0) {
        return Err(ImageIoError::BadExposure { path: path.to_path_buf(), exposure });
    }
    let (pixels, replaced) = sanitized(image);
    let bytes: Vec<u8> = pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(|c| (srgb_encode(c * exposure) * 255.0 + 0.5).clamp(0.0, 255.0) as u8)
        .collect();
    image::save_buffer_with_format(path, &bytes, image.width, image.height, image::ExtendedColorType::Rgb8, image::ImageFormat::Png)
        .map_err(|source| ImageIoError::WritePng { path: path.to_path_buf(), source })?;
    Ok(WriteReport { non_finite_replaced: replaced })
}

/// Reads the first RGB(A) layer of an OpenEXR file as linear radiance (alpha is ignored;
/// any sample type is converted to `f32`). Non-finite values are kept as read.
pub fn read_exr(path: &Path) -> Result<Image, ImageIoError> {
    let read = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _channels| (resolution.width(), vec![Vec3::ZERO; resolution.width() * resolution.height()]),
        |(w, pixels): &mut (usize, Vec<Vec3>), position, (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[position.y() * *w + position.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|source| ImageIoError::ReadExr { path: path.to_path_buf(), source })?;
    let size = read.layer_data.size;
    let (_, pixels) = read.layer_data.channel_data.pixels;
    Ok(Image { width: size.width() as u32, height: size.height() as u32, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_image() -> Image {
        let (width, height) = (7, 5);
        let pixels = (0..width * height).map(|i| Vec3::new(i as f32 * 0.25, 1.0 / (1.0 + i as f32), 1e-3 * i as f32 + 3.0)).collect();
        Image { width, height, pixels }
    }

    /// Rendering is deterministic, and so are the files: the same image written again gives
    /// the same bytes (an image of many blocks, which the parallel writer stored in the
    /// order its threads finished them).
    #[test]
    fn exr_bytes_are_the_same_for_the_same_image() {
        let dir = tempfile::tempdir().unwrap();
        let (width, height) = (300u32, 700u32);
        let pixels = (0..width * height).map(|i| Vec3::new((i % 977) as f32 * 0.37, 1.0 / (1.0 + (i % 131) as f32), (i as f32).sqrt())).collect();
        let image = Image { width, height, pixels };
        let first = dir.path().join("first.exr");
        write_exr(&first, &image).unwrap();
        let bytes = std::fs::read(&first).unwrap();
        for k in 0..8 {
            let again = dir.path().join(format!("again{k}.exr"));
            write_exr(&again, &image).unwrap();
            assert!(std::fs::read(&again).unwrap() == bytes, "write {k} differs from the first");
        }
        assert_eq!(read_exr(&first).unwrap(), image);
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let image = test_image();
        assert_eq!(write_exr(&path, &image).unwrap().non_finite_replaced, 0);
        assert_eq!(read_exr(&path).unwrap(), image);
    }

    #[test]
    fn non_finite_values_are_written_as_zero_and_counted() {
        let dir = tempfile::tempdir().unwrap();
        let mut image = test_image();
        image.pixels[3] = Vec3::new(f32::NAN, f32::INFINITY, 1.0);
        image.pixels[4].z = f32::NEG_INFINITY;
        let path = dir.path().join("b.exr");
        assert_eq!(write_exr(&path, &image).unwrap().non_finite_replaced, 3);
        let back = read_exr(&path).unwrap();
        assert_eq!(back.pixels[3], Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(back.pixels[4].z, 0.0);
        assert!(back.pixels.iter().all(|p| p.is_finite()));
        let png = dir.path().join("b.png");
        assert_eq!(write_png(&png, &image, 1.0).unwrap().non_finite_replaced, 3);
    }

    #[test]
    fn png_is_srgb_encoded_with_exposure() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.png");
        let image = Image { width: 4, height: 1, pixels: vec![Vec3::ZERO, Vec3::splat(0.25), Vec3::splat(0.5), Vec3::splat(100.0)] };
        write_png(&path, &image, 2.0).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (4, 1));
        let v: Vec<u8> = back.pixels().map(|p| p.0[0]).collect();
        // 0 -> 0, 0.5 -> 188 (sRGB), 1 -> 255, clamped 200 -> 255.
        assert_eq!(v, vec![0, 188, 255, 255]);
    }

    #[test]
    fn srgb_transfer_function_known_values() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.002) - 0.02584).abs() < 1e-5);
        assert!((srgb_encode(0.5) - 0.735_357).abs() < 1e-5);
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert_eq!(srgb_encode(-1.0), 0.0);
        assert_eq!(srgb_encode(7.0), 1.0);
    }

    #[test]
    fn errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no such dir").join("x.exr");
        let e = write_exr(&missing, &test_image()).unwrap_err().to_string();
        assert!(e.contains("x.exr"), "{e}");
        let e = write_png(&dir.path().join("no such dir").join("x.png"), &test_image(), 1.0).unwrap_err().to_string();
        assert!(e.contains("x.png"), "{e}");
        let e = read_exr(&dir.path().join("missing.exr")).unwrap_err().to_string();
        assert!(e.contains("missing.exr"), "{e}");
        let bad = Image { width: 3, height: 3, pixels: vec![Vec3::ZERO; 4] };
        let e = write_exr(&dir.path().join("bad.exr"), &bad).unwrap_err().to_string();
        assert!(e.contains("bad.exr") && e.contains("3x3"), "{e}");
        let e = write_png(&dir.path().join("e.png"), &test_image(), f32::NAN).unwrap_err().to_string();
        assert!(e.contains("e.png"), "{e}");
    }
}
