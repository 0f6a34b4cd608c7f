//! Image files a scene's `bitmap` textures name, decoded as Mitsuba 3 decodes them: PNG
//! and JPEG 8-bit texels are sRGB-encoded (kept 8-bit, decoded per lookup) unless `raw`,
//! 16-bit PNG is decoded to linear floats at load (sRGB unless `raw`), OpenEXR and Radiance
//! HDR are linear floats. Grey images become equal RGB; alpha channels are dropped (a mask
//! reads its own `opacity` texture, never a bitmap's alpha, as in Mitsuba).

use super::error::SceneFileError;
use arpa_core::render::texture::{srgb_decode, Texels};
use std::path::Path;

/// A decoded image: `width × height` texels, row-major from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedBitmap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The texels.
    pub texels: Texels,
}

/// Largest texel count of one texture (2^28, a 16k × 16k image): a bound on the memory a
/// file's header can ask for.
pub const MAX_TEXELS: u64 = 1 << 28;

/// Decodes the image file `bytes` (`path` names it in errors; its format comes from its
/// content, not its name). `raw` turns off the sRGB decoding of integer images.
pub fn decode(bytes: &[u8], path: &Path, raw: bool) -> Result<DecodedBitmap, SceneFileError> {
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        return decode_exr(bytes, path);
    }
    let img = read_image(bytes, path, &[image::ImageFormat::Png, image::ImageFormat::Jpeg, image::ImageFormat::Hdr], "PNG, JPEG, OpenEXR, Radiance HDR")?;
    let (width, height) = (img.width(), img.height());
    use image::DynamicImage as D;
    let texels = match img {
        D::ImageLuma8(_) | D::ImageLumaA8(_) | D::ImageRgb8(_) | D::ImageRgba8(_) => {
            let rgb: Vec<[u8; 3]> = img.to_rgb8().pixels().map(|p| p.0).collect();
            if raw { Texels::Linear8(rgb) } else { Texels::Srgb8(rgb) }
        }
        D::ImageRgb32F(_) | D::ImageRgba32F(_) => Texels::Float(img.to_rgb32f().pixels().map(|p| p.0).collect()),
        _ => {
            // 16-bit integer images: to floats at load, through the sRGB curve unless raw.
            let decode = |c: u16| {
                let c = c as f32 / 65535.0;
                if raw { c } else { srgb_decode(c) }
            };
            Texels::Float(img.to_rgb16().pixels().map(|p| p.0.map(decode)).collect())
        }
    };
    Ok(DecodedBitmap { width, height, texels })
}

/// The alpha channel of a PNG or JPEG image (`width`, `height`, one byte per texel from the
/// top row; 255 where the image has no alpha): what a glTF material's `alphaMode` reads.
pub fn decode_alpha(bytes: &[u8], path: &Path) -> Result<(u32, u32, Vec<u8>), SceneFileError> {
    let img = read_image(bytes, path, &[image::ImageFormat::Png, image::ImageFormat::Jpeg], "PNG, JPEG")?;
    Ok((img.width(), img.height(), img.to_rgba8().pixels().map(|p| p.0[3]).collect()))
}

/// Decodes `bytes` as one of `formats` (recognised by content; `names` lists them for the
/// error), within [`MAX_TEXELS`] and a matching allocation limit.
fn read_image(bytes: &[u8], path: &Path, formats: &[image::ImageFormat], names: &str) -> Result<image::DynamicImage, SceneFileError> {
    let err = |message: String| SceneFileError::Texture { path: path.to_path_buf(), message };
    let format = image::guess_format(bytes).map_err(|_| err(format!("not an image file arpa reads ({names})")))?;
    if !formats.contains(&format) {
        return Err(err(format!("{format:?} images are not supported here ({names} are)")));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_TEXELS * 16);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| err(format!("cannot decode: {e}")))?;
    let (width, height) = (img.width(), img.height());
    if width == 0 || height == 0 || width as u64 * height as u64 > MAX_TEXELS {
        return Err(err(format!("{width}×{height} texels: empty or larger than {MAX_TEXELS}")));
    }
    Ok(img)
}

/// The first RGB(A) layer of an OpenEXR file in memory, as linear floats (a grey layer
/// gives equal RGB).
fn decode_exr(bytes: &[u8], path: &Path) -> Result<DecodedBitmap, SceneFileError> {
    use exr::prelude::*;
    let read = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution: Vec2<usize>, _channels: &RgbaChannels| {
                let (w, h) = (resolution.width(), resolution.height());
                let n = if (w as u64) * (h as u64) <= MAX_TEXELS { w * h } else { 0 };
                (w, vec![[0f32; 3]; n])
            },
            |(w, pixels): &mut (usize, Vec<[f32; 3]>), position: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
                if let Some(p) = pixels.get_mut(position.y() * *w + position.x()) {
                    *p = [r, g, b];
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes));
    let image = match read {
        Ok(image) => image,
        // A grey image (one Y channel): read it as such.
        Err(_) => return decode_exr_grey(bytes, path),
    };
    let size = image.layer_data.size;
    let (width, height) = (size.width() as u32, size.height() as u32);
    let (_, pixels) = image.layer_data.channel_data.pixels;
    exr_texels(width, height, pixels, path)
}

