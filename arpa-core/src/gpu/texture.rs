//! A scene's textures as the device reads them: one `u32` word table
//! (`arpa_scene_texture_words`, binding 5 of group 0) that `path/texture.wgsl` (the twin
//! of [`crate::render::texture`]) and `path/scene.wgsl` read through
//! `arpa_texture_word(i)`:
//!
//! | words | what |
//! |---|---|
//! | `0..256` | the linear value of each 8-bit sRGB code ([`srgb_to_linear`], `f32` bits) |
//! | `256..512` | the linear value `c/255` of each 8-bit `raw` code |
//! | [`TEXTURE_FIRST`]`..` | one [`TEXTURE_RECORD_WORDS`]-word record per texture, by [`TextureId`] |
//! | then | one [`EMITTER_RECORD_WORDS`]-word record per textured emitter triangle ([`EmitterTexture`]), in the core's emitter order ([`emitter_records`]) |
//! | then | with an environment map, its [`ENVIRONMENT_RECORD_WORDS`]-word record ([`emitter_records`] gives it for the environment emitter) |
//! | then | the texels of every bitmap: 8-bit texels three bytes each (`r g b`, packed little-endian four bytes a word, then a padding word), so they stay 8-bit on the device; float texels three `f32` words each |
//! | then | with an environment map, its texels (three `f32` each) and sampling tables (`f32`: the row CDF, the per-row patch CDFs, the patch densities; [`crate::render::environment::MapView`]) |
//! | then | per mesh with texture coordinates, six `f32` words per triangle (`u0 v0 u1 v1 u2 v2`, the core's triangle order), from [`SceneMesh::uv_first`](crate::gpu::layout::SceneMesh::uv_first) |
//!
//! A texture record: `kind` ([`TEXTURE_BITMAP`] / [`TEXTURE_CHECKERBOARD`]), `width`,
//! `height`, `encoding` ([`TEXELS_SRGB8`] / [`TEXELS_LINEAR8`] / [`TEXELS_FLOAT`]), `filter`
//! ([`FILTER_BILINEAR`] / [`FILTER_NEAREST`]), `wrap` ([`WRAP_REPEAT`] / [`WRAP_MIRROR`] /
//! [`WRAP_CLAMP`]), the word index of its first texel, one padding word, the six `f32` of
//! `to_uv` (row-major `[A | t]`), then a checkerboard's `color0` and `color1` (linear RGB).
//! An emitter record: the texture id, the triangle's three texture coordinates (six `f32`),
//! `1/mean` (three `f32`). The environment record: `width`, `height`, the first words of
//! its texels, row CDF, patch CDFs and densities, `to_world` and its inverse (nine `f32`
//! each, column-major), the light's `mean` (three `f32`).
//! The 8-bit decode tables make the device's texel values those of the core bit for bit.

use alloc::vec::Vec;

use crate::render::environment::MapView;
use crate::render::prepared_scene::PreparedScene;
use crate::render::scene::{EmitterTexture, Scene, TriangleMesh};
use crate::render::texture::{srgb_to_linear, Texels, Texture, TextureFilter, TextureId, TextureWrap, UvTransform};

/// `ARPA_TEXTURE_SRGB_TABLE` of `texture.wgsl`: first word of the sRGB decode table.
pub const SRGB_TABLE: u32 = 0;
/// `ARPA_TEXTURE_RAW_TABLE`: first word of the `c/255` table.
pub const RAW_TABLE: u32 = 256;
/// `ARPA_TEXTURE_FIRST`: first word of texture record 0.
pub const TEXTURE_FIRST: u32 = 512;
/// `ARPA_TEXTURE_RECORD_WORDS`: words per texture record.
pub const TEXTURE_RECORD_WORDS: u32 = 20;
/// `ARPA_EMITTER_RECORD_WORDS`: words per textured-emitter record.
pub const EMITTER_RECORD_WORDS: u32 = 10;
/// `ARPA_ENVIRONMENT_RECORD_WORDS`: words of the environment map's record.
pub const ENVIRONMENT_RECORD_WORDS: u32 = 27;
/// `ARPA_NO_TEXTURE`: no texture (a material parameter without one; a mesh without
/// texture coordinates).
pub const NO_TEXTURE: u32 = u32::MAX;

