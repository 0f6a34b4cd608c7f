//! Textures: bitmaps and checkerboards looked up at a surface point's texture coordinates,
//! with the semantics of Mitsuba 3's `bitmap` and `checkerboard` plugins so that scenes
//! written for Mitsuba render alike.
//!
//! Texture coordinates `(u, v)` are those of the mesh (Mitsuba's convention: `v = 0` is the
//! first row of the image file, its top), or the hit's barycentric weights `(b1, b2)` on a
//! mesh without them, as Mitsuba does. A texture's `to_uv` maps them first:
//! `uv' = A uv + t`.
//!
//! Bitmaps ([`Bitmap`]):
//! - bilinear: `x = u'W − ½`, `y = v'H − ½`, the four texels around `(x, y)` weighted by
//!   the fractional parts; nearest: texel `(⌊u'W⌋, ⌊v'H⌋)`;
//! - every texel index is wrapped on its own: repeat (`i mod N`), clamp (`0..N−1`) or mirror
//!   (even periods as is, odd ones reversed, so the edge texel repeats);
//! - 8-bit sRGB texels are decoded to linear (`c/12.92` up to 0.04045, else
//!   `((c + 0.055)/1.055)^2.4`) before they are interpolated, and stay 8-bit in memory;
//!   8-bit `raw` texels are `c/255`; float texels (16-bit PNG decoded at load, EXR, HDR)
//!   are used as they are. Grey images are stored as equal RGB.
//!
//! A texture's single value ([`Texture::eval_1`], what an opacity mask reads) is the
//! luminance `0.212671 R + 0.715160 G + 0.072169 B` of its colour (the grey value of a grey
//! image), as Mitsuba's `eval_1`.

use alloc::vec::Vec;
use glam::{Vec2, Vec3};

/// Index into [`crate::render::scene::SceneTextures::textures`].
pub type TextureId = u32;

/// How a bitmap finds values between texel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TextureFilter {
    /// Bilinear interpolation of the four nearest texels (Mitsuba's default).
    #[default]
    Bilinear,
    /// The texel containing the point.
    Nearest,
}

/// How texel indices outside the image are mapped back into it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TextureWrap {
    /// Periodic (Mitsuba's default).
    #[default]
    Repeat,
    /// Periodic with every other period reversed.
    Mirror,
    /// The nearest edge texel.
    Clamp,
}

/// The texels of a bitmap, row-major from the first (top) row, RGB.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// 8-bit sRGB-encoded values, decoded to linear at every lookup.
    Srgb8(Vec<[u8; 3]>),
    /// 8-bit values used linearly as `c/255` (Mitsuba's `raw`).
    Linear8(Vec<[u8; 3]>),
    /// Linear values.
    Float(Vec<[f32; 3]>),
}

impl Texels {
    /// Number of texels.
    pub fn len(&self) -> usize {
        match self {
            Texels::Srgb8(t) | Texels::Linear8(t) => t.len(),
            Texels::Float(t) => t.len(),
        }
    }

    /// Whether there are no texels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The linear value of texel `i` (`i < len`).
    #[inline]
    pub fn linear(&self, i: usize) -> Vec3 {
        match self {
            Texels::Srgb8(t) => Vec3::from_array(t[i].map(srgb_to_linear)),
            Texels::Linear8(t) => Vec3::from_array(t[i].map(|c| c as f32 / 255.0)),
            Texels::Float(t) => Vec3::from_array(t[i]),
        }
    }
}

/// The linear value of the 8-bit sRGB-encoded value `c`.
#[inline]
pub fn srgb_to_linear(c: u8) -> f32 {
    srgb_decode(c as f32 / 255.0)
}

/// The sRGB transfer function: the linear value of the encoded value `c ∈ [0, 1]`.
#[inline]
pub fn srgb_decode(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { libm::powf((c + 0.055) / 1.055, 2.4) }
}

