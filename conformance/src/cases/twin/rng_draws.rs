//! rng.wgsl's draws that mirror the core's `f64` uses of a 32-bit word, bit for bit:
//! `arpa_rng_next_below(p)` against `rng.next_f64() < p` (the Fresnel choice and Russian
//! roulette of both passes) and `arpa_rng_next_f64_as_f32` against `rng.next_f64() as f32`
//! (the camera's pixel jitter). No tolerance: both are exact integer reformulations.
//!
//! Inputs: random streams at random positions with random probabilities, probabilities
//! placed on and one or two ulps either side of the draw itself (where `<` decides), the
//! ends (0, 1, just below 1, 2⁻³², the smallest normal) and degenerate ones (negative,
//! above 1, ±∞, NaN); for the rounding, words whose dropped bits are exactly half an ulp
//! (ties to even), just above or below it, and words below 2²⁴ (converted exactly), found
//! by scanning a stream on the CPU.

use std::cell::Cell;

use arpa_core::base::rng::{Rng, StreamDomain};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, run};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

/// Random draw positions per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

/// Output: next_below(p) (0/1), then next_f64_as_f32 of the following word, then the
/// counter (two draws consumed).
const BODY: &str = "
    var r = arpa_rng_new(in_u(ib), in_u(ib + 1u), in_u(ib + 2u), in_u(ib + 3u));
    r.counter = in_u(ib + 4u);
    out_u(ob, select(0u, 1u, arpa_rng_next_below(&r, in_f(ib + 5u))));
    out_f(ob + 1u, arpa_rng_next_f64_as_f32(&r));
    out_u(ob + 2u, r.counter);";

fn domain(d: u32) -> StreamDomain {
    [
        StreamDomain::Photon,
        StreamDomain::Camera,
        StreamDomain::Iteration,
        StreamDomain::User,
    ][d as usize]
}

/// One draw position: the stream (seed, iteration, index, domain), the draws already made,
/// and the probability of the `next_below` draw.
#[derive(Clone, Copy, Debug)]
struct Draw {
    stream: [u32; 4],
    counter: u32,
    p: f32,
}

fn core_rng(d: &Draw) -> Rng {
    let mut r = Rng::new(d.stream[0], d.stream[1], d.stream[2], domain(d.stream[3]));
    for _ in 0..d.counter {
        r.next_u32();
    }
    r
}

/// Runs the draws on the device and compares them with the core bit for bit; returns how
/// many were below.
fn check_draws(runner: &dyn KernelRunner, draws: &[Draw]) -> Result<usize, String> {
    let input: Vec<u32> = draws
        .iter()
        .flat_map(|d| {
            [
                d.stream[0],
                d.stream[1],
                d.stream[2],
                d.stream[3],
                d.counter,
                fb(d.p),
            ]
        })
        .collect();
    let out = run(runner, "rng draws", BODY, &input, 6, 3)?;
    let mut below = 0;
    for (d, g) in draws.iter().zip(&out) {
        let mut r = core_rng(d);
        let want_below = r.next_f64() < d.p as f64;
        let want_x = r.next_f64() as f32;
        check!(
            (g[0] == 1) == want_below,
            "next_below for {d:?}: twin {}, core {want_below}",
            g[0]
        );
        check!(
            f(g[1]).to_bits() == want_x.to_bits(),
            "next_f64 as f32 for {d:?}: {} vs core {}",
            f(g[1]),
            want_x
        );
        check!(
            g[2] == d.counter + 2,
            "draws consumed for {d:?}: counter {}, want {}",
            g[2],
            d.counter + 2
        );
        below += want_below as usize;
    }
    Ok(below)
}

/// `p` on the draw of position `d` and `k` ulps away from it.
fn on_the_draw(d: &Draw, k: i32) -> f32 {
    let w = core_rng(d).next_f64() as f32;
    f32::from_bits((w.to_bits() as i64 + k as i64).max(0) as u32)
}

/// Random draws, then degenerate probabilities, ties, near ties and small words, bit for
/// bit (see the module docs).
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let random = draws_match_core(runner)?;
    let ends = ends_ties_and_small_words_match_core(runner)?;
    Ok(format!(
        "{random} random draw pairs and {ends} at ends, ties and small words bit-exact"
    ))
}

/// Random positions and probabilities (a quarter on the draw ± 2 ulps, an eighth at the
/// ends and degenerate values); between 1000 and 3500 of each batch below. Returns the
/// number of draw pairs compared.
fn draws_match_core(runner: &dyn KernelRunner) -> Result<usize, String> {
    let compared = Cell::new(0usize);
    let strategy = prop::collection::vec(
        (
            (any::<u32>(), any::<u32>(), any::<u32>(), 0u32..4),
            0u32..300,
            0.0f32..1.0,
            0u32..8,
            -2i32..=2,
        ),
        ITEMS,
    );
    proptest_batches("twin-rng-draws", BATCHES, &strategy, |cases| {
        let special = [
            0.0,
            1.0,
            1.0 - f32::EPSILON / 2.0,
            2.328_306_4e-10,
            f32::MIN_POSITIVE,
            -0.25,
            1.5,
            f32::NAN,
        ];
        let draws: Vec<Draw> = cases
            .iter()
            .map(|&(s, counter, p, kind, k)| {
                let mut d = Draw {
                    stream: [s.0, s.1, s.2, s.3],
                    counter,
                    p,
                };
                match kind {
                    0..=3 => {}
                    4 | 5 => d.p = on_the_draw(&d, k),
                    _ => d.p = special[(counter % special.len() as u32) as usize],
                }
                d
            })
            .collect();
        let below = check_draws(runner, &draws).map_err(TestCaseError::fail)?;
        prop_assert!(below > 1000 && below < 3500, "below {}", below);
        compared.set(compared.get() + draws.len());
        Ok(())
    })?;
    Ok(compared.get())
}

/// Degenerate probabilities, and the rounding of words at ties, just off ties and below
/// 2²⁴, found by scanning a stream. Returns the number of draw pairs compared.
fn ends_ties_and_small_words_match_core(runner: &dyn KernelRunner) -> Result<usize, String> {
    let stream = [12_345, 6, 789, 1];
    let mut draws = Vec::new();
    let (mut ties, mut near, mut small) = (0, 0, 0);
    let mut r = Rng::new(stream[0], stream[1], stream[2], domain(stream[3]));
    for counter in 0..3_000_000u32 {
        let w = r.next_u32();
        if counter == 0 {
            continue;
        }
        let drop = 8u32.saturating_sub(w.leading_zeros());
        let class = if w < 1 << 24 {
            small += 1;
            small <= 16
        } else {
            let rem = w & ((1 << drop) - 1);
            let half = 1 << (drop - 1);
            if rem == half {
                ties += 1;
                ties <= 64
            } else if rem.abs_diff(half) == 1 {
                near += 1;
                near <= 64
            } else {
                false
            }
        };
        if class {
            // The word is the second draw of the kernel: start one draw earlier.
            draws.push(Draw {
                stream,
                counter: counter - 1,
                p: 0.5,
            });
        }
        if ties >= 64 && near >= 64 && small >= 16 {
            break;
        }
    }
    check!(
        ties >= 64 && near >= 64 && small >= 16,
        "ties {ties}, near ties {near}, small {small}"
    );
    for p in [
        0.0,
        -0.0,
        -1.0,
        1.0,
        2.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        1.0 - f32::EPSILON / 2.0,
    ] {
        for counter in 0..16 {
            draws.push(Draw { stream, counter, p });
        }
    }
    check_draws(runner, &draws)?;
    Ok(draws.len())
}