/// `ARPA_TEXTURE_BITMAP`: [`Texture::Bitmap`].
pub const TEXTURE_BITMAP: u32 = 0;
/// `ARPA_TEXTURE_CHECKERBOARD`: [`Texture::Checkerboard`].
pub const TEXTURE_CHECKERBOARD: u32 = 1;
/// `ARPA_TEXELS_SRGB8`: [`Texels::Srgb8`].
pub const TEXELS_SRGB8: u32 = 0;
/// `ARPA_TEXELS_LINEAR8`: [`Texels::Linear8`].
pub const TEXELS_LINEAR8: u32 = 1;
/// `ARPA_TEXELS_FLOAT`: [`Texels::Float`].
pub const TEXELS_FLOAT: u32 = 2;
/// `ARPA_FILTER_BILINEAR`: [`TextureFilter::Bilinear`].
pub const FILTER_BILINEAR: u32 = 0;
/// `ARPA_FILTER_NEAREST`: [`TextureFilter::Nearest`].
pub const FILTER_NEAREST: u32 = 1;
/// `ARPA_WRAP_REPEAT`: [`TextureWrap::Repeat`].
pub const WRAP_REPEAT: u32 = 0;
/// `ARPA_WRAP_MIRROR`: [`TextureWrap::Mirror`].
pub const WRAP_MIRROR: u32 = 1;
/// `ARPA_WRAP_CLAMP`: [`TextureWrap::Clamp`].
pub const WRAP_CLAMP: u32 = 2;

/// The word table outgrows `u32` word indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the scene's textures and texture coordinates need more than 2^32 - 1 words")]
pub struct TooManyTexels;

/// The word table of a scene's textures and texture coordinates (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureWords {
    /// The table.
    pub words: Vec<u32>,
    /// Per mesh, the word of its first triangle's texture coordinates, or [`NO_TEXTURE`].
    pub uv_first: Vec<u32>,
}

fn index(len: usize) -> Result<u32, TooManyTexels> {
    u32::try_from(len).ok().filter(|&i| i != NO_TEXTURE).ok_or(TooManyTexels)
}

fn push_f32s(words: &mut Vec<u32>, values: &[f32]) {
    words.extend(values.iter().map(|x| x.to_bits()));
}

fn to_uv_words(t: &UvTransform) -> [f32; 6] {
    let [a, b] = t.rows;
    [a[0], a[1], a[2], b[0], b[1], b[2]]
}

/// A texture's record, its texels starting at word `first_texel`.
pub fn texture_record(texture: &Texture, first_texel: u32) -> [u32; TEXTURE_RECORD_WORDS as usize] {
    let mut r = [0u32; TEXTURE_RECORD_WORDS as usize];
    let put_f32s = |r: &mut [u32], at: usize, values: &[f32]| {
        for (w, x) in r[at..].iter_mut().zip(values) {
            *w = x.to_bits();
        }
    };
    match texture {
        Texture::Bitmap(b) => {
            r[0] = TEXTURE_BITMAP;
            r[1] = b.width;
            r[2] = b.height;
            r[3] = match b.texels {
                Texels::Srgb8(_) => TEXELS_SRGB8,
                Texels::Linear8(_) => TEXELS_LINEAR8,
                Texels::Float(_) => TEXELS_FLOAT,
            };
            r[4] = match b.filter {
                TextureFilter::Bilinear => FILTER_BILINEAR,
                TextureFilter::Nearest => FILTER_NEAREST,
            };
            r[5] = match b.wrap {
                TextureWrap::Repeat => WRAP_REPEAT,
                TextureWrap::Mirror => WRAP_MIRROR,
                TextureWrap::Clamp => WRAP_CLAMP,
            };
            r[6] = first_texel;
            put_f32s(&mut r, 8, &to_uv_words(&b.to_uv));
        }
        Texture::Checkerboard { color0, color1, to_uv } => {
            r[0] = TEXTURE_CHECKERBOARD;
            put_f32s(&mut r, 8, &to_uv_words(to_uv));
            put_f32s(&mut r, 14, &color0.to_array());
            put_f32s(&mut r, 17, &color1.to_array());
        }
    }
    r
}

/// Appends a bitmap's texels as the module docs lay them out: 8-bit texels as their bytes
/// `r g b r g b …` packed little-endian into words, plus one word of padding (a texel's three
/// bytes may straddle two words, and the device reads both).
fn push_texels(words: &mut Vec<u32>, texels: &Texels) {
    match texels {
        Texels::Srgb8(t) | Texels::Linear8(t) => {
            let bytes: Vec<u8> = t.iter().flatten().copied().collect();
            words.extend(bytes.chunks(4).map(|c| c.iter().enumerate().fold(0u32, |w, (i, &b)| w | (b as u32) << (8 * i))));
            words.push(0);
        }
        Texels::Float(t) => words.extend(t.iter().flatten().map(|x| x.to_bits())),
    }
}

