//! texture.wgsl's `arpa_texture_eval` and `arpa_texture_eval_1` against
//! `arpa_core::render::texture::Texture::eval` and `eval_1`, on the word table the GPU
//! backends upload (`arpa_core::gpu::texture::texture_table`): random 8-bit sRGB, 8-bit
//! raw and float bitmaps of random sizes (1 to 9 texels a side, so every wrap mode meets
//! its edges), each filter and wrap mode, identity and random `to_uv` maps (scale, shear,
//! offset), and checkerboards; random coordinates over [-3, 3]², plus absurd ones (NaN,
//! ±∞, ±1e30) for which both must give finite values.
//!
//! Bounds: texel values are the core's bit for bit (the table holds the core's decoded
//! values), so what remains is the filter's f32 arithmetic, which a device may contract
//! into fused multiply-adds: bilinear values (continuous in the coordinates, also across
//! texel and wrap boundaries) within `1e-5 (1 + max |texel|)`. Nearest lookups and
//! checkerboards are exact, except where `u'W` (or `u'` for a checkerboard square) lies
//! within `1e-4 (1 + |u'W|)` of a boundary, where the rounding of `to_uv` decides the texel:
//! those items are skipped and counted (fewer than 2 % of them).

use std::cell::Cell;

use arpa_core::glam::{Vec2, Vec3};
use arpa_core::gpu::shaders::TEXTURE;
use arpa_core::gpu::texture::texture_table;
use arpa_core::render::texture::{Bitmap, Texels, Texture, TextureFilter, TextureWrap, UvTransform};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, run_prop};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

/// Lookups per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;
/// Words per item: texture id, u, v.
const STRIDE: usize = 3;

const BODY: &str = "
    if ib < TWIN_TEXTURE_TABLE_WORDS { return; }
    let id = in_u(ib);
    let uv = vec2<f32>(in_f(ib + 1u), in_f(ib + 2u));
    out_v3(ob, arpa_texture_eval(id, uv));
    out_f(ob + 3u, arpa_texture_eval_1(id, uv));";

/// The kernel's extra declarations: texture.wgsl reading its words from the front of the
/// input buffer (`table_words` of them, a multiple of [`STRIDE`]).
fn helpers(table_words: usize) -> String {
    format!(
        "const TWIN_TEXTURE_TABLE_WORDS: u32 = {table_words}u;\nfn arpa_texture_word(i: u32) -> u32 {{ return input[i]; }}\n{}",
        TEXTURE.source
    )
}

fn to_uv() -> impl Strategy<Value = UvTransform> {
    prop_oneof![
        1 => Just(UvTransform::IDENTITY),
        2 => (prop::array::uniform6(-2.0f32..2.0)).prop_map(|a| UvTransform { rows: [[a[0] * 2.0, a[1], a[2]], [a[3], a[4] * 2.0, a[5]]] }),
    ]
}

fn filter() -> impl Strategy<Value = TextureFilter> {
    prop_oneof![Just(TextureFilter::Bilinear), Just(TextureFilter::Nearest)]
}

fn wrap() -> impl Strategy<Value = TextureWrap> {
    prop_oneof![Just(TextureWrap::Repeat), Just(TextureWrap::Mirror), Just(TextureWrap::Clamp)]
}

fn bitmap() -> impl Strategy<Value = Texture> {
    (1u32..10, 1u32..10, 0u8..3, filter(), wrap(), to_uv()).prop_flat_map(|(w, h, kind, filter, wrap, to_uv)| {
        let n = (w * h) as usize;
        let texels = match kind {
            0 => prop::collection::vec(prop::array::uniform3(any::<u8>()), n).prop_map(Texels::Srgb8).boxed(),
            1 => prop::collection::vec(prop::array::uniform3(any::<u8>()), n).prop_map(Texels::Linear8).boxed(),
            _ => prop::collection::vec(prop::array::uniform3(0.0f32..4.0), n).prop_map(Texels::Float).boxed(),
        };
        texels.prop_map(move |texels| Texture::Bitmap(Bitmap { width: w, height: h, texels, filter, wrap, to_uv }))
    })
}

fn checkerboard() -> impl Strategy<Value = Texture> {
    (prop::array::uniform3(0.0f32..1.0), prop::array::uniform3(0.0f32..1.0), to_uv())
        .prop_map(|(a, b, to_uv)| Texture::Checkerboard { color0: Vec3::from_array(a), color1: Vec3::from_array(b), to_uv })
}

