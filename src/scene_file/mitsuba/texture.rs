//! Texture plugins: `bitmap` (image files through [`super::super::bitmap`]) and
//! `checkerboard`, with Mitsuba's parameters.

use super::loader::{Loader, Props, R};
use super::super::bitmap;
use super::super::spectrum::SpectrumUse;
use super::super::xml::Node;
use arpa_core::render::texture::{Bitmap, Texture, TextureFilter, TextureId, TextureWrap, UvTransform};
use glam::{DMat4, DVec3};

impl Loader<'_> {
    /// A `<texture>` element, decoded and added to the scene's textures.
    pub(super) fn texture(&mut self, n: &Node) -> R<TextureId> {
        let ty = n.attr("type").unwrap_or("");
        let p = self.props(n);
        let to_uv = self.to_uv(&p)?;
        let texture = match ty {
            "bitmap" => {
                let file = self.string(&p, "filename")?.ok_or_else(|| self.invalid(n.line, format!("{} lacks <string name=\"filename\">", n.describe())))?;
                let filter = match self.string(&p, "filter_type")?.as_deref().unwrap_or("bilinear") {
                    "bilinear" => TextureFilter::Bilinear,
                    "nearest" => TextureFilter::Nearest,
                    other => return Err(self.invalid(self.line_of(&p, "filter_type"), format!("filter_type '{other}' is not one of bilinear, nearest"))),
                };
                let wrap = match self.string(&p, "wrap_mode")?.as_deref().unwrap_or("repeat") {
                    "repeat" => TextureWrap::Repeat,
                    "mirror" => TextureWrap::Mirror,
                    "clamp" => TextureWrap::Clamp,
                    other => return Err(self.invalid(self.line_of(&p, "wrap_mode"), format!("wrap_mode '{other}' is not one of repeat, mirror, clamp"))),
                };
                let raw = self.boolean(&p, "raw")?.unwrap_or(false);
                // Storage precision and GPU texture objects: nothing for the image.
                let _ = (self.string(&p, "format")?, self.boolean(&p, "accel")?);
                let (path, bytes) = self.read_file(&file)?;
                let d = bitmap::decode(&bytes, &path, raw)?;
                Texture::Bitmap(Bitmap { width: d.width, height: d.height, texels: d.texels, filter, wrap, to_uv })
            }
            "checkerboard" => {
                // Constant colours (a texture there is an error naming it).
                let color0 = self.rgb(&p, "color0", SpectrumUse::Reflectance)?.unwrap_or(DVec3::splat(0.4));
                let color1 = self.rgb(&p, "color1", SpectrumUse::Reflectance)?.unwrap_or(DVec3::splat(0.2));
                Texture::Checkerboard { color0: color0.as_vec3(), color1: color1.as_vec3(), to_uv }
            }
            _ => return Err(self.unsupported(n, "supported textures: bitmap, checkerboard")),
        };
        self.finish(&p);
        self.textures.push(texture);
        Ok(self.textures.len() as TextureId - 1)
    }

    /// Mitsuba's `to_uv`: the affine part of the transform on `(u, v)` (its 2×2 block and
    /// its translation's first two components).
    fn to_uv(&self, p: &Props<'_>) -> R<UvTransform> {
        let line = self.line_of(p, "to_uv");
        let m = self.transform(p, "to_uv")?.unwrap_or(DMat4::IDENTITY);
        let rows = [[m.x_axis.x, m.y_axis.x, m.w_axis.x], [m.x_axis.y, m.y_axis.y, m.w_axis.y]].map(|r| r.map(|x| x as f32));
        let t = UvTransform { rows };
        if !t.is_finite() {
            return Err(self.invalid(line, "to_uv is not finite in single precision"));
        }
        Ok(t)
    }
}