/// Per emitter of `scene` (the core's order), the word of its record in the table of
/// [`TextureWords::new`], or [`NO_TEXTURE`] for an emitter without an emission texture.
pub fn emitter_records(scene: &PreparedScene) -> Vec<u32> {
    let first = TEXTURE_FIRST as usize + scene.scene().textures.textures.len() * TEXTURE_RECORD_WORDS as usize;
    let textured = (0..scene.emitters().len()).filter(|&i| scene.emitter_texture(i).is_some()).count();
    let environment = scene.environment().filter(|e| e.map_view().is_some()).map(|e| e.emitter);
    let mut k = 0usize;
    (0..scene.emitters().len())
        .map(|i| match scene.emitter_texture(i) {
            Some(_) => {
                let w = first + k * EMITTER_RECORD_WORDS as usize;
                k += 1;
                u32::try_from(w).unwrap_or(NO_TEXTURE)
            }
            None if environment == Some(i) => u32::try_from(first + textured * EMITTER_RECORD_WORDS as usize).unwrap_or(NO_TEXTURE),
            None => NO_TEXTURE,
        })
        .collect()
}

/// An emitter record (see the module docs).
pub fn emitter_record(t: &EmitterTexture) -> [u32; EMITTER_RECORD_WORDS as usize] {
    let [a, b, c] = t.uvs;
    let f = [a.x, a.y, b.x, b.y, c.x, c.y, t.inv_mean.x, t.inv_mean.y, t.inv_mean.z];
    let mut r = [t.texture; EMITTER_RECORD_WORDS as usize];
    for (w, x) in r[1..].iter_mut().zip(f) {
        *w = x.to_bits();
    }
    r
}

