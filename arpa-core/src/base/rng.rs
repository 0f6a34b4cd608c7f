//! Counter-based random numbers shared bit-for-bit with the GPU shaders.
//!
//! The generator is the `pcg4d` hash of Jarzynski & Olano, "Hash Functions for GPU
//! Rendering" (JCGT 2020). It uses only wrapping `u32` multiply, add, xor and shift, so a
//! WGSL copy reproduces it exactly. A stream is identified by `(seed, iteration, index)`
//! (index = photon or pixel number) plus a [`StreamDomain`], and every draw hashes the
//! four words `(seed, iteration, index, domain << 28 | counter)`. Streams are therefore
//! independent of the order in which threads run, which makes rendering deterministic for
//! a given seed regardless of thread count.

/// The pcg4d hash: maps four 32-bit words to four well-mixed 32-bit words.
#[inline]
pub const fn pcg4d(v: [u32; 4]) -> [u32; 4] {
    pcg4d_rounds([lcg(v[0]), lcg(v[1]), lcg(v[2]), lcg(v[3])])
}

/// pcg4d's first step on one word: `v · 1664525 + 1013904223` (mod 2³²).
#[inline]
const fn lcg(v: u32) -> u32 {
    v.wrapping_mul(1_664_525).wrapping_add(1_013_904_223)
}

/// The rest of [`pcg4d`], after [`lcg`] of each word.
#[inline]
const fn pcg4d_rounds(v: [u32; 4]) -> [u32; 4] {
    let [mut x, mut y, mut z, mut w] = v;
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    w ^= w >> 16;
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    [x, y, z, w]
}

/// Which part of the renderer a stream belongs to; keeps photon and camera streams with the
/// same index apart. Occupies the top four bits of the counter word.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum StreamDomain {
    /// Photon emission and propagation (index = photon number within the iteration).
    Photon = 0,
    /// Camera paths (index = pixel number).
    Camera = 1,
    /// Per-iteration global values such as lattice shifts (index chosen by the caller).
    Iteration = 2,
    /// Free for users linking the core into their own renderer.
    User = 3,
}

/// Number of draws a stream can make before its counter wraps into the next domain's bits.
pub const DRAWS_PER_STREAM: u32 = 1 << 28;

/// A counter-based random stream. Cheap to create; `Copy` so a stream can be forked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rng {
    /// [`lcg`] of `(seed, iteration, index)`: the part of every draw's hash that does not
    /// change along the stream, computed once.
    stream: [u32; 3],
    domain: u32,
    counter: u32,
}

impl Rng {
    /// The stream for `(seed, iteration, index)` in `domain`, positioned at its first draw.
    #[inline]
    pub const fn new(seed: u32, iteration: u32, index: u32, domain: StreamDomain) -> Self {
        Self { stream: [lcg(seed), lcg(iteration), lcg(index)], domain: (domain as u32) << 28, counter: 0 }
    }

    /// Number of draws made so far.
    #[inline]
    pub const fn counter(&self) -> u32 {
        self.counter
    }

