// Textures on the device: the twin of arpa_core::render::texture (Mitsuba 3's bitmap and
// checkerboard: to_uv, bilinear / nearest filtering, repeat / mirror / clamp wrapping,
// 8-bit sRGB texels decoded before they are interpolated, eval_1 as luminance with the
// checkerboard's swapped squares). The texture words are laid out by
// arpa_core::gpu::texture (decode tables, one 20-word record per texture, texels: 8-bit
// ones three bytes each, so they stay 8-bit on the device). Needs math.wgsl and, from the
// file that includes it, the word table:
//   fn arpa_texture_word(i: u32) -> u32
// (path/scene.wgsl: binding 5 of group 0; the twin cases: their input buffer).
//
// Precision: texel values are the core's bit for bit (the decode tables hold the core's
// values); filtering is the core's f32 arithmetic, which a device may contract into fused
// multiply-adds, so a lookup agrees with the core to a few ulps of the texel values, and a
// texel or checkerboard square chosen by the position of u'W (u' = to_uv(uv)) can differ
// where that position lies within rounding of a texel or square boundary. Texel indices
// saturate at +-2^30 (the core: +-1e15), which only coordinates beyond 2^30 / W tell apart.

const ARPA_TEXTURE_SRGB_TABLE: u32 = 0u;
const ARPA_TEXTURE_RAW_TABLE: u32 = 256u;
const ARPA_TEXTURE_FIRST: u32 = 512u;
const ARPA_TEXTURE_RECORD_WORDS: u32 = 20u;
const ARPA_NO_TEXTURE: u32 = 0xffffffffu;
const ARPA_TEXTURE_BITMAP: u32 = 0u;
const ARPA_TEXTURE_CHECKERBOARD: u32 = 1u;
const ARPA_TEXELS_SRGB8: u32 = 0u;
const ARPA_TEXELS_LINEAR8: u32 = 1u;
const ARPA_TEXELS_FLOAT: u32 = 2u;
const ARPA_FILTER_BILINEAR: u32 = 0u;
const ARPA_FILTER_NEAREST: u32 = 1u;
const ARPA_WRAP_REPEAT: u32 = 0u;
const ARPA_WRAP_MIRROR: u32 = 1u;
const ARPA_WRAP_CLAMP: u32 = 2u;
// texture::LUMINANCE.
const ARPA_LUMINANCE: vec3<f32> = vec3<f32>(0.212671, 0.715160, 0.072169);

fn arpa_texture_f32(i: u32) -> f32 {
    return bitcast<f32>(arpa_texture_word(i));
}

fn arpa_texture_vec3(i: u32) -> vec3<f32> {
    return vec3<f32>(arpa_texture_f32(i), arpa_texture_f32(i + 1u), arpa_texture_f32(i + 2u));
}

// First word of texture `id`'s record.
fn arpa_texture_record(id: u32) -> u32 {
    return ARPA_TEXTURE_FIRST + id * ARPA_TEXTURE_RECORD_WORDS;
}

// UvTransform::apply of the record at word r.
fn arpa_texture_to_uv(r: u32, uv: vec2<f32>) -> vec2<f32> {
    let a = arpa_texture_vec3(r + 8u);
    let b = arpa_texture_vec3(r + 11u);
    return vec2<f32>(a.x * uv.x + a.y * uv.y + a.z, b.x * uv.x + b.y * uv.y + b.z);
}

// floor_index: floor(x) as an index, saturating at +-2^30, 0 for NaN.
fn arpa_texture_floor_index(x: f32) -> i32 {
    let f = floor(x);
    if (bitcast<u32>(f) & 0x7fffffffu) > 0x7f800000u {
        return 0;
    }
    return i32(clamp(f, -1073741824.0, 1073741824.0));
}