/// The decode tables, the textures' records, the `emitters`' records and the textures'
/// texels, without texture coordinates: the table [`TextureWords::new`] starts with
/// (texture `id`'s record at `TEXTURE_FIRST + id · TEXTURE_RECORD_WORDS`, then the emitter
/// records in order).
pub fn texture_table(textures: &[Texture], emitters: &[EmitterTexture], environment: Option<(MapView<'_>, glam::DVec3)>) -> Result<Vec<u32>, TooManyTexels> {
    let mut words: Vec<u32> = Vec::new();
    words.extend((0..=255u8).map(|c| srgb_to_linear(c).to_bits()));
    words.extend((0..=255u8).map(|c| (c as f32 / 255.0).to_bits()));
    let records_end = (TEXTURE_FIRST as usize).saturating_add(textures.len().saturating_mul(TEXTURE_RECORD_WORDS as usize));
    words.resize(index(records_end)? as usize, 0);
    for e in emitters {
        words.extend(emitter_record(e));
    }
    let environment_at = words.len();
    if environment.is_some() {
        words.resize(environment_at + ENVIRONMENT_RECORD_WORDS as usize, 0);
    }
    for (id, t) in textures.iter().enumerate() {
        let first = index(words.len())?;
        if let Texture::Bitmap(b) = t {
            push_texels(&mut words, &b.texels);
        }
        let at = TEXTURE_FIRST as usize + id * TEXTURE_RECORD_WORDS as usize;
        words[at..at + TEXTURE_RECORD_WORDS as usize].copy_from_slice(&texture_record(t, first));
    }
    if let Some((map, mean)) = environment {
        let mut record = [0u32; ENVIRONMENT_RECORD_WORDS as usize];
        record[0] = map.width;
        record[1] = map.height;
        record[2] = index(words.len())?;
        words.extend(map.texels.iter().flat_map(|t| t.to_array()).map(f32::to_bits));
        for (k, table) in [map.rows, map.columns, map.density].into_iter().enumerate() {
            record[3 + k] = index(words.len())?;
            words.extend(table.iter().map(|&x| (x as f32).to_bits()));
        }
        let mats = [map.to_world, map.from_world].map(|m| m.to_cols_array().map(|x| (x as f32).to_bits()));
        record[6..15].copy_from_slice(&mats[0]);
        record[15..24].copy_from_slice(&mats[1]);
        record[24..27].copy_from_slice(&mean.to_array().map(|x| (x as f32).to_bits()));
        words[environment_at..environment_at + ENVIRONMENT_RECORD_WORDS as usize].copy_from_slice(&record);
    }
    index(words.len())?;
    Ok(words)
}

impl TextureWords {
    /// The table of `prepared`: its textures and textured emitters, then the texture
    /// coordinates of every mesh that has them and reads a texture (colour, opacity, normal
    /// or bump map, blend, emission); other meshes get
    /// [`NO_TEXTURE`] (the device then uses the hit's `(b1, b2)`, as the core does without
    /// coordinates, which no lookup of theirs reads).
    pub fn new(prepared: &PreparedScene) -> Result<Self, TooManyTexels> {
        let scene: &Scene = prepared.scene();
        let emitters: Vec<EmitterTexture> = (0..prepared.emitters().len()).filter_map(|i| prepared.emitter_texture(i).copied()).collect();
        let environment = prepared.environment().and_then(|e| e.map_view().map(|m| (m, e.light.mean)));
        let mut words = texture_table(&scene.textures.textures, &emitters, environment)?;
        let mut uv_first = Vec::with_capacity(scene.meshes.len());
        for (mi, m) in scene.meshes.iter().enumerate() {
            let maps = scene.textures.maps(m.material);
            let reads = maps.color.is_some()
                || matches!(maps.opacity, Some(crate::render::scene::Opacity::Texture(_)))
                || maps.normal.is_some()
                || maps.blend.is_some()
                || scene.textures.emission_of(mi).is_some();
            match (&m.uvs, reads) {
                (Some(_), true) => {
                    uv_first.push(index(words.len())?);
                    push_mesh_uvs(&mut words, m);
                    index(words.len())?;
                }
                _ => uv_first.push(NO_TEXTURE),
            }
        }
        Ok(Self { words, uv_first })
    }

    /// The record of texture `id` (its [`TEXTURE_RECORD_WORDS`] words).
    pub fn record(&self, id: TextureId) -> &[u32] {
        let at = TEXTURE_FIRST as usize + id as usize * TEXTURE_RECORD_WORDS as usize;
        &self.words[at..at + TEXTURE_RECORD_WORDS as usize]
    }
}

/// Appends a mesh's per-triangle texture coordinates (`u0 v0 u1 v1 u2 v2`); indices are
/// validated with the mesh, an out-of-range one reads `(0, 0)`.
fn push_mesh_uvs(words: &mut Vec<u32>, m: &TriangleMesh) {
    let Some(uvs) = &m.uvs else { return };
    for t in &m.indices {
        for i in t {
            let uv = uvs.get(*i as usize).copied().unwrap_or_default();
            push_f32s(words, &[uv.x, uv.y]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::texture::{Bitmap, UvTransform};
    use alloc::vec;
    use glam::Vec3;

    #[test]
    fn table_layout() {
        let bitmap = Texture::Bitmap(Bitmap {
            width: 2,
            height: 1,
            texels: Texels::Srgb8(vec![[1, 2, 3], [255, 128, 0]]),
            filter: TextureFilter::Nearest,
            wrap: TextureWrap::Mirror,
            to_uv: UvTransform { rows: [[2.0, 0.0, 0.5], [0.0, 3.0, 0.25]] },
        });
        let float = Texture::Bitmap(Bitmap {
            width: 1,
            height: 1,
            texels: Texels::Float(vec![[0.5, 1.5, 2.5]]),
            filter: TextureFilter::Bilinear,
            wrap: TextureWrap::Clamp,
            to_uv: UvTransform::IDENTITY,
        });
        let checker = Texture::Checkerboard { color0: Vec3::new(0.1, 0.2, 0.3), color1: Vec3::splat(0.9), to_uv: UvTransform::IDENTITY };
        let words = texture_table(&[bitmap, checker, float], &[], None).unwrap();
        assert_eq!(f32::from_bits(words[128]), srgb_to_linear(128));
        assert_eq!(f32::from_bits(words[256 + 51]), 51.0 / 255.0);
        let texels = TEXTURE_FIRST + 3 * TEXTURE_RECORD_WORDS;
        let r0 = &words[TEXTURE_FIRST as usize..][..20];
        assert_eq!(&r0[..7], &[TEXTURE_BITMAP, 2, 1, TEXELS_SRGB8, FILTER_NEAREST, WRAP_MIRROR, texels]);
        assert_eq!(f32::from_bits(r0[10]), 0.5);
        // The six bytes 1 2 3 255 128 0, little-endian, then a padding word.
        assert_eq!(words[texels as usize..][..3], [1 | 2 << 8 | 3 << 16 | 255 << 24, 128, 0]);
        let r1 = &words[(TEXTURE_FIRST + TEXTURE_RECORD_WORDS) as usize..][..20];
        assert_eq!(r1[0], TEXTURE_CHECKERBOARD);
        assert_eq!(f32::from_bits(r1[15]), 0.2);
        let r2 = &words[(TEXTURE_FIRST + 2 * TEXTURE_RECORD_WORDS) as usize..][..20];
        assert_eq!(r2[6], texels + 3, "the float bitmap's texels follow the first bitmap's three words");
        assert_eq!(words[r2[6] as usize + 1], 1.5f32.to_bits());
        assert_eq!(words.len() as u32, texels + 3 + 3);
    }
}
