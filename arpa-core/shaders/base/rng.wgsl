// WGSL twin of arpa_core::base::rng: the pcg4d hash (Jarzynski & Olano, JCGT 2020) and the
// counter-based streams built on it. u32 arithmetic only (WGSL u32 + and * wrap), so every
// word is bit-identical to the Rust `pcg4d`, `Rng::next_u32` and `Rng::next_f32`.
// Self-contained: no other shader file is needed.

// Draws a stream can make before its counter runs into the domain bits (2^28).
const ARPA_DRAWS_PER_STREAM: u32 = 0x10000000u;
// StreamDomain values (top four bits of the counter word).
const ARPA_DOMAIN_PHOTON: u32 = 0u;
const ARPA_DOMAIN_CAMERA: u32 = 1u;
const ARPA_DOMAIN_ITERATION: u32 = 2u;
const ARPA_DOMAIN_USER: u32 = 3u;

// The pcg4d hash: four 32-bit words to four well-mixed 32-bit words.
fn arpa_pcg4d(v_in: vec4<u32>) -> vec4<u32> {
    var v = v_in * 1664525u + vec4<u32>(1013904223u);
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v = v ^ (v >> vec4<u32>(16u));
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

// A stream (seed, iteration, index, domain) and the number of draws made so far.
struct ArpaRng {
    seed: u32,
    iteration: u32,
    index: u32,
    // Domain already shifted into the top four bits.
    domain_bits: u32,
    counter: u32,
}

// The stream for (seed, iteration, index) in `domain` (ARPA_DOMAIN_*), at its first draw.
fn arpa_rng_new(seed: u32, iteration: u32, index: u32, domain: u32) -> ArpaRng {
    return ArpaRng(seed, iteration, index, domain << 28u, 0u);
}

// Next uniformly distributed 32-bit word (Rng::next_u32).
fn arpa_rng_next_u32(rng: ptr<function, ArpaRng>) -> u32 {
    let word = (*rng).domain_bits | ((*rng).counter & (ARPA_DRAWS_PER_STREAM - 1u));
    (*rng).counter += 1u;
    return arpa_pcg4d(vec4<u32>((*rng).seed, (*rng).iteration, (*rng).index, word)).x;
}

// Uniform f32 in [0, 1) with 24 random bits (Rng::next_f32, bit-identical: the product is
// exact). It is also the f32 twin of Rng::next_f64: the same draw truncated to 24 bits, so
// 0 <= next_f64 - next_f32 < 2^-24. (Converting the full word to f32 would round 2^32 - 1 up
// to 1.0.)
fn arpa_rng_next_f32(rng: ptr<function, ArpaRng>) -> f32 {
    return f32(arpa_rng_next_u32(rng) >> 8u) * (1.0 / 16777216.0);
}

// Two successive draws as a point of the unit square (Rng::next_2d, each truncated as above).
fn arpa_rng_next_2d(rng: ptr<function, ArpaRng>) -> vec2<f32> {
    let x = arpa_rng_next_f32(rng);
    let y = arpa_rng_next_f32(rng);
    return vec2<f32>(x, y);
}

// `rng.next_f64() < p` of the core (Rng::next_f64 = word / 2^32, exact in f64), bit-exact
// for an f32 probability p: word / 2^32 < p <=> word < ceil(p 2^32) for p in (0, 1) (p 2^32
// is exact in f32). Always consumes one draw, as the core does; p >= 1 is always true, p <= 0
// or NaN never. The decisions it takes (Fresnel choice, Russian roulette) differ from the
// core's only where the f32 p differs from the core's f64 p.
fn arpa_rng_next_below(rng: ptr<function, ArpaRng>, p: f32) -> bool {
    let w = arpa_rng_next_u32(rng);
    if p >= 1.0 {
        return true;
    }
    if !(p > 0.0) {
        return false;
    }
    return w < u32(ceil(p * 4294967296.0));
}

// The core's `rng.next_f64() as f32` (word / 2^32 rounded to the nearest f32, ties to even;
// may round up to 1.0), in integer arithmetic so that no conversion rounding mode is assumed.
fn arpa_rng_next_f64_as_f32(rng: ptr<function, ArpaRng>) -> f32 {
    let word = arpa_rng_next_u32(rng);
    if word < 0x01000000u {
        return f32(word) * 2.3283064365386963e-10;
    }
    let drop = 8u - countLeadingZeros(word);
    var m = word >> drop;
    let rem = word & ((1u << drop) - 1u);
    let half = 1u << (drop - 1u);
    if rem > half || (rem == half && (m & 1u) == 1u) {
        m += 1u;
    }
    return ldexp(f32(m), i32(drop) - 32);
}