// wrap_index: texel index i of an axis of n texels, wrapped.
fn arpa_texture_wrap(i: i32, n: u32, wrap: u32) -> u32 {
    let m = i32(max(n, 1u));
    let r = ((i % m) + m) % m;
    if wrap == ARPA_WRAP_CLAMP {
        return u32(clamp(i, 0, m - 1));
    }
    if wrap == ARPA_WRAP_MIRROR {
        let period = (i - r) / m;
        if (period & 1) != 0 {
            return u32(m - 1 - r);
        }
    }
    return u32(r);
}

// The linear value of texel (x, y) of the bitmap record r, wrapped.
fn arpa_texture_texel(r: u32, x: i32, y: i32) -> vec3<f32> {
    let width = arpa_texture_word(r + 1u);
    let wrap = arpa_texture_word(r + 5u);
    let i = arpa_texture_wrap(x, width, wrap);
    let j = arpa_texture_wrap(y, arpa_texture_word(r + 2u), wrap);
    let k = j * width + i;
    let first = arpa_texture_word(r + 6u);
    let encoding = arpa_texture_word(r + 3u);
    if encoding == ARPA_TEXELS_FLOAT {
        return arpa_texture_vec3(first + 3u * k);
    }
    // Texel k's bytes r g b start at byte 3k of the texels (packed little-endian).
    let byte = 3u * k;
    let w = first + byte / 4u;
    let sh = (byte % 4u) * 8u;
    var p = arpa_texture_word(w) >> sh;
    if sh > 8u {
        p = p | (arpa_texture_word(w + 1u) << (32u - sh));
    }
    let c = vec3<u32>(p & 0xffu, (p >> 8u) & 0xffu, (p >> 16u) & 0xffu);
    var table = ARPA_TEXTURE_SRGB_TABLE;
    if encoding == ARPA_TEXELS_LINEAR8 {
        table = ARPA_TEXTURE_RAW_TABLE;
    }
    return vec3<f32>(arpa_texture_f32(table + c.x), arpa_texture_f32(table + c.y), arpa_texture_f32(table + c.z));
}

// Bitmap::eval after to_uv, at uv' (record r).
fn arpa_texture_bitmap(r: u32, uv: vec2<f32>) -> vec3<f32> {
    return arpa_texture_bitmap_lookup(r, uv).value;
}

// checker_same: the fractional parts of u and v on the same side of 1/2.
fn arpa_texture_checker_same(uv: vec2<f32>) -> bool {
    let f = uv - floor(uv);
    return (f.x > 0.5) == (f.y > 0.5);
}

// Texture::eval: the linear RGB value of texture `id` at texture coordinates uv.
fn arpa_texture_eval(id: u32, uv: vec2<f32>) -> vec3<f32> {
    let r = arpa_texture_record(id);
    let t = arpa_texture_to_uv(r, uv);
    if arpa_texture_word(r) == ARPA_TEXTURE_CHECKERBOARD {
        if arpa_texture_checker_same(t) {
            return arpa_texture_vec3(r + 14u);
        }
        return arpa_texture_vec3(r + 17u);
    }
    return arpa_texture_bitmap(r, t);
}

// Texture::eval_1: the single value (luminance; a checkerboard's squares swapped).
fn arpa_texture_eval_1(id: u32, uv: vec2<f32>) -> f32 {
    let r = arpa_texture_record(id);
    let t = arpa_texture_to_uv(r, uv);
    if arpa_texture_word(r) == ARPA_TEXTURE_CHECKERBOARD {
        if arpa_texture_checker_same(t) {
            return dot(arpa_texture_vec3(r + 17u), ARPA_LUMINANCE);
        }
        return dot(arpa_texture_vec3(r + 14u), ARPA_LUMINANCE);
    }
    return dot(arpa_texture_bitmap(r, t), ARPA_LUMINANCE);
}

