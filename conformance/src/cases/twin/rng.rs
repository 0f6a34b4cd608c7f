//! rng.wgsl against arpa_core::base::rng: the pinned known-answer vectors (arpa-core's
//! `rng::tests`, computed by an independent transcription of pcg4d), random streams and
//! the counter's wrap, bit for bit.

use std::cell::Cell;

use arpa_core::base::rng::{Rng, StreamDomain, pcg4d};
use proptest::prelude::*;

use super::{check, f, proptest_batches, run, run_prop};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

/// pcg4d known answers pinned in arpa-core (`KAT_PCG4D_ZERO`, `KAT_PCG4D_1234`).
const KAT_PCG4D: [([u32; 4], [u32; 4]); 2] = [
    (
        [0, 0, 0, 0],
        [251_852_841, 760_645_481, 850_445_371, 3_542_436_074],
    ),
    (
        [1, 2, 3, 4],
        [908_250_390, 4_044_648_920, 3_775_961_919, 45_698_095],
    ),
];

/// First four `next_u32` outputs of the streams pinned in arpa-core (`KAT_STREAMS`).
const KAT_STREAMS: [(u32, u32, u32, u32, [u32; 4]); 5] = [
    (
        0,
        0,
        0,
        0,
        [251_852_841, 2_376_007_650, 3_430_664_116, 2_668_274_553],
    ),
    (
        1,
        0,
        0,
        0,
        [188_542_915, 2_272_300_281, 1_105_341_687, 46_345_155],
    ),
    (
        42,
        7,
        12_345,
        0,
        [1_092_573_700, 1_028_676_220, 2_986_982_013, 957_826_947],
    ),
    (
        0xDEAD_BEEF,
        100_000,
        4_000_000,
        0,
        [2_487_117_684, 3_400_892_403, 3_027_552_238, 2_997_347_576],
    ),
    (
        1,
        0,
        0,
        1,
        [1_262_677_955, 1_481_313_529, 1_287_101_687, 2_947_746_755],
    ),
];

const PCG4D_BODY: &str = "
    let h = arpa_pcg4d(vec4<u32>(in_u(ib), in_u(ib + 1u), in_u(ib + 2u), in_u(ib + 3u)));
    out_u(ob, h.x); out_u(ob + 1u, h.y); out_u(ob + 2u, h.z); out_u(ob + 3u, h.w);";

/// Input (seed, iteration, index, domain, counter); output four u32 draws, then four f32
/// draws (bits) of the same stream continuing, then one next_2d.
const STREAM_BODY: &str = "
    var r = arpa_rng_new(in_u(ib), in_u(ib + 1u), in_u(ib + 2u), in_u(ib + 3u));
    r.counter = in_u(ib + 4u);
    for (var k = 0u; k < 4u; k++) { out_u(ob + k, arpa_rng_next_u32(&r)); }
    for (var k = 4u; k < 8u; k++) { out_f(ob + k, arpa_rng_next_f32(&r)); }
    let p = arpa_rng_next_2d(&r);
    out_f(ob + 8u, p.x); out_f(ob + 9u, p.y);";

/// Random streams per batch, and batches.
const STREAMS: usize = 2048;
const BATCHES: u32 = 4;

fn domain(d: u32) -> StreamDomain {
    [
        StreamDomain::Photon,
        StreamDomain::Camera,
        StreamDomain::Iteration,
        StreamDomain::User,
    ][d as usize]
}

/// The twin's pcg4d on the pinned inputs gives the pinned outputs, and the twin's streams
/// give the pinned first draws, then random streams and the counter wrap agree with the
/// core bit for bit (see the module docs).
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    pcg4d_known_answers(runner)?;
    stream_known_answers(runner)?;
    let n = streams_match_core(runner)?;
    counter_wraps_like_core(runner)?;
    Ok(format!(
        "{} pcg4d + {} stream known answers and {n} random streams (10 draws each) bit-exact, 2-D draw within 2^-24; counter wrap at 2^28 as the core",
        KAT_PCG4D.len(),
        KAT_STREAMS.len()
    ))
}

fn pcg4d_known_answers(runner: &dyn KernelRunner) -> Result<(), String> {
    let input: Vec<u32> = KAT_PCG4D.iter().flat_map(|(i, _)| *i).collect();
    let out = run(runner, "pcg4d KAT", PCG4D_BODY, &input, 4, 4)?;
    for ((inp, expected), got) in KAT_PCG4D.iter().zip(&out) {
        check!(
            got.as_slice() == expected,
            "pcg4d({inp:?}): twin {got:?}, pinned {expected:?}"
        );
    }
    Ok(())
}