/// The affine map `uv' = A uv + t` a texture applies to texture coordinates first:
/// `rows[r] = [A_r0, A_r1, t_r]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// The two rows of `[A | t]`.
    pub rows: [[f32; 3]; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl UvTransform {
    /// No change.
    pub const IDENTITY: Self = Self { rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] };

    /// `A uv + t`.
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [a, b] = self.rows;
        Vec2::new(a[0] * uv.x + a[1] * uv.y + a[2], b[0] * uv.x + b[1] * uv.y + b[2])
    }

    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rows.iter().flatten().all(|x| x.is_finite())
    }
}

/// An image texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    /// Width in texels (≥ 1).
    pub width: u32,
    /// Height in texels (≥ 1).
    pub height: u32,
    /// `width × height` texels.
    pub texels: Texels,
    /// Filter.
    pub filter: TextureFilter,
    /// Wrap mode of both axes.
    pub wrap: TextureWrap,
    /// Applied to the texture coordinates first.
    pub to_uv: UvTransform,
}

/// A texture: what a material parameter reads at a surface point.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// An image.
    Bitmap(Bitmap),
    /// Mitsuba's `checkerboard`: `color0` where the fractional parts of `u'` and `v'` are
    /// both above ½ or both at most ½, else `color1` (`uv' = to_uv(uv)`).
    Checkerboard {
        /// Linear RGB of the squares containing `uv' ∈ [0, ½]²`.
        color0: Vec3,
        /// Linear RGB of the others.
        color1: Vec3,
        /// Applied to the texture coordinates first.
        to_uv: UvTransform,
    },
}

/// Mitsuba's luminance weights of linear RGB (`eval_1` of an RGB texture).
pub const LUMINANCE: Vec3 = Vec3::new(0.212671, 0.715160, 0.072169);

/// The texel index `i` of an axis of `n` texels, wrapped (`n ≥ 1`).
#[inline]
pub fn wrap_index(i: i64, n: u32, wrap: TextureWrap) -> u32 {
    let n = n.max(1) as i64;
    match wrap {
        TextureWrap::Repeat => i.rem_euclid(n) as u32,
        TextureWrap::Clamp => i.clamp(0, n - 1) as u32,
        TextureWrap::Mirror => {
            let m = i.rem_euclid(n);
            if i.div_euclid(n) % 2 == 0 { m as u32 } else { (n - 1 - m) as u32 }
        }
    }
}

/// `⌊x⌋` as an integer index, saturating far outside the `i64` range (and 0 for NaN), so
/// absurd texture coordinates still give a texel.
#[inline]
fn floor_index(x: f32) -> i64 {
    let f = libm::floorf(x);
    if f.is_nan() { 0 } else { f.clamp(-1e15, 1e15) as i64 }
}

impl Bitmap {
    /// Whether the sizes agree and every float texel is finite.
    pub fn is_valid(&self) -> bool {
        self.width >= 1
            && self.height >= 1
            && self.texels.len() as u64 == self.width as u64 * self.height as u64
            && self.to_uv.is_finite()
            && match &self.texels {
                Texels::Float(t) => t.iter().flatten().all(|x| x.is_finite()),
                _ => true,
            }
    }

    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let (i, j) = (wrap_index(x, self.width, self.wrap), wrap_index(y, self.height, self.wrap));
        self.texels.linear(j as usize * self.width as usize + i as usize)
    }

    /// The linear RGB value at texture coordinates `uv` (before `to_uv`).
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        let uv = self.to_uv.apply(uv);
        let (w, h) = (self.width as f32, self.height as f32);
        match self.filter {
            TextureFilter::Nearest => self.texel(floor_index(uv.x * w), floor_index(uv.y * h)),
            TextureFilter::Bilinear => {
                let (x, y) = (uv.x * w - 0.5, uv.y * h - 0.5);
                let (x0, y0) = (libm::floorf(x), libm::floorf(y));
                let (fx, fy) = (x - x0, y - y0);
                let (fx, fy) = (if fx.is_finite() { fx } else { 0.0 }, if fy.is_finite() { fy } else { 0.0 });
                let (i, j) = (floor_index(x), floor_index(y));
                let t00 = self.texel(i, j);
                let t10 = self.texel(i.saturating_add(1), j);
                let t01 = self.texel(i, j.saturating_add(1));
                let t11 = self.texel(i.saturating_add(1), j.saturating_add(1));
                (t00 * (1.0 - fx) + t10 * fx) * (1.0 - fy) + (t01 * (1.0 - fx) + t11 * fx) * fy
            }
        }
    }
}