    /// Next uniformly distributed 32-bit word.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let word = self.domain | (self.counter & (DRAWS_PER_STREAM - 1));
        self.counter = self.counter.wrapping_add(1);
        let [x, y, z] = self.stream;
        pcg4d_rounds([x, y, z, lcg(word)])[0]
    }

    /// Uniform `f32` in `[0, 1)` with 24 random bits (exactly representable, never 1.0).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform `f64` in `[0, 1)` built from one 32-bit draw (`u32 / 2^32`). The GPU twin
    /// computes the same value in f32 up to rounding.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        self.next_u32() as f64 * (1.0 / 4_294_967_296.0)
    }

    /// Two successive [`Rng::next_f64`] draws as a point of the unit square.
    #[inline]
    pub fn next_2d(&mut self) -> glam::DVec2 {
        let x = self.next_f64();
        let y = self.next_f64();
        glam::DVec2::new(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known-answer vectors. A shader port must reproduce these exactly. They were computed
    /// by an independent Python transcription of the published pcg4d algorithm (arbitrary
    /// precision integers masked to 32 bits), not by this code.
    #[test]
    fn pcg4d_known_answers() {
        assert_eq!(pcg4d([0, 0, 0, 0]), KAT_PCG4D_ZERO);
        assert_eq!(pcg4d([1, 2, 3, 4]), KAT_PCG4D_1234);
    }

    const KAT_PCG4D_ZERO: [u32; 4] = [251_852_841, 760_645_481, 850_445_371, 3_542_436_074];
    const KAT_PCG4D_1234: [u32; 4] = [908_250_390, 4_044_648_920, 3_775_961_919, 45_698_095];

    #[test]
    fn first_outputs_known_answers() {
        for (seed, iteration, index, domain, expected) in KAT_STREAMS {
            let mut rng = Rng::new(*seed, *iteration, *index, *domain);
            let got: [u32; 4] = core::array::from_fn(|_| rng.next_u32());
            assert_eq!(&got, expected, "stream (seed {seed}, iteration {iteration}, index {index})");
        }
    }

    /// First four `next_u32` outputs of several streams.
    pub(crate) const KAT_STREAMS: &[(u32, u32, u32, StreamDomain, [u32; 4])] = &[
        (0, 0, 0, StreamDomain::Photon, [251_852_841, 2_376_007_650, 3_430_664_116, 2_668_274_553]),
        (1, 0, 0, StreamDomain::Photon, [188_542_915, 2_272_300_281, 1_105_341_687, 46_345_155]),
        (42, 7, 12_345, StreamDomain::Photon, [1_092_573_700, 1_028_676_220, 2_986_982_013, 957_826_947]),
        (0xDEAD_BEEF, 100_000, 4_000_000, StreamDomain::Photon, [2_487_117_684, 3_400_892_403, 3_027_552_238, 2_997_347_576]),
        (1, 0, 0, StreamDomain::Camera, [1_262_677_955, 1_481_313_529, 1_287_101_687, 2_947_746_755]),
    ];

    #[test]
    fn floats_in_unit_interval() {
        let mut rng = Rng::new(7, 1, 2, StreamDomain::Camera);
        for _ in 0..100_000 {
            let a = rng.next_f32();
            let b = rng.next_f64();
            assert!((0.0..1.0).contains(&a));
            assert!((0.0..1.0).contains(&b));
        }
    }

    #[test]
    fn domains_and_indices_give_different_streams() {
        let a = Rng::new(1, 0, 0, StreamDomain::Photon).next_u32();
        let b = Rng::new(1, 0, 0, StreamDomain::Camera).next_u32();
        let c = Rng::new(1, 0, 1, StreamDomain::Photon).next_u32();
        let d = Rng::new(1, 1, 0, StreamDomain::Photon).next_u32();
        let e = Rng::new(2, 0, 0, StreamDomain::Photon).next_u32();
        let all = [a, b, c, d, e];
        for i in 0..all.len() {
            for j in i + 1..all.len() {
                assert_ne!(all[i], all[j]);
            }
        }
    }

    /// Mean and variance of many draws, and a chi-square test over 64 bins.
    #[test]
    fn uniformity() {
        let n = 1_000_000u32;
        let mut bins = [0u32; 64];
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        for i in 0..n {
            // One draw per stream, across streams, as a GPU dispatch uses it.
            let x = Rng::new(42, 3, i, StreamDomain::Photon).next_f64();
            sum += x;
            sum2 += x * x;
            bins[(x * 64.0) as usize] += 1;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 2e-3, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 1e-3, "var {var}");
        let expected = n as f64 / 64.0;
        let chi2: f64 = bins.iter().map(|&b| (b as f64 - expected).powi(2) / expected).sum();
        // 63 degrees of freedom: the 99.9% quantile is about 103.
        assert!(chi2 < 103.0, "chi2 {chi2}");
    }
}