fn texture() -> impl Strategy<Value = Texture> {
    prop_oneof![4 => bitmap(), 1 => checkerboard()]
}

fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        30 => -3.0f32..3.0,
        1 => prop::sample::select(vec![f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, -1e30]),
    ]
}

/// A batch: 24 textures and lookups `(texture, u, v)`.
fn batch() -> impl Strategy<Value = (Vec<Texture>, Vec<(u32, f32, f32)>)> {
    (prop::collection::vec(texture(), 24), prop::collection::vec((0u32..24, coordinate(), coordinate()), ITEMS))
}

/// Where the lookup's choice of texel or square is decided by rounding (see the module
/// docs): `None` if nowhere near a boundary.
fn near_boundary(t: &Texture, uv: Vec2) -> bool {
    let close = |x: f32| {
        let x = x as f64;
        (x - x.round()).abs() < 1e-4 * (1.0 + x.abs())
    };
    match t {
        Texture::Bitmap(b) => {
            let p = b.to_uv.apply(uv);
            b.filter == TextureFilter::Nearest && (close(p.x * b.width as f32) || close(p.y * b.height as f32))
        }
        Texture::Checkerboard { to_uv, .. } => {
            let p = to_uv.apply(uv);
            close(2.0 * p.x) || close(2.0 * p.y)
        }
    }
}

/// The largest texel magnitude of a texture (its colours for a checkerboard).
fn magnitude(t: &Texture) -> f32 {
    match t {
        Texture::Bitmap(b) => (0..b.texels.len()).map(|i| b.texels.linear(i).max_element()).fold(0.0, f32::max),
        Texture::Checkerboard { color0, color1, .. } => color0.max_element().max(color1.max_element()),
    }
}

/// Random textures and lookups within the module's bounds; absurd coordinates give finite
/// values.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let totals = Cell::new((0usize, 0usize, 0usize));
    let worst = Cell::new(0.0f64);
    proptest_batches("twin-texture", BATCHES, &batch(), |(textures, lookups)| {
        let table = texture_table(&textures, &[], None).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let mut input = table.clone();
        input.resize(table.len().div_ceil(STRIDE) * STRIDE, 0);
        let table_words = input.len();
        for &(id, u, v) in &lookups {
            input.extend([id, fb(u), fb(v)]);
        }
        let out = run_prop(runner, "texture", &helpers(table_words), BODY, &input, STRIDE, 4)?;
        let (mut compared, mut skipped, mut absurd) = totals.get();
        let mut w = worst.get();
        for (&(id, u, v), g) in lookups.iter().zip(&out[table_words / STRIDE..]) {
            let t = &textures[id as usize];
            let uv = Vec2::new(u, v);
            let got = Vec3::new(f(g[0]), f(g[1]), f(g[2]));
            let got_1 = f(g[3]);
            if !(u.is_finite() && v.is_finite() && u.abs() < 1e3 && v.abs() < 1e3) {
                prop_assert!(got.is_finite() && got_1.is_finite(), "texture {} at ({}, {}): {} / {}", id, u, v, got, got_1);
                absurd += 1;
                continue;
            }
            if near_boundary(t, uv) {
                skipped += 1;
                continue;
            }
            let (want, want_1) = (t.eval(uv), t.eval_1(uv));
            let tol = 1e-5 * (1.0 + magnitude(t) as f64);
            let err = ((got - want).abs().max_element() as f64).max((got_1 - want_1).abs() as f64);
            prop_assert!(err <= tol, "texture {} ({:?}) at ({}, {}): twin {} / {}, core {} / {} (bound {:e})", id, t, u, v, got, got_1, want, want_1, tol);
            w = w.max(err / tol);
            compared += 1;
        }
        prop_assert!(skipped * 50 < compared, "{} lookups near a boundary, {} compared", skipped, compared);
        totals.set((compared, skipped, absurd));
        worst.set(w);
        Ok(())
    })?;
    let (compared, skipped, absurd) = totals.get();
    check!(compared > 10_000 && absurd > 100, "compared {compared}, absurd {absurd}");
    Ok(format!("compared {compared} lookups (worst error / bound {:.3}), skipped {skipped} at a texel or square boundary, {absurd} absurd coordinates finite", worst.get()))
}