fn stream_known_answers(runner: &dyn KernelRunner) -> Result<(), String> {
    let input: Vec<u32> = KAT_STREAMS
        .iter()
        .flat_map(|&(s, it, ix, d, _)| [s, it, ix, d, 0])
        .collect();
    let out = run(runner, "stream KAT", STREAM_BODY, &input, 5, 10)?;
    for (&(s, it, ix, d, expected), got) in KAT_STREAMS.iter().zip(&out) {
        check!(
            got[..4] == expected,
            "stream (seed {s}, iteration {it}, index {ix}, domain {d}): twin {:?}, pinned {expected:?}",
            &got[..4]
        );
    }
    Ok(())
}

/// The core's stream advanced `counter` draws, then the ten outputs the kernel writes.
fn core_outputs(seed: u32, iteration: u32, index: u32, d: u32, counter: u32) -> Vec<u32> {
    let mut r = Rng::new(seed, iteration, index, domain(d));
    for _ in 0..counter {
        r.next_u32();
    }
    let mut f64_draws = r; // next_f64 of the same draws, for the truncation bound
    let mut out: Vec<u32> = (0..4).map(|_| r.next_u32()).collect();
    out.extend((0..4).map(|_| r.next_f32().to_bits()));
    let p = r.next_2d();
    for _ in 0..8 {
        f64_draws.next_f64();
    }
    let q = f64_draws.next_2d();
    assert_eq!((p.x, p.y), (q.x, q.y));
    out.extend([p.x, p.y].map(|x| (x as f32).to_bits()));
    out
}

/// Random streams and positions: u32 and f32 draws bit-identical; the 2-D draw is the
/// core's f64 draw truncated to 24 bits (0 <= f64 - f32 < 2^-24). Returns the number of
/// streams compared.
fn streams_match_core(runner: &dyn KernelRunner) -> Result<usize, String> {
    let compared = Cell::new(0usize);
    let strategy = prop::collection::vec(
        (any::<u32>(), any::<u32>(), any::<u32>(), 0u32..4, 0u32..300),
        STREAMS,
    );
    proptest_batches("twin-rng", BATCHES, &strategy, |cases| {
        let input: Vec<u32> = cases
            .iter()
            .flat_map(|&(s, it, ix, d, c)| [s, it, ix, d, c])
            .collect();
        let out = run_prop(runner, "streams", "", STREAM_BODY, &input, 5, 10)?;
        for (&(s, it, ix, d, c), got) in cases.iter().zip(&out) {
            let want = core_outputs(s, it, ix, d, c);
            prop_assert_eq!(
                &got[..8],
                &want[..8],
                "stream ({}, {}, {}, domain {}) at draw {}",
                s,
                it,
                ix,
                d,
                c
            );
            let mut r = Rng::new(s, it, ix, domain(d));
            for _ in 0..c + 8 {
                r.next_u32();
            }
            let exact = r.next_2d();
            for (g, e) in [f(got[8]), f(got[9])].into_iter().zip([exact.x, exact.y]) {
                let diff = e - g as f64;
                prop_assert!(
                    (0.0..1.0 / 16_777_216.0).contains(&diff),
                    "2-D draw {} vs core {}",
                    g,
                    e
                );
            }
        }
        compared.set(compared.get() + cases.len());
        Ok(())
    })?;
    Ok(compared.get())
}

/// The counter wraps inside its 28 bits exactly as in the core (2^28 draws advanced on the
/// CPU, the counter set directly on the device).
fn counter_wraps_like_core(runner: &dyn KernelRunner) -> Result<(), String> {
    let start = (1u32 << 28) - 2;
    let mut r = Rng::new(9, 8, 7, StreamDomain::Camera);
    for _ in 0..start {
        r.next_u32();
    }
    let want: Vec<u32> = (0..4).map(|_| r.next_u32()).collect();
    let out = run(
        runner,
        "counter wrap",
        STREAM_BODY,
        &[9, 8, 7, 1, start],
        5,
        10,
    )?;
    check!(
        out[0][..4] == want[..],
        "draws across the wrap: twin {:?}, core {want:?}",
        &out[0][..4]
    );
    // The wrapped draws repeat the stream's first ones.
    let mut first = Rng::new(9, 8, 7, StreamDomain::Camera);
    let first = first.next_u32();
    check!(
        out[0][2] == first,
        "first draw after the wrap: twin {}, the stream's first {first}",
        out[0][2]
    );
    let kat = pcg4d([9, 8, 7, 1 << 28])[0];
    check!(
        kat == out[0][2],
        "pcg4d([9, 8, 7, 2^28])[0] = {kat}, twin {}",
        out[0][2]
    );
    Ok(())
}