impl Bitmap {
    /// The gradient `(∂f/∂u, ∂f/∂v)` of the single value `f` ([`Texture::eval_1`], the
    /// luminance) with respect to the texture coordinates before `to_uv`, as Mitsuba 3's
    /// `bitmap` gives it to `bumpmap`: the derivative of the bilinear interpolation inside the
    /// texel cell (scaled by the resolution and multiplied by `to_uv`'s transpose); zero for
    /// the nearest filter.
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        if self.filter == TextureFilter::Nearest {
            return Vec2::ZERO;
        }
        let t = self.to_uv.apply(uv);
        let (w, h) = (self.width as f32, self.height as f32);
        let (x, y) = (t.x * w - 0.5, t.y * h - 0.5);
        let (fx, fy) = (x - libm::floorf(x), y - libm::floorf(y));
        let (fx, fy) = (if fx.is_finite() { fx } else { 0.0 }, if fy.is_finite() { fy } else { 0.0 });
        let (i, j) = (floor_index(x), floor_index(y));
        let f = |x: i64, y: i64| self.texel(x, y).dot(LUMINANCE);
        let f00 = f(i, j);
        let f10 = f(i.saturating_add(1), j);
        let f01 = f(i, j.saturating_add(1));
        let f11 = f(i.saturating_add(1), j.saturating_add(1));
        // Partials with respect to the texel coordinates x and y.
        let dx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01);
        let dy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10);
        let [a, b] = self.to_uv.rows;
        Vec2::new(w * (a[0] * dx) + h * (b[0] * dy), w * (a[1] * dx) + h * (b[1] * dy))
    }
}

impl Texture {
    /// The linear RGB value at texture coordinates `uv`.
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Bitmap(b) => b.eval(uv),
            Texture::Checkerboard { color0, color1, to_uv } => {
                if checker_same(to_uv.apply(uv)) { *color0 } else { *color1 }
            }
        }
    }

    /// The single value at `uv` (an opacity mask's): the luminance of [`Texture::eval`] for
    /// a bitmap. For a checkerboard it is `color1`'s luminance where [`Texture::eval`] gives
    /// `color0` and the other way round: Mitsuba 3's `checkerboard` single-value lookup
    /// swaps the squares, and scenes are rendered as Mitsuba renders them.
    pub fn eval_1(&self, uv: Vec2) -> f32 {
        match self {
            Texture::Bitmap(b) => b.eval(uv).dot(LUMINANCE),
            Texture::Checkerboard { color0, color1, to_uv } => {
                if checker_same(to_uv.apply(uv)) { color1.dot(LUMINANCE) } else { color0.dot(LUMINANCE) }
            }
        }
    }

    /// The gradient of [`Texture::eval_1`] with respect to `uv` ([`Bitmap::eval_1_grad`]);
    /// zero for a checkerboard (piecewise constant; Mitsuba 3 gives it none, and the loaders
    /// refuse a checkerboard as a bump map).
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        match self {
            Texture::Bitmap(b) => b.eval_1_grad(uv),
            Texture::Checkerboard { .. } => Vec2::ZERO,
        }
    }

    /// The mean of [`Texture::eval_1`] over the texture's period: the mean luminance of a
    /// bitmap's texels, the mean of a checkerboard's two squares. What a material that
    /// cannot vary a parameter across its surface (the roughness that picks its scattering
    /// kind) reads of a texture.
    pub fn mean_1(&self) -> f32 {
        match self {
            Texture::Bitmap(b) => {
                let n = b.texels.len().max(1);
                let sum: f64 = (0..b.texels.len()).map(|i| b.texels.linear(i).dot(LUMINANCE) as f64).sum();
                (sum / n as f64) as f32
            }
            Texture::Checkerboard { color0, color1, .. } => 0.5 * (color0.dot(LUMINANCE) + color1.dot(LUMINANCE)),
        }
    }

    /// Whether the texture is well formed (sizes agree, values and transforms finite).
    pub fn is_valid(&self) -> bool {
        match self {
            Texture::Bitmap(b) => b.is_valid(),
            Texture::Checkerboard { color0, color1, to_uv } => color0.is_finite() && color1.is_finite() && to_uv.is_finite(),
        }
    }
}