/// A one-channel (`Y`) OpenEXR image as equal RGB.
fn decode_exr_grey(bytes: &[u8], path: &Path) -> Result<DecodedBitmap, SceneFileError> {
    let err = |message: String| SceneFileError::Texture { path: path.to_path_buf(), message };
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("Y")
        .collect_pixels(
            |resolution: Vec2<usize>, _channels: &(ChannelDescription,)| {
                let (w, h) = (resolution.width(), resolution.height());
                let n = if (w as u64) * (h as u64) <= MAX_TEXELS { w * h } else { 0 };
                (w, vec![[0f32; 3]; n])
            },
            |(w, pixels): &mut (usize, Vec<[f32; 3]>), position: Vec2<usize>, (y,): (f32,)| {
                if let Some(p) = pixels.get_mut(position.y() * *w + position.x()) {
                    *p = [y; 3];
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| err(format!("cannot decode OpenEXR: {e}")))?;
    let size = image.layer_data.size;
    let (width, height) = (size.width() as u32, size.height() as u32);
    let (_, pixels) = image.layer_data.channel_data.pixels;
    exr_texels(width, height, pixels, path)
}

/// The texels an OpenEXR reader filled, checked: the size the header gave (not empty, at
/// most [`MAX_TEXELS`]) and every value finite.
fn exr_texels(width: u32, height: u32, pixels: Vec<[f32; 3]>, path: &Path) -> Result<DecodedBitmap, SceneFileError> {
    let err = |message: String| SceneFileError::Texture { path: path.to_path_buf(), message };
    if width == 0 || height == 0 || pixels.len() as u64 != width as u64 * height as u64 {
        return Err(err(format!("{width}×{height} texels: empty or larger than {MAX_TEXELS}")));
    }
    if let Some(i) = pixels.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(err(format!("texel {i} is not finite")));
    }
    Ok(DecodedBitmap { width, height, texels: Texels::Float(pixels) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(img: image::DynamicImage) -> Vec<u8> {
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
        out
    }

    #[test]
    fn png_is_srgb_unless_raw_and_alpha_is_dropped() {
        let img = image::RgbaImage::from_raw(2, 1, vec![255, 128, 0, 0, 10, 20, 30, 255]).unwrap();
        let bytes = png(image::DynamicImage::ImageRgba8(img));
        let d = decode(&bytes, Path::new("t.png"), false).unwrap();
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.texels, Texels::Srgb8(vec![[255, 128, 0], [10, 20, 30]]));
        // Mitsuba: RGBA (255, 128, 0, a = 0) → (1, 0.21586, 0).
        assert!((d.texels.linear(0) - glam::Vec3::new(1.0, 0.21586, 0.0)).abs().max_element() < 1e-5);
        let raw = decode(&bytes, Path::new("t.png"), true).unwrap();
        assert_eq!(raw.texels, Texels::Linear8(vec![[255, 128, 0], [10, 20, 30]]));
        // Grey: equal RGB.
        let grey = png(image::DynamicImage::ImageLuma8(image::GrayImage::from_raw(1, 1, vec![77]).unwrap()));
        assert_eq!(decode(&grey, Path::new("g.png"), false).unwrap().texels, Texels::Srgb8(vec![[77; 3]]));
    }

    /// 16-bit PNG: decoded at load (Mitsuba: 32768 → 0.214 after sRGB).
    #[test]
    fn sixteen_bit_png_decodes_at_load() {
        let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![32768u16, 0, 65535]).unwrap();
        let d = decode(&png(image::DynamicImage::ImageRgb16(img)), Path::new("t.png"), false).unwrap();
        let Texels::Float(t) = &d.texels else { panic!("{:?}", d.texels) };
        assert!((t[0][0] - 0.214048).abs() < 1e-5 && t[0][1] == 0.0 && (t[0][2] - 1.0).abs() < 1e-6, "{t:?}");
    }

    #[test]
    fn exr_is_linear() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.exr");
        let image = arpa_core::render::tracer::Image { width: 2, height: 1, pixels: vec![glam::Vec3::new(2.5, 0.5, 0.0), glam::Vec3::splat(1e-3)] };
        crate::image_io::write_exr(&path, &image).unwrap();
        let d = decode(&std::fs::read(&path).unwrap(), &path, false).unwrap();
        assert_eq!(d.texels, Texels::Float(vec![[2.5, 0.5, 0.0], [1e-3; 3]]));
    }

    #[test]
    fn bad_files_name_the_file() {
        for bytes in [&b""[..], b"not an image", &[0x89, b'P', b'N', b'G', 13, 10, 26, 10, 0, 0][..], &[0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0][..]] {
            let e = decode(bytes, Path::new("dir/t.png"), false).unwrap_err();
            assert!(e.to_string().contains("dir/t.png"), "{e}");
        }
    }
}