// arpa_core::render::scene::EmitterTexture::factor from its record at word r
// (arpa_core::gpu::texture::emitter_record: texture id, u0 v0 u1 v1 u2 v2, 1/mean): the
// texture at barycentric weights (b1, b2) of the emitter triangle, non-negative, over its
// mean over the triangle (per channel).
fn arpa_emitter_texture_factor(r: u32, b1: f32, b2: f32) -> vec3<f32> {
    let uv0 = vec2<f32>(arpa_texture_f32(r + 1u), arpa_texture_f32(r + 2u));
    let uv1 = vec2<f32>(arpa_texture_f32(r + 3u), arpa_texture_f32(r + 4u));
    let uv2 = vec2<f32>(arpa_texture_f32(r + 5u), arpa_texture_f32(r + 6u));
    let uv = uv0 * (1.0 - b1 - b2) + uv1 * b1 + uv2 * b2;
    return max(arpa_texture_eval(arpa_texture_word(r), uv), vec3<f32>(0.0)) * arpa_texture_vec3(r + 7u);
}

// A texture's value and its single value's gradient at uv, from one set of texel reads.
struct ArpaTextureLookup {
    // Texture::eval.
    value: vec3<f32>,
    // Texture::eval_1_grad: the gradient of the single value with respect to uv (before
    // to_uv): the bilinear interpolation's derivative inside the texel cell, scaled by the
    // resolution and multiplied by to_uv's transpose; zero for the nearest filter and a
    // checkerboard.
    grad: vec2<f32>,
}

fn arpa_texture_eval_and_grad(id: u32, uv: vec2<f32>) -> ArpaTextureLookup {
    let r = arpa_texture_record(id);
    let t = arpa_texture_to_uv(r, uv);
    if arpa_texture_word(r) == ARPA_TEXTURE_CHECKERBOARD {
        var out: ArpaTextureLookup;
        out.value = select(arpa_texture_vec3(r + 17u), arpa_texture_vec3(r + 14u), arpa_texture_checker_same(t));
        out.grad = vec2<f32>(0.0);
        return out;
    }
    return arpa_texture_bitmap_lookup(r, t);
}

// Bitmap::eval and its single value's gradient after to_uv, at uv' (record r): the one
// bilinear (or nearest) fetch every bitmap lookup goes through.
fn arpa_texture_bitmap_lookup(r: u32, uv: vec2<f32>) -> ArpaTextureLookup {
    var out: ArpaTextureLookup;
    out.grad = vec2<f32>(0.0);
    let w = f32(arpa_texture_word(r + 1u));
    let h = f32(arpa_texture_word(r + 2u));
    if arpa_texture_word(r + 4u) == ARPA_FILTER_NEAREST {
        out.value = arpa_texture_texel(r, arpa_texture_floor_index(uv.x * w), arpa_texture_floor_index(uv.y * h));
        return out;
    }
    let x = uv.x * w - 0.5;
    let y = uv.y * h - 0.5;
    var fx = x - floor(x);
    var fy = y - floor(y);
    if !arpa_finite(fx) {
        fx = 0.0;
    }
    if !arpa_finite(fy) {
        fy = 0.0;
    }
    let i = arpa_texture_floor_index(x);
    let j = arpa_texture_floor_index(y);
    let t00 = arpa_texture_texel(r, i, j);
    let t10 = arpa_texture_texel(r, i + 1, j);
    let t01 = arpa_texture_texel(r, i, j + 1);
    let t11 = arpa_texture_texel(r, i + 1, j + 1);
    out.value = (t00 * (1.0 - fx) + t10 * fx) * (1.0 - fy) + (t01 * (1.0 - fx) + t11 * fx) * fy;
    let f00 = dot(t00, ARPA_LUMINANCE);
    let f10 = dot(t10, ARPA_LUMINANCE);
    let f01 = dot(t01, ARPA_LUMINANCE);
    let f11 = dot(t11, ARPA_LUMINANCE);
    let dx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01);
    let dy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10);
    let a = arpa_texture_vec3(r + 8u);
    let b = arpa_texture_vec3(r + 11u);
    out.grad = vec2<f32>(w * (a.x * dx) + h * (b.x * dy), w * (a.y * dx) + h * (b.y * dy));
    return out;
}