/// Whether the fractional parts of `u` and `v` fall on the same side of ½ (both above or
/// both at most ½): a checkerboard's `color0` squares.
#[inline]
fn checker_same(uv: Vec2) -> bool {
    let frac = |x: f32| x - libm::floorf(x);
    (frac(uv.x) > 0.5) == (frac(uv.y) > 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec;

    fn row(values: &[f32]) -> Bitmap {
        Bitmap {
            width: values.len() as u32,
            height: 1,
            texels: Texels::Float(values.iter().map(|&v| [v; 3]).collect()),
            filter: TextureFilter::Nearest,
            wrap: TextureWrap::Repeat,
            to_uv: UvTransform::IDENTITY,
        }
    }

    /// Mitsuba 3.9's texel indices for nearest lookups at u = −0.8, −0.3, −0.1, 1.1, 1.3,
    /// 1.6 on 4 texels (measured with Mitsuba).
    #[test]
    fn wrap_modes_are_mitsubas() {
        let us = [-0.8f32, -0.3, -0.1, 1.1, 1.3, 1.6];
        let expect = [(TextureWrap::Repeat, [0u32, 2, 3, 0, 1, 2]), (TextureWrap::Mirror, [3, 1, 0, 3, 2, 1]), (TextureWrap::Clamp, [0, 0, 0, 3, 3, 3])];
        for (wrap, want) in expect {
            let got = us.map(|u| wrap_index(floor_index(u * 4.0), 4, wrap));
            assert_eq!(got, want, "{wrap:?}");
        }
    }

    /// Bilinear between texel centres, wrapping at the border: at u = 0 with repeat, the
    /// mean of the last and the first texel (as Mitsuba gives).
    #[test]
    fn bilinear_weights_and_wrap() {
        let mut b = row(&[0.1, 0.2, 0.3, 0.4]);
        b.filter = TextureFilter::Bilinear;
        let at = |b: &Bitmap, u: f32| b.eval(Vec2::new(u, 0.5)).x;
        assert!((at(&b, 0.125) - 0.1).abs() < 1e-7, "a texel centre is the texel");
        assert!((at(&b, 0.25) - 0.15).abs() < 1e-7);
        assert!((at(&b, 0.0) - 0.25).abs() < 1e-7, "{}", at(&b, 0.0));
        b.wrap = TextureWrap::Clamp;
        assert!((at(&b, 0.0) - 0.1).abs() < 1e-7);
        // A 2×2 image: the centre is the mean of all four.
        let b = Bitmap { width: 2, height: 2, texels: Texels::Float(vec![[0.0; 3], [1.0; 3], [2.0; 3], [3.0; 3]]), filter: TextureFilter::Bilinear, wrap: TextureWrap::Clamp, to_uv: UvTransform::IDENTITY };
        assert!((b.eval(Vec2::splat(0.5)).x - 1.5).abs() < 1e-6);
        // Row 0 is the top of the image: v = 0.25 reads the first row.
        assert!((b.eval(Vec2::new(0.25, 0.25)).x - 0.0).abs() < 1e-6 && (b.eval(Vec2::new(0.25, 0.75)).x - 2.0).abs() < 1e-6);
    }

    /// sRGB texels are decoded before they are interpolated (Mitsuba: halfway between bytes
    /// 20 and 60 is 0.0260908, the mean of the linear values).
    #[test]
    fn srgb_texels_decode_then_interpolate() {
        assert!((srgb_to_linear(128) - 0.2158605).abs() < 2e-7);
        assert_eq!(srgb_to_linear(0), 0.0);
        assert!((srgb_to_linear(255) - 1.0).abs() < 1e-7);
        let b = Bitmap { width: 2, height: 1, texels: Texels::Srgb8(vec![[20; 3], [60; 3]]), filter: TextureFilter::Bilinear, wrap: TextureWrap::Clamp, to_uv: UvTransform::IDENTITY };
        assert!((b.eval(Vec2::new(0.5, 0.5)).x - 0.0260908).abs() < 1e-6, "{}", b.eval(Vec2::new(0.5, 0.5)).x);
        let raw = Bitmap { texels: Texels::Linear8(vec![[128; 3], [128; 3]]), ..b };
        assert!((raw.eval(Vec2::new(0.5, 0.5)).x - 128.0 / 255.0).abs() < 1e-7);
    }

    /// Mitsuba's checkerboard: colour0 on [0, ½)², colour1 beside it; its single value swaps
    /// the squares.
    #[test]
    fn gradient_is_the_bilinear_derivative() {
        // A 3x2 bitmap under a sheared, scaled to_uv: the gradient matches central finite
        // differences of eval_1 inside a texel cell, and is zero for the nearest filter.
        let mut b = Bitmap {
            width: 3,
            height: 2,
            texels: Texels::Float(vec![[0.1, 0.2, 0.3], [0.9, 0.1, 0.0], [0.4, 0.4, 0.4], [0.0, 0.7, 0.2], [0.5, 0.5, 0.1], [0.3, 0.0, 0.9]]),
            filter: TextureFilter::Bilinear,
            wrap: TextureWrap::Repeat,
            to_uv: UvTransform { rows: [[1.5, 0.25, 0.1], [-0.3, 2.0, 0.05]] },
        };
        let t = Texture::Bitmap(b.clone());
        for uv in [Vec2::new(0.21, 0.33), Vec2::new(0.47, 0.12), Vec2::new(-0.6, 1.7)] {
            let g = t.eval_1_grad(uv);
            let e = 1e-3;
            let du = (t.eval_1(uv + Vec2::new(e, 0.0)) - t.eval_1(uv - Vec2::new(e, 0.0))) / (2.0 * e);
            let dv = (t.eval_1(uv + Vec2::new(0.0, e)) - t.eval_1(uv - Vec2::new(0.0, e))) / (2.0 * e);
            assert!((g.x - du).abs() < 2e-2 * (1.0 + du.abs()) && (g.y - dv).abs() < 2e-2 * (1.0 + dv.abs()), "{uv}: {g} vs ({du}, {dv})");
            assert!(g.length() > 0.05, "a varying bitmap has a gradient");
        }
        b.filter = TextureFilter::Nearest;
        assert_eq!(Texture::Bitmap(b).eval_1_grad(Vec2::new(0.3, 0.3)), Vec2::ZERO);
    }

    #[test]
    fn checkerboard_is_mitsubas() {
        let c = Texture::Checkerboard { color0: Vec3::splat(0.4), color1: Vec3::splat(0.2), to_uv: UvTransform::IDENTITY };
        let at = |u: f32, v: f32| c.eval(Vec2::new(u, v)).x;
        assert_eq!([at(0.25, 0.25), at(0.75, 0.25), at(0.75, 0.75), at(-0.25, 0.25)], [0.4, 0.2, 0.4, 0.2]);
        assert!((c.eval_1(Vec2::new(0.25, 0.25)) - 0.2).abs() < 1e-6);
        let scaled = Texture::Checkerboard { color0: Vec3::ONE, color1: Vec3::ZERO, to_uv: UvTransform { rows: [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]] } };
        assert_eq!(scaled.eval(Vec2::new(0.3, 0.1)).x, 0.0, "to_uv first: (0.6, 0.2) is a colour1 square");
    }

    #[test]
    fn absurd_coordinates_give_a_texel() {
        let mut b = row(&[0.5, 1.0]);
        for filter in [TextureFilter::Nearest, TextureFilter::Bilinear] {
            b.filter = filter;
            for u in [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, -1e30] {
                let v = b.eval(Vec2::new(u, 0.5));
                assert!(v.is_finite(), "{filter:?} {u}: {v}");
            }
        }
    }
}
